/* Scene configuration parser (see scene_config.h), on cJSON. */
#include "io/scene_config.h"
#include "io/textfile.h"

#include "io/json_keys.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <fnmatch.h>
#include <libgen.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

void cv_light_spec_default(cv_light_spec *l) {
  memset(l, 0, sizeof *l);
  l->scale = 1.0;
  l->extract_sun = 1;
  l->turbidity = 3.0;
  l->sun_elevation_deg = 35.0;
  l->ground_albedo = 0.2;
}

void cv_scene_config_default(cv_scene_config *c) {
  memset(c, 0, sizeof *c);
  snprintf(c->source, sizeof c->source, "(built-in)");
  c->mesh_is_cabin = 1;
  c->cabin_tess = CV_SCENE_DEFAULT_TESS;
  c->clean_enabled = 1;
  c->weld_tolerance = c->crease_angle_deg = c->crack_width = c->sliver_aspect = -1;
  c->bands = 8; /* with prt.tail and --split 64: the issue 13 targets (docs/reference.md) */
  c->rays = 1024;
  c->bounces = 2;
  c->seed = 1;
  c->spread = 0.5;
  c->window_sampling = 1;
  c->tail = 1;
  c->error_budget = 0.05;
  cv_placement_default(&c->place);
  cv_light_spec_default(&c->light);
}

void cv_scene_config_free(cv_scene_config *c) {
  free(c->overrides);
  c->overrides = NULL;
  c->n_overrides = 0;
}

static int exists(const char *p) { return access(p, R_OK) == 0; }

int cv_resolve_env_path(const char *name, const char *base_dir, char out[CV_PATH_MAX],
                        cv_err *err) {
  char buf[CV_PATH_MAX];
  if (name[0] == '/' || (base_dir == NULL && exists(name))) {
    if (!exists(name)) return cv_err_set(err, CV_ERR_NOT_FOUND, "%s: no such file", name);
    snprintf(out, CV_PATH_MAX, "%s", name);
    return CV_OK;
  }
  if (base_dir) {
    snprintf(buf, sizeof buf, "%s/%s", base_dir, name);
    if (exists(buf)) {
      snprintf(out, CV_PATH_MAX, "%s", buf);
      return CV_OK;
    }
  }
  if (exists(name)) {
    snprintf(out, CV_PATH_MAX, "%s", name);
    return CV_OK;
  }
  snprintf(buf, sizeof buf, "%s/%s", CAVE_BLENDER_WORLD_DIR, name);
  if (exists(buf)) {
    snprintf(out, CV_PATH_MAX, "%s", buf);
    return CV_OK;
  }
  return cv_err_set(err, CV_ERR_NOT_FOUND,
                    "environment map '%s' not found (as given, next to the config, or in %s)",
                    name, CAVE_BLENDER_WORLD_DIR);
}

/* --- small typed accessors that name the field on error ------------------ */

typedef struct {
  const char *file;
  cv_err *err;
} ctx;

static int fail(ctx *x, const char *field, const char *fmt, const char *detail) {
  char what[256];
  snprintf(what, sizeof what, fmt, detail);
  return cv_err_set(x->err, CV_ERR_CONFIG, "%s: %s: %s", x->file, field, what);
}

/* Rejects keys not in the NULL-terminated allowed list. */
static int only_keys(ctx *x, const cJSON *obj, const char *path, const char *const *allowed) {
  if (!cJSON_IsObject(obj)) return fail(x, path, "expected an object%s", "");
  const cJSON *it;
  cJSON_ArrayForEach(it, obj) {
    if (!cv_json_key_allowed(it->string, allowed)) {
      char field[256], list[200]; /* fits fail()'s 256-byte message */
      char kbuf[64];
      snprintf(field, sizeof field, "%s%s%s", path, path[0] ? "." : "",
               cv_json_key_show(it->string, kbuf, sizeof kbuf));
      cv_json_key_list(allowed, list, sizeof list);
      return fail(x, field, "unknown field (expected one of: %s)", list);
    }
  }
  return CV_OK;
}

static int get_num(ctx *x, const cJSON *obj, const char *key, const char *path, double lo,
                   double hi, double *out) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
  if (!v) return CV_OK;
  char field[256];
  snprintf(field, sizeof field, "%s.%s", path, key);
  if (!cJSON_IsNumber(v) || !isfinite(v->valuedouble))
    return fail(x, field, "expected a number%s", "");
  if (v->valuedouble < lo || v->valuedouble > hi) {
    char rng[128];
    snprintf(rng, sizeof rng, "%.10g is outside [%.10g, %.10g]", v->valuedouble, lo, hi);
    return fail(x, field, "%s", rng);
  }
  *out = v->valuedouble;
  return CV_OK;
}

static int get_int(ctx *x, const cJSON *obj, const char *key, const char *path, int lo, int hi,
                   int *out) {
  double d = *out;
  int st = get_num(x, obj, key, path, lo, hi, &d);
  if (st) return st;
  if (d != floor(d)) {
    char field[256];
    snprintf(field, sizeof field, "%s.%s", path, key);
    return fail(x, field, "expected an integer%s", "");
  }
  *out = (int)d;
  return CV_OK;
}

static int get_rgb(ctx *x, const cJSON *v, const char *field, double lo, double hi,
                   double out[3]) {
  if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) != 3)
    return fail(x, field, "expected an array of 3 numbers [r, g, b]%s", "");
  for (int k = 0; k < 3; k++) {
    const cJSON *e = cJSON_GetArrayItem(v, k);
    if (!cJSON_IsNumber(e) || !isfinite(e->valuedouble) || e->valuedouble < lo ||
        e->valuedouble > hi) {
      char rng[96];
      snprintf(rng, sizeof rng, "expected numbers in [%.10g, %.10g]", lo, hi);
      return fail(x, field, "%s", rng);
    }
    out[k] = e->valuedouble;
  }
  return CV_OK;
}

static void resolve_rel(const char *base, const char *p, char out[CV_PATH_MAX]) {
  if (p[0] == '/' || !base)
    snprintf(out, CV_PATH_MAX, "%s", p);
  else
    snprintf(out, CV_PATH_MAX, "%s/%s", base, p);
}

static int get_vec3(ctx *x, const cJSON *obj, const char *key, const char *path, double out[3]) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
  if (!v) return CV_OK;
  char field[256];
  snprintf(field, sizeof field, "%s.%s", path, key);
  return get_rgb(x, v, field, -1e9, 1e9, out);
}

/* mesh.units / mesh.up / mesh.transform (see mesh/place.h). */
static int parse_placement(ctx *x, const cJSON *o, cv_placement *p) {
  const cJSON *u = cJSON_GetObjectItemCaseSensitive(o, "units");
  cv_err e;
  if (cJSON_IsNumber(u)) {
    if (!(isfinite(u->valuedouble) && u->valuedouble > 0))
      return fail(x, "mesh.units", "expected %s", cv_units_expected());
    p->unit_m = u->valuedouble;
  } else if (u) {
    if (!cJSON_IsString(u) || cv_parse_units(u->valuestring, &p->unit_m, &e))
      return fail(x, "mesh.units", "%.200s", cJSON_IsString(u) ? e.msg : "expected a string or a number");
  }
  const cJSON *up = cJSON_GetObjectItemCaseSensitive(o, "up");
  if (up && (!cJSON_IsString(up) || cv_parse_up(up->valuestring, &p->up, &e)))
    return fail(x, "mesh.up", "%.200s", cJSON_IsString(up) ? e.msg : "expected \"y\" or \"z\"");
  const cJSON *t = cJSON_GetObjectItemCaseSensitive(o, "transform");
  if (!t) return CV_OK;
  static const char *const keys[] = {"translate", "rotate_deg", "scale", NULL};
  int st = only_keys(x, t, "mesh.transform", keys);
  if (st) return st;
  if ((st = get_vec3(x, t, "translate", "mesh.transform", p->translate))) return st;
  if ((st = get_vec3(x, t, "rotate_deg", "mesh.transform", p->rotate_deg))) return st;
  if ((st = get_num(x, t, "scale", "mesh.transform", 1e-9, 1e9, &p->scale))) return st;
  return CV_OK;
}

static int parse_mesh(ctx *x, const cJSON *o, const char *base, cv_scene_config *c) {
  static const char *const keys[] = {"source", "path", "tess", "length", "width", "height",
                                     "units", "up", "transform", NULL};
  int st = only_keys(x, o, "mesh", keys);
  if (st) return st;
  const cJSON *src = cJSON_GetObjectItemCaseSensitive(o, "source");
  const cJSON *path = cJSON_GetObjectItemCaseSensitive(o, "path");
  if (src && (!cJSON_IsString(src) ||
              (strcmp(src->valuestring, "cabin") && strcmp(src->valuestring, "file"))))
    return fail(x, "mesh.source", "expected \"cabin\" or \"file\"%s", "");
  c->mesh_is_cabin = !(src ? strcmp(src->valuestring, "file") == 0 : path != NULL);
  if (!c->mesh_is_cabin) {
    if (!cJSON_IsString(path) || !path->valuestring[0])
      return fail(x, "mesh.path", "expected the mesh file's path (OBJ, PLY or glTF)%s", "");
    resolve_rel(base, path->valuestring, c->mesh_path);
    if ((st = parse_placement(x, o, &c->place))) return st;
  } else if (path) {
    return fail(x, "mesh.path", "not allowed with \"source\": \"cabin\"%s", "");
  } else {
    static const char *const file_only[] = {"units", "up", "transform", NULL};
    for (int i = 0; file_only[i]; i++)
      if (cJSON_GetObjectItemCaseSensitive(o, file_only[i])) {
        char field[64];
        snprintf(field, sizeof field, "mesh.%s", file_only[i]);
        return fail(x, field, "only for a mesh file (the cabin is built in metres, Y up)%s", "");
      }
  }
  if ((st = get_int(x, o, "tess", "mesh", 1, 64, &c->cabin_tess))) return st;
  if ((st = get_num(x, o, "length", "mesh", 1.5, 5.0, &c->cabin_length))) return st;
  if ((st = get_num(x, o, "width", "mesh", 1.0, 2.5, &c->cabin_width))) return st;
  return get_num(x, o, "height", "mesh", 0.9, 2.0, &c->cabin_height);
}

static int parse_materials(ctx *x, const cJSON *a, cv_scene_config *c) {
  if (!cJSON_IsArray(a)) return fail(x, "materials", "expected an array of objects%s", "");
  int n = cJSON_GetArraySize(a);
  c->overrides = calloc((size_t)n + 1, sizeof *c->overrides);
  if (!c->overrides) return cv_err_set(x->err, CV_ERR_NOMEM, "out of memory");
  static const char *const keys[] = {"name", "albedo", "tag", NULL};
  for (int i = 0; i < n; i++) {
    const cJSON *o = cJSON_GetArrayItem(a, i);
    char path[64];
    snprintf(path, sizeof path, "materials[%d]", i);
    int st = only_keys(x, o, path, keys);
    if (st) return st;
    cv_scene_material *ov = &c->overrides[c->n_overrides++];
    const cJSON *name = cJSON_GetObjectItemCaseSensitive(o, "name");
    char field[96];
    snprintf(field, sizeof field, "%s.name", path);
    if (!cJSON_IsString(name) || !name->valuestring[0] || strlen(name->valuestring) > 63)
      return fail(x, field, "expected a material name or glob pattern (1..63 characters)%s", "");
    snprintf(ov->name, sizeof ov->name, "%s", name->valuestring);
    const cJSON *alb = cJSON_GetObjectItemCaseSensitive(o, "albedo");
    if (alb) {
      double v[3];
      snprintf(field, sizeof field, "%s.albedo", path);
      if ((st = get_rgb(x, alb, field, 0.0, 1.0, v))) return st;
      for (int k = 0; k < 3; k++) ov->albedo[k] = (float)v[k];
      ov->has_albedo = 1;
    }
    const cJSON *tag = cJSON_GetObjectItemCaseSensitive(o, "tag");
    if (tag) {
      snprintf(field, sizeof field, "%s.tag", path);
      if (!cJSON_IsString(tag)) return fail(x, field, "expected \"window\", \"lcd\" or \"none\"%s", "");
      if (!strcmp(tag->valuestring, "window")) ov->flags = CV_MAT_WINDOW;
      else if (!strcmp(tag->valuestring, "lcd")) ov->flags = CV_MAT_LCD;
      else if (!strcmp(tag->valuestring, "none")) ov->flags = 0;
      else return fail(x, field, "expected \"window\", \"lcd\" or \"none\"%s", "");
      ov->has_tag = 1;
    }
  }
  return CV_OK;
}

static int parse_prt(ctx *x, const cJSON *o, cv_scene_config *c) {
  static const char *const keys[] = {"bands", "rays", "bounces", "seed", "spread", "window_sampling",
                                     "error_budget", "tail", NULL};
  int st = only_keys(x, o, "prt", keys);
  if (st) return st;
  const cJSON *b = cJSON_GetObjectItemCaseSensitive(o, "bands");
  if (cJSON_IsString(b)) {
    if (strcmp(b->valuestring, "auto")) return fail(x, "prt.bands", "expected 2..8 or \"auto\"%s", "");
    c->bands = 0;
  } else if (b && (st = get_int(x, o, "bands", "prt", 2, 8, &c->bands))) {
    return st;
  }
  const cJSON *r = cJSON_GetObjectItemCaseSensitive(o, "rays");
  if (cJSON_IsString(r)) {
    if (strcmp(r->valuestring, "auto")) return fail(x, "prt.rays", "expected 1..16777216 or \"auto\"%s", "");
    c->rays = 0;
  } else if (r && (st = get_int(x, o, "rays", "prt", 1, 1 << 24, &c->rays))) {
    return st;
  }
  if ((st = get_int(x, o, "bounces", "prt", 0, 16, &c->bounces))) return st;
  int seed = (int)c->seed;
  if ((st = get_int(x, o, "seed", "prt", 0, 2147483647, &seed))) return st;
  c->seed = (uint32_t)seed;
  if ((st = get_num(x, o, "spread", "prt", 0.0, 1.0, &c->spread))) return st;
  const cJSON *ws = cJSON_GetObjectItemCaseSensitive(o, "window_sampling");
  if (ws) {
    if (!cJSON_IsBool(ws)) return fail(x, "prt.window_sampling", "expected true or false%s", "");
    c->window_sampling = cJSON_IsTrue(ws);
  }
  const cJSON *tl = cJSON_GetObjectItemCaseSensitive(o, "tail");
  if (tl) {
    if (!cJSON_IsBool(tl)) return fail(x, "prt.tail", "expected true or false%s", "");
    c->tail = cJSON_IsTrue(tl);
  }
  return get_num(x, o, "error_budget", "prt", 1e-4, 1.0, &c->error_budget);
}

static int parse_clean(ctx *x, const cJSON *o, cv_scene_config *c) {
  static const char *const keys[] = {"enabled", "weld_tolerance", "crease_angle_deg",
                                     "crack_width", "sliver_aspect", NULL};
  int st = only_keys(x, o, "clean", keys);
  if (st) return st;
  const cJSON *en = cJSON_GetObjectItemCaseSensitive(o, "enabled");
  if (en) {
    if (!cJSON_IsBool(en)) return fail(x, "clean.enabled", "expected true or false%s", "");
    c->clean_enabled = cJSON_IsTrue(en);
  }
  if ((st = get_num(x, o, "weld_tolerance", "clean", 0, 0.1, &c->weld_tolerance))) return st;
  if ((st = get_num(x, o, "crease_angle_deg", "clean", 0, 180, &c->crease_angle_deg))) return st;
  if ((st = get_num(x, o, "crack_width", "clean", 0, 0.1, &c->crack_width))) return st;
  return get_num(x, o, "sliver_aspect", "clean", 1, 1e12, &c->sliver_aspect);
}


int cv_light_spec_parse_json(const void *json, const char *file, const char *base_dir,
                             cv_light_spec *l, cv_err *err) {
  const cJSON *o = json;
  ctx x = {file, err};
  static const char *const keys[] = {"env", "weights", "scale", "illuminance", "sun", "sky",
                                     "constant", "yaw_deg", "pitch_deg", "roll_deg", "absolute",
                                     NULL};
  int st = only_keys(&x, o, "lighting", keys);
  if (st) return st;
  const cJSON *env = cJSON_GetObjectItemCaseSensitive(o, "env");
  const cJSON *sky = cJSON_GetObjectItemCaseSensitive(o, "sky");
  const cJSON *cst = cJSON_GetObjectItemCaseSensitive(o, "constant");
  if (!!env + !!sky + !!cst != 1)
    return fail(&x, "lighting", "expected exactly one of \"env\", \"sky\", \"constant\"%s", "");
  if (env) {
    l->kind = CV_LIGHT_ENV;
    if (cJSON_IsString(env)) {
      if (!env->valuestring[0]) return fail(&x, "lighting.env", "expected a file name, got \"\"%s", "");
      if ((st = cv_resolve_env_path(env->valuestring, base_dir, l->env[0], err)))
        return cv_err_prefix(err, "%s: lighting.env", file);
      l->n_env = 1;
      l->weight[0] = 1;
    } else if (cJSON_IsArray(env) && cJSON_GetArraySize(env) >= 1 &&
               cJSON_GetArraySize(env) <= CV_MAX_ENV_MAPS) {
      l->n_env = cJSON_GetArraySize(env);
      for (int i = 0; i < l->n_env; i++) {
        const cJSON *e = cJSON_GetArrayItem(env, i);
        if (!cJSON_IsString(e) || !e->valuestring[0])
          return fail(&x, "lighting.env", "expected file names (an empty one is none)%s", "");
        if ((st = cv_resolve_env_path(e->valuestring, base_dir, l->env[i], err)))
          return cv_err_prefix(err, "%s: lighting.env[%d]", file, i);
        l->weight[i] = 1.0 / l->n_env;
      }
    } else {
      return fail(&x, "lighting.env", "expected a file name or an array of 1..8 file names%s", "");
    }
    const cJSON *w = cJSON_GetObjectItemCaseSensitive(o, "weights");
    if (w) {
      if (!cJSON_IsArray(w) || cJSON_GetArraySize(w) != l->n_env)
        return fail(&x, "lighting.weights", "expected one number per env map%s", "");
      double sum = 0;
      for (int i = 0; i < l->n_env; i++) {
        const cJSON *e = cJSON_GetArrayItem(w, i);
        if (!cJSON_IsNumber(e) || !(e->valuedouble >= 0) || !isfinite(e->valuedouble))
          return fail(&x, "lighting.weights", "expected non-negative numbers%s", "");
        l->weight[i] = e->valuedouble;
        sum += e->valuedouble;
      }
      if (!(sum > 0)) return fail(&x, "lighting.weights", "expected a positive sum%s", "");
    }
    const cJSON *sun = cJSON_GetObjectItemCaseSensitive(o, "sun");
    if (sun) {
      if (!cJSON_IsString(sun) || (strcmp(sun->valuestring, "auto") && strcmp(sun->valuestring, "none")))
        return fail(&x, "lighting.sun", "expected \"auto\" or \"none\"%s", "");
      l->extract_sun = strcmp(sun->valuestring, "auto") == 0;
    }
    if ((st = get_num(&x, o, "scale", "lighting", 0, 1e9, &l->scale))) return st;
    const cJSON *lux = cJSON_GetObjectItemCaseSensitive(o, "illuminance");
    if (lux && cJSON_GetObjectItemCaseSensitive(o, "scale"))
      return fail(&x, "lighting.illuminance", "not together with \"scale\" (both set the level)%s", "");
    if (cJSON_IsString(lux) && !strcmp(lux->valuestring, "auto")) {
      l->illuminance = CV_ILLUMINANCE_AUTO;
    } else if (lux && (st = get_num(&x, o, "illuminance", "lighting", 1e-6, 1e7, &l->illuminance))) {
      return fail(&x, "lighting.illuminance", "expected lux in [1e-6, 1e7] or \"auto\"%s", "");
    }
    const cJSON *abs_ = cJSON_GetObjectItemCaseSensitive(o, "absolute");
    if (abs_ && !cJSON_IsBool(abs_))
      return fail(&x, "lighting.absolute", "expected true or false%s", "");
    if (abs_ && lux)
      return fail(&x, "lighting.absolute", "not together with \"illuminance\" (which already "
                  "calibrates)%s", "");
    l->absolute = cJSON_IsTrue(abs_);
  } else if (sky) {
    l->kind = CV_LIGHT_SKY;
    static const char *const skeys[] = {"turbidity", "sun_elevation_deg", "sun_azimuth_deg",
                                        "ground_albedo", NULL};
    if ((st = only_keys(&x, sky, "lighting.sky", skeys))) return st;
    if ((st = get_num(&x, sky, "turbidity", "lighting.sky", 2, 10, &l->turbidity))) return st;
    if ((st = get_num(&x, sky, "sun_elevation_deg", "lighting.sky", -10, 90, &l->sun_elevation_deg)))
      return st;
    if ((st = get_num(&x, sky, "sun_azimuth_deg", "lighting.sky", -360, 360, &l->sun_azimuth_deg)))
      return st;
    if ((st = get_num(&x, sky, "ground_albedo", "lighting.sky", 0, 1, &l->ground_albedo))) return st;
  } else {
    l->kind = CV_LIGHT_CONSTANT;
    if ((st = get_rgb(&x, cst, "lighting.constant", 0, 1e9, l->constant))) return st;
  }
  if (l->kind != CV_LIGHT_ENV && cJSON_GetObjectItemCaseSensitive(o, "illuminance"))
    return fail(&x, "lighting.illuminance", "only for \"env\" maps (the sky is absolute)%s", "");
  if (l->kind != CV_LIGHT_ENV && cJSON_GetObjectItemCaseSensitive(o, "absolute"))
    return fail(&x, "lighting.absolute", "only for \"env\" maps (the sky and a constant are "
                "in cd/m^2)%s", "");
  if ((st = get_num(&x, o, "yaw_deg", "lighting", -360, 360, &l->yaw_deg))) return st;
  if ((st = get_num(&x, o, "pitch_deg", "lighting", -90, 90, &l->pitch_deg))) return st;
  return get_num(&x, o, "roll_deg", "lighting", -180, 180, &l->roll_deg);
}

int cv_scene_config_load(const char *path, cv_scene_config *c, cv_err *err) {
  cv_scene_config_default(c);
  snprintf(c->source, sizeof c->source, "%s", path);
  char *text = NULL;
  int rst = cv_read_json_file(path, &text, err);
  if (rst) return rst;
  const char *end = NULL;
  cJSON *root = cJSON_ParseWithOpts(text, &end, 1);
  if (!root) {
    int line, col;
    char what[128];
    cv_json_syntax_error(text, end, &line, &col, what, sizeof what);
    free(text);
    return cv_err_set(err, CV_ERR_CONFIG, "%s:%d:%d: %s", path, line, col, what);
  }
  free(text);
  char dirbuf[CV_PATH_MAX];
  snprintf(dirbuf, sizeof dirbuf, "%s", path);
  const char *base = dirname(dirbuf);
  ctx x = {path, err};
  static const char *const keys[] = {"mesh", "materials", "clean", "prt", "lighting", "lcd", NULL};
  int st = only_keys(&x, root, "", keys);
  const cJSON *o;
  /* "lcd": the panel settings, read and checked field by field by
   * src/lcd/lcd_config.c (cv_lcd_config_load_scene), which this layer
   * cannot call; only its type is checked here */
  if (!st && (o = cJSON_GetObjectItemCaseSensitive(root, "lcd")) && !cJSON_IsObject(o))
    st = cv_err_set(err, CV_ERR_CONFIG, "%s: lcd: expected an object", path);
  if (!st && (o = cJSON_GetObjectItemCaseSensitive(root, "mesh"))) st = parse_mesh(&x, o, base, c);
  if (!st && (o = cJSON_GetObjectItemCaseSensitive(root, "materials"))) st = parse_materials(&x, o, c);
  if (!st && (o = cJSON_GetObjectItemCaseSensitive(root, "clean"))) st = parse_clean(&x, o, c);
  if (!st && (o = cJSON_GetObjectItemCaseSensitive(root, "prt"))) st = parse_prt(&x, o, c);
  if (!st && (o = cJSON_GetObjectItemCaseSensitive(root, "lighting")))
    st = cv_light_spec_parse_json(o, path, base, &c->light, err);
  cJSON_Delete(root);
  if (st) cv_scene_config_free(c);
  return st;
}

int cv_scene_apply_overrides(const cv_scene_config *c, cv_mesh *m, cv_err *err) {
  return cv_scene_apply_overrides_ex(c, m, NULL, err);
}

int cv_scene_apply_overrides_ex(const cv_scene_config *c, cv_mesh *m,
                                cv_override_count *counts, cv_err *err) {
  /* check every pattern first, so that nothing is changed when one fails */
  for (int i = 0; i < c->n_overrides; i++) {
    int any = 0;
    for (size_t k = 0; k < m->nm && !any; k++)
      any = fnmatch(c->overrides[i].name, m->mats[k].name, 0) == 0;
    if (!any)
      return cv_err_set(err, CV_ERR_CONFIG,
                        "%s: materials[%d].name: pattern '%s' matches none of the mesh's %zu "
                        "materials (cave materials lists them)",
                        c->source, i, c->overrides[i].name, m->nm);
  }
  for (int i = 0; i < c->n_overrides; i++) {
    const cv_scene_material *ov = &c->overrides[i];
    cv_override_count n = {0, 0};
    for (size_t k = 0; k < m->nm; k++) {
      if (fnmatch(ov->name, m->mats[k].name, 0) != 0) continue;
      n.materials++;
      if (ov->has_albedo) memcpy(m->mats[k].albedo, ov->albedo, sizeof ov->albedo);
      if (ov->has_tag) m->mats[k].flags = ov->flags;
      for (size_t t = 0; t < m->nt; t++) n.triangles += m->tri_mat[t] == k;
    }
    if (counts) counts[i] = n;
  }
  return CV_OK;
}
