/* The pinhole view of `cave shade --view`: one Embree ray through each pixel
 * centre (core/pinhole.h); a pixel on geometry shows the radiance
 * interpolated from its triangle's vertices, plus the direct light of the
 * "pixel lights" (directional lights whose direct light the per-vertex
 * relight left out, cv_relight_opts) evaluated at the pixel's own surface
 * point with an Embree shadow ray under the window rule, times the
 * material's texture; a pixel whose ray leaves through a window shows the
 * background. */
#ifndef CV_PRT_SHADE_VIEW_H
#define CV_PRT_SHADE_VIEW_H

#include <stdint.h>

#include "core/image.h"
#include "core/pinhole.h"
#include "prt/prt.h"
#include "prt/relight.h"
#include "rt/rt.h"

/* Radiance arriving from unit direction d (car frame). */
typedef void (*cv_background_fn)(const void *ctx, const float d[3], float rgb[3]);

typedef struct cv_shade_view_params {
  cv_pinhole cam;
  const float *rad;            /* 3 * nv vertex exit radiance (may hold negative channels) */
  const cv_dir_light *lights;  /* pixel lights (may be NULL when n_lights = 0) */
  int n_lights;
  cv_image *const *tex;        /* per material its texture, NULL entries (or tex NULL): none */
  cv_background_fn background; /* NULL: black */
  const void *bg_ctx;
} cv_shade_view_params;

typedef struct cv_shade_view_stats {
  uint64_t escaped;          /* pixels that saw neither geometry nor a window (black) */
  uint64_t clamped_negative; /* pixel channels below 0 after the pixel lights, set to 0 */
  uint64_t nonfinite;        /* pixel channels NaN/Inf, set to 0 */
} cv_shade_view_stats;

/* Direct light at surface point x (on triangle t of p, unit normal n facing
 * the viewer) from the lights, added to rgb: sum over lights of
 * E / pi * albedo * max(0, n.s) * V(x, s), V by one Embree ray from x
 * (origin offset along n) that must reach the environment under the window
 * rule.  albedo = the material's, 1 on a textured material (the texture
 * multiplies afterwards), as the bake's receivers. */
void cv_point_direct(const cv_prt *p, const cv_rt *rt, uint32_t t, const float x[3],
                     const float n[3], const cv_dir_light *lights, int n_lights, float rgb[3]);

/* Renders the view into img (w x h x 3 of the camera).  rt must be built
 * from p's own mesh (cv_tracer_rt).  Threads: OpenMP over rows. */
void cv_shade_view(const cv_prt *p, const cv_rt *rt, const cv_shade_view_params *vp,
                   cv_image *img, cv_shade_view_stats *stats);

#endif
