/* CPU relighting of a baked PRT: exit radiance per vertex under SH lighting,
 * plus a directional sun with exact visibility.  This is the reference the
 * GPU renderer is checked against. */
#ifndef CV_PRT_RELIGHT_H
#define CV_PRT_RELIGHT_H

#include <stdint.h>

#include "prt/bake.h"
#include "prt/prt.h"

/* Lighting in the car frame. */
typedef struct cv_lighting {
  int bands;            /* bands of sh (>= the PRT's bands; extra ones ignored) */
  double sh[3 * 64];    /* SH radiance without the sun, sh[3*i + c] */
  int has_sun;
  double sun_dir[3];    /* unit, towards the sun */
  double sun_E[3];      /* RGB irradiance at normal incidence */
} cv_lighting;

typedef struct cv_relight_stats {
  uint64_t clamped_negative; /* vertex channels below 0 (SH ringing) set to 0 */
  uint64_t nonfinite;        /* vertex channels that were NaN/Inf, set to 0 */
} cv_relight_stats;

/* out_rgb[3v+c] = exit radiance of vertex v.  The sun adds its indirect light
 * through the interreflected transfer (as an SH delta) and, when tr is
 * non-NULL, its direct light with ray-traced visibility (sun_samples fan
 * points per vertex).  tr must be built from the PRT's own mesh. */
int cv_prt_relight(const cv_prt *p, const cv_lighting *l, const cv_tracer *tr, int sun_samples,
                   float *out_rgb, cv_relight_stats *stats);

/* A directional light split out of the lighting (scene_light.h). */
typedef struct cv_dir_light {
  double dir[3]; /* unit, car frame, towards the light */
  double E[3];   /* RGB irradiance at normal incidence */
} cv_dir_light;

/* cv_prt_relight plus n_extra more directional lights, each treated as the
 * sun is: direct light with ray-traced visibility (needs tr), indirect light
 * through the interreflected transfer.  Negative channels are clamped after
 * everything is summed. */
int cv_prt_relight_ex(const cv_prt *p, const cv_lighting *l, const cv_dir_light *extra,
                      int n_extra, const cv_tracer *tr, int sun_samples, float *out_rgb,
                      cv_relight_stats *stats);

/* The direct light of the n_extra lights alone, added to out_rgb (3*nv,
 * not clamped): what cv_prt_relight_ex adds for them with ray-traced
 * visibility (same samples and seeds).  The GPU renderer takes it per
 * vertex (cv_renderer_set_split).  Needs tr when n_extra > 0. */
int cv_split_direct(const cv_prt *p, const cv_tracer *tr, const cv_dir_light *extra,
                    int n_extra, int sun_samples, float *out_rgb);

#endif
