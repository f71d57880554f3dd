/* Lat-long mapping between directions and image coordinates (see latlong.h). */
#include "sh/latlong.h"

#include <math.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

void cv_latlong_dir(double u, double v, double d[3]) {
  const double theta = M_PI * v;                /* polar angle from +Y */
  const double alpha = 2.0 * M_PI * (u - 0.5);  /* azimuth from -Z towards +X */
  const double st = sin(theta);
  d[0] = st * sin(alpha);
  d[1] = cos(theta);
  d[2] = -st * cos(alpha);
}

void cv_latlong_uv(const double d[3], double *u, double *v) {
  const double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  if (!(len > 0.0)) {
    *u = 0.5;
    *v = 0.5;
    return;
  }
  double y = d[1] / len;
  if (y > 1.0) y = 1.0;
  if (y < -1.0) y = -1.0;
  double uu = 0.5 + atan2(d[0], -d[2]) / (2.0 * M_PI);
  if (uu >= 1.0) uu -= 1.0; /* atan2 returns +pi for d = +Z exactly */
  if (uu < 0.0) uu = 0.0;
  *u = uu;
  *v = acos(y) / M_PI;
}

void cv_latlong_pixel_dir(int x, int y, int w, int h, double d[3]) {
  cv_latlong_dir((x + 0.5) / w, (y + 0.5) / h, d);
}

void cv_latlong_trig(int w, int h, double *sin_a, double *cos_a, double *sin_t, double *cos_t) {
  for (int x = 0; x < w; x++) { /* cv_latlong_dir's expressions */
    const double alpha = 2.0 * M_PI * ((x + 0.5) / w - 0.5);
    sin_a[x] = sin(alpha), cos_a[x] = cos(alpha);
  }
  for (int y = 0; y < h; y++) {
    const double theta = M_PI * ((y + 0.5) / h);
    sin_t[y] = sin(theta), cos_t[y] = cos(theta);
  }
}

double cv_latlong_pixel_solid_angle(int y, int w, int h) {
  return (2.0 * M_PI / w) * (cos(M_PI * y / h) - cos(M_PI * (y + 1) / h));
}
