/* Lighting of a scene in the car frame, built from a cv_light_spec: HDR
 * environment maps (blended, scaled, rotated by the car's yaw/pitch/roll,
 * with a sun split out as a directional light when one is found), the
 * Preetham analytic sky with its sun, or a constant environment.  Provides
 * the SH projection (for PRT), the sun, and the background radiance seen
 * through the windows (for views). */
#ifndef CV_PRT_SCENE_LIGHT_H
#define CV_PRT_SCENE_LIGHT_H

#include <stdio.h>

#include "io/scene_config.h"
#include "prt/relight.h"

typedef struct cv_scene_light cv_scene_light;

/* Builds the lighting with `bands` SH bands (2..8).  *out owned by the caller.
 * Errors name the map file or the field. */
int cv_scene_light_build(const cv_light_spec *spec, int bands, cv_scene_light **out, cv_err *err);
void cv_scene_light_destroy(cv_scene_light *sl);
/* SH lighting (sun excluded) and the sun, in the car frame. */
cv_lighting cv_scene_light_sh(const cv_scene_light *sl);
/* Radiance arriving from car-frame direction d (unit), sun included. */
void cv_scene_light_background(const cv_scene_light *sl, const float d[3], float rgb[3]);
/* One or two lines: what the lighting is, whether a sun was found, its energy. */
void cv_scene_light_print(FILE *f, const cv_scene_light *sl);

#endif
