/* Scripted drive loader and evaluation (drive.h), on cJSON.
 *
 * Like the display loader (compensate/display.c) the parser does not stop at
 * the first problem: every check appends a "file: field: what" line to a
 * collector, so cv_drive_validate_all lists them all and cv_drive_load
 * reports the first with a count of the others.  The drive is only built
 * once the file is free of problems. */
#include "service/drive.h"

#include "core/hash.h"
#include "io/json_keys.h"
#include "io/problems.h"
#include "io/textfile.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct key {
  double t, yaw, pitch, roll;
  double w[CV_MAX_ENV_MAPS]; /* normalised to sum 1 */
  double turbidity, elevation, azimuth;
} key;

struct cv_drive {
  char *description;
  int loop, is_sky, n_maps;
  char maps[CV_MAX_ENV_MAPS][CV_PATH_MAX];
  double scale, ground_albedo;
  double illuminance; /* lux, CV_ILLUMINANCE_AUTO, or 0 (scale applies) */
  int absolute;       /* "absolute": true: the maps times scale are in cd/m^2 */
  int n_keys;
  key *keys;
};

/* --- problem collector (as compensate/display.c) -------------------------- */

typedef cv_problems ctx; /* io/problems.h */

static int finish(ctx *x, cv_err *err) { return cv_problems_finish(x, err); }


/* Optional finite number in [lo, hi]; 1 when present and valid. */
static int opt_num(ctx *x, const cJSON *obj, const char *path, const char *name, double lo,
                   double hi, double *out) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, name);
  if (!v) return 0;
  char field[256];
  snprintf(field, sizeof field, "%s%s%s", path, path[0] ? "." : "", name);
  if (!cJSON_IsNumber(v)) {
    cv_problem(x, CV_ERR_CONFIG, field, "expected a number");
    return 0;
  }
  double d = v->valuedouble;
  if (!isfinite(d)) {
    cv_problem(x, CV_ERR_NONFINITE, field, "expected a finite number");
    return 0;
  }
  if (d < lo || d > hi) {
    cv_problem(x, CV_ERR_RANGE, field, "%.10g is outside [%.10g, %.10g]", d, lo, hi);
    return 0;
  }
  *out = d;
  return 1;
}

static int opt_bool(ctx *x, const cJSON *obj, const char *name, int *out) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, name);
  if (!v) return 0;
  if (!cJSON_IsBool(v)) {
    cv_problem(x, CV_ERR_CONFIG, name, "expected true or false");
    return 0;
  }
  *out = cJSON_IsTrue(v);
  return 1;
}

/* --- keyframes ------------------------------------------------------------- */

static const char *const map_key_fields[] = {"t", "yaw", "pitch", "roll", "weights", NULL};
static const char *const sky_key_fields[] = {"t",         "yaw",           "pitch",
                                             "roll",      "turbidity",     "sun_elevation",
                                             "sun_azimuth", NULL};

#define ANGLE_MAX 1e6 /* degrees; any finite attitude is fine, this keeps sums sane */

/* Parses keyframe k into *kf, starting from prev's values (or the defaults).
 * n_maps < 0: the map list itself was bad, skip the weights' length check. */
static void parse_key(ctx *x, const cJSON *o, int k, int is_sky, int n_maps, const key *prev,
                      key *kf) {
  char path[64];
  snprintf(path, sizeof path, "keyframes[%d]", k);
  if (!cJSON_IsObject(o)) {
    cv_problem(x, CV_ERR_CONFIG, path, "expected an object");
    return;
  }
  cv_problems_only_keys(x, o, path, is_sky ? sky_key_fields : map_key_fields);
  if (prev) {
    *kf = *prev;
  } else {
    memset(kf, 0, sizeof *kf);
    kf->w[0] = 1.0;
    kf->turbidity = 3.0;
    kf->elevation = 35.0;
  }
  char field[96];
  snprintf(field, sizeof field, "%s.t", path);
  if (!cJSON_GetObjectItemCaseSensitive(o, "t")) {
    cv_problem(x, CV_ERR_CONFIG, field, "missing (expected the time in seconds)");
  } else if (opt_num(x, o, path, "t", 0.0, 1e9, &kf->t)) {
    if (!prev && kf->t != 0.0)
      cv_problem(x, CV_ERR_RANGE, field, "the first keyframe must be at t = 0, got %g", kf->t);
    if (prev && !(kf->t > prev->t))
      cv_problem(x, CV_ERR_RANGE, field, "t = %g is not after the previous keyframe's %g", kf->t,
              prev->t);
  }
  opt_num(x, o, path, "yaw", -ANGLE_MAX, ANGLE_MAX, &kf->yaw);
  opt_num(x, o, path, "pitch", -ANGLE_MAX, ANGLE_MAX, &kf->pitch);
  opt_num(x, o, path, "roll", -ANGLE_MAX, ANGLE_MAX, &kf->roll);
  if (is_sky) {
    opt_num(x, o, path, "turbidity", 2.0, 10.0, &kf->turbidity);
    opt_num(x, o, path, "sun_elevation", -10.0, 90.0, &kf->elevation); /* as lighting.sky and --sky: the same Preetham sky */
    opt_num(x, o, path, "sun_azimuth", -ANGLE_MAX, ANGLE_MAX, &kf->azimuth);
    return;
  }
  const cJSON *w = cJSON_GetObjectItemCaseSensitive(o, "weights");
  if (!w) return;
  snprintf(field, sizeof field, "%s.weights", path);
  if (!cJSON_IsArray(w)) {
    cv_problem(x, CV_ERR_CONFIG, field, "expected an array of numbers, one per map");
    return;
  }
  int n = cJSON_GetArraySize(w);
  if (n_maps >= 0 && n != n_maps) {
    cv_problem(x, CV_ERR_CONFIG, field, "%d weights for %d maps", n, n_maps);
    return;
  }
  if (n > CV_MAX_ENV_MAPS) return; /* the maps problem is reported already */
  double v[CV_MAX_ENV_MAPS] = {0}, sum = 0.0;
  int ok = 1;
  for (int i = 0; i < n; i++) {
    char f[128];
    snprintf(f, sizeof f, "%s[%d]", field, i);
    const cJSON *e = cJSON_GetArrayItem(w, i);
    if (!cJSON_IsNumber(e)) {
      cv_problem(x, CV_ERR_CONFIG, f, "expected a number");
      ok = 0;
    } else if (!isfinite(e->valuedouble)) {
      cv_problem(x, CV_ERR_NONFINITE, f, "expected a finite number");
      ok = 0;
    } else if (e->valuedouble < 0 || e->valuedouble > 1e12) {
      cv_problem(x, CV_ERR_RANGE, f, "%g is outside [0, 1e12]", e->valuedouble);
      ok = 0;
    } else {
      v[i] = e->valuedouble;
      sum += v[i];
    }
  }
  if (!ok) return;
  if (!(sum > 0)) {
    cv_problem(x, CV_ERR_RANGE, field, "the weights sum to 0 (expected a positive sum)");
    return;
  }
  for (int i = 0; i < CV_MAX_ENV_MAPS; i++) kf->w[i] = v[i] / sum;
}

/* --- the whole file ------------------------------------------------------- */

static const char *const top_fields[] = {"description", "loop",          "maps",
                                         "sky",         "scale",         "ground_albedo",
                                         "keyframes",   "illuminance",   "absolute",
                                         NULL};

/* Checks the JSON text; when out is non-NULL and there is no problem,
 * builds the drive. */
static void parse_drive(ctx *x, const char *json, const char *base_dir, cv_drive **out) {
  cJSON *root = cJSON_Parse(json);
  if (!root) {
    int line, col;
    char f[48], what[128];
    cv_json_syntax_error(json, cJSON_GetErrorPtr(), &line, &col, what, sizeof what);
    snprintf(f, sizeof f, "line %d, column %d", line, col);
    cv_problem(x, CV_ERR_CONFIG, f, "%s", what);
    return;
  }
  cv_drive *d = calloc(1, sizeof *d);
  if (!d) {
    cv_problem(x, CV_ERR_NOMEM, "", "out of memory");
    cJSON_Delete(root);
    return;
  }
  d->scale = 1.0;
  d->ground_albedo = 0.2;
  if (!cJSON_IsObject(root)) {
    cv_problem(x, CV_ERR_CONFIG, "", "expected a JSON object");
    goto done;
  }
  cv_problems_only_keys(x, root, "", top_fields);

  const cJSON *desc = cJSON_GetObjectItemCaseSensitive(root, "description");
  if (desc && !cJSON_IsString(desc)) cv_problem(x, CV_ERR_CONFIG, "description", "expected a string");
  d->description = strdup(desc && cJSON_IsString(desc) ? desc->valuestring : "");
  if (!d->description) cv_problem(x, CV_ERR_NOMEM, "", "out of memory");
  opt_bool(x, root, "loop", &d->loop);
  opt_bool(x, root, "sky", &d->is_sky);

  const cJSON *maps = cJSON_GetObjectItemCaseSensitive(root, "maps");
  int n_maps = -1; /* unknown: the list is bad */
  if (d->is_sky) {
    n_maps = 0;
    if (maps) cv_problem(x, CV_ERR_CONFIG, "maps", "not allowed with \"sky\": true (choose one)");
    if (cJSON_GetObjectItemCaseSensitive(root, "scale"))
      cv_problem(x, CV_ERR_CONFIG, "scale", "only for map drives (the sky has its own radiance)");
    if (cJSON_GetObjectItemCaseSensitive(root, "illuminance"))
      cv_problem(x, CV_ERR_CONFIG, "illuminance", "only for map drives (the sky is absolute)");
    if (cJSON_GetObjectItemCaseSensitive(root, "absolute"))
      cv_problem(x, CV_ERR_CONFIG, "absolute", "only for map drives (the sky is in cd/m^2)");
    opt_num(x, root, "", "ground_albedo", 0.0, 1.0, &d->ground_albedo);
  } else {
    if (cJSON_GetObjectItemCaseSensitive(root, "ground_albedo"))
      cv_problem(x, CV_ERR_CONFIG, "ground_albedo", "only for sky drives");
    if (cJSON_GetObjectItemCaseSensitive(root, "scale") &&
        opt_num(x, root, "", "scale", 0.0, 1e12, &d->scale) && !(d->scale > 0))
      cv_problem(x, CV_ERR_RANGE, "scale", "expected a positive multiplier, got %g", d->scale);
    const cJSON *lux = cJSON_GetObjectItemCaseSensitive(root, "illuminance");
    if (lux && cJSON_GetObjectItemCaseSensitive(root, "scale"))
      cv_problem(x, CV_ERR_CONFIG, "illuminance", "not together with \"scale\" (both set the level)");
    else if (cJSON_IsString(lux) && !strcmp(lux->valuestring, "auto"))
      d->illuminance = CV_ILLUMINANCE_AUTO;
    else if (lux && !cJSON_IsNumber(lux))
      cv_problem(x, CV_ERR_CONFIG, "illuminance", "expected lux or \"auto\"");
    else if (lux)
      opt_num(x, root, "", "illuminance", 1e-6, 1e7, &d->illuminance);
    opt_bool(x, root, "absolute", &d->absolute);
    if (lux && d->absolute)
      cv_problem(x, CV_ERR_CONFIG, "absolute", "not together with \"illuminance\" (which already calibrates)");
    if (!maps) {
      cv_problem(x, CV_ERR_CONFIG, "maps",
              "missing (expected a list of environment maps, or \"sky\": true)");
    } else if (!cJSON_IsArray(maps) || cJSON_GetArraySize(maps) < 1 ||
               cJSON_GetArraySize(maps) > CV_MAX_ENV_MAPS) {
      cv_problem(x, CV_ERR_CONFIG, "maps", "expected an array of 1..%d file names",
              CV_MAX_ENV_MAPS);
    } else {
      n_maps = cJSON_GetArraySize(maps);
      for (int i = 0; i < n_maps; i++) {
        char f[32];
        snprintf(f, sizeof f, "maps[%d]", i);
        const cJSON *e = cJSON_GetArrayItem(maps, i);
        if (!cJSON_IsString(e) || !e->valuestring[0]) {
          cv_problem(x, CV_ERR_CONFIG, f, "expected a file name");
          continue;
        }
        cv_err e2;
        cv_err_clear(&e2);
        if (cv_resolve_env_path(e->valuestring, base_dir, d->maps[i], &e2))
          cv_problem(x, e2.status, f, "%s", e2.msg);
      }
      d->n_maps = n_maps;
    }
  }

  const cJSON *keys = cJSON_GetObjectItemCaseSensitive(root, "keyframes");
  if (!keys) {
    cv_problem(x, CV_ERR_CONFIG, "keyframes", "missing (expected an array of keyframe objects)");
  } else if (!cJSON_IsArray(keys) || cJSON_GetArraySize(keys) < 1 ||
             cJSON_GetArraySize(keys) > CV_DRIVE_MAX_KEYS) {
    cv_problem(x, CV_ERR_CONFIG, "keyframes", "expected an array of 1..%d keyframe objects",
            CV_DRIVE_MAX_KEYS);
  } else {
    int n = cJSON_GetArraySize(keys);
    d->keys = calloc((size_t)n, sizeof *d->keys);
    if (!d->keys) {
      cv_problem(x, CV_ERR_NOMEM, "", "out of memory");
    } else {
      d->n_keys = n;
      int k = 0;
      const cJSON *o;
      cJSON_ArrayForEach(o, keys) {
        parse_key(x, o, k, d->is_sky, n_maps, k ? &d->keys[k - 1] : NULL, &d->keys[k]);
        k++;
      }
    }
  }

done:
  cJSON_Delete(root);
  if (x->count == 0 && out)
    *out = d;
  else
    cv_drive_destroy(d);
}

int cv_drive_parse(const char *json, const char *name, const char *base_dir, cv_drive **out,
                   cv_err *err) {
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "drive: NULL output");
  *out = NULL;
  if (!name) name = "(drive)";
  if (!json) return cv_err_set(err, CV_ERR_INVALID, "%s: NULL text", name);
  ctx x;
  memset(&x, 0, sizeof x);
  x.file = name;
  parse_drive(&x, json, base_dir, out);
  return finish(&x, err);
}

/* Folder part of path ("." when none), into dir[n]. */
static void dir_of(const char *path, char *dir, size_t n) {
  const char *s = strrchr(path, '/');
  if (!s)
    snprintf(dir, n, ".");
  else if (s == path)
    snprintf(dir, n, "/");
  else
    snprintf(dir, n, "%.*s", (int)(s - path), path);
}

int cv_drive_load(const char *path, cv_drive **out, cv_err *err) {
  if (out) *out = NULL;
  if (!path) return cv_err_set(err, CV_ERR_INVALID, "drive: NULL path");
  char *text;
  int st = cv_read_text_file(path, &text, NULL, err);
  if (st) return st;
  char dir[CV_PATH_MAX];
  dir_of(path, dir, sizeof dir);
  st = cv_drive_parse(text, path, dir, out, err);
  free(text);
  return st;
}

int cv_drive_validate_text(const char *json, const char *name, const char *base_dir, char *buf,
                           size_t n, int *n_problems) {
  ctx x;
  memset(&x, 0, sizeof x);
  x.file = name ? name : "(drive)";
  x.buf = buf;
  x.cap = buf ? n : 0;
  if (buf && n) buf[0] = '\0';
  if (!json)
    cv_problem(&x, CV_ERR_INVALID, "", "NULL text");
  else
    parse_drive(&x, json, base_dir, NULL);
  if (n_problems) *n_problems = x.count;
  return x.count ? (x.first_status ? x.first_status : CV_ERR_CONFIG) : CV_OK;
}

int cv_drive_validate_all(const char *path, char *buf, size_t n, int *n_problems) {
  char *text;
  cv_err e;
  cv_err_clear(&e);
  if (buf && n) buf[0] = '\0';
  int st = cv_read_text_file(path, &text, NULL, &e);
  if (st) {
    if (buf && n) snprintf(buf, n, "%s\n", e.msg);
    if (n_problems) *n_problems = 1;
    return st;
  }
  char dir[CV_PATH_MAX];
  dir_of(path, dir, sizeof dir);
  st = cv_drive_validate_text(text, path, dir, buf, n, n_problems);
  free(text);
  return st;
}

void cv_drive_destroy(cv_drive *d) {
  if (!d) return;
  free(d->description);
  free(d->keys);
  free(d);
}

/* --- accessors ------------------------------------------------------------ */

double cv_drive_duration(const cv_drive *d) { return d->keys[d->n_keys - 1].t; }
int cv_drive_n_maps(const cv_drive *d) { return d->n_maps; }
const char *cv_drive_map_path(const cv_drive *d, int i) {
  return (i >= 0 && i < d->n_maps) ? d->maps[i] : NULL;
}
int cv_drive_is_sky(const cv_drive *d) { return d->is_sky; }
int cv_drive_loops(const cv_drive *d) { return d->loop; }
int cv_drive_n_keys(const cv_drive *d) { return d->n_keys; }
const char *cv_drive_description(const cv_drive *d) { return d->description; }

/* --- evaluation ----------------------------------------------------------- */

/* x wrapped to [-180, 180). */
static double wrap180(double x) { return x - 360.0 * floor((x + 180.0) / 360.0); }

/* From a towards b along the shorter arc. */
static double lerp_angle(double a, double b, double f) { return a + f * wrap180(b - a); }

static void key_state(const cv_drive *d, const key *k, cv_drive_state *out) {
  out->yaw_deg = k->yaw;
  out->pitch_deg = k->pitch;
  out->roll_deg = k->roll;
  for (int i = 0; i < d->n_maps; i++) out->weights[i] = k->w[i];
  if (d->is_sky) {
    out->turbidity = k->turbidity;
    out->sun_elevation_deg = k->elevation;
    out->sun_azimuth_deg = k->azimuth;
  }
}

void cv_drive_eval(const cv_drive *d, double t, cv_drive_state *out) {
  memset(out, 0, sizeof *out);
  if (!isfinite(t)) t = 0.0;
  out->t = t;
  out->n_maps = d->n_maps;
  out->is_sky = d->is_sky;
  const key *k = d->keys;
  int n = d->n_keys;
  double dur = k[n - 1].t, tt = t;
  if (d->loop && dur > 0) {
    tt = fmod(t, dur);
    if (tt < 0) tt += dur;
  }
  if (n == 1 || tt <= 0) {
    key_state(d, &k[0], out);
    return;
  }
  if (tt >= dur) {
    key_state(d, &k[n - 1], out);
    return;
  }
  int lo = 0, hi = n - 1; /* k[lo].t <= tt < k[hi].t */
  while (hi - lo > 1) {
    int mid = lo + (hi - lo) / 2;
    if (k[mid].t <= tt)
      lo = mid;
    else
      hi = mid;
  }
  const key *a = &k[lo], *b = &k[hi];
  double f = (tt - a->t) / (b->t - a->t);
  out->yaw_deg = lerp_angle(a->yaw, b->yaw, f);
  out->pitch_deg = lerp_angle(a->pitch, b->pitch, f);
  out->roll_deg = lerp_angle(a->roll, b->roll, f);
  if (d->is_sky) {
    out->turbidity = a->turbidity + f * (b->turbidity - a->turbidity);
    out->sun_elevation_deg = a->elevation + f * (b->elevation - a->elevation);
    out->sun_azimuth_deg = lerp_angle(a->azimuth, b->azimuth, f);
    return;
  }
  double sum = 0.0;
  for (int i = 0; i < d->n_maps; i++) {
    out->weights[i] = (1 - f) * a->w[i] + f * b->w[i];
    sum += out->weights[i];
  }
  if (sum > 0)
    for (int i = 0; i < d->n_maps; i++) out->weights[i] /= sum;
}

void cv_drive_to_light_spec(const cv_drive *d, const cv_drive_state *s, cv_light_spec *out) {
  cv_light_spec_default(out);
  out->yaw_deg = s->yaw_deg;
  out->pitch_deg = s->pitch_deg;
  out->roll_deg = s->roll_deg;
  out->extract_sun = 1;
  if (d->is_sky) {
    out->kind = CV_LIGHT_SKY;
    out->turbidity = s->turbidity;
    out->sun_elevation_deg = s->sun_elevation_deg;
    out->sun_azimuth_deg = s->sun_azimuth_deg;
    out->ground_albedo = d->ground_albedo;
    return;
  }
  out->kind = CV_LIGHT_ENV;
  out->scale = d->scale;
  out->illuminance = d->illuminance;
  out->absolute = d->absolute;
  int n = s->n_maps < d->n_maps ? s->n_maps : d->n_maps;
  for (int i = 0; i < n; i++) {
    if (!(s->weights[i] > 0)) continue;
    snprintf(out->env[out->n_env], CV_PATH_MAX, "%s", d->maps[i]);
    out->weight[out->n_env++] = s->weights[i];
  }
  if (out->n_env == 0 && d->n_maps > 0) { /* a state without weight: show the first map */
    snprintf(out->env[0], CV_PATH_MAX, "%s", d->maps[0]);
    out->weight[0] = 1.0;
    out->n_env = 1;
  }
}

/* --- cache key ------------------------------------------------------------ */

/* round(x / step) as an integer, clamped so the cast is defined. */
static int64_t quant(double x, double step) {
  double q = floor(x / step + 0.5);
  if (!(q > -9e18)) q = -9e18; /* also NaN */
  if (q > 9e18) q = 9e18;
  return (int64_t)q;
}

/* Angle quantised on the circle, so that 0 and 360 (and -0.1 and 359.9 at a
 * 1 degree step) give the same integer. */
static int64_t quant_angle(double deg, double step) {
  double a = isfinite(deg) ? deg - 360.0 * floor(deg / 360.0) : 0.0; /* [0, 360) */
  int64_t q = quant(a, step), n = quant(360.0, step);
  if (n > 0) q %= n;
  return q;
}

uint64_t cv_drive_state_key(const cv_drive_state *s, double yaw_step_deg, double weight_step) {
  if (!(yaw_step_deg > 0) || !isfinite(yaw_step_deg)) yaw_step_deg = 1.0;
  if (!(weight_step > 0) || !isfinite(weight_step)) weight_step = 1e-3;
  uint64_t h = cv_hash64_init();
  h = cv_hash64_update(h, "cv_drive_state_key/1", 20);
  h = cv_hash64_u64(h, (uint64_t)quant_angle(s->yaw_deg, yaw_step_deg));
  h = cv_hash64_u64(h, (uint64_t)quant_angle(s->pitch_deg, yaw_step_deg));
  h = cv_hash64_u64(h, (uint64_t)quant_angle(s->roll_deg, yaw_step_deg));
  h = cv_hash64_u64(h, (uint64_t)(s->is_sky ? 1 : 0));
  if (s->is_sky) {
    h = cv_hash64_u64(h, (uint64_t)quant(s->turbidity, 0.1));
    h = cv_hash64_u64(h, (uint64_t)quant(s->sun_elevation_deg, 0.5));
    h = cv_hash64_u64(h, (uint64_t)quant_angle(s->sun_azimuth_deg, 0.5));
  } else {
    int n = s->n_maps < 0 ? 0 : s->n_maps > CV_MAX_ENV_MAPS ? CV_MAX_ENV_MAPS : s->n_maps;
    h = cv_hash64_u64(h, (uint64_t)n);
    for (int i = 0; i < n; i++) h = cv_hash64_u64(h, (uint64_t)quant(s->weights[i], weight_step));
  }
  return h;
}
