/* Fast per-frame lighting for a drive over a fixed set of environment maps
 * (the render service changes the blend weights and the car's attitude every
 * frame).  Each map is loaded once, its sun split out (light/sun.h) and its
 * residual projected into SH in the world frame; a frame then only blends
 * coefficients and rotates them into the car frame (microseconds instead of
 * the seconds cv_scene_light_build takes to load, blend, extract and project).
 *
 * Suns of a blend: the sun of the map with the largest weighted sun
 * luminance stays the directional sun (exact visibility in the renderer);
 * every other map's sun joins the SH as a delta light (coefficients
 * w E y(d)), which is what projecting the blended map would keep of it.
 * For one map the result is cv_scene_light_build's (same steps). */
#ifndef CV_PRT_LIGHTMIX_H
#define CV_PRT_LIGHTMIX_H

#include "core/image.h"
#include "core/status.h"
#include "prt/relight.h"

typedef struct cv_lightmix cv_lightmix;

/* Loads n maps (paths), multiplies them by scale (> 0), extracts their suns
 * and projects `bands` SH bands (2..8).  *out owned by the caller.  Errors
 * name the map: CV_ERR_IO, CV_ERR_FORMAT, CV_ERR_NONFINITE, CV_ERR_RANGE,
 * CV_ERR_NOMEM. */
int cv_lightmix_create(const char *const *paths, int n, double scale, int bands,
                       cv_lightmix **out, cv_err *err);
/* As cv_lightmix_create, with each map calibrated instead of scaled when
 * illuminance != 0 (light/calibrate.h): scaled so that the horizontal
 * illuminance of its upper hemisphere is `illuminance` lux, or its
 * blender-data default for CV_ILLUMINANCE_AUTO (an error for other maps);
 * then scale must be 1.  Blends of maps calibrated alike keep the level
 * (weights sum to 1). */
int cv_lightmix_create_calibrated(const char *const *paths, int n, double scale,
                                  double illuminance, int bands, cv_lightmix **out, cv_err *err);
void cv_lightmix_destroy(cv_lightmix *m);
int cv_lightmix_count(const cv_lightmix *m);

/* Lighting in the car frame for weights w[0..n) (>= 0, sum > 0; normalised
 * here) and the car attitude (degrees, cv_car_rotation).  CV_ERR_INVALID on
 * bad weights. */
int cv_lightmix_lighting(const cv_lightmix *m, const double *w, double yaw_deg, double pitch_deg,
                         double roll_deg, cv_lighting *out);

/* Background radiance seen from the car (sun included, as in the maps):
 * a lat-long table w x w/2 in the car frame (docs/conventions.md), the
 * weighted sum of the maps looked up in the world direction R d.  *out owned
 * by the caller.  Errors: CV_ERR_INVALID, CV_ERR_NOMEM. */
int cv_lightmix_background(const cv_lightmix *m, const double *w, double yaw_deg,
                           double pitch_deg, double roll_deg, int width, cv_image **out);

#endif
