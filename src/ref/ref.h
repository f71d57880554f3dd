/* Reference renderer: an unbiased Monte Carlo path tracer for the car
 * interior, the independent judge of the PRT pipeline (docs/reference.md).
 * It shares no transfer code with what it judges: no SH, no per-vertex
 * transfer, no per-vertex albedo.  It shares the scene (mesh, per-triangle
 * material albedos), the ray queries and window rule of rt/rt.h (rays reach
 * the environment only through window triangles), the map orientation
 * (light/envmap.h) and the pinhole camera of `cave shade --view`.
 *
 * Light transport (pbrt-v4, chapters 13-14): Lambert surfaces, two-sided
 * (the normal is flipped to face the arriving ray), albedo of the hit
 * triangle's material.  At every path vertex: next-event estimation of the
 * environment (ref_light.h: luminance alias table) combined by the balance
 * heuristic with the cosine-sampled continuation ray that escapes through a
 * window (Veach 1997, ch. 9), and of the sun (a delta light: NEE only), both
 * with ray-traced visibility through the windows.  Russian roulette from the
 * third vertex on, survival min(0.95, max throughput channel).
 *
 * Bounce count: vertex k of a path (k = 0 the camera hit) gathers the light
 * that has bounced k times before reaching the eye; `bounces` = N keeps
 * vertices 0..N (N = 0 direct light only, N = 2 what a 2-bounce bake
 * holds), -1 keeps going until roulette ends the path.
 *
 * Determinism: sample s of pixel (x, y) draws from a generator seeded by
 * (seed, x, y, s) only, and each pixel's sums run over s in order, so the
 * same seed gives the same image whatever the thread count. */
#ifndef CV_REF_REF_H
#define CV_REF_REF_H

#include <stdint.h>

#include "core/image.h"
#include "core/status.h"
#include "mesh/mesh.h"
#include "ref/ref_light.h"

typedef struct cv_ref_scene cv_ref_scene;

/* Builds the scene (Embree through rt/rt.h) from a mesh; the mesh is copied.
 * *out owned by the caller.  Errors: CV_ERR_EMPTY (no opaque triangle),
 * CV_ERR_RANGE (an albedo outside [0, 1] or not finite: names the
 * material), CV_ERR_BACKEND, CV_ERR_NOMEM. */
int cv_ref_scene_create(const cv_mesh *m, cv_ref_scene **out, cv_err *err);
void cv_ref_scene_destroy(cv_ref_scene *s);

/* Pinhole camera of `cave shade --view`: one ray through each pixel centre. */
typedef struct cv_ref_camera {
  double eye[3], look[3], up[3];
  double fov_deg; /* vertical field of view, (1, 179) */
  int w, h;
} cv_ref_camera;

typedef struct cv_ref_params {
  int spp;            /* samples per pixel, >= 1 */
  int pass_spp;       /* samples per progressive pass (progress line after each), >= 1 */
  int bounces;        /* -1: until roulette; 0..1000: keep path vertices 0..bounces */
  uint32_t seed;
  double emission[3]; /* radiance emitted by every opaque surface (furnace tests; 0) */
  int quiet;          /* 1: no progress lines on stderr */
} cv_ref_params;

/* Sets the defaults: 64 spp in passes of 16, until roulette, seed 1, no emission. */
void cv_ref_params_default(cv_ref_params *p);

typedef struct cv_ref_stats {
  uint64_t paths;        /* camera samples traced */
  uint64_t rays;         /* Embree queries (closest hit, occlusion and window tests) */
  uint64_t vertices;     /* path vertices (surface hits) */
  uint64_t nonfinite;    /* samples dropped for a NaN/Inf (counted; 0 expected) */
  uint64_t blocked_view; /* camera rays that saw neither geometry nor a window (black) */
  double seconds;
  double median_rel_se;  /* median over lit pixels of se(Y)/Y of the pixel mean */
  double p90_rel_se;
} cv_ref_stats;

/* Renders the view progressively into mean (w x h x 3, linear radiance) and
 * se (may be NULL; w x h x 3: standard error of each channel's mean).  Both
 * images must be allocated by the caller with the camera's size.  Errors:
 * CV_ERR_INVALID (bad camera, parameters or image sizes; err names which),
 * CV_ERR_NOMEM. */
int cv_ref_render(const cv_ref_scene *s, const cv_ref_light *l, const cv_ref_camera *cam,
                  const cv_ref_params *p, cv_image *mean, cv_image *se, cv_ref_stats *stats,
                  cv_err *err);

/* Material index + 1 of the triangle each camera ray hits first (0: none,
 * the environment or black; + 1 because EXR readers clamp negatives), into ids (w x h x 1, allocated by the caller): the
 * per-region masks of the error report.  Errors as cv_ref_render. */
int cv_ref_material_ids(const cv_ref_scene *s, const cv_ref_camera *cam, cv_image *ids,
                        cv_err *err);

/* Radiance arriving at org from direction -dir (i.e. seen along the unit ray
 * dir), averaged over n samples: mean[3] and its standard error se[3] (may
 * be NULL).  Deterministic for (p->seed).  For tests and probes. */
int cv_ref_radiance(const cv_ref_scene *s, const cv_ref_light *l, const cv_ref_params *p,
                    const double org[3], const double dir[3], int n, double mean[3],
                    double se[3], cv_ref_stats *stats);

#endif
