/* Absolute light levels for environment maps.  blender-data's maps (and most
 * HDRIs) are relative: their pixel values say nothing about how bright the
 * scene was.  A map is calibrated by scaling it so that the horizontal
 * illuminance of its upper hemisphere (what a lux meter lying face up at the
 * centre of the map would read, the sun included) is a given value:
 *
 *   E_h = sum over pixels with direction d.y > 0 of
 *         Y(pixel) * cos(theta) * dOmega,   dOmega = (2 pi / w)(pi / h) sin(theta)
 *
 * with Y the Rec.709 luminance of the pixel and theta the angle from +Y.
 * After scaling, pixel luminance is in cd/m^2 and E_h in lux.  A constant
 * map of luminance L has E_h = pi L. */
#ifndef CV_LIGHT_CALIBRATE_H
#define CV_LIGHT_CALIBRATE_H

#include "light/envmap.h"

/* E_h of the map in its own units (>= 0; 0 for a black upper hemisphere). */
double cv_envmap_horizontal_illuminance(const cv_envmap *env);

/* The documented default horizontal illuminance (lux) of a blender-data
 * studio-light world map, by its file name (city, courtyard, forest,
 * interior, night, studio, sunrise, sunset; docs/scene-config.md); 0 when the
 * path is not one of them in CAVE_BLENDER_WORLD_DIR. */
double cv_blender_map_default_lux(const char *path);

/* The multiplier that brings map env (loaded from path) to `illuminance`
 * lux (> 0), or for illuminance < 0 (CV_ILLUMINANCE_AUTO) to its
 * blender-data default.  CV_ERR_CONFIG (err names the path) when auto meets
 * a map without a documented level or the upper hemisphere is black. */
int cv_envmap_calibration(const char *path, const cv_envmap *env, double illuminance,
                          double *factor, cv_err *err);

#endif
