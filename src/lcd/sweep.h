/* Readability as a function of the light level (`cave lcd
 * --illuminance-sweep LO:HI[:N]`, docs/readability.md).  The final gather
 * and the veil are linear in the light: at k times the level every texel's
 * reflected luminance and the veil are k times those of one render (the
 * panel's own white and black do not change), so one render at the
 * reference level E_ref (the lighting's outdoor horizontal illuminance,
 * light_level.h) gives the figures at any illuminance E with k = E / E_ref.
 *
 * The mean CR crosses cr_min where L_on + k A = c (L_off + k A),
 * A = L_r + L_v at E_ref:  E* = E_ref (L_on - c L_off) / ((c - 1) A).
 * Pure computation, no MPI, nothing printed. */
#ifndef CV_LCD_SWEEP_H
#define CV_LCD_SWEEP_H

#include "lcd/accum.h"
#include "lcd/readability.h"

#define CV_LCD_SWEEP_MAX 1000 /* steps */

/* Parses "LO:HI[:N]" (lux, 0 < LO < HI <= 1e7; N steps 2..CV_LCD_SWEEP_MAX,
 * default 21), logarithmic spacing.  Errors: CV_ERR_INVALID with `why`
 * saying what was expected (one line). */
int cv_lcd_sweep_parse(const char *s, double *lo, double *hi, int *n, char *why, size_t why_n);

/* Step i of n (0..n-1) from lo to hi, equal ratios. */
double cv_lcd_sweep_level(double lo, double hi, int n, int i);

/* The figures at illuminance E from the render at E_ref (> 0): the
 * reflection and the veil lv_ref scaled by E / E_ref.  As
 * cv_lcd_readability_compute. */
int cv_lcd_sweep_figures(const cv_lcd_accum *acc, const cv_lcd_read_params *p,
                         const cv_lcd_figure *lv_ref, double E_ref, double E,
                         cv_lcd_readability *out, cv_err *err);

/* The illuminance where the mean CR falls to p->cr_min, from the figures at
 * E_ref (rd_ref: L_r and L_v with their errors), with its standard error
 * (first order: the relative error of L_r + L_v).  Returns 1 with *E_star;
 * 0 when the panel never meets cr_min (L_on <= cr_min L_off: *E_star 0) or
 * always does (no reflection nor veil: *E_star 0). */
int cv_lcd_sweep_crossing(const cv_lcd_readability *rd_ref, const cv_lcd_read_params *p,
                          double E_ref, double *E_star, double *se);

/* The first level of the grid E[0..n-1] (ascending) where ok[] turns from 1
 * to 0, interpolated in log E between the two steps with the values
 * v[] against the threshold t (v falling through t).  Returns 1 with *E_x;
 * 0 when ok[] never turns (*E_x 0). */
int cv_lcd_sweep_grid_crossing(const double *E, const double *v, double t, int n, double *E_x);

#endif
