/* The illuminance sweep (sweep.h). */
#include "lcd/sweep.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* One number of the sweep: the whole of [s, end) must be it. */
static int num(const char *s, const char *end, double *out) {
  char buf[64];
  const size_t n = (size_t)(end - s);
  if (n == 0 || n >= sizeof buf) return -1;
  memcpy(buf, s, n);
  buf[n] = '\0';
  char *e;
  *out = strtod(buf, &e);
  return *e || !isfinite(*out) ? -1 : 0;
}

int cv_lcd_sweep_parse(const char *s, double *lo, double *hi, int *n, char *why, size_t why_n) {
  const char *c1 = s ? strchr(s, ':') : NULL;
  const char *c2 = c1 ? strchr(c1 + 1, ':') : NULL;
  double N = 21;
  if (!c1 || num(s, c1, lo) || num(c1 + 1, c2 ? c2 : c1 + 1 + strlen(c1 + 1), hi) ||
      (c2 && num(c2 + 1, c2 + 1 + strlen(c2 + 1), &N))) {
    snprintf(why, why_n, "expected LO:HI[:N] (lux, N steps), got '%s'", s ? s : "");
    return CV_ERR_INVALID;
  }
  if (!(*lo > 0) || !(*hi > 0)) {
    snprintf(why, why_n, "'%s': the illuminances must be positive lux (the steps are spaced "
             "logarithmically), got LO %g, HI %g", s, *lo, *hi);
    return CV_ERR_INVALID;
  }
  if (!(*lo < *hi) || *hi > 1e7) {
    snprintf(why, why_n, "'%s': expected LO < HI <= 1e7 lux, got LO %g, HI %g", s, *lo, *hi);
    return CV_ERR_INVALID;
  }
  if (N != floor(N) || N < 2 || N > CV_LCD_SWEEP_MAX) {
    snprintf(why, why_n, "'%s': expected N, the number of steps, an integer 2..%d, got %g", s,
             CV_LCD_SWEEP_MAX, N);
    return CV_ERR_INVALID;
  }
  *n = (int)N;
  return CV_OK;
}

double cv_lcd_sweep_level(double lo, double hi, int n, int i) {
  if (n < 2 || i <= 0) return lo;
  if (i >= n - 1) return hi;
  return lo * pow(hi / lo, (double)i / (n - 1));
}

int cv_lcd_sweep_figures(const cv_lcd_accum *acc, const cv_lcd_read_params *p,
                         const cv_lcd_figure *lv_ref, double E_ref, double E,
                         cv_lcd_readability *out, cv_err *err) {
  if (!(E_ref > 0) || !isfinite(E_ref) || !(E > 0) || !isfinite(E))
    return cv_err_set(err, CV_ERR_INVALID, "sweep: illuminance %g lx against reference %g: "
                      "expected both finite and > 0", E, E_ref);
  const double k = E / E_ref;
  const cv_lcd_figure lv = {lv_ref->value * k, lv_ref->se * k};
  return cv_lcd_readability_compute_scaled(acc, p, &lv, k, out, err);
}

int cv_lcd_sweep_crossing(const cv_lcd_readability *rd_ref, const cv_lcd_read_params *p,
                          double E_ref, double *E_star, double *se) {
  *E_star = *se = 0;
  const double c = p->cr_min, A = rd_ref->L_r.value + rd_ref->L_v.value;
  const double num_ = p->white - c * p->black;
  if (!(num_ > 0) || !(c > 1) || !(A > 0) || !(E_ref > 0)) return 0;
  *E_star = E_ref * num_ / ((c - 1) * A);
  const double sA = sqrt(rd_ref->L_r.se * rd_ref->L_r.se + rd_ref->L_v.se * rd_ref->L_v.se);
  *se = *E_star * sA / A;
  return isfinite(*E_star) ? 1 : (*E_star = *se = 0, 0);
}

int cv_lcd_sweep_grid_crossing(const double *E, const double *v, double t, int n, double *E_x) {
  *E_x = 0;
  for (int i = 1; i < n; i++) {
    if (!(v[i - 1] >= t) || v[i] >= t) continue;
    const double f = (v[i - 1] - t) / (v[i - 1] - v[i]); /* in (0, 1] */
    *E_x = exp(log(E[i - 1]) + f * (log(E[i]) - log(E[i - 1])));
    return 1;
  }
  return 0;
}
