/* Temporal adaptation of the visual system, Pattanaik et al. 2000 "Time-
 * Dependent Visual Adaptation for Fast Realistic Image Display": a fast neural
 * stage and slow pigment bleaching, for cones and rods.  Per frame the target
 * luminance G (the foveal log-average) is held constant, and both linear ODEs
 * are integrated in closed form, so the result does not depend on the frame
 * rate: two steps of dt equal one step of 2dt (up to rounding), and unlike
 * explicit Euler the rod pigment cannot go negative at G = 1e4 cd/m2.
 *
 *   neural:    dA/dt = (G - A)/t0          ->  A += (G - A)(1 - exp(-dt/t0))
 *   bleaching: dB/dt = (1 - B)/tau - G B/K ->  B = Binf + (B - Binf) exp(-dt (1/tau + G/K)),
 *              Binf = 1/(1 + G tau/K)
 *
 * Simplification: rods see the photopic luminance (no scotopic conversion). */
#ifndef CV_TONEMAP_ADAPT_H
#define CV_TONEMAP_ADAPT_H

typedef struct cv_adapt_params {
  double t0_cone, t0_rod;   /* neural time constants, s: 0.080, 0.150 */
  double tau_cone, tau_rod; /* pigment regeneration time constants, s: 110, 400 */
  double k_cone, k_rod;     /* bleaching half-luminance, cd/m2: 2.2e8, 16 */
} cv_adapt_params;

typedef struct cv_adapt_state {
  double a_cone, a_rod; /* neural-stage adapted luminance, cd/m2 */
  double b_cone, b_rod; /* unbleached pigment fraction in [0, 1] */
  double time;          /* seconds integrated so far */
  int initialised;
} cv_adapt_state;

/* Pattanaik 2000 constants (above). */
void cv_adapt_default_params(cv_adapt_params *p);

/* Steady state at luminance g (cd/m2): A = g, B = 1/(1 + g tau/K), time 0.
 * Non-finite or negative g is treated as CV_LUM_EPS-like floor 1e-4. */
void cv_adapt_init(cv_adapt_state *s, const cv_adapt_params *p, double g);

/* Advances the state by dt seconds with the target luminance g held constant.
 * Errors: CV_ERR_INVALID (state unchanged) for g NaN/Inf/negative, dt < 0 or
 * NaN/Inf, or non-positive/non-finite params.  dt == 0 is a no-op.  An
 * uninitialised state is initialised at g (steady state) and then stepped.
 * Late/missing adaptation data: do not call (keep the state); the next call
 * passes the real elapsed dt. */
int cv_adapt_step(cv_adapt_state *s, const cv_adapt_params *p, double g, double dt);

/* Adaptation luminance for the tone mapper (cd/m2), finite and in
 * [1e-4, 1e12] always (an uninitialised state gives 1).
 *
 * Pattanaik 2000: only unbleached pigment catches light, so a receptor class
 * with neural level A and unbleached fraction B is adapted like a steady eye
 * at the world luminance A/B.  The more sensitive class sets the adaptation:
 *   Lwa = min(A_cone / (c B_cone), A_rod / B_rod),
 * where c, the cones' share of vision, is 0 below 1e-3 cd/m2 (cones blind),
 * 1 above 1e-2 cd/m2 and linear in log10(A_cone) between.  In a steady state
 * Lwa = G (1 + G tau/K) of the governing class: within 0.5% of G from 1e-2
 * to 1e4 cd/m2 (cones) and below 2e-4 cd/m2 (rods); up to ~18% above G in
 * the hand-over 1e-3..1e-2 cd/m2, where the rods are already partly bleached.
 * After a jump from bright to scotopic the rods' pigment regenerates over
 * minutes (tau_rod = 400 s) and Lwa stays high: dark adaptation.  Rods see
 * the photopic luminance (no scotopic conversion; a simplification). */
double cv_adapt_lwa(const cv_adapt_state *s);

/* The one start-and-step policy of `cave run` (the master) and `cave
 * render`: per frame, the frame's dt (0 for the first) is added to the time
 * waiting; with a target luminance (the foveal log-average of the frame, the
 * master's priming round giving frame 0's) an uninitialised state starts in
 * steady state at it, a started one steps by the waiting time; without one
 * (empty foveal cone, late reports) the state is kept and the time waits
 * for the next target.  Until the first target the adaptation luminance is
 * 1 cd/m2 (cv_adapt_lwa). */
typedef struct cv_adapt_feed {
  cv_adapt_state s;
  double pending_dt; /* seconds not yet integrated */
} cv_adapt_feed;

/* One frame of the policy above: g is the target (cd/m2) when have_g.
 * Returns 1 when the state started this frame, 0 otherwise, or
 * CV_ERR_INVALID (state unchanged) for a non-finite or negative dt or g. */
int cv_adapt_feed_frame(cv_adapt_feed *f, const cv_adapt_params *p, double dt, int have_g, double g);

#endif
