/* Sun extraction from an HDR environment map.  A sun is not low-frequency:
 * with 25 SH coefficients an unshadowed sun still errs about 6%, shadowed
 * through a window about 50% (REFERENCES.md, PRT).  So the compact, very
 * bright region around a map's brightest pixel is cut out and handed over as
 * a directional light (exact visibility: shadow map or rays), and PRT
 * carries the residual map (sky and indirect light).
 *
 * Method.  Luminance L = Rec.709 Y of each pixel.  Starting at the brightest
 * pixel, grow the 8-connected region (wrapping in u, and across the poles)
 * of pixels with L > threshold, threshold = max(rel_threshold * L_max,
 * median_factor * median(L)); then add `dilate` rings of neighbours so that
 * the partially covered pixels at the rim of the disc (below the threshold)
 * go too.  The region is a sun if it is compact (solid angle <=
 * max_solid_angle) AND carries a real share of the light (energy fraction
 * = sum_region L dOmega / sum_map L dOmega >= min_energy_fraction).
 * The residual map has the region's pixels replaced by the solid-angle
 * weighted mean colour of the ring of pixels just outside it; the sun light
 * is exactly what was removed, sum_region (L_rgb - fill_rgb) dOmega, so
 * residual + sun = original and no energy is counted twice. */
#ifndef CV_LIGHT_SUN_H
#define CV_LIGHT_SUN_H

#include <stdio.h>

#include "light/envmap.h"

typedef struct cv_sun_params {
  double rel_threshold;       /* of the peak luminance (default 0.05) */
  double median_factor;       /* k: the threshold is at least k * median L (default 20) */
  double max_solid_angle;     /* sr, compactness limit (default 0.01) */
  double min_energy_fraction; /* share of the map's luminous energy (default 0.05) */
  int dilate;                 /* rings added around the thresholded region (default 1) */
} cv_sun_params;

/* Fills p with the defaults above. */
void cv_sun_params_default(cv_sun_params *p);

typedef struct cv_sun_info {
  int found;              /* 1: the candidate passed both tests and was removed */
  double dir[3];          /* unit direction, centroid weighted by removed luminance */
  double elevation_deg;   /* asin(dir.y) */
  double solid_angle;     /* sr, of the candidate region (after dilation) */
  double rgb[3];          /* sum (L - fill) dOmega: RGB irradiance at normal incidence;
                             a channel that comes out negative (region less saturated
                             than its ring) is set to 0 and counted in rgb_clamped */
  int rgb_clamped;
  double energy_fraction; /* sum_region L dOmega / sum_map L dOmega (luminance) */
  double total_energy;    /* sum_map L dOmega (luminance) */
  long pixels;            /* pixels in the candidate region */
  double peak_luminance, median_luminance, threshold;
  double fill_rgb[3];     /* radiance written into the region of the residual */
} cv_sun_info;

/* Looks for a sun in env with parameters p (NULL: defaults).  info is always
 * filled: when no sun is accepted, found = 0 and the other fields describe
 * the rejected candidate (pixels = 0 when even the brightest pixel is below
 * the threshold, e.g. a constant map).  residual (may be NULL) receives a new
 * map (owned by the caller, cv_envmap_destroy): env minus the sun when found,
 * an unmodified copy otherwise.  Errors: CV_ERR_INVALID (NULL env or info,
 * parameters out of range: rel_threshold in (0, 1], median_factor >= 0,
 * max_solid_angle > 0, min_energy_fraction in [0, 1], dilate in 0..16),
 * CV_ERR_NOMEM. */
int cv_sun_extract(const cv_envmap *env, const cv_sun_params *p, cv_sun_info *info,
                   cv_envmap **residual);

/* Prints info on one line (no trailing text other than '\n'). */
void cv_sun_info_print(FILE *f, const cv_sun_info *info);

#endif
