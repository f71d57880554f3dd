/* HDR environment maps: the distant lighting of the car, as lat-long
 * (equirectangular) linear RGB radiance maps in the layout of sh/latlong.h
 * (u = 0.5 straight ahead along -Z, v = 0 the zenith +Y).  Loading from EXR,
 * bilinear lookup, blending of several maps (time of day, weather), rotation
 * into the car's frame, and SH projection for PRT relighting.
 *
 * Rotation convention.  R = cv_car_rotation(...) is the car-to-world
 * rotation: a direction d in the car's frame is R d in the world.  The map
 * the car sees in its own frame is out(d) = env(R d) (cv_envmap_rotate).  Its
 * SH coefficients are those of env rotated by R^T (sh/sh.h):
 *   project(cv_envmap_rotate(env, R)) = cv_sh_rotate(rotation(R^T), project(env))
 * up to resampling (bilinear) and pixel quadrature error; relighting should
 * rotate the n*n*3 coefficients, which is exact and costs nothing, rather
 * than resample the map every frame. */
#ifndef CV_LIGHT_ENVMAP_H
#define CV_LIGHT_ENVMAP_H

#include <stdint.h>

#include "core/image.h"
#include "core/status.h"

typedef struct cv_envmap {
  cv_image *img;             /* w x h x 3 linear RGB radiance, owned by the map */
  uint64_t negative_clamped; /* input channel values < 0 set to 0 when made */
} cv_envmap;

/* Rec.709 / sRGB luminance of linear RGB (the Y row of the RGB->XYZ matrix). */
static inline double cv_luminance(double r, double g, double b) {
  return 0.2126 * r + 0.7152 * g + 0.0722 * b;
}

/* New black w x h map (*out owned by the caller, cv_envmap_destroy).
 * Errors: CV_ERR_INVALID (w < 1, h < 2), CV_ERR_NOMEM. */
int cv_envmap_create(int w, int h, cv_envmap **out);

/* New map holding a copy of img (1 channel: grey; 3 or 4: RGB, alpha
 * dropped).  Any aspect ratio is accepted (2:1 is usual).  Negative values
 * are set to 0 and counted in negative_clamped.  Errors (err: one line):
 * CV_ERR_INVALID (NULL, 2 channels, h < 2), CV_ERR_NONFINITE (names the
 * pixel), CV_ERR_NOMEM. */
int cv_envmap_from_image(const cv_image *img, cv_envmap **out, cv_err *err);

/* Loads a lat-long map from an OpenEXR file (io/exr.h; the reader rejects
 * NaN/Inf and clamps negative values, counted in negative_clamped).  Any
 * aspect ratio is accepted; maps less than 2 pixels high are refused
 * (CV_ERR_FORMAT).  Other errors as cv_exr_read; err names the file. */
int cv_envmap_load(const char *path, cv_envmap **out, cv_err *err);

/* Frees env and its image; accepts NULL. */
void cv_envmap_destroy(cv_envmap *env);

/* New deep copy of env. Errors: CV_ERR_INVALID, CV_ERR_NOMEM. */
int cv_envmap_clone(const cv_envmap *env, cv_envmap **out);

/* Radiance seen in direction d (unit or not; zero/NaN gives black):
 * bilinear between pixel centres, wrapping in u and clamping in v. */
void cv_envmap_lookup(const cv_envmap *env, const float d[3], float rgb[3]);

/* The same at lat-long coordinates (u wraps, v clamped to [0, 1]). */
void cv_envmap_sample_uv(const cv_envmap *env, double u, double v, float rgb[3]);

/* out = sum_k weights[k] * maps[k], an out_w x out_h map.  Weights must be
 * finite and >= 0 and need not sum to 1 (a sum other than 1 scales the
 * light: use it for exposure, or normalise the weights yourself).  Maps of a
 * size other than out_w x out_h are resampled: each output pixel averages a
 * ceil(w/out_w) x ceil(h/out_h) grid of bilinear samples over its (u, v)
 * rectangle (a box filter when shrinking, bilinear when enlarging).  Sums in
 * double.  *out owned by the caller.  Errors (err: one line):
 * CV_ERR_INVALID (count < 1, NULL map, negative/non-finite weight k, out
 * size w < 1 or h < 2), CV_ERR_NOMEM. */
int cv_envmap_blend(const cv_envmap *const *maps, const double *weights, int count, int out_w,
                    int out_h, cv_envmap **out, cv_err *err);

/* Car-to-world rotation R (row-major 3x3, d_world = R d_car) for the car's
 * attitude in degrees, applied roll first, then pitch, then yaw:
 *   R = Ry(yaw) Rx(pitch) R_{-Z}(roll)
 * yaw about +Y: positive turns the car to the left (counter-clockwise seen
 * from above; the nose -Z moves towards -X); pitch about +X: positive raises
 * the nose; roll about -Z (the forward axis): positive lowers the right (+X)
 * side, the roof tilting to the right. */
void cv_car_rotation(double yaw_deg, double pitch_deg, double roll_deg, double R[9]);

/* Resamples env into the frame rotated by R: out(d) = env(R d) for the
 * centre d of every output pixel (same size as env, bilinear, so about a
 * pixel of blur).  With R the car-to-world rotation, out is what the car
 * sees in its own frame.  *out owned by the caller.  Errors: CV_ERR_INVALID
 * (NULL, R not a rotation to 1e-6), CV_ERR_NOMEM. */
int cv_envmap_rotate(const cv_envmap *env, const double R[9], cv_envmap **out);

/* SH projection of the map (cv_sh_project_latlong): coeffs = 3*n*n doubles,
 * c[3*i+ch].  Errors as cv_sh_project_latlong. */
int cv_envmap_project_sh(const cv_envmap *env, int n, double *coeffs);

#endif
