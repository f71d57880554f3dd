/* Pattanaik et al. 2000 time-dependent adaptation (see adapt.h), integrated
 * in closed form per frame.  For constant G both stages are linear first-
 * order ODEs, x' = (x_inf - x) * rate, whose exact solution is
 * x(dt) = x_inf + (x - x_inf) exp(-rate dt); composing two steps multiplies
 * the exponentials, so the result is independent of the step size. */
#include "tonemap/adapt.h"

#include "core/status.h"

#include <math.h>

#define LUM_FLOOR 1e-4 /* = CV_LUM_EPS: adaptation below this is black anyway */
#define LWA_MAX 1e12

void cv_adapt_default_params(cv_adapt_params *p) {
  p->t0_cone = 0.080;
  p->t0_rod = 0.150;
  p->tau_cone = 110.0;
  p->tau_rod = 400.0;
  p->k_cone = 2.2e8;
  p->k_rod = 16.0;
}

static int pos_finite(double v) { return v > 0.0 && isfinite(v); }

static int params_ok(const cv_adapt_params *p) {
  return p && pos_finite(p->t0_cone) && pos_finite(p->t0_rod) && pos_finite(p->tau_cone) &&
         pos_finite(p->tau_rod) && pos_finite(p->k_cone) && pos_finite(p->k_rod);
}

/* Steady-state unbleached fraction, 1/(1 + G tau/K). */
static double b_inf(double g, double tau, double k) { return 1.0 / (1.0 + g * tau / k); }

void cv_adapt_init(cv_adapt_state *s, const cv_adapt_params *p, double g) {
  cv_adapt_params def;
  if (!params_ok(p)) {
    cv_adapt_default_params(&def);
    p = &def;
  }
  if (!(g >= LUM_FLOOR) || !isfinite(g)) g = LUM_FLOOR;
  s->a_cone = g;
  s->a_rod = g;
  s->b_cone = b_inf(g, p->tau_cone, p->k_cone);
  s->b_rod = b_inf(g, p->tau_rod, p->k_rod);
  s->time = 0.0;
  s->initialised = 1;
}

/* Pigment: dB/dt = (1-B)/tau - G B/K = (Binf - B)(1/tau + G/K). */
static double bleach_step(double b, double g, double tau, double k, double dt) {
  double rate = 1.0 / tau + g / k;
  double binf = b_inf(g, tau, k);
  double nb = binf + (b - binf) * exp(-rate * dt);
  return nb < 0.0 ? 0.0 : (nb > 1.0 ? 1.0 : nb); /* rounding only */
}

int cv_adapt_step(cv_adapt_state *s, const cv_adapt_params *p, double g, double dt) {
  if (!s || !params_ok(p) || !(g >= 0.0) || !isfinite(g) || !(dt >= 0.0) || !isfinite(dt))
    return CV_ERR_INVALID;
  if (!s->initialised) cv_adapt_init(s, p, g);
  if (dt == 0.0) return CV_OK;
  /* Neural stage, A += (G - A)(1 - exp(-dt/t0)), written around G. */
  s->a_cone = g + (s->a_cone - g) * exp(-dt / p->t0_cone);
  s->a_rod = g + (s->a_rod - g) * exp(-dt / p->t0_rod);
  s->b_cone = bleach_step(s->b_cone, g, p->tau_cone, p->k_cone, dt);
  s->b_rod = bleach_step(s->b_rod, g, p->tau_rod, p->k_rod, dt);
  s->time += dt;
  return CV_OK;
}

double cv_adapt_lwa(const cv_adapt_state *s) {
  if (!s || !s->initialised) return 1.0;
  double ac = s->a_cone, ar = s->a_rod, bc = s->b_cone, br = s->b_rod;
  if (!(ac >= LUM_FLOOR) || !isfinite(ac)) ac = LUM_FLOOR;
  if (!(ar >= LUM_FLOOR) || !isfinite(ar)) ar = LUM_FLOOR;
  if (!(bc >= 0.0)) bc = 0.0;
  if (!(br >= 0.0)) br = 0.0;
  if (bc > 1.0) bc = 1.0;
  if (br > 1.0) br = 1.0;
  /* Cones' share of vision: 0 below 1e-3 cd/m2, 1 above 1e-2, log-linear. */
  double t = log10(ac) + 3.0;
  double cw = t <= 0.0 ? 0.0 : (t >= 1.0 ? 1.0 : t);
  /* Each class is adapted like a steady eye at A/B (only unbleached pigment
   * absorbs, Pattanaik 2000); the more sensitive one governs. */
  double l_rod = br > 0.0 ? ar / br : LWA_MAX;
  double l_cone = cw * bc > 0.0 ? ac / (cw * bc) : LWA_MAX;
  double lwa = l_cone < l_rod ? l_cone : l_rod;
  if (!(lwa >= LUM_FLOOR)) lwa = LUM_FLOOR;
  if (!(lwa <= LWA_MAX)) lwa = LWA_MAX;
  return lwa;
}

int cv_adapt_feed_frame(cv_adapt_feed *f, const cv_adapt_params *p, double dt, int have_g, double g) {
  if (!(dt >= 0.0) || !isfinite(dt) || (have_g && (!(g >= 0.0) || !isfinite(g)))) return CV_ERR_INVALID;
  f->pending_dt += dt;
  if (!have_g) return 0;
  if (!f->s.initialised) {
    cv_adapt_init(&f->s, p, g);
    f->pending_dt = 0;
    return 1;
  }
  int st = cv_adapt_step(&f->s, p, g, f->pending_dt);
  if (st) return st;
  f->pending_dt = 0;
  return 0;
}
