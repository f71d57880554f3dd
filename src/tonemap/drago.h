/* Drago et al. 2003 "Adaptive Logarithmic Mapping for Displaying High Contrast
 * Scenes": the display operator of the wall-eye renderer.  The CPU code here is
 * the reference the fragment shader must reproduce; cv_drago_prepare computes
 * exactly the uniforms the shader needs so both sides share one set of numbers.
 *
 * Formula (Drago 2003, eq. 4), world luminances divided by the adaptation
 * luminance Lwa first (Lw' = Lw/Lwa, Lwmax' = Lwmax/Lwa):
 *   Ld = (Ldmax*0.01 / log10(Lwmax'+1)) * ln(Lw'+1) / ln(2 + 8*(Lw'/Lwmax')^p),
 *   p  = ln(bias)/ln(0.5)
 * Ld is a display value in [0, 1] (1 = 100 cd/m2 with the default Ldmax),
 * clamped: with bias 0.85 the raw curve exceeds 1 and stops being monotone
 * once Lwmax' passes ~2.2e5 (REFERENCES.md).
 *
 * GLSL equivalent (uniforms = cv_drago_consts, same names):
 *   uniform float lwa, lwmax_a, scale, p_exp, ld_top;
 *   float drago(float lw) {                  // lw: Rec.709 Y, cd/m2
 *     if (!(lw > 0.0)) return 0.0;           // NaN, negative, 0 -> 0 (NaN fails >)
 *     float x = lw / lwa;                    // +Inf ends here too: x >= lwmax_a
 *     if (x >= lwmax_a) return ld_top;       // saturation at and beyond Lwmax
 *     float ld = scale * log(x + 1.0) / log(2.0 + 8.0 * pow(x / lwmax_a, p_exp));
 *     return (ld > 0.0) ? min(ld, ld_top) : 0.0; // NaN-safe clamp
 *   }
 *   rgb_out = min(rgb * (drago(Y) / Y), 1.0) for Y > 0, else 0 (Y = dot(rgb,
 *   vec3(0.2126, 0.7152, 0.0722))); then cv_rec709_transfer per channel
 *   (or the sRGB framebuffer, which the renderer documents).
 * The CPU evaluates the same expression in double from the float uniforms
 * (log1p for log(x + 1)); float shader arithmetic agrees to ~1e-6.
 * Why the upper clamp is ld_top = min(1, Ldmax/100), the curve's value at
 * Lwmax, and not just 1: beyond Lwmax the raw curve falls again, and for
 * Lwmax/Lwa > ~2.2e5 (bias 0.85) it overshoots Ld(Lwmax) below Lwmax; both
 * would make the map non-monotone.
 */
#ifndef CV_TONEMAP_DRAGO_H
#define CV_TONEMAP_DRAGO_H

#include "core/image.h"

#include <stdint.h>

/* User-facing parameters. */
typedef struct cv_drago {
  double bias;  /* Drago's b, 0.85 (0.7..0.9 sensible; must be in (0,1)) */
  double ldmax; /* display maximum luminance, cd/m2, 100 */
  double lwa;   /* adaptation luminance, cd/m2 (> 0) */
  double lwmax; /* maximum world luminance, cd/m2 */
} cv_drago;

/* Per-frame constants, exactly what the fragment shader takes as uniforms. */
typedef struct cv_drago_consts {
  float lwa;     /* sanitised adaptation luminance, cd/m2 */
  float lwmax_a; /* lwmax / lwa (>= 1e-6) */
  float scale;   /* ldmax*0.01 / log10(lwmax_a + 1) */
  float p_exp;   /* ln(bias) / ln(0.5) */
  float ld_top;  /* min(1, ldmax/100): the value at and beyond Lwmax, upper clamp
                  * (1 with the default ldmax; added to the agreed API) */
} cv_drago_consts;

/* Default parameters: bias 0.85, ldmax 100, lwa 1, lwmax 100. */
void cv_drago_default(cv_drago *d);

/* Computes the shader constants from d.  Never fails; sanitises:
 *   lwa <= 0, NaN or Inf             -> 1e-4 (CV_LUM_EPS, an all-black frame)
 *   lwmax NaN/Inf or lwmax < lwa*1e-6 -> lwa  (lwmax_a = 1)
 *   bias outside (0,1) or NaN         -> 0.85
 *   ldmax <= 0 or NaN/Inf             -> 100
 * so the constants are always finite and scale > 0. */
void cv_drago_prepare(const cv_drago *d, cv_drago_consts *out);

/* Display value of world luminance lw (cd/m2) in [0, ld_top] before the
 * transfer curve; non-decreasing in lw.  NaN, negative and 0 -> 0; lw >=
 * Lwmax (+Inf included) -> ld_top; clamped to [0, ld_top].
 * Computed in double from the float constants (the shader uses float). */
double cv_drago_map(const cv_drago_consts *c, double lw);

/* Rec.709-style transfer with gamma 2.2 used by Drago 2003:
 * 6.75 e for e <= 0.012, else 1.099 e^(0.9/2.2) - 0.099.  Input is clamped
 * to [0, 1] first (NaN -> 0). */
double cv_rec709_transfer(double e);

/* The 8-bit code a display gets for display-linear e: lrintf((float)
 * cv_rec709_transfer(e) * 255), what the PNG previews store.  The table
 * holds the 255 smallest floats at which the code steps (found by bisection
 * on the exact curve, which is monotone), and per 1/512 octave of e (its
 * float bits >> 14: 65,025 buckets, 64 KB) the code at the bucket's lower
 * end, so a lookup starts there and steps past the one threshold a bucket
 * can hold on this curve (one compare-and-add; init measures `adv`, and a
 * table with more steps a bucket walks them) instead of bisecting (8
 * unpredictable branches: 12% of a wall-eye rank's CPU in `cave run`,
 * docs/benchmarks.md).  Buckets of 1/32 octave (4 KB) needed three
 * compare-and-adds: 22 ms against 11.7 ms for a 1440^2 RGB image.  It
 * equals the direct formula for every float (NaN and e <= 0 give 0).
 * Initialise once with cv_rec709_lut_init (1.3 ms); read-only afterwards. */
#define CV_REC709_SHIFT 14
#define CV_REC709_BUCKETS ((0x3f800000u >> CV_REC709_SHIFT) + 1) /* float bits >> SHIFT of (0, 1] */
typedef struct cv_rec709_lut {
  float step[256]; /* step[k]: smallest e with code > k; step[255] = +Inf (a sentinel) */
  uint8_t first[CV_REC709_BUCKETS]; /* first[b]: code of the float with bits b << CV_REC709_SHIFT */
  uint8_t adv; /* the most thresholds inside one bucket (1 for this curve) */
} cv_rec709_lut;
void cv_rec709_lut_init(cv_rec709_lut *t);
uint8_t cv_rec709_code(const cv_rec709_lut *t, float e);
/* Codes of n values (e.g. 3 w h of an RGB image). */
void cv_rec709_codes(const cv_rec709_lut *t, const float *e, size_t n, uint8_t *out);
/* The direct formula (the reference of the table). */
uint8_t cv_rec709_code_exact(float e);

/* Tone-maps an image.  in: c = 1 (luminance), 3 (RGB) or 4 (RGBA, alpha copied).
 * RGB colour is scaled by Ld/Lw with Lw = Rec.709 Y = 0.2126R + 0.7152G + 0.0722B;
 * the result is clamped per channel to [0, 1] (saturated colours can exceed 1
 * after the ratio; those channels are clamped, not counted).  With
 * apply_transfer the Rec.709 curve is applied per channel afterwards.
 * Pixels with any NaN/Inf/negative colour channel are written as 0 and counted
 * in *n_invalid (may be NULL).  out must be preallocated with in's w, h, c
 * (out may equal in); the map runs in double from the float constants.  Errors: CV_ERR_INVALID for NULL/mismatched images.
 * Uses OpenMP over rows. */
int cv_drago_image(const cv_image *in, const cv_drago *d, int apply_transfer, cv_image *out,
                   uint64_t *n_invalid);

/* cv_drago_image plus *n_clamped (may be NULL): pixels with a colour channel
 * above 1 after the Ld/Lw ratio (saturated colours), written as 1. */
int cv_drago_image_counts(const cv_image *in, const cv_drago *d, int apply_transfer,
                          cv_image *out, uint64_t *n_invalid, uint64_t *n_clamped);

#endif
