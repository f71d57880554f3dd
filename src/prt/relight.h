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
  uint64_t clamped_negative; /* vertex channels below 0 (SH ringing) set to 0 (with
                                cv_relight_opts.clamp = 0: found below 0, kept) */
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
 * sun is: direct light with ray-traced visibility (needs tr, sun_samples fan
 * points for every light), indirect light through the interreflected
 * transfer.  Negative channels are clamped after everything is summed. */
int cv_prt_relight_ex(const cv_prt *p, const cv_lighting *l, const cv_dir_light *extra,
                      int n_extra, const cv_tracer *tr, int sun_samples, float *out_rgb,
                      cv_relight_stats *stats);

/* The direct light of the n_extra lights alone, added to out_rgb (3*nv,
 * not clamped): what cv_prt_relight_ex adds for them with ray-traced
 * visibility (same samples and seeds).  The GPU renderer takes it per
 * vertex (cv_renderer_set_split).  Needs tr when n_extra > 0. */
int cv_split_direct(const cv_prt *p, const cv_tracer *tr, const cv_dir_light *extra,
                    int n_extra, int sun_samples, float *out_rgb);

/* What cv_prt_relight_opt traces per vertex. */
typedef struct cv_relight_opts {
  int sun_samples;   /* fan points per vertex for the sun's direct light (1..4096) */
  int split_samples; /* fan points per vertex for each extra light's direct light (1..4096) */
  int sun_direct;    /* 0: the sun's direct light is left out (a view adds it per pixel,
                        cv_shade_view); its indirect light stays */
  int extra_direct;  /* 0: the same for the extra lights */
  int clamp;         /* 1: negative channels are set to 0 (and counted); 0: only counted,
                        for a caller that adds per-pixel light first and clamps after */
} cv_relight_opts;

/* Defaults: 16 sun samples, CV_SPLIT_SAMPLES_DEFAULT split samples, all direct
 * light per vertex, clamped. */
#define CV_SPLIT_SAMPLES_DEFAULT 4
void cv_relight_opts_default(cv_relight_opts *o);

/* cv_prt_relight_ex with the options o.  Errors: CV_ERR_RANGE (bands; a
 * sample count < 1 for light traced per vertex), CV_ERR_INVALID (extra
 * lights without tr). */
int cv_prt_relight_opt(const cv_prt *p, const cv_lighting *l, const cv_dir_light *extra,
                       int n_extra, const cv_tracer *tr, const cv_relight_opts *o,
                       float *out_rgb, cv_relight_stats *stats);

#endif
