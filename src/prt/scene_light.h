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
#include "prt/bake.h"
#include "prt/relight.h"

typedef struct cv_scene_light cv_scene_light;

/* Builds the lighting with `bands` SH bands (2..8), or with bands 0 only
 * its background and sun (no SH projection: the lighting's SH stay 0, for
 * a caller that takes them from elsewhere; cv_scene_light_split refuses
 * it).  *out owned by the caller.  Errors name the map file or the field. */
int cv_scene_light_build(const cv_light_spec *spec, int bands, cv_scene_light **out, cv_err *err);
/* The same, with the env maps decoded once per path in `maps` (may be NULL:
 * then as cv_scene_light_build): the same lighting, bit for bit. */
struct cv_envmap_cache;
int cv_scene_light_build_cached(const cv_light_spec *spec, int bands, struct cv_envmap_cache *maps,
                                cv_scene_light **out, cv_err *err);
void cv_scene_light_destroy(cv_scene_light *sl);
/* SH lighting (sun excluded) and the sun, in the car frame. */
cv_lighting cv_scene_light_sh(const cv_scene_light *sl);
/* Radiance arriving from car-frame direction d (unit), sun included. */
void cv_scene_light_background(const cv_scene_light *sl, const float d[3], float rgb[3]);
/* Radiance from car-frame direction d (unit) of the map the SH lighting and
 * the split lights share: the map after the sun extraction (the split cells
 * included); the constant for a constant environment. */
void cv_scene_light_residual(const cv_scene_light *sl, const float d[3], float rgb[3]);
/* All-frequency window light (issue 13): splits up to k more directional
 * lights out of the SH lighting.  The map left after the sun (the residual)
 * is cut into cells of a grid_w x grid_w/2 lat-long grid; each cell scores
 * its luminous energy sum(Y Omega) times the fraction of up to 256 probe
 * points of the mesh (tr, vertex fan points) that see its centre through a
 * window; the k best cells with a score > 0 become directional lights (RGB
 * irradiance = the cell's sum(L Omega), direction = its luminance-weighted
 * centroid), are removed from the map and the SH lighting is re-projected
 * without them.  Replaces an earlier split.  Only for maps and the sky (a
 * constant environment has nothing to split: returns 0 lights).  Errors:
 * CV_ERR_RANGE (k outside 0..4096, grid_w not even in 4..1024), CV_ERR_NOMEM. */
int cv_scene_light_split(cv_scene_light *sl, const cv_tracer *tr, int k, int grid_w,
                         cv_err *err);
/* The split lights (car frame); returns their number, *lights owned by sl. */
int cv_scene_light_extra(const cv_scene_light *sl, const cv_dir_light **lights);

/* One or two lines: what the lighting is, whether a sun was found, its energy. */
void cv_scene_light_print(FILE *f, const cv_scene_light *sl);

#endif
