/* Model placement: units, up axis, user transform (see place.h). */
#include "mesh/place.h"

#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

static void rotation(const double deg[3], double R[3][3]);

void cv_placement_default(cv_placement *p) {
  memset(p, 0, sizeof *p);
  p->scale = 1.0;
}

const char *cv_units_expected(void) {
  return "mm, cm, m, in, ft or a positive number of metres per unit";
}

int cv_parse_units(const char *s, double *unit_m, cv_err *err) {
  static const struct {
    const char *name;
    double m;
  } named[] = {{"mm", 0.001}, {"cm", 0.01}, {"m", 1.0}, {"in", 0.0254}, {"ft", 0.3048}};
  if (!s) return cv_err_set(err, CV_ERR_INVALID, "missing unit (expected %s)", cv_units_expected());
  for (size_t i = 0; i < sizeof named / sizeof named[0]; i++)
    if (!strcmp(s, named[i].name)) {
      *unit_m = named[i].m;
      return CV_OK;
    }
  char *end;
  double v = strtod(s, &end);
  if (end != s && *end == '\0' && isfinite(v) && v > 0) {
    *unit_m = v;
    return CV_OK;
  }
  return cv_err_set(err, CV_ERR_INVALID, "unknown unit '%s' (expected %s)", s,
                    cv_units_expected());
}

int cv_parse_up(const char *s, char *up, cv_err *err) {
  if (s && (!strcasecmp(s, "y") || !strcasecmp(s, "z"))) {
    *up = (char)tolower((unsigned char)s[0]);
    return CV_OK;
  }
  return cv_err_set(err, CV_ERR_INVALID, "unknown up axis '%s' (expected y or z)", s ? s : "");
}

int cv_placement_check(const cv_placement *p, cv_err *err) {
  if (!(isfinite(p->unit_m) && p->unit_m >= 0))
    return cv_err_set(err, CV_ERR_INVALID, "units %g: expected %s", p->unit_m,
                      cv_units_expected());
  if (p->up != 0 && p->up != 'y' && p->up != 'z')
    return cv_err_set(err, CV_ERR_INVALID, "up '%c': expected y or z", p->up);
  if (!(isfinite(p->scale) && p->scale > 0))
    return cv_err_set(err, CV_ERR_INVALID, "transform scale %g: expected a positive number",
                      p->scale);
  for (int k = 0; k < 3; k++)
    if (!isfinite(p->rotate_deg[k]) || !isfinite(p->translate[k]))
      return cv_err_set(err, CV_ERR_INVALID, "transform: expected finite numbers");
  return CV_OK;
}

void cv_rotation_xyz_deg(const double deg[3], double out[9]) {
  double R[3][3];
  rotation(deg, R);
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) out[3 * i + j] = R[i][j];
}

/* R = Rz * Ry * Rx, row-major. */
static void rotation(const double deg[3], double R[3][3]) {
  const double d2r = 3.14159265358979323846 / 180.0;
  double cx = cos(deg[0] * d2r), sx = sin(deg[0] * d2r);
  double cy = cos(deg[1] * d2r), sy = sin(deg[1] * d2r);
  double cz = cos(deg[2] * d2r), sz = sin(deg[2] * d2r);
  double Rx[3][3] = {{1, 0, 0}, {0, cx, -sx}, {0, sx, cx}};
  double Ry[3][3] = {{cy, 0, sy}, {0, 1, 0}, {-sy, 0, cy}};
  double Rz[3][3] = {{cz, -sz, 0}, {sz, cz, 0}, {0, 0, 1}};
  double T[3][3];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      T[i][j] = 0;
      for (int k = 0; k < 3; k++) T[i][j] += Ry[i][k] * Rx[k][j];
    }
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      R[i][j] = 0;
      for (int k = 0; k < 3; k++) R[i][j] += Rz[i][k] * T[k][j];
    }
}

void cv_placement_measure(const cv_mesh *m, cv_placement_report *r) {
  cv_mesh_bounds(m, r->lo, r->hi);
  double big = 0;
  for (int k = 0; k < 3; k++) {
    r->size[k] = (double)r->hi[k] - (double)r->lo[k];
    if (r->size[k] > big) big = r->size[k];
  }
  r->implausible_car = big < CV_CAR_MIN_EXTENT_M || big > CV_CAR_MAX_EXTENT_M;
}

int cv_mesh_place(cv_mesh *m, const cv_placement *p, const cv_file_frame *ff,
                  cv_placement_report *r, cv_err *err) {
  int st = cv_placement_check(p, err);
  if (st) return st;
  cv_placement_report local;
  if (!r) r = &local;
  memset(r, 0, sizeof *r);
  r->unit_m = 1.0, r->unit_from = "default";
  if (p->unit_m > 0)
    r->unit_m = p->unit_m, r->unit_from = "option";
  else if (ff && ff->unit_m > 0)
    r->unit_m = ff->unit_m, r->unit_from = "file";
  r->up = 'y', r->up_from = "default";
  if (p->up)
    r->up = p->up, r->up_from = "option";
  else if (ff && ff->up)
    r->up = ff->up, r->up_from = "file";
  double R[3][3];
  rotation(p->rotate_deg, R);
  const double s = r->unit_m * p->scale;
  for (size_t v = 0; v < m->nv; v++) {
    float *q = &m->pos[3 * v];
    double a[3] = {s * q[0], s * q[1], s * q[2]};
    if (r->up == 'z') { /* (x, y, z) -> (x, z, -y) */
      double y = a[1];
      a[1] = a[2];
      a[2] = -y;
    }
    for (int i = 0; i < 3; i++) {
      double b = R[i][0] * a[0] + R[i][1] * a[1] + R[i][2] * a[2] + p->translate[i];
      if (!isfinite(b) || fabs(b) > 3.0e38)
        return cv_err_set(err, CV_ERR_NONFINITE,
                          "vertex %zu: coordinate out of range after placement", v);
      q[i] = (float)b;
    }
  }
  cv_placement_measure(m, r);
  return CV_OK;
}
