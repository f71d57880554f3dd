/* Clock offsets (NTP closed form, bounds under asymmetric delays, min round
 * trip selection, ageing) and constant-velocity head prediction. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include "cv_test_near.h"

#include "service/clocksync.h"
#include "test_service.h"

/* A probe: master at t (its clock), wire delays d_out / d_back, the rank
 * holds it for hold seconds; the rank's clock = master clock + off. */
static cv_clock_sample probe(double t, double off, double d_out, double hold, double d_back) {
  cv_clock_sample s = {t, t + d_out + off, t + d_out + hold + off, t + d_out + hold + d_back};
  return s;
}

static void test_offset_closed_form(void **state) {
  (void)state;
  double o, u;
  cv_clock_sample s = probe(100.0, 0.0375, 2e-4, 5e-5, 2e-4);
  assert_int_equal(cv_clock_offset(&s, &o, &u), CV_OK);
  assert_near(o, 0.0375, 1e-12); /* symmetric delays: exact */
  assert_near(u, 2e-4, 1e-12);   /* half of the 4e-4 on the wire */
  /* Asymmetric delays: off by half the asymmetry, inside the bound. */
  s = probe(100.0, -0.25, 9e-4, 1e-4, 1e-4);
  assert_int_equal(cv_clock_offset(&s, &o, &u), CV_OK);
  assert_near(o, (-0.25 + 4e-4), 1e-12);
  assert_near(o, (-0.25), u + 1e-15);
  /* Impossible and non-finite samples. */
  cv_clock_sample bad = {1.0, 5.0, 4.0, 2.0};
  assert_int_equal(cv_clock_offset(&bad, &o, &u), CV_ERR_RANGE);
  cv_clock_sample bad2 = {1.0, 5.0, 5.5, 1.1}; /* held longer than the round trip */
  assert_int_equal(cv_clock_offset(&bad2, &o, &u), CV_ERR_RANGE);
  cv_clock_sample nan = {1.0, NAN, 5.5, 7.0};
  assert_int_equal(cv_clock_offset(&nan, &o, &u), CV_ERR_NONFINITE);
}

static void test_estimator(void **state) {
  (void)state;
  cv_clock_est e;
  cv_clock_est_init(&e, 2.0);
  double o, u;
  assert_int_equal(cv_clock_est_get(&e, 0.0, &o, &u), 0);
  /* Noisy delays: the sample with the smallest round trip wins. */
  const double off = 1.5e-3;
  for (int i = 0; i < 20; i++) {
    double d1 = 1e-4 * (1 + (i * 7) % 11), d2 = 1e-4 * (1 + (i * 5) % 13);
    if (i == 13) d1 = d2 = 2e-5;
    cv_clock_sample s = probe(0.1 * i, off, d1, 1e-5, d2);
    cv_clock_est_add(&e, &s);
  }
  assert_int_equal(cv_clock_est_get(&e, 1.9, &o, &u), 1);
  assert_near(u, 2e-5, 1e-12);
  assert_near(o, off, 1e-12);
  /* Ageing: 10 s later nothing is left in the 2 s window. */
  assert_int_equal(cv_clock_est_get(&e, 12.0, &o, &u), 0);
  /* A drifted clock: new samples replace the old estimate. */
  cv_clock_sample s2 = probe(20.0, off + 1e-3, 3e-4, 1e-5, 3e-4);
  cv_clock_est_add(&e, &s2);
  assert_int_equal(cv_clock_est_get(&e, 20.5, &o, &u), 1);
  assert_near(o, (off + 1e-3), 1e-12);
  cv_clock_sample bad = {5.0, 1.0, 0.5, 6.0};
  cv_clock_est_add(&e, &bad);
  assert_int_equal((int)e.rejected, 1);
}

static void test_predict(void **state) {
  (void)state;
  double p[3], g[3];
  /* Straight line at 0.5 m/s, gaze turning 30 deg/s about +Y. */
  const double p0[3] = {0, 1.2, 0}, p1[3] = {0.005, 1.2, 0};
  const double a0 = 0, a1 = 0.3 * M_PI / 180;
  const double g0[3] = {sin(a0), 0, -cos(a0)}, g1[3] = {sin(a1), 0, -cos(a1)};
  double dt = cv_head_predict(p0, g0, 1.00, p1, g1, 1.01, 1.05, 0.1, p, g);
  assert_near(dt, 0.04, 1e-12);
  assert_near(p[0], 0.025, 1e-12);
  assert_near(p[1], 1.2, 1e-12);
  const double a = 1.5 * M_PI / 180; /* 30 deg/s for 0.05 s */
  assert_near(g[0], sin(a), 1e-9);
  assert_near(g[2], -(cos(a)), 1e-9);
  assert_near(g[1], 0, 1e-12);
  /* Horizon: a stale tracker is extrapolated at most 0.1 s. */
  dt = cv_head_predict(p0, g0, 1.00, p1, g1, 1.01, 9.0, 0.1, p, g);
  assert_near(dt, 0.1, 1e-12);
  assert_near(p[0], 0.055, 1e-12);
  /* One sample, or a target in the past: the newest pose. */
  dt = cv_head_predict(p1, g1, 1.01, p1, g1, 1.01, 1.05, 0.1, p, g);
  assert_true(dt == 0 && p[0] == p1[0] && g[0] == g1[0]);
  dt = cv_head_predict(p0, g0, 1.00, p1, g1, 1.01, 0.5, 0.1, p, g);
  assert_true(dt == 0 && p[0] == p1[0]);
  /* Standing still stays still; NaN target holds. */
  dt = cv_head_predict(p1, g1, 1.0, p1, g1, 1.01, 1.05, 0.1, p, g);
  assert_true(p[0] == p1[0]);
  assert_near(g[0], g1[0], 1e-15);
  dt = cv_head_predict(p0, g0, 1.0, p1, g1, 1.01, NAN, 0.1, p, g);
  assert_true(dt == 0 && isfinite(p[0]));
}

int run_clocksync_tests(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_offset_closed_form),
      cmocka_unit_test(test_estimator),
      cmocka_unit_test(test_predict),
  };
  return cmocka_run_group_tests_name("clocksync", tests, NULL, NULL);
}
