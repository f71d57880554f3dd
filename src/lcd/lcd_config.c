/* The "lcd" settings block (see lcd_config.h), on cJSON. */
#include "lcd/lcd_config.h"

#include "io/textfile.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/json_keys.h"
#include "lcd/brdf.h"

void cv_lcd_config_default(cv_lcd_config *c) {
  memset(c, 0, sizeof *c);
  c->width = 400;
  c->height = 0;
  c->spp = 40;
  c->rounds = 1;
  snprintf(c->brdf, sizeof c->brdf, "%s", CV_BRDF_BUILTIN_ANTIGLARE);
  c->content_luminance = CV_LCD_WHITE_DEFAULT;
  c->black_luminance = -1;
  c->cr_min = 3;
  c->age = 40;
  c->pigment = 0.5;
  c->eye_tolerance = 0.005;
  c->brdf_fraction = 0.9;
  c->seed = 1;
  c->env_width = 1024;
  c->sun_samples = 16;
  c->clamp = 0;
}

static int num(const char *file, const cJSON *o, const char *key, double lo, double hi,
               int integer, double *out, cv_err *err) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  if (!v) return CV_OK;
  if (!cJSON_IsNumber(v) || !isfinite(v->valuedouble))
    return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.%s: expected a number", file, key);
  if (v->valuedouble < lo || v->valuedouble > hi)
    return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.%s: %.10g is outside [%.10g, %.10g]", file, key,
                      v->valuedouble, lo, hi);
  if (integer && v->valuedouble != floor(v->valuedouble))
    return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.%s: expected an integer", file, key);
  *out = v->valuedouble;
  return CV_OK;
}

static int path_field(const char *file, const char *base, const cJSON *o, const char *key,
                      int allow_builtin, char out[CV_PATH_MAX], cv_err *err) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  if (!v) return CV_OK;
  if (!cJSON_IsString(v))
    return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.%s: expected a file name (string)", file, key);
  const char *s = v->valuestring;
  int absolute = !s[0] || s[0] == '/' || (allow_builtin && !strncmp(s, "builtin:", 8));
  size_t nb = absolute ? 0 : strlen(base) + 1, ns = strlen(s);
  if (nb + ns >= CV_PATH_MAX)
    return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.%s: path longer than %d bytes", file, key,
                      CV_PATH_MAX - 1);
  if (nb) {
    memcpy(out, base, nb - 1);
    out[nb - 1] = '/';
  }
  memcpy(out + nb, s, ns + 1);
  return CV_OK;
}

double cv_lcd_config_black(const cv_lcd_config *c) {
  return c->black_luminance >= 0 ? c->black_luminance : CV_LCD_BLACK_LEVEL * c->content_luminance;
}

/* A content file must exist when the config is read: a missing one fails
 * before any long work. */
static int content_readable(const char *file, const char *key, const char *content, cv_err *err) {
  if (!content[0]) return CV_OK;
  FILE *f = fopen(content, "rb");
  if (!f)
    return cv_err_set(err, CV_ERR_CONFIG, "%s: %s: %s: cannot open (%s)", file, key, content,
                      strerror(errno));
  fclose(f);
  return CV_OK;
}

static int name_ok(const char *s) {
  size_t n = strlen(s);
  if (n < 1 || n >= CV_LCD_NAME_MAX) return 0;
  for (size_t i = 0; i < n; i++) {
    const char ch = s[i];
    if (!((ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') ||
          ch == '_' || ch == '-'))
      return 0;
  }
  return 1;
}

/* lcd.panels[i].corners: three points, a rectangle's lower-left,
 * lower-right and upper-left corners. */
static int corners_field(const char *file, const char *key, const cJSON *v, double out[3][3],
                         cv_err *err) {
  if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) != 3)
    return cv_err_set(err, CV_ERR_CONFIG,
                      "%s: %s: expected [[x,y,z] lower-left, [x,y,z] lower-right, [x,y,z] upper-left]",
                      file, key);
  for (int i = 0; i < 3; i++) {
    const cJSON *pt = cJSON_GetArrayItem(v, i);
    if (!cJSON_IsArray(pt) || cJSON_GetArraySize(pt) != 3)
      return cv_err_set(err, CV_ERR_CONFIG, "%s: %s[%d]: expected [x, y, z] in metres", file, key, i);
    for (int k = 0; k < 3; k++) {
      const cJSON *x = cJSON_GetArrayItem(pt, k);
      if (!cJSON_IsNumber(x) || !isfinite(x->valuedouble) || fabs(x->valuedouble) > 1e4)
        return cv_err_set(err, CV_ERR_CONFIG, "%s: %s[%d]: expected [x, y, z] in metres", file, key, i);
      out[i][k] = x->valuedouble;
    }
  }
  double u[3], v2[3], lu = 0, lv = 0, d = 0;
  for (int k = 0; k < 3; k++) {
    u[k] = out[1][k] - out[0][k];
    v2[k] = out[2][k] - out[0][k];
    lu += u[k] * u[k];
    lv += v2[k] * v2[k];
    d += u[k] * v2[k];
  }
  lu = sqrt(lu), lv = sqrt(lv);
  if (!(lu >= 0.005 && lv >= 0.005))
    return cv_err_set(err, CV_ERR_CONFIG, "%s: %s: sides of %.4g and %.4g m (at least 5 mm expected)",
                      file, key, lu, lv);
  if (fabs(d / (lu * lv)) > 0.01)
    return cv_err_set(err, CV_ERR_CONFIG,
                      "%s: %s: not a rectangle: the sides meet at %.2f deg (90 +- 0.6 expected)", file,
                      key, acos(d / (lu * lv)) * 180 / M_PI);
  return CV_OK;
}

static int resolution_field(const char *file, const char *key, const cJSON *res, int *w, int *h,
                            cv_err *err) {
  const cJSON *a = cJSON_GetArrayItem(res, 0), *b = cJSON_GetArrayItem(res, 1);
  if (!cJSON_IsArray(res) || cJSON_GetArraySize(res) != 2 || !cJSON_IsNumber(a) ||
      !cJSON_IsNumber(b) || a->valuedouble != floor(a->valuedouble) ||
      b->valuedouble != floor(b->valuedouble) || a->valuedouble < 1 || a->valuedouble > 16384 ||
      b->valuedouble < 1 || b->valuedouble > 16384)
    return cv_err_set(err, CV_ERR_CONFIG, "%s: %s: expected [width, height], integers in 1..16384",
                      file, key);
  *w = (int)a->valuedouble;
  *h = (int)b->valuedouble;
  return CV_OK;
}

/* One entry of lcd.panels. */
static int panel_entry(const char *file, const char *base, const cJSON *e, int i,
                       cv_lcd_panel_config *pc, cv_err *err) {
  static const char *const pkeys[] = {"name", "corners", "resolution", "brdf", "content",
                                      "content_luminance", "black_luminance", NULL};
  char key[96], list[300];
  memset(pc, 0, sizeof *pc);
  pc->content_luminance = -1;
  pc->black_luminance = -2;
  if (!cJSON_IsObject(e))
    return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.panels[%d]: expected an object", file, i);
  const cJSON *it;
  cJSON_ArrayForEach(it, e) {
    if (!cv_json_key_allowed(it->string, pkeys)) {
      char kbuf[128];
      cv_json_key_list(pkeys, list, sizeof list);
      return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.panels[%d].%s: unknown field (expected one of: %s)",
                        file, i, cv_json_key_show(it->string, kbuf, sizeof kbuf), list);
    }
  }
  const cJSON *nm = cJSON_GetObjectItemCaseSensitive(e, "name");
  if (!cJSON_IsString(nm) || !name_ok(nm->valuestring))
    return cv_err_set(err, CV_ERR_CONFIG,
                      "%s: lcd.panels[%d].name: expected 1..%d letters, digits, '_' or '-' (required)",
                      file, i, CV_LCD_NAME_MAX - 1);
  snprintf(pc->name, sizeof pc->name, "%s", nm->valuestring);
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(e, "corners");
  snprintf(key, sizeof key, "lcd.panels[%d].corners", i);
  if (v) {
    int st = corners_field(file, key, v, pc->corners, err);
    if (st) return st;
    pc->has_corners = 1;
  }
  v = cJSON_GetObjectItemCaseSensitive(e, "resolution");
  snprintf(key, sizeof key, "lcd.panels[%d].resolution", i);
  if (v && resolution_field(file, key, v, &pc->width, &pc->height, err)) return CV_ERR_CONFIG;
  snprintf(key, sizeof key, "panels[%d].content_luminance", i);
  double d = -1;
  int st = num(file, e, "content_luminance", 0, 1e6, 0, &d, err);
  if (st) return cv_err_set(err, st, "%s: lcd.%s: expected a number in [0, 1e6] cd/m2", file, key);
  pc->content_luminance = d;
  d = -2;
  snprintf(key, sizeof key, "panels[%d].black_luminance", i);
  if ((st = num(file, e, "black_luminance", 0, 1e6, 0, &d, err)))
    return cv_err_set(err, st, "%s: lcd.%s: expected a number in [0, 1e6] cd/m2", file, key);
  pc->black_luminance = d;
  snprintf(key, sizeof key, "panels[%d].brdf", i);
  const cJSON *b = cJSON_GetObjectItemCaseSensitive(e, "brdf");
  if (b && (!cJSON_IsString(b) || !b->valuestring[0]))
    return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.%s: expected a file name (string)", file, key);
  if ((st = path_field(file, base, e, "brdf", 1, pc->brdf, err)))
    return cv_err_set(err, st, "%s: lcd.%s: expected a file name (string)", file, key);
  if (cJSON_GetObjectItemCaseSensitive(e, "content")) {
    if ((st = path_field(file, base, e, "content", 0, pc->content, err)))
      return cv_err_set(err, st, "%s: lcd.panels[%d].content: expected a file name (string)", file, i);
    pc->content_set = 1;
    snprintf(key, sizeof key, "lcd.panels[%d].content", i);
    if ((st = content_readable(file, key, pc->content, err))) return st;
  }
  return CV_OK;
}

static int panels_field(const char *file, const char *base, const cJSON *o, cv_lcd_config *c,
                        cv_err *err) {
  const cJSON *ps = cJSON_GetObjectItemCaseSensitive(o, "panels");
  if (!ps) return CV_OK;
  const int n = cJSON_GetArraySize(ps);
  if (!cJSON_IsArray(ps) || n < 1 || n > CV_LCD_MAX_PANELS)
    return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.panels: expected a list of 1..%d panels", file,
                      CV_LCD_MAX_PANELS);
  int mesh_panel = -1;
  for (int i = 0; i < n; i++) {
    int st = panel_entry(file, base, cJSON_GetArrayItem(ps, i), i, &c->panels[i], err);
    if (st) return st;
    for (int j = 0; j < i; j++)
      if (!strcmp(c->panels[j].name, c->panels[i].name))
        return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.panels[%d].name: '%s' is also lcd.panels[%d]'s",
                          file, i, c->panels[i].name, j);
    if (!c->panels[i].has_corners) {
      if (mesh_panel >= 0)
        return cv_err_set(err, CV_ERR_CONFIG,
                          "%s: lcd.panels[%d].corners: required (lcd.panels[%d] already takes the "
                          "mesh's lcd triangles)", file, i, mesh_panel);
      mesh_panel = i;
    }
  }
  c->n_panels = n;
  return CV_OK;
}

int cv_lcd_config_panels(cv_lcd_config *c, cv_err *err) {
  const char *file = c->source[0] ? c->source : "lcd";
  if (c->n_panels <= 0) {
    memset(&c->panels[0], 0, sizeof c->panels[0]);
    snprintf(c->panels[0].name, sizeof c->panels[0].name, "lcd");
    c->panels[0].content_luminance = -1;
    c->panels[0].black_luminance = -2;
    c->n_panels = 1;
  }
  for (int i = 0; i < c->n_panels; i++) {
    cv_lcd_panel_config *p = &c->panels[i];
    if (!p->brdf[0]) snprintf(p->brdf, sizeof p->brdf, "%s", c->brdf);
    if (!p->content_set) snprintf(p->content, sizeof p->content, "%s", c->content);
    p->content_set = 1;
    if (p->content_luminance < 0) p->content_luminance = c->content_luminance;
    if (p->black_luminance < -1) /* unset: the block's own, or its level of this white */
      p->black_luminance = c->black_luminance >= 0 ? c->black_luminance
                                                   : CV_LCD_BLACK_LEVEL * p->content_luminance;
    if (p->width <= 0) p->width = c->width, p->height = c->height;
    if (p->black_luminance > p->content_luminance && !c->source[0]) /* options, no file */
      return cv_err_set(err, CV_ERR_CONFIG,
                        "panel '%s': white_luminance %g is below black_luminance %g (expected white >= black)",
                        p->name, p->content_luminance, p->black_luminance);
    if (p->black_luminance > p->content_luminance)
      return cv_err_set(err, CV_ERR_CONFIG,
                        "%s: lcd.panels[%d].black_luminance: %g is above the white (content_luminance) %g",
                        file, i, p->black_luminance, p->content_luminance);
  }
  return CV_OK;
}

void cv_lcd_config_override(cv_lcd_config *c, unsigned what) {
  for (int i = 0; i < c->n_panels && i < CV_LCD_MAX_PANELS; i++) {
    cv_lcd_panel_config *p = &c->panels[i];
    if (what & CV_LCD_SET_SIZE) p->width = p->height = 0;
    if (what & CV_LCD_SET_BRDF) p->brdf[0] = 0;
    if (what & CV_LCD_SET_CONTENT) p->content_set = 0;
    if (what & CV_LCD_SET_WHITE) p->content_luminance = -1;
    if (what & CV_LCD_SET_BLACK) p->black_luminance = -2;
  }
}

static int load(const char *path, int scene, cv_lcd_config *c, cv_err *err) {
  char *buf = NULL;
  int rst = cv_read_json_file(path, &buf, err);
  if (rst) return rst;
  const char *end = NULL;
  cJSON *root = cJSON_ParseWithOpts(buf, &end, 0);
  if (!root) {
    int line, col;
    char what[128];
    cv_json_syntax_error(buf, end, &line, &col, what, sizeof what);
    free(buf);
    return cv_err_set(err, CV_ERR_CONFIG, "%s: line %d, column %d: %s", path, line, col, what);
  }
  free(buf);
  char base[CV_PATH_MAX];
  snprintf(base, sizeof base, "%s", path);
  char *slash = strrchr(base, '/');
  if (slash) *slash = 0;
  else snprintf(base, sizeof base, ".");
  int st = CV_OK;
  const cJSON *o = cJSON_GetObjectItemCaseSensitive(root, "lcd");
  static const char *const top[] = {"lcd", NULL};
  static const char *const keys[] = {"resolution", "spp", "rounds", "brdf", "content",
                                     "content_luminance", "eye_tolerance", "brdf_fraction",
                                     "seed", "env_width", "sun_samples", "clamp",
                                     "black_luminance", "cr_min", "age", "pigment", "panels",
                                     NULL};
  char list[600];
  const cJSON *it;
  if (!cJSON_IsObject(root)) {
    st = cv_err_set(err, CV_ERR_CONFIG, "%s: expected an object with an \"lcd\" field", path);
    goto done;
  }
  cJSON_ArrayForEach(it, root) {
    if (!scene && !cv_json_key_allowed(it->string, top)) {
      char kbuf[128];
      st = cv_err_set(err, CV_ERR_CONFIG, "%s: %s: unknown field (expected lcd)", path,
                      cv_json_key_show(it->string, kbuf, sizeof kbuf));
      goto done;
    }
  }
  if (!o) goto done;
  if (!cJSON_IsObject(o)) {
    st = cv_err_set(err, CV_ERR_CONFIG, "%s: lcd: expected an object", path);
    goto done;
  }
  cJSON_ArrayForEach(it, o) {
    if (!cv_json_key_allowed(it->string, keys)) {
      char kbuf[128];
      cv_json_key_list(keys, list, sizeof list);
      st = cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.%s: unknown field (expected one of: %s)", path,
                      cv_json_key_show(it->string, kbuf, sizeof kbuf), list);
      goto done;
    }
  }
  snprintf(c->source, sizeof c->source, "%s", path);
  const cJSON *res = cJSON_GetObjectItemCaseSensitive(o, "resolution");
  if (res && (st = resolution_field(path, "lcd.resolution", res, &c->width, &c->height, err)))
    goto done;
  double d;
  d = c->spp;
  if ((st = num(path, o, "spp", 1, 65536, 1, &d, err))) goto done;
  c->spp = (int)d;
  d = c->rounds;
  if ((st = num(path, o, "rounds", 1, 100000, 1, &d, err))) goto done;
  c->rounds = (int)d;
  if ((st = num(path, o, "content_luminance", 0, 1e6, 0, &c->content_luminance, err))) goto done;
  if ((st = num(path, o, "eye_tolerance", CV_LCD_TOLERANCE_MIN, CV_LCD_TOLERANCE_MAX, 0, &c->eye_tolerance, err))) goto done;
  if ((st = num(path, o, "brdf_fraction", 0, 1, 0, &c->brdf_fraction, err))) goto done;
  d = c->seed;
  if ((st = num(path, o, "seed", 0, 4294967295.0, 1, &d, err))) goto done;
  c->seed = (uint32_t)d;
  d = c->env_width;
  if ((st = num(path, o, "env_width", 16, 16384, 1, &d, err))) goto done;
  c->env_width = (int)d;
  d = c->sun_samples;
  if ((st = num(path, o, "sun_samples", 1, 4096, 1, &d, err))) goto done;
  c->sun_samples = (int)d;
  if ((st = num(path, o, "clamp", 0, 1e30, 0, &c->clamp, err))) goto done;
  if ((st = num(path, o, "black_luminance", 0, 1e6, 0, &c->black_luminance, err))) goto done;
  if ((st = num(path, o, "cr_min", 1, CV_LCD_CR_MAX, 0, &c->cr_min, err))) goto done;
  if ((st = num(path, o, "age", 0, 150, 0, &c->age, err))) goto done;
  if ((st = num(path, o, "pigment", 0, 1, 0, &c->pigment, err))) goto done;
  if (cv_lcd_config_black(c) > c->content_luminance) {
    st = cv_err_set(err, CV_ERR_CONFIG,
                    "%s: lcd.black_luminance: %g is above the white lcd.content_luminance %g",
                    path, cv_lcd_config_black(c), c->content_luminance);
    goto done;
  }
  if ((st = path_field(path, base, o, "brdf", 1, c->brdf, err))) goto done;
  if ((st = path_field(path, base, o, "content", 0, c->content, err))) goto done;
  if ((st = content_readable(path, "lcd.content", c->content, err))) goto done;
  st = panels_field(path, base, o, c, err);
done:
  cJSON_Delete(root);
  return st;
}

int cv_lcd_config_load(const char *path, cv_lcd_config *c, cv_err *err) {
  return load(path, 0, c, err);
}

int cv_lcd_config_load_scene(const char *path, cv_lcd_config *c, cv_err *err) {
  return load(path, 1, c, err);
}
