/* Foveal adaptation statistics (REFERENCES "Foveal adaptation"): the tone
 * mapper adapts to the log-average luminance seen inside a cone (10 degrees
 * full angle) around the tracked gaze.  Each wall-eye view contributes the
 * solid-angle weighted sum of ln(L + eps) of its pixels inside the cone, the
 * summed weight and its maximum; the statistics of several walls (or several
 * cluster nodes) merge by plain double-precision summation, so the merge is
 * order-independent up to rounding.
 *
 * Pure C, no GL: the renderer reads back a small luminance image per wall
 * (lum_res x lum_res, e.g. 128x128) and calls cv_foveal_accumulate on it. */
#ifndef CV_TONEMAP_FOVEAL_H
#define CV_TONEMAP_FOVEAL_H

#include <stdint.h>

#include "core/image.h"

/* Luminance floor inside the logarithm (cd/m2); keeps ln finite for black. */
#define CV_LUM_EPS 1e-4

typedef struct cv_lumstats {
  double sum_log;      /* sum w*ln(L + CV_LUM_EPS) */
  double weight;       /* sum w (steradians) */
  double max_l;        /* max L of the valid accumulated pixels (0 when none) */
  uint64_t n_pixels;   /* valid pixels accumulated */
  uint64_t n_invalid;  /* NaN/Inf/negative pixels inside the cone, excluded */
} cv_lumstats;

/* Accumulates into *acc (zero it first) the pixels of the luminance image lum
 * (w x h floats, row 0 at the top, i.e. next to pc) that covers the rectangle
 * pa (lower-left), pb (lower-right), pc (upper-left), metres, whose centre
 * direction from eye lies within half_angle_rad of the unit vector gaze.
 * Weight of a pixel = its solid angle seen from eye, area*cos(theta)/dist^2
 * at the pixel centre (midpoint rule, relative error O((pitch/dist)^2), of
 * order 1e-4 for a 128-pixel 3 m wall seen from 1.5 m); |cos| is used, so
 * the wall's orientation does not matter.  A wall the cone misses
 * (cv_foveal_touches) is skipped without visiting its pixels.  NaN/Inf/
 * negative pixels in the cone are excluded and counted in n_invalid.  Degenerate arguments (NULL, w/h <= 0, zero-length gaze,
 * non-finite inputs) accumulate nothing.  gaze need not be normalised. */
void cv_foveal_accumulate(const float *lum, int w, int h, const double pa[3], const double pb[3],
                          const double pc[3], const double eye[3], const double gaze[3],
                          double half_angle_rad, cv_lumstats *acc);

/* Whole-image statistics with weight 1 per pixel (the global log-average of
 * `cave tonemap`): L = the channel for c = 1, Rec.709 Y = 0.2126 R +
 * 0.7152 G + 0.0722 B for c >= 3 (alpha ignored).  Pixels with a NaN/Inf/
 * negative colour channel are excluded and counted in n_invalid.  Accumulates
 * into *acc (zero it first); c = 2 or NULL accumulates nothing. */
void cv_lumstats_image(const cv_image *img, cv_lumstats *acc);

/* The luminance image of a rendered frame (what `cave run`'s wall-eyes
 * give cv_foveal_accumulate instead of a luminance pass of their own):
 * each pixel of lum (c = 1, any size; row 0 at the top as src) is the
 * area-weighted mean Rec.709 Y (0.2126 R + 0.7152 G + 0.0722 B) of the
 * pixels of src (c >= 3, linear radiance) under its footprint, the
 * footprints of lum tiling src exactly (fractional pixels weighted by the
 * area they cover).  src pixels with a NaN/Inf/negative channel are left
 * out of the means and counted in *n_invalid; a lum pixel covered by no
 * valid one is NaN (cv_foveal_accumulate then counts it as invalid).
 * *max_y: the largest Y of the valid src pixels (0 when none): Drago's
 * Lwmax from every shaded pixel, not from the coarser image.
 * Sums in double.  Errors: CV_ERR_INVALID (NULL, lum->c != 1, src->c < 3). */
int cv_lum_downsample(const cv_image *src, cv_image *lum, double *max_y, uint64_t *n_invalid);

/* into += from (sums add, max of max, counts add). */
void cv_lumstats_merge(cv_lumstats *into, const cv_lumstats *from);

/* Log-average adaptation luminance *lwa = exp(sum_log / weight).  The eps
 * inside the log is not subtracted again: it is 1e-4 cd/m2, far below any
 * adaptation level that matters, and keeping it makes lwa > 0 for an
 * all-black region.  Returns 0 and leaves *lwa untouched when weight == 0
 * (empty region, the caller keeps its previous adaptation state); returns 1
 * when *lwa was written.  Non-finite sums also return 0. */
int cv_lumstats_lwa(const cv_lumstats *s, double *lwa);

/* 1 if the cone of half-angle half_angle_rad around gaze from eye intersects
 * the rectangle pa, pb, pc (from its front or back), 0 otherwise.  Geometric
 * test, no pixels: the cone touches the rectangle iff the angle between gaze
 * and the closest direction to a rectangle point is <= half_angle (checked by
 * the gaze ray hitting the rectangle, or the minimum angle to each edge). */
int cv_foveal_touches(const double pa[3], const double pb[3], const double pc[3],
                      const double eye[3], const double gaze[3], double half_angle_rad);

#endif
