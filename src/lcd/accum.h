/* Progressive LCD images in fixed point, and the key that says which images
 * may be summed (Dmitriev et al. 2004, section 4.3 and 6: rough images of 40
 * samples per texel from every node, summed while the camera position
 * matches).
 *
 * Every sample value (RGB radiance, clamped to [0, clamp]) is rounded to an
 * integer number of `unit`s and summed in int64, so a sum over any set of
 * rounds is the same integer whatever the order, the split over
 * contributors or the thread count: bit-identical, and safe to reduce with
 * MPI_SUM on MPI_INT64_T (float reductions differ bit-wise between MPI's
 * algorithms).  The whole buffer is one int64 array: CV_LCD_ACC_HEADER
 * counters (summed like the pixels), then 3*w*h RGB sums (row 0 at the
 * top), then 2*w*h words of the second moment of the luminance (for the
 * error estimate): the sample's luminance is quantised like the RGB values
 * (q <= 2^40) and q^2 (up to 2^80) is split into q^2 >> 40 and
 * q^2 & (2^40 - 1), each summed in its own int64 word, so the second moment
 * is exact too and still sums word by word (MPI_SUM, no carries).
 *
 * unit = 2^(ceil(log2(clamp)) - 40): one sample adds at most 2^40 to a
 * word, so a texel holds more than 4 million samples before int64 could
 * overflow (checked: CV_ERR_RANGE).  Resolution: clamp * 2^-40 per sample. */
#ifndef CV_LCD_ACCUM_H
#define CV_LCD_ACCUM_H

#include <stddef.h>
#include <stdint.h>

#include "core/image.h"
#include "core/status.h"

/* Counters at the start of the buffer (all summed). */
enum {
  CV_LCD_ACC_SPP = 0,      /* samples per texel */
  CV_LCD_ACC_ROUNDS,       /* rounds summed */
  CV_LCD_ACC_CLAMPED,      /* sample channel values above the clamp (fireflies), set to it */
  CV_LCD_ACC_NONFINITE,    /* sample channel values NaN/Inf or negative, set to 0 */
  CV_LCD_ACC_HITS,         /* gather rays that hit the interior (PRT radiance) */
  CV_LCD_ACC_ENV,          /* gather rays that left through a window (environment) */
  CV_LCD_ACC_LOST,         /* gather rays that escaped without crossing a window (black) */
  CV_LCD_ACC_SHADOW,       /* sun shadow rays traced */
  CV_LCD_ACC_SUNLIT,       /* of those, unblocked */
  CV_LCD_ACC_BEHIND,       /* texel samples whose eye is behind the panel (black) */
  CV_LCD_ACC_VEILS,        /* rounds that carry veils (cv_lcd_accum_set_veil) */
  CV_LCD_ACC_VEIL,         /* veil slot k: L_v at word VEIL + 2k, its standard error at
                              VEIL + 2k + 1, in CV_LCD_VEIL_UNIT (one slot per panel) */
  CV_LCD_ACC_HEADER = 32
};
#define CV_LCD_ACC_VEIL_SLOTS 8
_Static_assert(CV_LCD_ACC_VEIL + 2 * CV_LCD_ACC_VEIL_SLOTS <= CV_LCD_ACC_HEADER,
               "the veil slots fit the header");
/* The light words after the veils: rounds that carry the light level
 * (cv_lcd_accum_set_light), then the outdoor horizontal illuminance, the
 * eye's horizontal and vertical illuminance (light_level.h), in
 * CV_LCD_VEIL_UNIT, summed like the veils. */
#define CV_LCD_ACC_LIGHTS (CV_LCD_ACC_VEIL + 2 * CV_LCD_ACC_VEIL_SLOTS)
#define CV_LCD_ACC_LIGHT (CV_LCD_ACC_LIGHTS + 1)
_Static_assert(CV_LCD_ACC_LIGHT + 3 <= CV_LCD_ACC_HEADER, "the light words fit the header");

/* The veil words: every round of one key carries the same veil (a pure
 * function of the key's eye and lighting), so their sum over rounds divided
 * by the rounds that carry one is that veil again, bit for bit, whoever
 * rendered the rounds.  Fixed point, independent of the clamp: 2^-24 cd/m^2
 * (6e-8), up to 2^38 cd/m^2 per round. */
#define CV_LCD_VEIL_UNIT (1.0 / 16777216.0)

#define CV_LCD_MAX_SPP (1 << 22) /* samples per texel a buffer may hold */
#define CV_LCD_M2_SHIFT 40       /* split of the squared luminance */

typedef struct cv_lcd_accum {
  int w, h;
  double clamp;   /* per-sample, per-channel radiance clamp */
  double unit;    /* radiance per LSB of the RGB sums (a power of two) */
  size_t n;       /* int64 entries in data */
  int64_t *data;  /* owned */
} cv_lcd_accum;

/* Index of texel (x, y)'s first RGB sum / its two second-moment words
 * (high: units of unit^2 * 2^40, then low: units of unit^2) in data. */
static inline size_t cv_lcd_acc_rgb(const cv_lcd_accum *a, int x, int y) {
  return CV_LCD_ACC_HEADER + 3 * ((size_t)y * (size_t)a->w + (size_t)x);
}
static inline size_t cv_lcd_acc_m2(const cv_lcd_accum *a, int x, int y) {
  return CV_LCD_ACC_HEADER + 3 * (size_t)a->w * (size_t)a->h +
         2 * ((size_t)y * (size_t)a->w + (size_t)x);
}

/* int64 words of a w x h buffer (header + 3 w h + 2 w h): size message
 * buffers with this, never by hand. */
static inline size_t cv_lcd_accum_words(int w, int h) {
  return CV_LCD_ACC_HEADER + 5 * (size_t)w * (size_t)h;
}

/* The fixed-point unit for a clamp (> 0, finite). */
double cv_lcd_unit_for_clamp(double clamp);

/* A zeroed w x h buffer for samples clamped at `clamp`.  *out owned by the
 * caller.  Errors: CV_ERR_INVALID (sizes < 1 or > 16384, clamp not > 0 and
 * finite), CV_ERR_NOMEM. */
int cv_lcd_accum_create(int w, int h, double clamp, cv_lcd_accum **out);
void cv_lcd_accum_destroy(cv_lcd_accum *a);
void cv_lcd_accum_clear(cv_lcd_accum *a);
/* Deep copy; *out owned by the caller. */
int cv_lcd_accum_clone(const cv_lcd_accum *a, cv_lcd_accum **out);
/* dst += src.  Errors: CV_ERR_INVALID (different size or unit),
 * CV_ERR_RANGE (the sum would exceed CV_LCD_MAX_SPP; dst unchanged). */
int cv_lcd_accum_add(cv_lcd_accum *dst, const cv_lcd_accum *src);

/* Image of the mean radiance per texel (w x h x 3), plus `emitted` (the
 * panel's own content, same size, may be NULL).  *out owned by the caller.
 * Errors: CV_ERR_EMPTY (no sample yet), CV_ERR_INVALID (emitted size),
 * CV_ERR_NOMEM. */
int cv_lcd_accum_to_image(const cv_lcd_accum *a, const cv_image *emitted, cv_image **out);

/* Error estimate of the reflected image from the per-texel sample variance
 * of the luminance Y: se^2 = (E[Y^2] - E[Y]^2) / n per texel;
 * rel_rms = sqrt(mean se^2) / mean Y.  Samples of one texel are
 * quasi-random (Owen-scrambled Sobol), not independent, so this i.i.d.
 * estimate is an upper bound in practice. */
typedef struct cv_lcd_error {
  uint64_t spp;
  double mean_luminance;  /* mean over texels of the reflected luminance */
  double rms_se;          /* sqrt(mean over texels of se^2) */
  double rel_rms;         /* rms_se / mean_luminance (0 if the image is black) */
} cv_lcd_error;
int cv_lcd_accum_error(const cv_lcd_accum *a, cv_lcd_error *e);

/* Stores the veil of `slot` (value, se in cd/m^2, finite, >= 0, below 2^38)
 * in a buffer holding ONE round: the slot is overwritten, VEILS set to 1.
 * Errors: CV_ERR_INVALID (a bad value or slot, or the buffer holds other
 * than one round). */
int cv_lcd_accum_set_veil(cv_lcd_accum *a, int slot, double value, double se);
/* The veil of `slot` in a sum of rounds (their mean): returns 1, or 0 (and
 * 0, 0) when no round carried veils. */
int cv_lcd_accum_veil(const cv_lcd_accum *a, int slot, double *value, double *se);
/* The light level of a round (E[0] outdoor horizontal, E[1] eye horizontal,
 * E[2] eye vertical illuminance; each in 0..2^38), in a buffer holding ONE
 * round, as cv_lcd_accum_set_veil.  CV_ERR_INVALID otherwise. */
int cv_lcd_accum_set_light(cv_lcd_accum *a, const double E[3]);
/* The light level the rounds carried (their mean): 1, or 0 with E zero
 * when none carried one. */
int cv_lcd_accum_light(const cv_lcd_accum *a, double E[3]);

/* Binary save/restore of a buffer (magic "CVLCDACC", version 2; sizes,
 * clamp, then the int64 array, little-endian), for resuming progressive
 * rendering.  err names the path. */
int cv_lcd_accum_write(const char *path, const cv_lcd_accum *a, cv_err *err);
int cv_lcd_accum_read(const char *path, cv_lcd_accum **out, cv_err *err);

/* --- keys ------------------------------------------------------------------
 * Images with equal keys may be summed.  eye_q is the eye position divided
 * by the tolerance and rounded: every contributor renders from the
 * quantised position (cv_lcd_key_eye), so equal keys mean equal inputs.
 * light_hash fingerprints the lighting state (cv_lcd_light's data hash),
 * setup_hash everything else the samples depend on (scene, BRDF, panel
 * size, samples per round, sampling mode, seed, clamp, tolerance:
 * cv_lcd_setup_hash). */
typedef struct cv_lcd_key {
  int32_t eye_q[3];
  uint32_t reserved;   /* 0 */
  uint64_t light_hash;
  uint64_t setup_hash;
} cv_lcd_key;

/* Errors: CV_ERR_INVALID (tolerance not > 0, non-finite eye),
 * CV_ERR_RANGE (eye / tolerance beyond int32). */
int cv_lcd_key_make(const float eye[3], double tolerance, uint64_t light_hash,
                    uint64_t setup_hash, cv_lcd_key *out);
/* The position all contributors render from: eye_q * tolerance. */
void cv_lcd_key_eye(const cv_lcd_key *k, double tolerance, float eye[3]);
/* Total order (eye_q, then light, then setup): <0, 0, >0. */
int cv_lcd_key_compare(const cv_lcd_key *a, const cv_lcd_key *b);
int cv_lcd_key_equal(const cv_lcd_key *a, const cv_lcd_key *b);

/* A progressive image: the running sum under one key.  Submitting a buffer
 * with the same key adds it; a different key starts over from that buffer. */
typedef struct cv_lcd_progress {
  int has_key;
  cv_lcd_key key;
  cv_lcd_accum *acc; /* owned; NULL before the first submit */
  uint64_t restarts; /* key changes seen */
} cv_lcd_progress;

/* Errors: as cv_lcd_accum_add / clone.  *restarted (may be NULL) is 1 when
 * the key differed (or was the first). */
int cv_lcd_progress_submit(cv_lcd_progress *p, const cv_lcd_key *key, const cv_lcd_accum *buf,
                           int *restarted);
void cv_lcd_progress_free(cv_lcd_progress *p);

#endif
