/* Implausible head poses (issue 35, defect 8): src/service/posegate.c and the
 * CAVE config's "tracking" block (src/view/cave.c). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <stdio.h>
#include <string.h>

#include "service/posegate.h"
#include "view/cave.h"

static void test_gate(void **state) {
  (void)state;
  const double lo[3] = {-2, 0, -2}, hi[3] = {2, 3, 2};
  cv_pose_gate g;
  cv_pose_gate_init(&g, lo, hi, 10.0);
  const double a[3] = {0, 1.2, 0}, far[3] = {10, 1.2, 0}, jump[3] = {1.5, 1.2, 0}, walk[3] = {0.05, 1.2, 0};
  double v;
  assert_int_equal(cv_pose_gate_check(&g, a, 0.0, &v), CV_POSE_OK);
  /* 10 m outside the CAVE: held */
  assert_int_equal(cv_pose_gate_check(&g, far, 0.01, &v), CV_POSE_OUTSIDE);
  /* walking 5 cm in 10 ms (5 m/s): taken */
  assert_int_equal(cv_pose_gate_check(&g, walk, 0.01, &v), CV_POSE_OK);
  assert_true(v > 4.9 && v < 5.1);
  /* 1.45 m in 10 ms (145 m/s): held; the last good pose stays */
  assert_int_equal(cv_pose_gate_check(&g, jump, 0.02, &v), CV_POSE_TOO_FAST);
  assert_true(v > 100);
  assert_true(g.last[0] == 0.05);
  /* the same place 0.2 s later (7.25 m/s from the last good pose): taken */
  assert_int_equal(cv_pose_gate_check(&g, jump, 0.21, &v), CV_POSE_OK);
  assert_int_equal((int)g.outside, 1);
  assert_int_equal((int)g.too_fast, 1);
  /* no speed limit */
  cv_pose_gate_init(&g, lo, hi, 0);
  assert_int_equal(cv_pose_gate_check(&g, a, 0.0, &v), CV_POSE_OK);
  assert_int_equal(cv_pose_gate_check(&g, jump, 0.001, &v), CV_POSE_OK);
}

static const char *k_cave =
    "{\"walls\": [{\"name\": \"front\", \"pa\": [-1.5, 0, -1.5], \"pb\": [1.5, 0, -1.5], \"pc\": [-1.5, 3, -1.5],"
    " \"res\": [64, 64]}] %s}";

static void test_config(void **state) {
  (void)state;
  char txt[1024];
  cv_cave c;
  cv_err err;
  cv_err_clear(&err);
  snprintf(txt, sizeof txt, k_cave, "");
  assert_int_equal(cv_cave_parse(txt, "t.json", &c, &err), CV_OK);
  /* default: the walls' box + 0.5 m, 10 m/s */
  assert_true(c.track_lo[0] == -2.0 && c.track_hi[0] == 2.0 && c.track_lo[1] == -0.5 && c.track_hi[1] == 3.5);
  assert_true(c.track_lo[2] == -2.0 && c.track_hi[2] == -1.0);
  assert_true(c.max_head_speed == 10.0);
  snprintf(txt, sizeof txt, k_cave, ", \"tracking\": {\"volume\": [[-3, 0, -3], [3, 2.5, 3]], \"max_head_speed\": 6}");
  assert_int_equal(cv_cave_parse(txt, "t.json", &c, &err), CV_OK);
  assert_true(c.track_lo[0] == -3 && c.track_hi[1] == 2.5 && c.max_head_speed == 6);
  snprintf(txt, sizeof txt, k_cave, ", \"tracking\": {\"volume\": [[3, 0, -3], [-3, 2.5, 3]]}");
  assert_int_not_equal(cv_cave_parse(txt, "t.json", &c, &err), CV_OK);
  printf("%s\n", err.msg);
  assert_non_null(strstr(err.msg, "tracking.volume"));
  snprintf(txt, sizeof txt, k_cave, ", \"tracking\": {\"max_speed\": 6}");
  assert_int_not_equal(cv_cave_parse(txt, "t.json", &c, &err), CV_OK);
  assert_non_null(strstr(err.msg, "max_speed"));
}

int main(void) {
  const struct CMUnitTest tests[] = {cmocka_unit_test(test_gate), cmocka_unit_test(test_config)};
  return cmocka_run_group_tests(tests, NULL, NULL);
}
