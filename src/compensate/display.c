/* Display description loader and patch geometry (see display.h), on cJSON.
 *
 * The parser does not stop at the first problem: every check appends a
 * "file: field: what" line to a collector, so that cv_display_validate_all
 * can list them all and cv_display_load can report the first one with a
 * count of the others.  Geometry (patches, projector factors) is only built
 * once the description is free of problems. */
#include "compensate/display.h"

#include "io/textfile.h"

#include "core/vec3d.h"
#include "io/json_keys.h"
#include "io/problems.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846
#define MAX_PATCHES_PER_AXIS 4096
#define MAX_PATCHES_TOTAL (1u << 22)
#define RIGHT_ANGLE_TOL_DEG 0.01

/* --- problem collector ---------------------------------------------------- */

typedef cv_problems ctx; /* io/problems.h */


/* --- typed field readers: each reports its own problem and returns 0 on it */

static void field_name(char *out, size_t n, const char *path, const char *key) {
  snprintf(out, n, "%s%s%s", path, (path[0] && key[0]) ? "." : "", key);
}

static int read_number(ctx *x, const cJSON *v, const char *field, double *out) {
  if (!cJSON_IsNumber(v)) {
    cv_problem(x, CV_ERR_CONFIG, field, "expected a number");
    return 0;
  }
  if (!isfinite(v->valuedouble)) {
    cv_problem(x, CV_ERR_NONFINITE, field, "expected a finite number, got %g", v->valuedouble);
    return 0;
  }
  *out = v->valuedouble;
  return 1;
}

/* Array of exactly n finite numbers, each in [lo, hi]. */
static int read_vec(ctx *x, const cJSON *v, const char *field, int n, double lo, double hi,
                    const char *what, double *out) {
  if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) != n) {
    cv_problem(x, CV_ERR_CONFIG, field, "expected %s", what);
    return 0;
  }
  int ok = 1;
  for (int k = 0; k < n; k++) {
    char f[300];
    snprintf(f, sizeof f, "%s[%d]", field, k);
    double d;
    if (!read_number(x, cJSON_GetArrayItem(v, k), f, &d)) {
      ok = 0;
      continue;
    }
    if (d < lo || d > hi) {
      cv_problem(x, CV_ERR_RANGE, f, "%g is outside [%g, %g]", d, lo, hi);
      ok = 0;
      continue;
    }
    out[k] = d;
  }
  return ok;
}


static const cJSON *required(ctx *x, const cJSON *obj, const char *path, const char *key,
                             const char *what) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
  if (!v) {
    char field[256];
    field_name(field, sizeof field, path, key);
    cv_problem(x, CV_ERR_CONFIG, field, "missing (expected %s)", what);
  }
  return v;
}

/* Optional number in [lo, hi] (open ends when the flags say so). */
static int read_opt_num(ctx *x, const cJSON *obj, const char *path, const char *key, double lo,
                        int lo_open, double hi, int hi_open, double *out) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
  if (!v) return 1;
  char field[256];
  field_name(field, sizeof field, path, key);
  double d;
  if (!read_number(x, v, field, &d)) return 0;
  if ((lo_open ? !(d > lo) : !(d >= lo)) || (hi_open ? !(d < hi) : !(d <= hi))) {
    cv_problem(x, CV_ERR_RANGE, field, "%g is outside %c%g, %g%c", d, lo_open ? '(' : '[', lo, hi,
            hi_open ? ')' : ']');
    return 0;
  }
  *out = d;
  return 1;
}

static int read_req_num(ctx *x, const cJSON *obj, const char *path, const char *key, double lo,
                        int lo_open, double hi, const char *what, double *out) {
  if (!required(x, obj, path, key, what)) return 0;
  return read_opt_num(x, obj, path, key, lo, lo_open, hi, 0, out);
}

/* [lo, hi] pair with lo < hi, both within [min, max]. */
static int read_range(ctx *x, const cJSON *obj, const char *path, const char *key, double min,
                      double max, double max_span, const char *what, double out[2]) {
  const cJSON *v = required(x, obj, path, key, what);
  if (!v) return 0;
  char field[256];
  field_name(field, sizeof field, path, key);
  if (!read_vec(x, v, field, 2, min, max, what, out)) return 0;
  if (!(out[1] > out[0])) {
    cv_problem(x, CV_ERR_RANGE, field, "expected the first value below the second, got [%g, %g]",
            out[0], out[1]);
    return 0;
  }
  if (out[1] - out[0] > max_span) {
    cv_problem(x, CV_ERR_RANGE, field, "span %g exceeds %g", out[1] - out[0], max_span);
    return 0;
  }
  return 1;
}

/* --- surfaces --------------------------------------------------------------- */

/* The surface's "type" into s->kind (default plane).  Returns 0 on a problem. */
static int parse_surface_kind(ctx *x, const cJSON *o, const char *path, cv_display_surface *s) {
  char field[128];
  s->kind = CV_SURFACE_PLANE;
  const cJSON *type = cJSON_GetObjectItemCaseSensitive(o, "type");
  if (!type) return 1;
  field_name(field, sizeof field, path, "type");
  if (cJSON_IsString(type) && !strcmp(type->valuestring, "plane"))
    s->kind = CV_SURFACE_PLANE;
  else if (cJSON_IsString(type) && !strcmp(type->valuestring, "cylinder"))
    s->kind = CV_SURFACE_CYLINDER;
  else if (cJSON_IsString(type) && !strcmp(type->valuestring, "dome"))
    s->kind = CV_SURFACE_DOME;
  else {
    cv_problem(x, CV_ERR_CONFIG, field, "expected \"plane\", \"cylinder\" or \"dome\"");
    return 0;
  }
  return 1;
}

/* Only the keys of the surface's kind.  Returns 0 on a problem. */
static int check_surface_keys(ctx *x, const cJSON *o, const char *path, const cv_display_surface *s) {
  static const char *const plane_keys[] = {"name", "type", "corners", "patches", "reflectance",
                                           "cosine_exponent", "normal_tilt_deg", "refine", NULL};
  static const char *const cyl_keys[] = {"name", "type", "center", "radius", "angle_deg",
                                         "height", "patches", "reflectance",
                                         "cosine_exponent", "normal_tilt_deg", "refine", NULL};
  static const char *const dome_keys[] = {"name", "type", "center", "radius", "elevation_deg",
                                          "azimuth_deg", "patches", "reflectance",
                                          "cosine_exponent", "normal_tilt_deg", "refine", NULL};
  int before = x->count;
  cv_problems_only_keys(x, o,
            path, s->kind == CV_SURFACE_CYLINDER ? cyl_keys
                  : s->kind == CV_SURFACE_DOME   ? dome_keys
                                                 : plane_keys);
  return x->count == before;
}

/* "name" (required, 1..63 characters).  Returns 0 on a problem. */
static int parse_surface_name(ctx *x, const cJSON *o, const char *path, cv_display_surface *s) {
  char field[128];
  const cJSON *name = required(x, o, path, "name", "a surface name (1..63 characters)");
  if (!name) return 0;
  field_name(field, sizeof field, path, "name");
  if (!cJSON_IsString(name) || !name->valuestring[0] || strlen(name->valuestring) > 63) {
    cv_problem(x, CV_ERR_CONFIG, field, "expected a surface name (1..63 characters)");
    return 0;
  }
  snprintf(s->name, sizeof s->name, "%s", name->valuestring);
  return 1;
}

/* "patches" (required, [nu, nv]).  Returns 0 on a problem. */
static int parse_patches(ctx *x, const cJSON *o, const char *path, cv_display_surface *s) {
  char field[128];
  const cJSON *pt = required(x, o, path, "patches", "[nu, nv], positive integers");
  if (!pt) return 0;
  field_name(field, sizeof field, path, "patches");
  if (!cJSON_IsArray(pt) || cJSON_GetArraySize(pt) != 2) {
    cv_problem(x, CV_ERR_CONFIG, field, "expected [nu, nv], positive integers");
    return 0;
  }
  int ok = 1;
  for (int a = 0; a < 2; a++) {
    char f[160];
    double v;
    snprintf(f, sizeof f, "%s[%d]", field, a);
    if (!read_number(x, cJSON_GetArrayItem(pt, a), f, &v)) {
      ok = 0;
    } else if (v != floor(v) || v < 1 || v > MAX_PATCHES_PER_AXIS) {
      cv_problem(x, CV_ERR_RANGE, f, "expected a positive integer up to %d, got %g",
                 MAX_PATCHES_PER_AXIS, v);
      ok = 0;
    } else {
      *(a ? &s->nv : &s->nu) = (int)v;
    }
  }
  return ok;
}

/* The optional "refine" block (seam refinement: seams, strength, width).
 * Returns 0 on a problem. */
static int parse_refine(ctx *x, const cJSON *o, const char *path, cv_display_surface *s) {
  const cJSON *rf = cJSON_GetObjectItemCaseSensitive(o, "refine");
  s->refine_strength = 3.0;
  s->refine_width = 0.15;
  if (!rf) return 1;
  char rpath[200];
  field_name(rpath, sizeof rpath, path, "refine");
  static const char *const rkeys[] = {"seams", "strength", "width", NULL};
  if (!cJSON_IsObject(rf)) {
    cv_problem(x, CV_ERR_CONFIG, rpath, "expected {\"seams\": \"auto\" | [edges], \"strength\", \"width\"}");
    return 0;
  }
  int ok = 1;
  cv_problems_only_keys(x, rf, rpath, rkeys);
  s->refine = 1;
  const cJSON *sm = cJSON_GetObjectItemCaseSensitive(rf, "seams");
  char sf[220];
  field_name(sf, sizeof sf, rpath, "seams");
  if (!sm || (cJSON_IsString(sm) && !strcmp(sm->valuestring, "auto"))) {
    s->refine_auto = 1;
  } else if (cJSON_IsArray(sm)) {
    const cJSON *e;
    cJSON_ArrayForEach(e, sm) {
      static const char *const names[4] = {"left", "right", "bottom", "top"};
      int hit = -1;
      for (int q = 0; q < 4; q++)
        if (cJSON_IsString(e) && !strcmp(e->valuestring, names[q])) hit = q;
      if (hit < 0) {
        cv_problem(x, CV_ERR_CONFIG, sf, "expected \"auto\" or edge names left, right, bottom, top");
        ok = 0;
      } else {
        s->refine_edges |= 1u << hit;
      }
    }
  } else {
    cv_problem(x, CV_ERR_CONFIG, sf, "expected \"auto\" or edge names left, right, bottom, top");
    ok = 0;
  }
  if (!read_opt_num(x, rf, rpath, "strength", 0, 0, 100, 0, &s->refine_strength)) ok = 0;
  if (!read_opt_num(x, rf, rpath, "width", 0.01, 0, 1, 0, &s->refine_width)) ok = 0;
  return ok;
}

/* A plane's "corners" [pa, pb, pc]: a rectangle.  Returns 0 on a problem. */
static int parse_plane_corners(ctx *x, const cJSON *o, const char *path, cv_display_surface *s) {
  char field[128];
  const cJSON *c = required(x, o, path, "corners", "[pa, pb, pc]: lower-left, lower-right, upper-left");
  if (!c) return 0;
  field_name(field, sizeof field, path, "corners");
  if (!cJSON_IsArray(c) || cJSON_GetArraySize(c) != 3) {
    cv_problem(x, CV_ERR_CONFIG, field,
               "expected [pa, pb, pc] (lower-left, lower-right, upper-left), each [x, y, z]");
    return 0;
  }
  double *p[3] = {s->pa, s->pb, s->pc};
  int cok = 1;
  for (int a = 0; a < 3; a++) {
    char f[160];
    snprintf(f, sizeof f, "%s[%d]", field, a);
    if (!read_vec(x, cJSON_GetArrayItem(c, a), f, 3, -1e6, 1e6, "[x, y, z] in metres", p[a]))
      cok = 0;
  }
  if (!cok) return 0;
  double e1[3], e2[3];
  sub3(s->pb, s->pa, e1);
  sub3(s->pc, s->pa, e2);
  double l1 = len3(e1), l2 = len3(e2);
  if (!(l1 > 1e-9) || !(l2 > 1e-9)) {
    cv_problem(x, CV_ERR_CONFIG, field, "pa->%s has zero length", !(l1 > 1e-9) ? "pb" : "pc");
    return 0;
  }
  double cosang = dot3(e1, e2) / (l1 * l2);
  double ang = acos(fmax(-1.0, fmin(1.0, cosang))) * 180.0 / PI;
  if (fabs(ang - 90.0) > RIGHT_ANGLE_TOL_DEG) {
    cv_problem(x, CV_ERR_CONFIG, field,
               "pa->pb and pa->pc are not perpendicular (angle %.4g deg); the surface must be a "
               "rectangle",
               ang);
    return 0;
  }
  return 1;
}

/* A degree range [a0, a1] of field `key` into out[] in radians.  Returns 0
 * on a problem. */
static int read_deg_range(ctx *x, const cJSON *o, const char *path, const char *key, double lo,
                          double hi, double max_span, const char *what, double out[2]) {
  double a[2];
  if (!read_range(x, o, path, key, lo, hi, max_span, what, a)) return 0;
  out[0] = a[0] * PI / 180;
  out[1] = a[1] * PI / 180;
  return 1;
}

/* A cylinder's or dome's center, radius and parameter ranges.  Returns 0
 * on a problem. */
static int parse_curved_shape(ctx *x, const cJSON *o, const char *path, cv_display_surface *s) {
  char field[128];
  int ok = 1;
  const cJSON *c = required(x, o, path, "center", "[x, y, z] in metres");
  field_name(field, sizeof field, path, "center");
  if (!c || !read_vec(x, c, field, 3, -1e6, 1e6, "[x, y, z] in metres", s->center)) ok = 0;
  if (!read_req_num(x, o, path, "radius", 0, 1, 1e6, "a radius in metres", &s->radius)) ok = 0;
  if (s->kind == CV_SURFACE_CYLINDER) {
    if (!read_deg_range(x, o, path, "angle_deg", -720, 720, 360, "[a0, a1] in degrees", s->range_u))
      ok = 0;
    double h[2];
    if (read_range(x, o, path, "height", -1e6, 1e6, 2e6, "[y0, y1] in metres, relative to center",
                   h)) {
      s->range_v[0] = h[0];
      s->range_v[1] = h[1];
    } else {
      ok = 0;
    }
  } else {
    if (!read_deg_range(x, o, path, "elevation_deg", -90, 90, 180, "[e0, e1] in degrees",
                        s->range_v))
      ok = 0;
    if (!read_deg_range(x, o, path, "azimuth_deg", -720, 720, 360, "[a0, a1] in degrees",
                        s->range_u))
      ok = 0;
  }
  return ok;
}

static int parse_surface(ctx *x, const cJSON *o, int k, cv_display_surface *s) {
  char path[64], field[128];
  snprintf(path, sizeof path, "surfaces[%d]", k);
  if (!cJSON_IsObject(o)) {
    cv_problem(x, CV_ERR_CONFIG, path, "expected an object");
    return 0;
  }
  s->cosine_exponent = 1.0;
  s->normal_tilt_deg = 0.0;
  int ok = parse_surface_kind(x, o, path, s);
  if (!check_surface_keys(x, o, path, s)) ok = 0;
  if (!parse_surface_name(x, o, path, s)) ok = 0;
  if (!parse_patches(x, o, path, s)) ok = 0;
  const cJSON *refl = required(x, o, path, "reflectance", "[r, g, b] in [0, 1]");
  field_name(field, sizeof field, path, "reflectance");
  if (!refl || !read_vec(x, refl, field, 3, 0.0, 1.0, "[r, g, b] in [0, 1]", s->reflectance)) ok = 0;
  if (!read_opt_num(x, o, path, "cosine_exponent", 0, 1, 1000, 0, &s->cosine_exponent)) ok = 0;
  if (!parse_refine(x, o, path, s)) ok = 0;
  if (!read_opt_num(x, o, path, "normal_tilt_deg", -90, 1, 90, 1, &s->normal_tilt_deg)) ok = 0;
  if (s->kind == CV_SURFACE_PLANE) return parse_plane_corners(x, o, path, s) ? ok : 0;
  if (!parse_curved_shape(x, o, path, s)) ok = 0;
  return ok;
}

/* Point of surface s at parameters (su, tv) in [0, 1]^2. */
static void surface_point(const cv_display_surface *s, double su, double tv, double p[3]) {
  switch (s->kind) {
  case CV_SURFACE_PLANE:
    for (int k = 0; k < 3; k++)
      p[k] = s->pa[k] + su * (s->pb[k] - s->pa[k]) + tv * (s->pc[k] - s->pa[k]);
    break;
  case CV_SURFACE_CYLINDER: {
    double a = s->range_u[0] + su * (s->range_u[1] - s->range_u[0]);
    double h = s->range_v[0] + tv * (s->range_v[1] - s->range_v[0]);
    p[0] = s->center[0] + s->radius * sin(a);
    p[1] = s->center[1] + h;
    p[2] = s->center[2] - s->radius * cos(a);
    break;
  }
  case CV_SURFACE_DOME: {
    double a = s->range_u[0] + su * (s->range_u[1] - s->range_u[0]);
    double e = s->range_v[0] + tv * (s->range_v[1] - s->range_v[0]);
    p[0] = s->center[0] + s->radius * cos(e) * sin(a);
    p[1] = s->center[1] + s->radius * sin(e);
    p[2] = s->center[2] - s->radius * cos(e) * cos(a);
    break;
  }
  }
}

/* Lobe normalisation: 1 / integral over the front hemisphere (normal +z) of
 * max(0, a . w)^c, a = (0, sin t, cos t).  Midpoint rule in (cos theta, phi),
 * where d(omega) = d(cos theta) d(phi); the integrand is smooth except for the
 * kink at a . w = 0 (only when tilted), so 512 x 1024 cells give ~1e-6. */
static double lobe_norm(double c, double tilt_deg) {
  if (tilt_deg == 0.0) return (c + 1.0) / (2.0 * PI);
  const double t = tilt_deg * PI / 180.0, sy = sin(t), cz = cos(t);
  const int nm = 512, np = 1024;
  double sum = 0;
  for (int i = 0; i < nm; i++) {
    double mu = (i + 0.5) / nm, st = sqrt(1.0 - mu * mu), row = 0;
    for (int j = 0; j < np; j++) {
      double ph = 2.0 * PI * (j + 0.5) / np;
      double d = sy * st * sin(ph) + cz * mu;
      if (d > 0) row += pow(d, c);
    }
    sum += row;
  }
  sum *= (1.0 / nm) * (2.0 * PI / np);
  return 1.0 / sum;
}

/* Boundaries t_0 = 0 < ... < t_n = 1 equidistributing the density
 * 1 + A sum_e exp(-d_e(t) / w) over the selected ends (bit 0: t = 0,
 * bit 1: t = 1), by inverting its tabulated integral. */
static void graded_edges(int n, unsigned ends, double A, double w, double *t) {
  enum { M = 8192 };
  double cum[M + 1];
  cum[0] = 0;
  for (int i = 0; i < M; i++) {
    double x = (i + 0.5) / M, rho = 1;
    if (ends & 1u) rho += A * exp(-x / w);
    if (ends & 2u) rho += A * exp(-(1 - x) / w);
    cum[i + 1] = cum[i] + rho / M;
  }
  t[0] = 0;
  t[n] = 1;
  int i = 0;
  for (int k = 1; k < n; k++) {
    double target = cum[M] * k / n;
    while (i < M && cum[i + 1] < target) i++;
    double f = (target - cum[i]) / (cum[i + 1] - cum[i]);
    t[k] = (i + f) / M;
  }
}

/* Edges of surface k that touch another surface: points along the edge lie
 * within 0.6 patch diagonals (of the other surface) of its patch corners. */
static unsigned find_seams(const cv_display *d, size_t k) {
  const cv_display_surface *s = &d->surfaces[k];
  unsigned bits = 0;
  for (int e = 0; e < 4; e++) {
    int touching = 1;
    for (int q = 1; q <= 5 && touching; q++) {
      double t = q / 6.0, su = e == 0 ? 0 : e == 1 ? 1 : t, tv = e == 2 ? 0 : e == 3 ? 1 : t;
      double p[3];
      surface_point(s, su, tv, p);
      int near = 0;
      for (size_t o = 0; o < d->n_surfaces && !near; o++) {
        if (o == k) continue;
        const cv_display_surface *S = &d->surfaces[o];
        for (size_t i = S->offset; i < S->offset + (size_t)S->nu * S->nv && !near; i++) {
          const cv_patch *pt = &d->patches[i];
          double diag[3], dd[3];
          sub3(pt->q[2], pt->q[0], diag);
          double tol = 0.6 * len3(diag);
          for (int c = 0; c < 4 && !near; c++) {
            sub3(p, pt->q[c], dd);
            near = len3(dd) <= tol;
          }
        }
      }
      touching = near;
    }
    if (touching) bits |= 1u << e;
  }
  return bits;
}

static int build_patches_pass(cv_display *d);

static int build_patches(cv_display *d) {
  /* Pass 1 uniform; pass 2 regrades the surfaces that ask for it (their
   * seams are found against the other surfaces' uniform patches). */
  int any = 0;
  for (size_t k = 0; k < d->n_surfaces; k++) {
    cv_display_surface *s = &d->surfaces[k];
    s->edge_u = malloc((size_t)(s->nu + 1) * sizeof(double));
    s->edge_v = malloc((size_t)(s->nv + 1) * sizeof(double));
    if (!s->edge_u || !s->edge_v) return CV_ERR_NOMEM;
    for (int i = 0; i <= s->nu; i++) s->edge_u[i] = (double)i / s->nu;
    for (int i = 0; i <= s->nv; i++) s->edge_v[i] = (double)i / s->nv;
    any |= s->refine;
  }
  int st = build_patches_pass(d);
  if (st || !any) return st;
  for (size_t k = 0; k < d->n_surfaces; k++) {
    cv_display_surface *s = &d->surfaces[k];
    if (!s->refine) continue;
    if (s->refine_auto) s->refine_edges = find_seams(d, k);
    unsigned eu = (s->refine_edges & CV_EDGE_LEFT ? 1u : 0u) | (s->refine_edges & CV_EDGE_RIGHT ? 2u : 0u);
    unsigned ev = (s->refine_edges & CV_EDGE_BOTTOM ? 1u : 0u) | (s->refine_edges & CV_EDGE_TOP ? 2u : 0u);
    graded_edges(s->nu, eu, s->refine_strength, s->refine_width, s->edge_u);
    graded_edges(s->nv, ev, s->refine_strength, s->refine_width, s->edge_v);
  }
  free(d->patches);
  d->patches = NULL;
  return build_patches_pass(d);
}

static int build_patches_pass(cv_display *d) {
  size_t total = 0;
  for (size_t k = 0; k < d->n_surfaces; k++) {
    d->surfaces[k].offset = total;
    total += (size_t)d->surfaces[k].nu * (size_t)d->surfaces[k].nv;
  }
  d->n_patches = total;
  d->patches = calloc(total ? total : 1, sizeof *d->patches);
  if (!d->patches) return CV_ERR_NOMEM;
  for (size_t k = 0; k < d->n_surfaces; k++) {
    cv_display_surface *s = &d->surfaces[k];
    s->lobe_norm = lobe_norm(s->cosine_exponent, s->normal_tilt_deg);
    const double tr = s->normal_tilt_deg * PI / 180.0;
    for (int v = 0; v < s->nv; v++)
      for (int u = 0; u < s->nu; u++) {
        cv_patch *p = &d->patches[s->offset + (size_t)v * s->nu + u];
        const double u0 = s->edge_u[u], u1 = s->edge_u[u + 1];
        const double v0 = s->edge_v[v], v1 = s->edge_v[v + 1];
        surface_point(s, u0, v0, p->q[0]);
        surface_point(s, u1, v0, p->q[1]);
        surface_point(s, u1, v1, p->q[2]);
        surface_point(s, u0, v1, p->q[3]);
        for (int a = 0; a < 3; a++)
          p->c[a] = 0.25 * (p->q[0][a] + p->q[1][a] + p->q[2][a] + p->q[3][a]);
        double d1[3], d2[3], n[3];
        sub3(p->q[2], p->q[0], d1);
        sub3(p->q[3], p->q[1], d2);
        cross3(d1, d2, n);
        double ln = len3(n);
        p->area = 0.5 * ln;
        for (int a = 0; a < 3; a++) p->n[a] = ln > 0 ? n[a] / ln : 0;
        /* Emission axis: n rotated by the tilt towards +v (n x u_hat). */
        double uh[3], w[3];
        for (int a = 0; a < 3; a++) uh[a] = (p->q[1][a] - p->q[0][a]) + (p->q[2][a] - p->q[3][a]);
        double lu = len3(uh);
        for (int a = 0; a < 3; a++) uh[a] = lu > 0 ? uh[a] / lu : 0;
        cross3(p->n, uh, w);
        for (int a = 0; a < 3; a++) p->nt[a] = cos(tr) * p->n[a] + sin(tr) * w[a];
        double lt = len3(p->nt);
        for (int a = 0; a < 3; a++) p->nt[a] = lt > 0 ? p->nt[a] / lt : p->n[a];
        p->surface = (uint32_t)k;
        p->u = (uint32_t)u;
        p->v = (uint32_t)v;
      }
  }
  /* Tiles of the patch grid (compression clusters). */
  free(d->cluster);
  d->cluster = malloc((total ? total : 1) * sizeof *d->cluster);
  if (!d->cluster) return CV_ERR_NOMEM;
  size_t nc = 0;
  for (size_t k = 0; k < d->n_surfaces; k++) {
    const cv_display_surface *s = &d->surfaces[k];
    const int tu = (s->nu + CV_DISPLAY_TILE - 1) / CV_DISPLAY_TILE;
    const int tv = (s->nv + CV_DISPLAY_TILE - 1) / CV_DISPLAY_TILE;
    for (int v = 0; v < s->nv; v++)
      for (int u = 0; u < s->nu; u++)
        d->cluster[s->offset + (size_t)v * s->nu + u] =
            (uint32_t)(nc + (size_t)(v / CV_DISPLAY_TILE) * (size_t)tu + (size_t)(u / CV_DISPLAY_TILE));
    nc += (size_t)tu * (size_t)tv;
  }
  d->n_clusters = nc;
  return CV_OK;
}

/* Projector-to-patch factors.  The paper's F = f cos(alpha) dA / (pi r^2) is
 * the fraction of the projector's light landing on the patch; the radiosity
 * the patch gets per unit input is that per unit area, i.e. proportional to
 * cos(alpha) / r^2.  We normalise it per projector so that the patch it lights
 * most strongly gets intensity_scale (the paper's f), sum over projectors,
 * and use |cos| so that rear projection (projector behind the screen) works.
 * Visibility between projector and patch is not tested. */
static void build_projector_factors(cv_display *d, ctx *x) {
  const size_t n = d->n_patches;
  if (d->ideal_projectors) {
    for (size_t i = 0; i < n; i++) d->proj[i] = 1.0f;
    return;
  }
  double *acc = calloc(n ? n : 1, sizeof *acc);
  if (!acc) return;
  for (size_t pi = 0; pi < d->n_projectors; pi++) {
    const cv_display_projector *pr = &d->projectors[pi];
    double mx = 0;
    for (int pass = 0; pass < 2; pass++)
      for (size_t i = 0; i < n; i++) {
        const cv_patch *p = &d->patches[i];
        if (!pr->lights[p->surface]) continue;
        double r[3];
        sub3(pr->position, p->c, r);
        double r2 = dot3(r, r);
        if (!(r2 > 0)) continue;
        double raw = fabs(dot3(r, p->n)) / (sqrt(r2) * r2);
        if (pass == 0)
          mx = fmax(mx, raw);
        else if (mx > 0)
          acc[i] += pr->intensity_scale * raw / mx;
      }
  }
  for (size_t k = 0; k < d->n_surfaces; k++) {
    const cv_display_surface *s = &d->surfaces[k];
    size_t unlit = 0, np = (size_t)s->nu * s->nv;
    for (size_t i = s->offset; i < s->offset + np; i++) {
      if (!(acc[i] > 0)) unlit++;
      d->proj[i] = (float)acc[i];
    }
    if (unlit)
      cv_problem(x, CV_ERR_CONFIG, "projectors",
              "%zu of %zu patches of surface '%s' (surfaces[%zu]) receive no projector light",
              unlit, np, s->name, k);
  }
  free(acc);
}

static void parse_projectors(ctx *x, const cJSON *pj, cv_display *d) {
  d->ideal_projectors = 1;
  if (!pj) return;
  if (cJSON_IsString(pj)) {
    if (strcmp(pj->valuestring, "ideal"))
      cv_problem(x, CV_ERR_CONFIG, "projectors",
              "expected \"ideal\" or an array of {\"position\", \"surfaces\", \"intensity_scale\"}");
    return;
  }
  if (!cJSON_IsArray(pj) || cJSON_GetArraySize(pj) < 1) {
    cv_problem(x, CV_ERR_CONFIG, "projectors",
            "expected \"ideal\" or a non-empty array of {\"position\", \"surfaces\", "
            "\"intensity_scale\"}");
    return;
  }
  d->ideal_projectors = 0;
  int np = cJSON_GetArraySize(pj);
  d->projectors = calloc((size_t)np, sizeof *d->projectors);
  if (!d->projectors) {
    cv_problem(x, CV_ERR_NOMEM, "projectors", "out of memory");
    return;
  }
  d->n_projectors = (size_t)np;
  static const char *const keys[] = {"position", "surfaces", "intensity_scale", NULL};
  for (int i = 0; i < np; i++) {
    cv_display_projector *pr = &d->projectors[i];
    pr->intensity_scale = 1.0;
    pr->lights = calloc(d->n_surfaces ? d->n_surfaces : 1, 1);
    if (!pr->lights) {
      cv_problem(x, CV_ERR_NOMEM, "projectors", "out of memory");
      return;
    }
    char path[64], field[128];
    snprintf(path, sizeof path, "projectors[%d]", i);
    const cJSON *o = cJSON_GetArrayItem(pj, i);
    if (!cJSON_IsObject(o)) {
      cv_problem(x, CV_ERR_CONFIG, path, "expected an object");
      continue;
    }
    cv_problems_only_keys(x, o, path, keys);
    const cJSON *pos = required(x, o, path, "position", "[x, y, z] in metres");
    field_name(field, sizeof field, path, "position");
    if (pos) read_vec(x, pos, field, 3, -1e6, 1e6, "[x, y, z] in metres", pr->position);
    read_opt_num(x, o, path, "intensity_scale", 0, 1, 1e6, 0, &pr->intensity_scale);
    const cJSON *sl = cJSON_GetObjectItemCaseSensitive(o, "surfaces");
    if (!sl) {
      memset(pr->lights, 1, d->n_surfaces);
      continue;
    }
    field_name(field, sizeof field, path, "surfaces");
    if (!cJSON_IsArray(sl) || cJSON_GetArraySize(sl) < 1) {
      cv_problem(x, CV_ERR_CONFIG, field, "expected a non-empty array of surface names");
      continue;
    }
    for (int k = 0; k < cJSON_GetArraySize(sl); k++) {
      const cJSON *e = cJSON_GetArrayItem(sl, k);
      char f[160];
      snprintf(f, sizeof f, "%s[%d]", field, k);
      if (!cJSON_IsString(e)) {
        cv_problem(x, CV_ERR_CONFIG, f, "expected a surface name");
        continue;
      }
      int idx = cv_display_find_surface(d, e->valuestring);
      if (idx < 0)
        cv_problem(x, CV_ERR_CONFIG, f, "no surface is named '%s'", e->valuestring);
      else
        pr->lights[idx] = 1;
    }
  }
}

static void parse_root(ctx *x, const cJSON *root, cv_display *d) {
  static const char *const keys[] = {"description", "surfaces", "environment", "viewer",
                                     "projectors", NULL};
  if (!cJSON_IsObject(root)) {
    cv_problem(x, CV_ERR_CONFIG, "", "expected a JSON object at the top level");
    return;
  }
  cv_problems_only_keys(x, root, "", keys);
  const cJSON *desc = cJSON_GetObjectItemCaseSensitive(root, "description");
  if (desc && !cJSON_IsString(desc)) cv_problem(x, CV_ERR_CONFIG, "description", "expected a string");

  const cJSON *surfs = required(x, root, "", "surfaces", "a non-empty array of surfaces");
  int ns = surfs && cJSON_IsArray(surfs) ? cJSON_GetArraySize(surfs) : 0;
  if (surfs && ns == 0)
    cv_problem(x, CV_ERR_CONFIG, "surfaces", "expected a non-empty array of surfaces");
  int geometry_ok = ns > 0;
  if (ns > 0) {
    d->surfaces = calloc((size_t)ns, sizeof *d->surfaces);
    if (!d->surfaces) {
      cv_problem(x, CV_ERR_NOMEM, "surfaces", "out of memory");
      return;
    }
    d->n_surfaces = (size_t)ns;
    size_t total = 0;
    for (int k = 0; k < ns; k++) {
      cv_display_surface *s = &d->surfaces[k];
      if (!parse_surface(x, cJSON_GetArrayItem(surfs, k), k, s)) geometry_ok = 0;
      total += (size_t)s->nu * (size_t)s->nv;
      for (int j = 0; j < k; j++)
        if (s->name[0] && !strcmp(s->name, d->surfaces[j].name)) {
          char f[64];
          snprintf(f, sizeof f, "surfaces[%d].name", k);
          cv_problem(x, CV_ERR_CONFIG, f, "duplicate surface name '%s' (also surfaces[%d])", s->name, j);
          break;
        }
    }
    if (total > MAX_PATCHES_TOTAL) {
      cv_problem(x, CV_ERR_RANGE, "surfaces", "%zu patches in all; at most %u are supported", total,
              MAX_PATCHES_TOTAL);
      geometry_ok = 0;
    }
  }
  const cJSON *env = cJSON_GetObjectItemCaseSensitive(root, "environment");
  if (env) read_vec(x, env, "environment", 3, 0.0, 1e6, "[r, g, b] >= 0", d->environment);
  const cJSON *view = cJSON_GetObjectItemCaseSensitive(root, "viewer");
  if (view && read_vec(x, view, "viewer", 3, -1e6, 1e6, "[x, y, z] in metres", d->viewer))
    d->has_viewer = 1;
  parse_projectors(x, cJSON_GetObjectItemCaseSensitive(root, "projectors"), d);
  if (!geometry_ok || x->count) return;

  if (build_patches(d)) {
    cv_problem(x, CV_ERR_NOMEM, "surfaces", "out of memory");
    return;
  }
  if (d->has_viewer)
    for (size_t k = 0; k < d->n_surfaces; k++) {
      const cv_display_surface *s = &d->surfaces[k];
      size_t away = 0, np = (size_t)s->nu * s->nv;
      for (size_t i = s->offset; i < s->offset + np; i++) {
        double r[3];
        sub3(d->viewer, d->patches[i].c, r);
        if (!(dot3(r, d->patches[i].n) > 0)) away++;
      }
      if (away) {
        char f[64];
        snprintf(f, sizeof f, "surfaces[%zu]%s", k, s->kind == CV_SURFACE_PLANE ? ".corners" : "");
        cv_problem(x, CV_ERR_CONFIG, f,
                "%zu of %zu patches face away from the viewer [%g, %g, %g]%s", away, np,
                d->viewer[0], d->viewer[1], d->viewer[2],
                s->kind == CV_SURFACE_PLANE
                    ? " (front side = cross(pb - pa, pc - pa); swap pb and pc to flip it)"
                    : " (the inner side is the front)");
      }
    }
  const size_t n = d->n_patches;
  d->refl = malloc(3 * (n ? n : 1) * sizeof *d->refl);
  d->env = malloc(3 * (n ? n : 1) * sizeof *d->env);
  d->proj = malloc((n ? n : 1) * sizeof *d->proj);
  if (!d->refl || !d->env || !d->proj) {
    cv_problem(x, CV_ERR_NOMEM, "surfaces", "out of memory");
    return;
  }
  for (size_t i = 0; i < n; i++)
    for (int c = 0; c < 3; c++) {
      d->refl[3 * i + c] = (float)d->surfaces[d->patches[i].surface].reflectance[c];
      d->env[3 * i + c] = (float)d->environment[c];
    }
  build_projector_factors(d, x);
}

/* Parses text into a display, collecting problems into x. */
/* The display of a parsed tree (problems collected in x; NULL when out of
 * memory). */
static cv_display *parse_tree(ctx *x, const cJSON *root) {
  cv_display *d = calloc(1, sizeof *d);
  if (!d) {
    cv_problem(x, CV_ERR_NOMEM, "", "out of memory");
    return NULL;
  }
  snprintf(d->source, sizeof d->source, "%s", x->file);
  parse_root(x, root, d);
  return d;
}

/* JSON text parsed, or NULL with its syntax error (line and column) as a
 * problem. */
static cJSON *parse_json(ctx *x, const char *text) {
  const char *end = NULL;
  cJSON *root = cJSON_ParseWithOpts(text, &end, 1);
  if (!root) {
    int line, col;
    char f[48], what[128];
    cv_json_syntax_error(text, end, &line, &col, what, sizeof what);
    snprintf(f, sizeof f, "line %d, column %d", line, col);
    cv_problem(x, CV_ERR_CONFIG, f, "%s", what);
  }
  return root;
}

static cv_display *parse_text(ctx *x, const char *text) {
  cJSON *root = parse_json(x, text);
  if (!root) return NULL;
  cv_display *d = parse_tree(x, root);
  cJSON_Delete(root);
  return d;
}

static int read_file(const char *path, char **text, ctx *x) {
  cv_err e;
  int st = cv_read_json_file(path, text, &e);
  if (st) cv_problem(x, st, "", "%s", cv_err_after_path(e.msg, path));
  return st;
}

static int finish(ctx *x, cv_display *d, cv_display **out, cv_err *err) {
  if (x->count == 0 && d) {
    *out = d;
    return CV_OK;
  }
  cv_display_destroy(d);
  if (x->count == 0) return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", x->file);
  return cv_problems_finish(x, err);
}

int cv_display_parse(const char *json, const char *name, cv_display **out, cv_err *err) {
  *out = NULL;
  ctx x = {.file = name ? name : "(display)"};
  cv_display *d = parse_text(&x, json);
  return finish(&x, d, out, err);
}

int cv_display_read_json(const char *path, cJSON **root, cv_err *err) {
  *root = NULL;
  ctx x = {.file = path};
  char *text;
  if (read_file(path, &text, &x)) return cv_problems_finish(&x, err);
  *root = parse_json(&x, text);
  free(text);
  return cv_problems_finish(&x, err);
}

int cv_display_from_json(const cJSON *root, const char *name, cv_display **out, cv_err *err) {
  *out = NULL;
  ctx x = {.file = name ? name : "(display)"};
  cv_display *d = parse_tree(&x, root);
  return finish(&x, d, out, err);
}

int cv_display_load(const char *path, cv_display **out, cv_err *err) {
  *out = NULL;
  ctx x = {.file = path};
  char *text;
  if (read_file(path, &text, &x)) return finish(&x, NULL, out, err);
  cv_display *d = parse_text(&x, text);
  free(text);
  return finish(&x, d, out, err);
}

static int validate(ctx *x, const char *text, char *buf, size_t n, int *n_problems) {
  if (text) cv_display_destroy(parse_text(x, text));
  if (n_problems) *n_problems = x->count;
  if (buf && n) buf[x->len < n ? x->len : n - 1] = '\0';
  return x->count ? (x->first_status ? x->first_status : CV_ERR_CONFIG) : CV_OK;
}

int cv_display_validate_text(const char *json, const char *name, char *buf, size_t n,
                             int *n_problems) {
  ctx x = {.file = name ? name : "(display)", .buf = buf, .cap = n};
  return validate(&x, json, buf, n, n_problems);
}

int cv_display_validate_all(const char *path, char *buf, size_t n, int *n_problems) {
  ctx x = {.file = path, .buf = buf, .cap = n};
  char *text = NULL;
  read_file(path, &text, &x);
  int st = validate(&x, text, buf, n, n_problems);
  free(text);
  return st;
}

void cv_display_destroy(cv_display *d) {
  if (!d) return;
  for (size_t i = 0; i < d->n_projectors; i++) free(d->projectors[i].lights);
  free(d->projectors);
  for (size_t k = 0; k < d->n_surfaces && d->surfaces; k++) {
    free(d->surfaces[k].edge_u);
    free(d->surfaces[k].edge_v);
  }
  free(d->surfaces);
  free(d->patches);
  free(d->cluster);
  free(d->refl);
  free(d->proj);
  free(d->env);
  free(d);
}

size_t cv_display_patch_count(const cv_display *d) { return d->n_patches; }
size_t cv_display_surface_count(const cv_display *d) { return d->n_surfaces; }
const cv_patch *cv_display_patch(const cv_display *d, size_t i) { return &d->patches[i]; }
const cv_display_surface *cv_display_surface_at(const cv_display *d, size_t k) {
  return &d->surfaces[k];
}

int cv_display_find_surface(const cv_display *d, const char *name) {
  for (size_t k = 0; k < d->n_surfaces; k++)
    if (!strcmp(d->surfaces[k].name, name)) return (int)k;
  return -1;
}

size_t cv_display_patch_index(const cv_display *d, size_t k, int u, int v) {
  return d->surfaces[k].offset + (size_t)v * d->surfaces[k].nu + (size_t)u;
}

void cv_display_scatter_system(const cv_display *d, const cv_ffmatrix *F, cv_scatter_system *out) {
  out->n = d->n_patches;
  out->F = F;
  out->refl = d->refl;
  out->proj = d->proj;
  out->env = d->env;
  out->cluster = d->cluster;
  out->n_clusters = d->n_clusters;
}

unsigned cv_display_seam_edges(const cv_display *d, size_t k) {
  if (!d || k >= d->n_surfaces) return 0;
  return find_seams(d, k);
}

int cv_display_refine_seams(cv_display *d, double strength, double width, int *n_regraded) {
  if (n_regraded) *n_regraded = 0;
  if (!d || !(strength > 0 && strength <= 100) || !(width >= 0.01 && width <= 1))
    return CV_ERR_INVALID;
  int nr = 0;
  for (size_t k = 0; k < d->n_surfaces; k++) {
    cv_display_surface *s = &d->surfaces[k];
    if (s->refine && !s->refine_auto) continue; /* explicit edges: the config decides */
    s->refine = 1;
    s->refine_auto = 1;
    s->refine_strength = strength;
    s->refine_width = width;
    nr++;
  }
  if (!nr) return CV_OK;
  for (size_t k = 0; k < d->n_surfaces; k++) {
    free(d->surfaces[k].edge_u);
    free(d->surfaces[k].edge_v);
    d->surfaces[k].edge_u = d->surfaces[k].edge_v = NULL;
  }
  free(d->patches);
  d->patches = NULL;
  if (build_patches(d)) return CV_ERR_NOMEM;
  ctx x = {.file = d->source};
  build_projector_factors(d, &x);
  if (x.count) return x.first_status ? x.first_status : CV_ERR_NOMEM;
  if (n_regraded) *n_regraded = nr;
  return CV_OK;
}
