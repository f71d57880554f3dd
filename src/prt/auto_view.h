/* Image-space choice of SH bands and split window lights (issue 13): the
 * error a viewer sees in one view, estimated before the bake.
 *
 * A coarse grid of camera rays (the pinhole of `cave shade --view`) finds
 * the pixels' triangles; their vertices are the pilot.  On them, one pass
 * of the bake's direct estimator (same rays, cv_bake_direct_radiance_subset)
 * gives both the 8-band direct transfer td and the all-frequency direct
 * light of the map the SH lighting comes from (after the sun extraction).
 * Per candidate (bands n, split K): the PRT's direct light = albedo x
 * (sum_{i < n^2} l_i td_i, l the map's SH without the K split cells, + the K
 * split lights' ray-traced direct light); the truth = albedo x the
 * all-frequency estimate; both plus the sun's direct light (identical).
 * Interpolated to each pixel with its barycentrics: per-pixel relative
 * luminance error, median and 90th percentile, and the mean ratio.
 *
 * What it leaves out: the interreflected light (same in both up to its own
 * SH truncation, which is smoother), so the relative error is that of the
 * direct light alone and overstates the picture's error where indirect
 * light dominates: docs/reference.md compares the estimate with the
 * reference path tracer. */
#ifndef CV_PRT_AUTO_VIEW_H
#define CV_PRT_AUTO_VIEW_H

#include "prt/bake.h"
#include "prt/scene_light.h"

#define CV_AUTO_VIEW_MAX_CAND 64

typedef struct cv_view_cam {
  double eye[3], look[3], up[3];
  double fov_deg; /* vertical */
  int w, h;       /* pixel grid of the estimate */
} cv_view_cam;

typedef struct cv_view_cand {
  int bands, split;
  double median, p90, mean_ratio; /* per-pixel relative error of the direct light */
  double cost;                    /* relative: bake (1 + 0.03 n^2) + relight (0.02 K) */
} cv_view_cand;

typedef struct cv_view_auto {
  int bands, split;   /* the pick */
  double median, p90, mean_ratio;
  int met_budget;     /* 0: no candidate met it; the lowest median was picked */
  int pixels, pilot_vertices, n_cand;
  cv_view_cand cand[CV_AUTO_VIEW_MAX_CAND];
  double seconds;
} cv_view_auto;

/* The driver's view of the issue (eye -0.37,1.02,0 looking at
 * -0.15,0.65,-1.0, fov 60) on a 48 x 36 grid. */
void cv_view_cam_driver(cv_view_cam *c);

/* Candidates: bands 2..8 (fixed_bands > 0 pins it) x split K in
 * {0, 16, 64} (fixed_split >= 0 pins it); the cheapest whose median <=
 * budget and p90 <= 3 x budget.  sl is re-split for every K (left with the
 * pick's split).  rays: the pilot's rays per vertex.  Errors name the
 * problem (no pixel sees geometry, out of memory). */
int cv_auto_view_select(const cv_tracer *tr, cv_scene_light *sl, const cv_view_cam *cam, double budget, int rays, uint32_t seed,
                        int fixed_bands, int fixed_split, cv_view_auto *res, cv_err *err);

#endif
