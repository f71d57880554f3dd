/* Can the driver read the LCD?  Readability figures of one panel from the
 * progressive final-gather estimate (accum.h), pure computation: no tracing,
 * no files, no MPI (docs/readability.md has the model and its sources).
 *
 *   L_r  reflected luminance per texel (cd/m^2): the luminance Y of the
 *        gathered reflection, with its Monte Carlo standard error from the
 *        per-texel second moment;
 *   L_v  veiling luminance at the eye (cd/m^2) by the CIE 146:2002 general
 *        disability glare equation, integrated over what the eye sees
 *        around the line of sight (a luminance callback: environment
 *        through the windows, interior radiance) plus point sources (the
 *        sun) of known illuminance;
 *   CR   contrast ratio (L_on + L_r + L_v) / (L_off + L_r + L_v) per texel
 *        and for the panel mean, against a required minimum (3:1, ISO 15008);
 *   VL   visibility level (L_on - L_off) / dL_t(L_a), dL_t the threshold
 *        of Ferwerda et al. 1996 (cones and rods, the lower one) at the
 *        adaptation luminance L_a.
 * Every panel figure comes with its standard error (cv_lcd_figure.se). */
#ifndef CV_LCD_READABILITY_H
#define CV_LCD_READABILITY_H

#include <stdint.h>

#include "core/status.h"
#include "lcd/accum.h"

/* An estimate and its standard error (1 sigma). */
typedef struct cv_lcd_figure {
  double value, se;
} cv_lcd_figure;

/* --- disability glare ------------------------------------------------------ */

#define CV_GLARE_THETA_MIN_DEG 0.1   /* validity of the CIE equation */
#define CV_GLARE_THETA_MAX_DEG 100.0

/* CIE 146:2002 general disability glare equation: L_v / E_gl in
 * (cd/m^2) / lx for a source at theta_deg (degrees) from the line of sight,
 * observer age `age` (years) and eye pigmentation p (0 dark .. 1 light blue):
 *   10/th^3 + (5/th^2 + 0.1 p/th) (1 + (A/62.5)^4) + 0.0025 p.
 * E_gl is the illuminance at the eye on the plane normal to the line of
 * sight.  0 outside [CV_GLARE_THETA_MIN_DEG, CV_GLARE_THETA_MAX_DEG]. */
double cv_cie_glare(double theta_deg, double age, double p);

/* Luminance (cd/m^2) the eye sees in direction dir (unit); 0 for the task
 * itself (the panel) and for whatever must not count as glare. */
typedef double (*cv_lcd_luminance_fn)(void *ctx, const double dir[3]);

/* A point source (the sun): unit direction from the eye and illuminance E
 * (lx) on a plane normal to that direction; the caller decides visibility. */
typedef struct cv_lcd_point_source {
  double dir[3];
  double E;
} cv_lcd_point_source;

typedef struct cv_lcd_veil_params {
  double age;        /* years, >= 0 (default 40) */
  double pigment;    /* 0..1 (default 0.5) */
  int rows, cols;    /* cells in theta (log-spaced over [0.1, 100] deg) and phi (48 x 96) */
  int spc;           /* jittered samples per cell, even, >= 2 (4) */
  uint32_t seed;     /* (1) */
} cv_lcd_veil_params;

void cv_lcd_veil_params_default(cv_lcd_veil_params *p);

/* L_v at the eye looking along `gaze` (unit):
 *   integral over the cap theta in [0.1, 100] deg of L(w) g(theta) cos(theta) dw
 *   + sum over sources of g(theta_s) E_s cos(theta_s)
 * with g = cv_cie_glare.  The cap is cut into rows (equal steps of
 * log theta) and columns of phi; each cell is cut again into spc
 * sub-strata (nt x np, np even) with one sample each, theta drawn
 * log-uniformly and phi uniformly within its sub-stratum, and the cell's
 * estimate is the mean of L g cos sin(theta) theta ln(th1/th0) dphi (theta
 * in radians where it measures solid angle).  se: from the differences of
 * neighbouring sub-strata in pairs (slightly conservative); the point
 * sources add no error.
 * Errors: CV_ERR_INVALID (age < 0 or not finite, pigment outside [0, 1],
 * rows/cols < 1, spc odd or < 2, gaze not unit, NULL fn with no sources, source
 * with E < 0 or a bad direction). */
int cv_lcd_veil(const double gaze[3], const cv_lcd_veil_params *p, cv_lcd_luminance_fn fn,
                void *ctx, const cv_lcd_point_source *src, int nsrc, cv_lcd_figure *lv);

/* --- threshold versus intensity ------------------------------------------- */

/* Ferwerda et al. 1996 threshold luminance difference (cd/m^2) at adaptation
 * luminance La (cd/m^2, > 0): the cone and the rod branch, the lower of the
 * two (whichever system detects the smaller difference). */
double cv_tvi_ferwerda(double La);

/* --- the panel's figures ---------------------------------------------------- */

typedef struct cv_lcd_read_params {
  double white;        /* L_on: content white luminance, cd/m^2 (250) */
  double black;        /* L_off: content black luminance, cd/m^2 (0.5) */
  double cr_min;       /* required contrast ratio (3, ISO 15008) */
  double adaptation;   /* L_a, cd/m^2; 0: the background seen, L_off + L_r + L_v */
  double area_min;     /* verdict: share of the area that must meet cr_min (0.95) */
  double vl_min;       /* verdict: smallest visibility level (5) */
} cv_lcd_read_params;

void cv_lcd_read_params_default(cv_lcd_read_params *p);

/* Checks the parameters; on error `err` names the key (white_luminance,
 * black_luminance, cr_min, adaptation) and the value.  CV_ERR_INVALID. */
int cv_lcd_read_params_check(const cv_lcd_read_params *p, cv_err *err);

typedef struct cv_lcd_readability {
  int w, h;
  float *lr;           /* w*h reflected luminance, cd/m^2 (row 0 at the top); owned */
  float *lr_se;        /* its standard error per texel; owned */
  float *cr;           /* w*h contrast ratio; owned */
  float *cr_smooth;    /* CR of L_r box-filtered over (2 smooth_radius + 1)^2 texels; owned */
  int smooth_radius;   /* max(1, w / 80) */
  cv_lcd_figure L_r;   /* panel mean reflected luminance */
  cv_lcd_figure L_v;   /* veiling luminance (as given) */
  cv_lcd_figure cr_mean; /* CR of the panel mean luminances */
  cv_lcd_figure frac_ok; /* share of the panel's area with CR >= cr_min, on cr_smooth */
  cv_lcd_figure vl;    /* visibility level */
  cv_lcd_figure L_a;   /* adaptation luminance used */
  double dL_threshold; /* dL_t(L_a) */
  double cr_worst;     /* smallest texel CR (no error attached) */
  double cr_min;       /* the requirement used */
  double white, black; /* L_on, L_off used (cd/m^2) */
  uint64_t spp;        /* samples per texel behind the estimate */
} cv_lcd_readability;

/* Figures of the panel from the accumulated reflection `acc` and the veil
 * `lv`.  The area share is counted on cr_smooth, the CR of the box-filtered
 * L_r (per texel noise would pull a raw count towards 50% wherever CR is
 * near the requirement, and upwards since CR is convex in L_r); its se
 * treats each texel as a Bernoulli variable with p_i = P(CR_i >= cr_min)
 * from a normal error of the filtered L_r (variance: box mean of the texel
 * variances / box size), boxes moving together:
 * sqrt(box size * sum p_i (1 - p_i)) / n (an approximation; the veil's
 * error, common to all texels, is left out of it).  Other se by
 * first-order propagation (the reflection and the veil are independent
 * estimates).
 * *out is filled (free with cv_lcd_readability_free).  Errors:
 * CV_ERR_INVALID (parameters, lv not finite), CV_ERR_EMPTY (no sample),
 * CV_ERR_NOMEM. */
int cv_lcd_readability_compute(const cv_lcd_accum *acc, const cv_lcd_read_params *p,
                               const cv_lcd_figure *lv, cv_lcd_readability *out, cv_err *err);
/* The same with the reflection scaled by k > 0 (each texel's L_r and its
 * error times k; the veil lv is used as given): the figures under the same
 * lighting at k times its level (the gather is linear in the light), for
 * the illuminance sweep.  CV_ERR_INVALID for k not finite or <= 0. */
int cv_lcd_readability_compute_scaled(const cv_lcd_accum *acc, const cv_lcd_read_params *p,
                                      const cv_lcd_figure *lv, double k,
                                      cv_lcd_readability *out, cv_err *err);
void cv_lcd_readability_free(cv_lcd_readability *r);

/* Heat map of the CR map as 8-bit RGB: the panel (w x h) above a colour bar
 * (bar_h rows, CR from 1 to 10 left to right, log scale), colours viridis
 * over log10(CR) in [0, 1] (CR 1..10, clamped) of each texel's own CR, the
 * threshold contour drawn white where cr_smooth (cr when NULL) crosses
 * cr_min (so that the noise of single texels does not speckle it), and the
 * bar's cr_min position marked white.  px: w * (h + bar_h) * 3 bytes, row 0
 * at the top.  Returns CV_OK. */
int cv_lcd_heatmap_rgb(const cv_lcd_readability *r, int bar_h, uint8_t *px);
/* The heat maps' colour of t in [0, 1] (clamped): viridis, 8-bit RGB. */
void cv_lcd_viridis(double t, uint8_t rgb[3]);

#endif
