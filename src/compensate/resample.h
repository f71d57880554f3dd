/* Between image resolution Q and patch resolution P (Bimber et al. 2006,
 * section 3.4): box down-sampling, bilinear up-sampling at patch centres,
 * and the paper's equation 7, which applies a correction solved on patches
 * to a full-resolution image without showing the patch structure:
 *     I_Q = I_Q0 - up(down(I_Q0) - I_P). */
#ifndef CV_COMPENSATE_RESAMPLE_H
#define CV_COMPENSATE_RESAMPLE_H

#include <stdint.h>

#include "core/image.h"

/* The patch grid of a surface: nu x nv cells whose boundaries in the
 * surface parameters are eu[0..nu] and ev[0..nv] (ascending from 0 to 1;
 * NULL = uniform), row v = 0 at the BOTTOM (the display convention); the
 * image spans the whole surface with row 0 at the TOP.  Returns -1 when out
 * of memory. */

/* Area-weighted mean of img (3 channels) over each patch; out: 3 nu nv,
 * index (v * nu + u). */
int cv_downsample_to_patches(const cv_image *img, int nu, int nv, const double *eu,
                             const double *ev, double *out);

/* Bilinear interpolation between patch centres (clamped beyond the outer
 * centres) at every pixel of out (w x h x 3). */
int cv_upsample_from_patches(const double *patches, int nu, int nv, const double *eu,
                             const double *ev, cv_image *out);

/* Equation 7 for one surface: I = I0 - up(down(I0) - IP), written into out
 * (same size as I0), clamped to [0, 1]; returns the number of channel values
 * clamped.  IP: patch-resolution solution (3 * nu * nv). */
uint64_t cv_apply_patch_correction(const cv_image *I0, const double *IP, int nu, int nv,
                                   const double *eu, const double *ev, cv_image *out);

/* out = clamp(I0 - up(delta), 0, 1) for a patch-resolution delta (3 nu nv):
 * equation 7 with delta = down(I0) - I_P computed once, e.g. from the
 * average of a stereo pair and applied to both eyes.  Returns clamp count. */
uint64_t cv_apply_patch_delta(const cv_image *I0, const double *delta, int nu, int nv,
                              const double *eu, const double *ev, cv_image *out);

#endif
