/* Kooima 2008 generalized perspective projection (see offaxis.h), computed
 * in double and stored as float column-major OpenGL matrices. */
#include "view/offaxis.h"

#include "core/status.h"

#include <math.h>
#include <string.h>

#include "core/vec3d.h"

/* Normalises v in place; returns its length. */
static double norm3(double v[3]) {
  double l = sqrt(dot3(v, v));
  if (l > 0.0)
    for (int k = 0; k < 3; k++) v[k] /= l;
  return l;
}

int cv_offaxis_compute(const double pa[3], const double pb[3], const double pc[3],
                       const double pe[3], double n, double f, cv_offaxis *out) {
  if (!pa || !pb || !pc || !pe || !out) return CV_ERR_INVALID;
  if (!finite3(pa) || !finite3(pb) || !finite3(pc) || !finite3(pe)) return CV_ERR_INVALID;
  if (!(n > 0.0) || !(f > n) || !isfinite(f)) return CV_ERR_INVALID;
  double vr[3], vu[3], vn[3], va[3], vb[3], vc[3];
  for (int k = 0; k < 3; k++) {
    vr[k] = pb[k] - pa[k];
    vu[k] = pc[k] - pa[k];
    va[k] = pa[k] - pe[k];
    vb[k] = pb[k] - pe[k];
    vc[k] = pc[k] - pe[k];
  }
  if (!(norm3(vr) > 1e-12) || !(norm3(vu) > 1e-12)) return CV_ERR_INVALID;
  if (fabs(dot3(vr, vu)) > CV_OFFAXIS_RECT_TOL) return CV_ERR_INVALID;
  cross3(vr, vu, vn);
  norm3(vn);
  /* Distance from the eye to the screen plane (Kooima eq. d = -vn.va). */
  double d = -dot3(vn, va);
  if (!(d > 1e-9)) return CV_ERR_INVALID;
  cv_offaxis o;
  memset(&o, 0, sizeof o);
  memcpy(o.vr, vr, sizeof vr);
  memcpy(o.vu, vu, sizeof vu);
  memcpy(o.vn, vn, sizeof vn);
  o.l = dot3(vr, va) * n / d;
  o.r = dot3(vr, vb) * n / d;
  o.b = dot3(vu, va) * n / d;
  o.t = dot3(vu, vc) * n / d;
  o.n = n;
  o.f = f;

  double P[16] = {0}, V[16] = {0}, M[16];
  /* glFrustum, column-major: P[col*4 + row]. */
  P[0] = 2.0 * n / (o.r - o.l);
  P[5] = 2.0 * n / (o.t - o.b);
  P[8] = (o.r + o.l) / (o.r - o.l);
  P[9] = (o.t + o.b) / (o.t - o.b);
  P[10] = -(f + n) / (f - n);
  P[11] = -1.0;
  P[14] = -2.0 * f * n / (f - n);
  /* M^T (rows vr, vu, vn) times T(-pe). */
  const double *rows[3] = {vr, vu, vn};
  for (int i = 0; i < 3; i++) {
    for (int j = 0; j < 3; j++) V[j * 4 + i] = rows[i][j];
    V[12 + i] = -dot3(rows[i], pe);
  }
  V[15] = 1.0;
  for (int c = 0; c < 4; c++)
    for (int r = 0; r < 4; r++) {
      double s = 0.0;
      for (int k = 0; k < 4; k++) s += P[k * 4 + r] * V[c * 4 + k];
      M[c * 4 + r] = s;
    }
  for (int i = 0; i < 16; i++) {
    o.proj[i] = (float)P[i];
    o.view[i] = (float)V[i];
    o.viewproj[i] = (float)M[i];
    o.viewproj_d[i] = M[i];
  }
  *out = o;
  return CV_OK;
}

void cv_head_eyes(const double head[3], const double gaze[3], double separation, double left[3],
                  double right[3]) {
  static const double up[3] = {0.0, 1.0, 0.0};
  double rt[3];
  cross3(gaze, up, rt);
  double l = sqrt(dot3(rt, rt)), gl = sqrt(dot3(gaze, gaze));
  /* Gaze (nearly) vertical or degenerate: no defined head roll, use +X. */
  if (!(l > 1e-6 * gl) || !(gl > 0.0)) {
    rt[0] = 1.0;
    rt[1] = rt[2] = 0.0;
    l = 1.0;
  }
  double h = 0.5 * separation / l;
  for (int k = 0; k < 3; k++) {
    left[k] = head[k] - h * rt[k];
    right[k] = head[k] + h * rt[k];
  }
}

double cv_offaxis_project(const double m[16], const double p[3], double ndc[3]) {
  double c[4];
  for (int r = 0; r < 4; r++) c[r] = m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r];
  if (c[3] != 0.0)
    for (int k = 0; k < 3; k++) ndc[k] = c[k] / c[3];
  else
    ndc[0] = ndc[1] = ndc[2] = NAN;
  return c[3];
}
