/* The project's lat-long (equirectangular) mapping between unit directions
 * and image coordinates, shared by SH projection, environment maps and the
 * sky renderer so that there is exactly one definition of it.
 *
 * Convention (docs/conventions.md): direction d (unit, +Y up, the car looks
 * along -Z) maps to
 *   u = 0.5 + atan2(d.x, -d.z) / (2 pi)  in [0, 1)   (u = 0.5: straight ahead, -Z;
 *                                                     u = 0.75: +X, the right)
 *   v = acos(d.y) / pi                   in [0, 1]   (v = 0: top row, zenith +Y)
 * Pixel (x, y) of a w x h map covers u in [x/w, (x+1)/w), v in [y/h, (y+1)/h);
 * its exact solid angle is (2 pi / w) * (cos(pi y / h) - cos(pi (y+1) / h)),
 * so the weights of a whole map sum to 4 pi. */
#ifndef CV_SH_LATLONG_H
#define CV_SH_LATLONG_H

/* Unit direction for lat-long coordinates (u, v); any u (wraps), v in [0,1]. */
void cv_latlong_dir(double u, double v, double d[3]);

/* Lat-long coordinates of direction d (need not be unit; zero maps to the
 * front, u = 0.5, v = 0.5).  u in [0, 1), v in [0, 1]. */
void cv_latlong_uv(const double d[3], double *u, double *v);

/* Direction through the centre of pixel (x, y) of a w x h map. */
void cv_latlong_pixel_dir(int x, int y, int w, int h, double d[3]);

/* The sines and cosines that cv_latlong_pixel_dir computes for each pixel,
 * once per column (azimuth: sin_a, cos_a, w values) and per row (polar
 * angle: sin_t, cos_t, h values), so that a loop over a whole map makes
 * the same directions without two sincos per pixel:
 * cv_latlong_trig_dir gives bit for bit cv_latlong_pixel_dir's d. */
void cv_latlong_trig(int w, int h, double *sin_a, double *cos_a, double *sin_t, double *cos_t);
static inline void cv_latlong_trig_dir(double sin_a, double cos_a, double sin_t, double cos_t,
                                       double d[3]) {
  d[0] = sin_t * sin_a;
  d[1] = cos_t;
  d[2] = -sin_t * cos_a;
}

/* Exact solid angle (sr) of any pixel of row y of a w x h map. */
double cv_latlong_pixel_solid_angle(int y, int w, int h);

#endif
