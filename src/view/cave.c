/* CAVE configuration loader (see cave.h), on cJSON.
 *
 * Like the display loader (compensate/display.c) the parser does not stop at
 * the first problem: every check appends "field: problem" to a collector, and
 * the error line lists all of them, "file: field: problem; field: problem".
 * *out is written only when there was no problem. */
#include "view/cave.h"

#include "io/json_keys.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define COORD_LIMIT 1e6

/* --- problem collector ---------------------------------------------------- */

typedef struct ctx {
  const char *file;
  int count;
  int first_status;
  char all[4096]; /* "field: what; field: what" */
  size_t len;
  int truncated;
} ctx;

static void problem(ctx *x, int status, const char *field, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

static void problem(ctx *x, int status, const char *field, const char *fmt, ...) {
  char what[384], line[512];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(what, sizeof what, fmt, ap);
  va_end(ap);
  if (field && field[0])
    snprintf(line, sizeof line, "%s: %s", field, what);
  else
    snprintf(line, sizeof line, "%s", what);
  if (x->count++ == 0) x->first_status = status;
  size_t need = strlen(line) + (x->len ? 2 : 0);
  if (x->len + need + 1 > sizeof x->all) {
    x->truncated = 1;
    return;
  }
  x->len += (size_t)snprintf(x->all + x->len, sizeof x->all - x->len, "%s%s",
                             x->len ? "; " : "", line);
}

/* Writes the collected problems into err, all on one line. */
static int finish(ctx *x, cv_err *err) {
  int st = x->first_status ? x->first_status : CV_ERR_CONFIG;
  char tail[64] = "";
  if (x->count > 1) snprintf(tail, sizeof tail, " [%d problems]", x->count);
  if (!err) return st;
  char head[200];
  snprintf(head, sizeof head, "%s: ", x->file);
  size_t cap = sizeof err->msg - 1, hl = strlen(head), tl = strlen(tail);
  if (!x->truncated && hl + x->len + tl <= cap) {
    cv_err_set(err, st, "%s%s%s", head, x->all, tail);
  } else {
    /* Keep as many whole problems as fit, then say how many there were. */
    size_t room = cap > hl + tl + 5 ? cap - hl - tl - 5 : 0;
    size_t cut = x->len < room ? x->len : room;
    while (cut > 0 && cut < x->len && strncmp(x->all + cut, "; ", 2) != 0) cut--;
    cv_err_set(err, st, "%s%.*s; ...%s", head, (int)cut, x->all, tail);
  }
  return st;
}

/* --- typed readers ---------------------------------------------------------- */

static int read_number(ctx *x, const cJSON *v, const char *field, double *out) {
  if (!cJSON_IsNumber(v)) {
    problem(x, CV_ERR_CONFIG, field, "expected a number");
    return 0;
  }
  if (!isfinite(v->valuedouble)) {
    problem(x, CV_ERR_NONFINITE, field, "expected a finite number, got %g", v->valuedouble);
    return 0;
  }
  *out = v->valuedouble;
  return 1;
}

/* Array of exactly 3 finite numbers within +-COORD_LIMIT. */
static int read_vec3(ctx *x, const cJSON *v, const char *field, double out[3]) {
  if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) != 3) {
    problem(x, CV_ERR_CONFIG, field, "expected [x, y, z] in metres");
    return 0;
  }
  int ok = 1;
  double t[3];
  for (int k = 0; k < 3; k++) {
    char f[160];
    snprintf(f, sizeof f, "%s[%d]", field, k);
    if (!read_number(x, cJSON_GetArrayItem(v, k), f, &t[k])) {
      ok = 0;
    } else if (fabs(t[k]) > COORD_LIMIT) {
      problem(x, CV_ERR_RANGE, f, "%g is outside [-%g, %g]", t[k], COORD_LIMIT, COORD_LIMIT);
      ok = 0;
    }
  }
  if (ok) memcpy(out, t, sizeof t);
  return ok;
}

/* Optional number in the interval lo..hi (ends open when flagged). */
static int opt_num(ctx *x, const cJSON *o, const char *key, double lo, int lo_open, double hi,
                   int hi_open, double *out) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  if (!v) return 1;
  double d;
  if (!read_number(x, v, key, &d)) return 0;
  if ((lo_open ? !(d > lo) : !(d >= lo)) || (hi_open ? !(d < hi) : !(d <= hi))) {
    problem(x, CV_ERR_RANGE, key, "%g is outside %c%g, %g%c", d, lo_open ? '(' : '[', lo, hi,
            hi_open ? ')' : ']');
    return 0;
  }
  *out = d;
  return 1;
}

static int opt_int(ctx *x, const cJSON *o, const char *key, int lo, int hi, int *out) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  if (!v) return 1;
  double d;
  if (!read_number(x, v, key, &d)) return 0;
  if (d != floor(d) || d < lo || d > hi) {
    problem(x, CV_ERR_RANGE, key, "expected an integer in [%d, %d], got %g", lo, hi, d);
    return 0;
  }
  *out = (int)d;
  return 1;
}

static void only_keys(ctx *x, const cJSON *obj, const char *path, const char *const *allowed) {
  const cJSON *it;
  cJSON_ArrayForEach(it, obj) {
    if (!cv_json_key_allowed(it->string, allowed)) {
      char field[256], list[320];
      snprintf(field, sizeof field, "%s%s%s", path, path[0] ? "." : "", it->string);
      cv_json_key_list(allowed, list, sizeof list);
      problem(x, CV_ERR_CONFIG, field, "unknown field (expected one of: %s)", list);
    }
  }
}

/* --- geometry ------------------------------------------------------------- */

static double dot3(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Unit normal (pb-pa) x (pc-pa) of a wall (towards the viewer). */
static void wall_normal(const cv_wall *w, double n[3]) {
  double e1[3], e2[3];
  for (int k = 0; k < 3; k++) {
    e1[k] = w->pb[k] - w->pa[k];
    e2[k] = w->pc[k] - w->pa[k];
  }
  n[0] = e1[1] * e2[2] - e1[2] * e2[1];
  n[1] = e1[2] * e2[0] - e1[0] * e2[2];
  n[2] = e1[0] * e2[1] - e1[1] * e2[0];
  double l = sqrt(dot3(n, n));
  if (l > 0)
    for (int k = 0; k < 3; k++) n[k] /= l;
}

/* Signed distance of p in front of wall w (positive = the viewer's side). */
static double wall_distance(const cv_wall *w, const double p[3]) {
  double n[3], d[3];
  wall_normal(w, n);
  for (int k = 0; k < 3; k++) d[k] = p[k] - w->pa[k];
  return dot3(n, d);
}

/* --- walls ---------------------------------------------------------------- */

static int parse_wall(ctx *x, const cJSON *o, int i, cv_wall *w) {
  char path[32], f[64];
  snprintf(path, sizeof path, "walls[%d]", i);
  if (!cJSON_IsObject(o)) {
    problem(x, CV_ERR_CONFIG, path, "expected an object {name, pa, pb, pc, res}");
    return 0;
  }
  static const char *const keys[] = {"name", "pa", "pb", "pc", "res", NULL};
  int before = x->count;
  only_keys(x, o, path, keys);
  int ok = x->count == before;

  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, "name");
  snprintf(f, sizeof f, "%s.name", path);
  if (!v) {
    problem(x, CV_ERR_CONFIG, f, "missing (expected a wall name, 1..31 characters)");
    ok = 0;
  } else if (!cJSON_IsString(v) || !v->valuestring[0] ||
             strlen(v->valuestring) >= sizeof w->name) {
    problem(x, CV_ERR_CONFIG, f, "expected a wall name, 1..31 characters");
    ok = 0;
  } else {
    snprintf(w->name, sizeof w->name, "%s", v->valuestring);
  }

  static const char *const cn[3] = {"pa", "pb", "pc"};
  static const char *const what[3] = {"lower-left", "lower-right", "upper-left"};
  double *p[3] = {w->pa, w->pb, w->pc};
  int corners = 1;
  for (int k = 0; k < 3; k++) {
    snprintf(f, sizeof f, "%s.%s", path, cn[k]);
    v = cJSON_GetObjectItemCaseSensitive(o, cn[k]);
    if (!v) {
      problem(x, CV_ERR_CONFIG, f, "missing (expected the %s corner [x, y, z] in metres)",
              what[k]);
      corners = 0;
    } else if (!read_vec3(x, v, f, p[k])) {
      corners = 0;
    }
  }
  if (corners) {
    double e1[3], e2[3];
    for (int k = 0; k < 3; k++) {
      e1[k] = w->pb[k] - w->pa[k];
      e2[k] = w->pc[k] - w->pa[k];
    }
    double l1 = sqrt(dot3(e1, e1)), l2 = sqrt(dot3(e2, e2));
    if (!(l1 > 1e-6) || !(l2 > 1e-6)) {
      snprintf(f, sizeof f, "%s.%s", path, !(l1 > 1e-6) ? "pb" : "pc");
      problem(x, CV_ERR_CONFIG, f, "coincides with pa: the wall has zero area");
      corners = 0;
    } else {
      double c = dot3(e1, e2) / (l1 * l2);
      double off = fabs(acos(fmax(-1.0, fmin(1.0, c))) - 1.57079632679489661923);
      if (off > CV_CAVE_RIGHT_ANGLE_TOL) {
        snprintf(f, sizeof f, "%s.pc", path);
        problem(x, CV_ERR_CONFIG, f,
                "pb-pa and pc-pa are %.4g degrees apart; the corners must form a rectangle "
                "(90 degrees within %g rad)",
                acos(fmax(-1.0, fmin(1.0, c))) * 57.29577951308232, CV_CAVE_RIGHT_ANGLE_TOL);
        corners = 0;
      }
    }
  }
  ok &= corners;

  snprintf(f, sizeof f, "%s.res", path);
  v = cJSON_GetObjectItemCaseSensitive(o, "res");
  if (!v) {
    problem(x, CV_ERR_CONFIG, f, "missing (expected [w, h] pixels, each 1..%d)", CV_CAVE_MAX_RES);
    ok = 0;
  } else if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) != 2) {
    problem(x, CV_ERR_CONFIG, f, "expected [w, h] pixels, each 1..%d", CV_CAVE_MAX_RES);
    ok = 0;
  } else {
    for (int k = 0; k < 2; k++) {
      char fk[80];
      snprintf(fk, sizeof fk, "%s[%d]", f, k);
      double d;
      if (!read_number(x, cJSON_GetArrayItem(v, k), fk, &d)) {
        ok = 0;
      } else if (d != floor(d) || d < 1 || d > CV_CAVE_MAX_RES) {
        problem(x, CV_ERR_RANGE, fk, "expected an integer in [1, %d], got %g", CV_CAVE_MAX_RES,
                d);
        ok = 0;
      } else {
        w->res[k] = (int)d;
      }
    }
  }
  return ok;
}

/* --- root ----------------------------------------------------------------- */

void cv_cave_defaults(cv_cave *c) {
  memset(c, 0, sizeof *c);
  c->eye_separation = 0.064;
  c->supersample = 1;
  c->foveal_deg = 10.0;
  c->lum_res = 128;
  c->drago_bias = 0.85;
  c->drago_ldmax = 100.0;
  c->t0_cone = 0.080;
  c->t0_rod = 0.150;
  c->tau_cone = 110.0;
  c->tau_rod = 400.0;
  c->head[1] = 1.2;
  c->gaze[2] = -1.0;
  c->near = 0.05;
  c->far = 50.0;
}

static void parse_root(ctx *x, const cJSON *root, cv_cave *c) {
  if (!cJSON_IsObject(root)) {
    problem(x, CV_ERR_CONFIG, "", "expected a JSON object with \"walls\"");
    return;
  }
  static const char *const keys[] = {
      "description", "walls",   "eye_separation", "supersample", "foveal_deg",
      "lum_res",     "drago_bias", "drago_ldmax", "t0_cone",     "t0_rod",
      "tau_cone",    "tau_rod", "head",           "gaze",        "scene_offset",
      "near",        "far",     NULL};
  only_keys(x, root, "", keys);

  const cJSON *v = cJSON_GetObjectItemCaseSensitive(root, "description");
  if (v && !cJSON_IsString(v)) problem(x, CV_ERR_CONFIG, "description", "expected a string");

  int walls_ok = 0;
  v = cJSON_GetObjectItemCaseSensitive(root, "walls");
  if (!v) {
    problem(x, CV_ERR_CONFIG, "walls", "missing (expected 1..%d walls {name, pa, pb, pc, res})",
            CV_CAVE_MAX_WALLS);
  } else if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) < 1 ||
             cJSON_GetArraySize(v) > CV_CAVE_MAX_WALLS) {
    problem(x, CV_ERR_CONFIG, "walls", "expected an array of 1..%d walls", CV_CAVE_MAX_WALLS);
  } else {
    walls_ok = 1;
    c->n_walls = cJSON_GetArraySize(v);
    for (int i = 0; i < c->n_walls; i++)
      if (!parse_wall(x, cJSON_GetArrayItem(v, i), i, &c->walls[i])) walls_ok = 0;
    for (int i = 0; i < c->n_walls; i++)
      for (int j = 0; j < i; j++)
        if (c->walls[i].name[0] && !strcmp(c->walls[i].name, c->walls[j].name)) {
          char f[40];
          snprintf(f, sizeof f, "walls[%d].name", i);
          problem(x, CV_ERR_CONFIG, f, "duplicate name \"%s\" (also walls[%d].name)",
                  c->walls[i].name, j);
          break;
        }
  }

  opt_num(x, root, "eye_separation", 0.0, 0, 0.2, 0, &c->eye_separation);
  const cJSON *ss = cJSON_GetObjectItemCaseSensitive(root, "supersample");
  if (ss) {
    double d;
    if (read_number(x, ss, "supersample", &d)) {
      if (d == 1.0 || d == 2.0)
        c->supersample = (int)d;
      else
        problem(x, CV_ERR_RANGE, "supersample", "expected 1 or 2, got %g", d);
    }
  }
  opt_num(x, root, "foveal_deg", 0.0, 1, 180.0, 1, &c->foveal_deg);
  opt_int(x, root, "lum_res", 1, 4096, &c->lum_res);
  opt_num(x, root, "drago_bias", 0.0, 1, 1.0, 1, &c->drago_bias);
  opt_num(x, root, "drago_ldmax", 0.0, 1, 1e6, 0, &c->drago_ldmax);
  opt_num(x, root, "t0_cone", 0.0, 1, 1e6, 0, &c->t0_cone);
  opt_num(x, root, "t0_rod", 0.0, 1, 1e6, 0, &c->t0_rod);
  opt_num(x, root, "tau_cone", 0.0, 1, 1e6, 0, &c->tau_cone);
  opt_num(x, root, "tau_rod", 0.0, 1, 1e6, 0, &c->tau_rod);

  int head_ok = 1;
  v = cJSON_GetObjectItemCaseSensitive(root, "head");
  if (v) head_ok = read_vec3(x, v, "head", c->head);
  v = cJSON_GetObjectItemCaseSensitive(root, "gaze");
  if (v) {
    double g[3];
    if (read_vec3(x, v, "gaze", g)) {
      double l = sqrt(dot3(g, g));
      if (!(l > 1e-9))
        problem(x, CV_ERR_CONFIG, "gaze", "expected a non-zero direction");
      else
        for (int k = 0; k < 3; k++) c->gaze[k] = g[k] / l;
    }
  }
  v = cJSON_GetObjectItemCaseSensitive(root, "scene_offset");
  if (v) read_vec3(x, v, "scene_offset", c->scene_offset);

  int clip_ok = opt_num(x, root, "near", 0.0, 1, 1e3, 0, &c->near);
  clip_ok &= opt_num(x, root, "far", 0.0, 1, 1e7, 0, &c->far);
  if (clip_ok && !(c->far > c->near))
    problem(x, CV_ERR_RANGE, "far", "expected far > near, got near %g, far %g", c->near, c->far);

  /* The default head must see every wall from its front. */
  if (walls_ok && head_ok)
    for (int i = 0; i < c->n_walls; i++) {
      double d = wall_distance(&c->walls[i], c->head);
      if (!(d > 1e-6))
        problem(x, CV_ERR_RANGE, "head",
                "(%g, %g, %g) is on or behind wall \"%s\" (walls[%d]), %.3g m from its plane",
                c->head[0], c->head[1], c->head[2], c->walls[i].name, i, d);
    }
}

int cv_cave_parse(const char *json_text, const char *name_for_errors, cv_cave *out,
                  cv_err *err) {
  ctx x;
  memset(&x, 0, sizeof x);
  x.file = name_for_errors ? name_for_errors : "(cave)";
  if (!json_text || !out) {
    problem(&x, CV_ERR_INVALID, "", "no text or no output");
    return finish(&x, err);
  }
  cJSON *root = cJSON_Parse(json_text);
  if (!root) {
    const char *e = cJSON_GetErrorPtr();
    int line = 1;
    if (e)
      for (const char *q = json_text; q < e && *q; q++) line += *q == '\n';
    problem(&x, CV_ERR_FORMAT, "", "not valid JSON (near line %d)", line);
    return finish(&x, err);
  }
  cv_cave *c = malloc(sizeof *c);
  if (!c) {
    cJSON_Delete(root);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", x.file);
  }
  cv_cave_defaults(c);
  parse_root(&x, root, c);
  cJSON_Delete(root);
  if (x.count) {
    free(c);
    return finish(&x, err);
  }
  *out = *c;
  free(c);
  cv_err_clear(err);
  return CV_OK;
}

int cv_cave_load(const char *path, cv_cave *out, cv_err *err) {
  if (!path || !out) return cv_err_set(err, CV_ERR_INVALID, "cv_cave_load: no path or output");
  FILE *f = fopen(path, "rb");
  if (!f) return cv_err_set(err, CV_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
  char *t = NULL;
  long n = -1;
  if (fseek(f, 0, SEEK_END) == 0) n = ftell(f);
  if (n < 0 || n > (16 << 20) || fseek(f, 0, SEEK_SET) != 0) {
    fclose(f);
    return cv_err_set(err, CV_ERR_CONFIG, "%s: not a plausible CAVE description (size %ld)",
                      path, n);
  }
  t = malloc((size_t)n + 1);
  if (!t || fread(t, 1, (size_t)n, f) != (size_t)n) {
    int st = t ? CV_ERR_IO : CV_ERR_NOMEM;
    fclose(f);
    free(t);
    return cv_err_set(err, st, "%s: read failed", path);
  }
  fclose(f);
  t[n] = '\0';
  int st = cv_cave_parse(t, path, out, err);
  free(t);
  return st;
}

int cv_cave_check_eye(const cv_cave *c, const double eye[3], cv_err *err) {
  if (!c || !eye) return cv_err_set(err, CV_ERR_INVALID, "cv_cave_check_eye: NULL argument");
  if (!isfinite(eye[0]) || !isfinite(eye[1]) || !isfinite(eye[2]))
    return cv_err_set(err, CV_ERR_NONFINITE, "eye position is not finite");
  for (int i = 0; i < c->n_walls; i++) {
    double d = wall_distance(&c->walls[i], eye);
    if (!(d > 1e-6))
      return cv_err_set(err, CV_ERR_RANGE,
                        "eye (%g, %g, %g) is on or behind wall \"%s\" (walls[%d]), %.3g m from "
                        "its plane",
                        eye[0], eye[1], eye[2], c->walls[i].name, i, d);
  }
  cv_err_clear(err);
  return CV_OK;
}
