/* How far equation 7's up-sampled correction is off near seams, estimated
 * from the patch solution alone, so that refinement can be decided per frame
 * without a fine reference solve (Bimber et al. 2006, future work: adaptive
 * subdivision; REFERENCES.md: "a correction solved on coarse patches and
 * up-sampled leaves errors of several percent at the corner").
 *
 * The correction delta (projector input removed per patch, cv_apply_patch_delta)
 * is up-sampled bilinearly between patch centres and held constant beyond the
 * outer centres.  Per patch and along each grid direction, with centres x_u
 * (as fractions of the surface) and values f_u:
 *   between two centres    error ~ h^2 / 8 |f''|   (linear interpolation),
 *                          f'' from second divided differences;
 *   between edge and the   error ~ |f'| x_0          (held constant where the
 *   first centre                                      correction still slopes)
 * and the patch's estimate is the largest of those touching it, over the
 * three channels.  At a seam the scattered light, and so the correction,
 * peaks, and the second term dominates; graded patches shrink x_0 and h. */
#ifndef CV_COMPENSATE_SEAM_H
#define CV_COMPENSATE_SEAM_H

#include <stddef.h>

#include "compensate/display.h"

typedef struct cv_seam_estimate {
  double seam_max;     /* largest estimate within dist_m of a seam */
  double seam_rms;     /* RMS of the estimates there */
  double rest_max;     /* largest estimate elsewhere */
  size_t seam_patches; /* patches within dist_m of a seam */
} cv_seam_estimate;

/* delta: 3n values (interleaved RGB, patch order of d).  dist_m: how far
 * from a seam (metres, along the surface) counts as "near" (the paper's
 * 0.5 m).  Returns CV_OK, or CV_ERR_INVALID (NULL, dist_m < 0). */
int cv_seam_estimate_error(const cv_display *d, const double *delta, double dist_m,
                           cv_seam_estimate *out);

#endif
