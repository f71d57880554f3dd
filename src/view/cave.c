/* CAVE configuration loader (see cave.h), on cJSON.
 *
 * Like the display loader (compensate/display.c) the parser does not stop at
 * the first problem: every check appends "field: problem" to a collector, and
 * the error line lists all of them, "file: field: problem; field: problem".
 * *out is written only when there was no problem. */
#include "view/cave.h"

#include "io/textfile.h"

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
  char prefix[64]; /* prepended to field names (nested objects read with opt_num) */
  char *lines;    /* optional: every problem, "file: field: what\n" (not owned) */
  size_t lines_cap, lines_len;
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
    snprintf(line, sizeof line, "%s%s: %s", x->prefix, field, what);
  else
    snprintf(line, sizeof line, "%s", what);
  if (x->count++ == 0) x->first_status = status;
  if (x->lines && x->lines_len + 1 < x->lines_cap) {
    int w = snprintf(x->lines + x->lines_len, x->lines_cap - x->lines_len, "%s: %s\n", x->file, line);
    if (w > 0) x->lines_len += (size_t)w;
    if (x->lines_len >= x->lines_cap) x->lines_len = x->lines_cap - 1;
  }
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
      problem(x, CV_ERR_RANGE, f, "%.10g is outside [-%.10g, %.10g]", t[k], COORD_LIMIT, COORD_LIMIT);
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
    problem(x, CV_ERR_RANGE, key, "%.10g is outside %c%.10g, %.10g%c", d, lo_open ? '(' : '[', lo, hi,
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
      char field[256], list[320], kbuf[128];
      snprintf(field, sizeof field, "%s%s%s", path, path[0] ? "." : "",
               cv_json_key_show(it->string, kbuf, sizeof kbuf));
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

static void ctx_field_prefix(ctx *x, const char *p) { snprintf(x->prefix, sizeof x->prefix, "%s", p); }

/* --- outputs ---------------------------------------------------------------- */

const char *cv_stereo_mode_name(int mode) {
  switch (mode) {
  case CV_STEREO_PASSIVE: return "passive";
  case CV_STEREO_QUAD: return "quad";
  case CV_STEREO_SIDE_BY_SIDE: return "side-by-side";
  case CV_STEREO_TOP_BOTTOM: return "top-bottom";
  default: return "?";
  }
}

/* Without "outputs": one passive output per wall-eye, rank order wall-major
 * (rank 1 + 2w + e), this host's $DISPLAY, tiled at run time, GPU auto. */
static void default_outputs(cv_cave *c) {
  c->n_outputs = 0;
  for (int w = 0; w < c->n_walls; w++)
    for (int e = 0; e < 2; e++) {
      cv_output *o = &c->outputs[c->n_outputs++];
      memset(o, 0, sizeof *o);
      o->wall = w;
      o->eyes = 1 << e;
      o->gpu = CV_GPU_AUTO;
      o->stereo = CV_STEREO_PASSIVE;
    }
}

/* "name:N.S" -> host part ("" when none) and the rest. */
static void display_host(const char *d, char *host, size_t cap) {
  const char *colon = strrchr(d, ':');
  size_t n = colon ? (size_t)(colon - d) : 0;
  if (n >= cap) n = cap - 1;
  memcpy(host, d, n);
  host[n] = 0;
}

static int parse_output(ctx *x, const cJSON *o, int i, const cv_cave *c, cv_output *out) {
  char path[32], f[64];
  snprintf(path, sizeof path, "outputs[%d]", i);
  if (!cJSON_IsObject(o)) {
    problem(x, CV_ERR_CONFIG, path, "expected an object {wall, eye, host, display, geometry, gpu, stereo}");
    return 0;
  }
  static const char *const keys[] = {"wall", "eye", "host", "display", "geometry", "fullscreen",
                                     "gpu", "stereo", NULL};
  int before = x->count;
  only_keys(x, o, path, keys);
  memset(out, 0, sizeof *out);
  out->wall = -1;
  out->gpu = CV_GPU_UNSET;
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, "wall");
  snprintf(f, sizeof f, "%s.wall", path);
  if (!v || !cJSON_IsString(v)) {
    problem(x, CV_ERR_CONFIG, f, "%s (expected the name of one of the walls)", v ? "not a string" : "missing");
  } else {
    for (int w = 0; w < c->n_walls; w++)
      if (!strcmp(c->walls[w].name, v->valuestring)) out->wall = w;
    if (out->wall < 0) problem(x, CV_ERR_CONFIG, f, "no wall named \"%s\"", v->valuestring);
  }
  v = cJSON_GetObjectItemCaseSensitive(o, "stereo");
  snprintf(f, sizeof f, "%s.stereo", path);
  out->stereo = CV_STEREO_PASSIVE;
  if (v) {
    int m = -1;
    for (int k = 0; k < 4 && cJSON_IsString(v); k++)
      if (!strcmp(v->valuestring, cv_stereo_mode_name(k))) m = k;
    if (m < 0) problem(x, CV_ERR_CONFIG, f, "expected \"passive\", \"quad\", \"side-by-side\" or \"top-bottom\"");
    else out->stereo = m;
  }
  v = cJSON_GetObjectItemCaseSensitive(o, "eye");
  snprintf(f, sizeof f, "%s.eye", path);
  if (out->stereo == CV_STEREO_PASSIVE) {
    if (!v || !cJSON_IsString(v) || (strcmp(v->valuestring, "left") && strcmp(v->valuestring, "right")))
      problem(x, CV_ERR_CONFIG, f, "%s (a passive output shows one eye: \"left\" or \"right\")",
              v ? "invalid" : "missing");
    else
      out->eyes = strcmp(v->valuestring, "left") ? 2 : 1;
  } else {
    if (v && (!cJSON_IsString(v) || strcmp(v->valuestring, "both")))
      problem(x, CV_ERR_CONFIG, f, "a %s output shows both eyes: \"both\" or leave it out",
              cv_stereo_mode_name(out->stereo));
    out->eyes = 3;
  }
  v = cJSON_GetObjectItemCaseSensitive(o, "host");
  snprintf(f, sizeof f, "%s.host", path);
  if (v) {
    if (!cJSON_IsString(v) || strlen(v->valuestring) >= sizeof out->host || strchr(v->valuestring, ' '))
      problem(x, CV_ERR_CONFIG, f, "expected a host name (no spaces, up to %zu characters)", sizeof out->host - 1);
    else
      snprintf(out->host, sizeof out->host, "%s", v->valuestring);
  }
  v = cJSON_GetObjectItemCaseSensitive(o, "display");
  snprintf(f, sizeof f, "%s.display", path);
  if (v) {
    if (!cJSON_IsString(v) || strlen(v->valuestring) >= sizeof out->display || !strchr(v->valuestring, ':'))
      problem(x, CV_ERR_CONFIG, f, "expected an X display such as \":0\" or \":0.1\"");
    else
      snprintf(out->display, sizeof out->display, "%s", v->valuestring);
  }
  v = cJSON_GetObjectItemCaseSensitive(o, "fullscreen");
  snprintf(f, sizeof f, "%s.fullscreen", path);
  if (v) {
    if (!cJSON_IsBool(v)) problem(x, CV_ERR_CONFIG, f, "expected true or false");
    else out->fullscreen = cJSON_IsTrue(v);
  }
  v = cJSON_GetObjectItemCaseSensitive(o, "geometry");
  snprintf(f, sizeof f, "%s.geometry", path);
  if (v) {
    int ok = cJSON_IsArray(v) && cJSON_GetArraySize(v) == 4;
    for (int k = 0; ok && k < 4; k++) {
      const cJSON *e = cJSON_GetArrayItem(v, k);
      if (!cJSON_IsNumber(e) || e->valuedouble != floor(e->valuedouble) ||
          fabs(e->valuedouble) > 65535 || (k >= 2 && e->valuedouble < 1))
        ok = 0;
      else
        out->geometry[k] = (int)e->valuedouble;
    }
    if (!ok) {
      problem(x, CV_ERR_CONFIG, f, "expected [x, y, w, h] in pixels (w, h >= 1)");
      out->geometry[2] = 0;
    } else if (out->fullscreen) {
      problem(x, CV_ERR_CONFIG, f, "give geometry or \"fullscreen\": true, not both");
    }
  }
  v = cJSON_GetObjectItemCaseSensitive(o, "gpu");
  snprintf(f, sizeof f, "%s.gpu", path);
  if (!v) {
    problem(x, CV_ERR_CONFIG, f, "missing (expected a hardware EGL device index >= 0, \"auto\" or \"software\")");
  } else if (cJSON_IsString(v) && !strcmp(v->valuestring, "auto")) {
    out->gpu = CV_GPU_AUTO;
  } else if (cJSON_IsString(v) && !strcmp(v->valuestring, "software")) {
    out->gpu = CV_GPU_SOFTWARE;
  } else if (cJSON_IsNumber(v) && v->valuedouble == floor(v->valuedouble) && v->valuedouble >= 0 &&
             v->valuedouble < 64) {
    out->gpu = (int)v->valuedouble;
  } else {
    problem(x, CV_ERR_CONFIG, f, "expected a hardware EGL device index 0..63, \"auto\" or \"software\"");
  }
  if (out->display[0] && out->host[0]) {
    char dh[64];
    display_host(out->display, dh, sizeof dh);
    if (dh[0] && strcmp(dh, out->host)) {
      snprintf(f, sizeof f, "%s.display", path);
      problem(x, CV_ERR_CONFIG, f, "\"%s\" is a display of host \"%s\", but the output runs on \"%s\"",
              out->display, dh, out->host);
    }
  }
  return x->count == before;
}

/* Two outputs share a screen when they are on the same host and X display
 * (an empty display means the rank's $DISPLAY: the same for one host). */
static int same_screen(const cv_output *a, const cv_output *b) {
  return !strcmp(a->host, b->host) && !strcmp(a->display, b->display);
}

static int overlap(const cv_output *a, const cv_output *b) {
  if (a->fullscreen || b->fullscreen) return 1;
  if (!a->geometry[2] || !b->geometry[2]) return 0; /* tiled at run time, side by side */
  return a->geometry[0] < b->geometry[0] + b->geometry[2] && b->geometry[0] < a->geometry[0] + a->geometry[2] &&
         a->geometry[1] < b->geometry[1] + b->geometry[3] && b->geometry[1] < a->geometry[1] + a->geometry[3];
}

static void parse_outputs(ctx *x, const cJSON *v, cv_cave *c) {
  if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) < 1 || cJSON_GetArraySize(v) > CV_CAVE_MAX_OUTPUTS) {
    problem(x, CV_ERR_CONFIG, "outputs", "expected an array of 1..%d outputs", CV_CAVE_MAX_OUTPUTS);
    return;
  }
  const int n = cJSON_GetArraySize(v);
  int ok = 1;
  for (int i = 0; i < n; i++) ok &= parse_output(x, cJSON_GetArrayItem(v, i), i, c, &c->outputs[i]);
  c->n_outputs = n;
  /* Every wall-eye exactly once. */
  int cover[CV_CAVE_MAX_WALLS][2];
  memset(cover, 0, sizeof cover);
  for (int i = 0; i < n; i++)
    for (int e = 0; e < 2; e++)
      if (c->outputs[i].wall >= 0 && (c->outputs[i].eyes >> e & 1)) {
        int *cv = &cover[c->outputs[i].wall][e];
        if (*cv) {
          char f[32];
          snprintf(f, sizeof f, "outputs[%d]", i);
          problem(x, CV_ERR_CONFIG, f, "wall \"%s\" %s eye is already shown by outputs[%d]",
                  c->walls[c->outputs[i].wall].name, e ? "right" : "left", *cv - 1);
        } else {
          *cv = i + 1;
        }
      }
  if (ok)
    for (int w = 0; w < c->n_walls; w++)
      for (int e = 0; e < 2; e++)
        if (!cover[w][e])
          problem(x, CV_ERR_CONFIG, "outputs", "no output shows wall \"%s\" %s eye", c->walls[w].name,
                  e ? "right" : "left");
  /* Windows sharing a screen must not overlap; a display naming a host
   * belongs to that host alone. */
  for (int i = 0; i < n; i++)
    for (int j = 0; j < i; j++) {
      const cv_output *a = &c->outputs[i], *b = &c->outputs[j];
      char f[32];
      snprintf(f, sizeof f, "outputs[%d]", i);
      if (same_screen(a, b) && overlap(a, b))
        problem(x, CV_ERR_CONFIG, f, "window overlaps outputs[%d] on host \"%s\" display \"%s\"", j,
                a->host[0] ? a->host : "(any)", a->display[0] ? a->display : "$DISPLAY");
      char ha[64], hb[64];
      display_host(a->display, ha, sizeof ha);
      display_host(b->display, hb, sizeof hb);
      if (ha[0] && !strcmp(a->display, b->display) && strcmp(a->host, b->host))
        problem(x, CV_ERR_CONFIG, f, "display \"%s\" is used by hosts \"%s\" (outputs[%d]) and \"%s\"",
                a->display, b->host[0] ? b->host : "(any)", j, a->host[0] ? a->host : "(any)");
    }
}

cv_rank_role cv_cave_rank_role(const cv_cave *c, int rank) {
  cv_rank_role r = {CV_ROLE_GATHER, -1};
  if (rank == 0) r.role = CV_ROLE_MASTER;
  else if (rank - 1 < c->n_outputs) r.role = CV_ROLE_RENDER, r.output = rank - 1;
  return r;
}

int cv_cave_walleye_rank(const cv_cave *c, int wall, int eye) {
  for (int i = 0; i < c->n_outputs; i++)
    if (c->outputs[i].wall == wall && (c->outputs[i].eyes >> eye & 1)) return 1 + i;
  return -1;
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
  c->rate = 60.0;
  c->screen_reflectance = 0.8;
  c->screen_patches = 24;
  c->max_head_speed = 10.0;
}

/* "tracking": {"volume": [[x0, y0, z0], [x1, y1, z1]], "max_head_speed": V};
 * without a volume, the walls' bounding box grown by 0.5 m. */
static void parse_tracking(ctx *x, const cJSON *root, cv_cave *c, int walls_ok) {
  int have_vol = 0;
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(root, "tracking");
  if (v && !cJSON_IsObject(v)) {
    problem(x, CV_ERR_CONFIG, "tracking", "expected an object {volume, max_head_speed}");
  } else if (v) {
    static const char *const tkeys[] = {"volume", "max_head_speed", NULL};
    only_keys(x, v, "tracking", tkeys);
    const cJSON *vol = cJSON_GetObjectItemCaseSensitive(v, "volume");
    if (vol) {
      if (!cJSON_IsArray(vol) || cJSON_GetArraySize(vol) != 2) {
        problem(x, CV_ERR_CONFIG, "tracking.volume", "expected two corners [[x0, y0, z0], [x1, y1, z1]] (m)");
      } else if (read_vec3(x, cJSON_GetArrayItem(vol, 0), "tracking.volume[0]", c->track_lo) &&
                 read_vec3(x, cJSON_GetArrayItem(vol, 1), "tracking.volume[1]", c->track_hi)) {
        have_vol = 1;
        for (int k = 0; k < 3; k++)
          if (!(c->track_hi[k] > c->track_lo[k]))
            problem(x, CV_ERR_RANGE, "tracking.volume", "expected corner 1 above corner 0 on every axis, got "
                    "%g <= %g on axis %d", c->track_hi[k], c->track_lo[k], k);
      }
    }
    ctx_field_prefix(x, "tracking.");
    opt_num(x, v, "max_head_speed", 0.0, 0, 1000.0, 0, &c->max_head_speed);
    ctx_field_prefix(x, "");
  }
  if (have_vol || !walls_ok) return;
  for (int k = 0; k < 3; k++) c->track_lo[k] = INFINITY, c->track_hi[k] = -INFINITY;
  for (int i = 0; i < c->n_walls; i++) {
    const cv_wall *w = &c->walls[i];
    for (int k = 0; k < 3; k++) {
      const double q[4] = {w->pa[k], w->pb[k], w->pc[k], w->pb[k] + w->pc[k] - w->pa[k]};
      for (int j = 0; j < 4; j++) {
        c->track_lo[k] = fmin(c->track_lo[k], q[j] - 0.5);
        c->track_hi[k] = fmax(c->track_hi[k], q[j] + 0.5);
      }
    }
  }
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
      "near",        "far",     "rate",           "screens",     "outputs",
      "tracking",    NULL};
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

  opt_num(x, root, "rate", 0.0, 1, 1000.0, 0, &c->rate);
  v = cJSON_GetObjectItemCaseSensitive(root, "screens");
  if (v) {
    static const char *const skeys[] = {"reflectance", "patches", NULL};
    if (!cJSON_IsObject(v)) {
      problem(x, CV_ERR_CONFIG, "screens", "expected an object {reflectance, patches}");
    } else {
      only_keys(x, v, "screens", skeys);
      ctx_field_prefix(x, "screens.");
      opt_num(x, v, "reflectance", 0.0, 0, 1.0, 1, &c->screen_reflectance);
      opt_int(x, v, "patches", 1, 256, &c->screen_patches);
      ctx_field_prefix(x, "");
    }
  }
  parse_tracking(x, root, c, walls_ok);
  if (walls_ok) {
    v = cJSON_GetObjectItemCaseSensitive(root, "outputs");
    if (v) {
      c->outputs_given = 1;
      parse_outputs(x, v, c);
    } else {
      default_outputs(c);
    }
  }

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

static int cave_parse(const char *json_text, const char *name_for_errors, cv_cave *out, char *lines,
                      size_t cap, int *count, cv_err *err);

int cv_cave_parse(const char *json_text, const char *name_for_errors, cv_cave *out,
                  cv_err *err) {
  return cave_parse(json_text, name_for_errors, out, NULL, 0, NULL, err);
}

static int cave_from_tree(ctx *x, const cJSON *root, cv_cave *out, int *count, cv_err *err);

static int cave_parse(const char *json_text, const char *name_for_errors, cv_cave *out, char *lines,
                      size_t cap, int *count, cv_err *err) {
  ctx x;
  memset(&x, 0, sizeof x);
  x.lines = lines;
  x.lines_cap = cap;
  if (lines && cap) lines[0] = 0;
  if (count) *count = 0;
  x.file = name_for_errors ? name_for_errors : "(cave)";
  if (!json_text || !out) {
    problem(&x, CV_ERR_INVALID, "", "no text or no output");
    return finish(&x, err);
  }
  cJSON *root = cJSON_Parse(json_text);
  if (!root) {
    int line, col;
    char f[48], what[128];
    cv_json_syntax_error(json_text, cJSON_GetErrorPtr(), &line, &col, what, sizeof what);
    snprintf(f, sizeof f, "line %d, column %d", line, col);
    problem(&x, CV_ERR_FORMAT, f, "%s", what);
    if (count) *count = x.count;
    return finish(&x, err);
  }
  int st = cave_from_tree(&x, root, out, count, err);
  cJSON_Delete(root);
  return st;
}

/* The CAVE of a parsed tree (problems collected in x). */
static int cave_from_tree(ctx *x, const cJSON *root, cv_cave *out, int *count, cv_err *err) {
  cv_cave *c = malloc(sizeof *c);
  if (!c) return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", x->file);
  cv_cave_defaults(c);
  parse_root(x, root, c);
  if (count) *count = x->count;
  if (x->count) {
    free(c);
    return finish(x, err);
  }
  *out = *c;
  free(c);
  cv_err_clear(err);
  return CV_OK;
}

int cv_cave_from_json(const cJSON *root, const char *name_for_errors, cv_cave *out, cv_err *err) {
  ctx x;
  memset(&x, 0, sizeof x);
  x.file = name_for_errors ? name_for_errors : "(cave)";
  return cave_from_tree(&x, root, out, NULL, err);
}

int cv_cave_load(const char *path, cv_cave *out, cv_err *err) {
  return cv_cave_load_all(path, out, NULL, 0, NULL, err);
}

int cv_cave_load_all(const char *path, cv_cave *out, char *buf, size_t cap, int *count, cv_err *err) {
  if (count) *count = 1;
  if (buf && cap) buf[0] = 0;
  if (!path || !out) return cv_err_set(err, CV_ERR_INVALID, "cv_cave_load: no path or output");
  char *t = NULL;
  int rst = cv_read_json_file(path, &t, err);
  if (rst) return rst;
  int st = cave_parse(t, path, out, buf, cap, count, err);
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

int cv_gpu_parse(const char *s, int *gpu) {
  if (!s) return -1;
  if (!strcmp(s, "auto")) return *gpu = CV_GPU_AUTO, 0;
  if (!strcmp(s, "software")) return *gpu = CV_GPU_SOFTWARE, 0;
  char *end;
  errno = 0;
  long v = strtol(s, &end, 10);
  if (end == s || *end || errno || v < 0 || v > 63) return -1;
  *gpu = (int)v;
  return 0;
}

void cv_cave_fit_res(cv_cave *c, int n) {
  if (n <= 0) return;
  for (int i = 0; i < c->n_walls; i++) {
    int *r = c->walls[i].res, big = r[0] > r[1] ? r[0] : r[1];
    int w = (int)lround((double)r[0] * n / big), h = (int)lround((double)r[1] * n / big);
    r[0] = w < 1 ? 1 : w;
    r[1] = h < 1 ? 1 : h;
  }
}
