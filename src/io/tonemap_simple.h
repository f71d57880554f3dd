/* A simple global tone map for previews of HDR images (environment maps,
 * renders, bake checks).  Not the display pipeline's operator (Drago et
 * al. with adaptation lives in the tonemap module): this one only has to be
 * robust and predictable.
 *
 *   exposure k: given, or automatic k = 0.18 / Lavg with the log-average
 *               luminance Lavg = exp(mean(log(1e-4 + Y))) over finite
 *               positive pixels (Reinhard et al. 2002, "Photographic tone
 *               reproduction for digital images", eq. 1), Y = Rec.709
 *               luminance 0.2126 R + 0.7152 G + 0.0722 B;
 *   curve:      L = k Y, Ld = L / (1 + L) (ibid. eq. 3), applied as a
 *               scale Ld / Y on R, G, B so that chroma is preserved;
 *   output:     sRGB transfer (IEC 61966-2-1), clamped to [0, 255].
 *
 * Input NaN/Inf or negative channel values are treated as 0 and counted;
 * channels above 1 after the scale (saturated colours) are clamped and
 * counted. */
#ifndef CV_IO_TONEMAP_SIMPLE_H
#define CV_IO_TONEMAP_SIMPLE_H

#include <stdint.h>

#include "core/image.h"
#include "core/status.h"

typedef struct cv_preview_stats {
  uint64_t pixels;           /* pixels processed */
  uint64_t nonfinite_pixels; /* pixels with a NaN/Inf channel (set to 0) */
  uint64_t negative_pixels;  /* pixels with a negative channel (set to 0) */
  uint64_t clamped_channels; /* output channels clamped to 1 before sRGB */
  uint64_t log_avg_pixels;   /* finite positive pixels in the log average */
  double log_avg_luminance;  /* Lavg (0 when no pixel qualified) */
  double exposure;           /* k actually used */
} cv_preview_stats;

/* Tone maps hdr (c = 1: gray, 3: RGB, 4: RGBA with alpha ignored) into
 * out_rgb8 (w*h*3 bytes, caller-owned, row 0 at the top).  exposure <= 0
 * selects the automatic exposure (k = 1 if no pixel is positive).  stats
 * may be NULL.  Errors: CV_ERR_INVALID (NULL, bad channels, non-finite
 * exposure). */
int cv_preview_to_srgb8(const cv_image *hdr, double exposure, uint8_t *out_rgb8,
                        cv_preview_stats *stats);

/* Tone maps as above and writes an RGB PNG (see cv_png_write). */
int cv_preview_write_png(const char *path, const cv_image *hdr, double exposure,
                         cv_preview_stats *stats, cv_err *err);

/* sRGB transfer of a linear value in [0, 1] (not clamped). */
double cv_srgb_encode(double linear);

#endif
