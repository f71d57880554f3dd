/* Double-precision 3-vector helpers for the display geometry, the form
 * factors, the off-axis projection and the foveal cone (cglm, the project's
 * vector library, is single precision; form factors next to a shared edge
 * and the Kooima projection are computed in double). */
#ifndef CV_CORE_VEC3D_H
#define CV_CORE_VEC3D_H

#include <math.h>

static inline void sub3(const double a[3], const double b[3], double o[3]) {
  o[0] = a[0] - b[0];
  o[1] = a[1] - b[1];
  o[2] = a[2] - b[2];
}
static inline double dot3(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
/* o = a x b (o may alias a or b). */
static inline void cross3(const double a[3], const double b[3], double o[3]) {
  double t0 = a[1] * b[2] - a[2] * b[1];
  double t1 = a[2] * b[0] - a[0] * b[2];
  double t2 = a[0] * b[1] - a[1] * b[0];
  o[0] = t0;
  o[1] = t1;
  o[2] = t2;
}
static inline double len3(const double a[3]) { return sqrt(dot3(a, a)); }
static inline int finite3(const double a[3]) {
  return isfinite(a[0]) && isfinite(a[1]) && isfinite(a[2]);
}
static inline double dist3(const double a[3], const double b[3]) {
  double d[3];
  sub3(a, b, d);
  return len3(d);
}

#endif
