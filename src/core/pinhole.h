/* A pinhole camera through pixel centres, as `cave shade --view` and the
 * view-budget estimate (src/prt/auto_view.c) cast their rays: eye, look-at
 * point, up vector, vertical field of view, w x h pixels, row 0 at the top. */
#ifndef CV_CORE_PINHOLE_H
#define CV_CORE_PINHOLE_H

#include <math.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

typedef struct cv_pinhole {
  double eye[3], f[3], r[3], u[3]; /* position, forward, right, up (orthonormal) */
  double th, aspect;               /* tan(fov / 2), w / h */
  int w, h;
} cv_pinhole;

static inline void cv_pinhole_init(cv_pinhole *c, const double eye[3], const double look[3],
                                   const double up[3], double fov_deg, int w, int h) {
  double *f = c->f, *r = c->r, *u = c->u;
  for (int k = 0; k < 3; k++) {
    c->eye[k] = eye[k];
    f[k] = look[k] - eye[k];
  }
  double fl = sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
  for (int k = 0; k < 3; k++) f[k] /= fl;
  r[0] = f[1] * up[2] - f[2] * up[1];
  r[1] = f[2] * up[0] - f[0] * up[2];
  r[2] = f[0] * up[1] - f[1] * up[0];
  double rl = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
  for (int k = 0; k < 3; k++) r[k] /= rl;
  u[0] = r[1] * f[2] - r[2] * f[1];
  u[1] = r[2] * f[0] - r[0] * f[2];
  u[2] = r[0] * f[1] - r[1] * f[0];
  c->th = tan(fov_deg * M_PI / 360);
  c->aspect = (double)w / h;
  c->w = w;
  c->h = h;
}

/* The ray through the centre of pixel (x, y): origin o, unit direction d. */
static inline void cv_pinhole_ray(const cv_pinhole *c, int x, int y, float o[3], float d[3]) {
  double sx = (2 * (x + 0.5) / c->w - 1) * c->th * c->aspect, sy = (1 - 2 * (y + 0.5) / c->h) * c->th;
  double dl = 0;
  for (int k = 0; k < 3; k++) {
    double dk = c->f[k] + sx * c->r[k] + sy * c->u[k];
    d[k] = (float)dk;
    dl += dk * dk;
  }
  for (int k = 0; k < 3; k++) {
    d[k] /= (float)sqrt(dl);
    o[k] = (float)c->eye[k];
  }
}

#endif
