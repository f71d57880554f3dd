/* Lighting for the reference path tracer (ref.h): the distant environment
 * as a piecewise-constant lat-long radiance map with an importance-sampling
 * table, plus an optional directional sun.  Independent of the PRT: it
 * never projects anything onto spherical harmonics and does not split a sun
 * out of a map (a map's sun stays in the map, where the luminance table
 * finds it), so that what the reference computes is the map itself.
 *
 * Map model.  Pixel (x, y) of the w x h map holds a constant radiance over
 * its lat-long cell (sh/latlong.h: u in [x/w, (x+1)/w), v in [y/h,
 * (y+1)/h)), whose solid angle is Omega_y.  Sampling picks a pixel with
 * probability p_i = Y_i Omega_i / sum_j Y_j Omega_j (Y = Rec.709 luminance)
 * from Walker's alias table (Vose's construction, O(1) per sample), then a
 * direction uniformly in solid angle inside the cell (u uniform, cos theta
 * uniform), so pdf(w) = p_i / Omega_i exactly (pbrt-v4, section 12.5.2, with
 * the sin(theta) Jacobian folded into Omega).  A map that is black
 * everywhere has no table and is never sampled.
 *
 * Frames.  The map is stored in the world frame; R is the car-to-world
 * rotation (light/envmap.h): a car-frame direction d sees map(R d). */
#ifndef CV_REF_REF_LIGHT_H
#define CV_REF_REF_LIGHT_H

#include <stdint.h>
#include <stdio.h>

#include "core/status.h"
#include "io/scene_config.h"
#include "light/envmap.h"

typedef struct cv_ref_light cv_ref_light;

/* Builds the lighting of spec (env maps blended and scaled, Preetham sky
 * tabulated 1024 x 512 with its sun as a directional light, or a constant
 * environment), rotated by the car's yaw/pitch/roll.  spec->extract_sun is
 * ignored: a map's sun is sampled inside the map.  *out owned by the caller
 * (cv_ref_light_destroy).  Errors name the map file or the field. */
int cv_ref_light_build(const cv_light_spec *spec, cv_ref_light **out, cv_err *err);

/* Lighting from a world-frame map (copied) and a car-to-world rotation R
 * (NULL: identity).  background (may be NULL: the map) is looked up for
 * camera rays that leave through a window, so that views show the same
 * background as `cave shade`.  Errors: CV_ERR_INVALID, CV_ERR_NOMEM. */
int cv_ref_light_from_map(const cv_envmap *world, const double R[9], cv_ref_light **out,
                          cv_err *err);

/* Adds a directional sun: unit world direction towards the sun, RGB
 * irradiance at normal incidence.  Replaces an earlier one. */
void cv_ref_light_set_sun(cv_ref_light *l, const double dir_world[3], const double E[3]);

void cv_ref_light_destroy(cv_ref_light *l);

/* Radiance of the piecewise-constant map in car-frame direction d (unit). */
void cv_ref_light_env(const cv_ref_light *l, const double d[3], double rgb[3]);
/* Radiance a camera sees in car-frame direction d through a window: the
 * bilinear map (as `cave shade`), the analytic sky, or the constant. */
void cv_ref_light_background(const cv_ref_light *l, const double d[3], float rgb[3]);
/* Solid-angle pdf with which cv_ref_light_sample draws car-frame direction d
 * (0 when the map is black or d falls in a black pixel). */
double cv_ref_light_pdf(const cv_ref_light *l, const double d[3]);
/* Draws a car-frame direction from three uniforms in [0, 1) (u1 picks the
 * pixel through the alias table, u2 and u3 the point inside it): fills d,
 * the map radiance there and the pdf; returns 0 when the map is black. */
int cv_ref_light_sample(const cv_ref_light *l, double u1, double u2, double u3, double d[3],
                        double rgb[3], double *pdf);
/* The sun in the car frame: returns 1 and fills dir and E when there is one. */
int cv_ref_light_sun(const cv_ref_light *l, double dir[3], double E[3]);

/* One line: what the lighting is and its total luminous power (sum Y Omega). */
void cv_ref_light_print(FILE *f, const cv_ref_light *l);

#endif
