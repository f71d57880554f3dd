/* Scripted drives: parsing (defaults carried between keyframes, weight
 * normalisation, map resolution next to the file and in blender-data's
 * folder), evaluation against hand-computed values (linear, shorter arc,
 * loop and hold), the light spec handed to the lighting code, the cache key's
 * quantisation, every kind of error with its field path, and the shipped
 * configs/drives files. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include "cv_test_near.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "service/drive.h"
#include "test_service.h"

static const char *maps_json =
    "{\"description\": \"test\", \"loop\": false,\n"
    " \"maps\": [\"forest.exr\", \"city.exr\", \"sunset.exr\"], \"scale\": 2.5,\n"
    " \"keyframes\": [\n"
    "   {\"t\": 0, \"yaw\": 0, \"pitch\": 10, \"weights\": [1, 0, 0]},\n"
    "   {\"t\": 4, \"yaw\": 90, \"weights\": [2, 2, 0]},\n"
    "   {\"t\": 6, \"yaw\": 350, \"roll\": -4},\n"
    "   {\"t\": 8, \"yaw\": 10, \"weights\": [0, 0, 3]}]}";

static cv_drive *parse_ok(const char *json) {
  cv_drive *d = NULL;
  cv_err err;
  cv_err_clear(&err);
  int st = cv_drive_parse(json, "test.json", NULL, &d, &err);
  if (st) fail_msg("unexpected error %d: %s", st, err.msg);
  return d;
}

static void test_drive_parse_eval(void **state) {
  (void)state;
  cv_drive *d = parse_ok(maps_json);
  assert_true(cv_drive_duration(d) == 8.0);
  assert_int_equal(cv_drive_n_maps(d), 3);
  assert_int_equal(cv_drive_n_keys(d), 4);
  assert_false(cv_drive_is_sky(d));
  assert_false(cv_drive_loops(d));
  assert_string_equal(cv_drive_description(d), "test");
  assert_string_equal(cv_drive_map_path(d, 1), CAVE_BLENDER_WORLD_DIR "/city.exr");
  assert_null(cv_drive_map_path(d, 3));

  cv_drive_state s;
  /* t = 2: halfway between key 0 and 1: yaw 45, pitch 10 (carried), weights
   * halfway between (1,0,0) and (0.5,0.5,0) = (0.75, 0.25, 0). */
  cv_drive_eval(d, 2.0, &s);
  assert_true(s.t == 2.0 && s.n_maps == 3 && !s.is_sky);
  assert_near(s.yaw_deg, 45, 1e-12);
  assert_true(s.pitch_deg == 10);
  assert_true(s.roll_deg == 0);
  assert_near(s.weights[0], 0.75, 1e-12);
  assert_near(s.weights[1], 0.25, 1e-12);
  assert_true(s.weights[2] == 0);
  /* Key 2 carries key 1's weights (0.5, 0.5, 0) and pitch 10. */
  cv_drive_eval(d, 6.0, &s);
  assert_true(s.yaw_deg == 350 && s.roll_deg == -4 && s.pitch_deg == 10);
  assert_near(s.weights[0], 0.5, 1e-12);
  assert_near(s.weights[1], 0.5, 1e-12);
  /* 90 -> 350 along the shorter arc is -100 degrees: at t = 5, 40. */
  cv_drive_eval(d, 5.0, &s);
  assert_near(s.yaw_deg, 40, 1e-12);
  assert_near(s.roll_deg, -2, 1e-12);
  /* 350 -> 10 passes through 0 (= 360), not 180. */
  cv_drive_eval(d, 7.0, &s);
  assert_near(s.yaw_deg, 360, 1e-12);
  assert_near(s.weights[0], 0.25, 1e-12);
  assert_near(s.weights[2], 0.5, 1e-12);
  double sum = s.weights[0] + s.weights[1] + s.weights[2];
  assert_near(sum, 1, 1e-15);
  /* Hold the ends (no loop). */
  cv_drive_eval(d, -3, &s);
  assert_true(s.yaw_deg == 0 && s.weights[0] == 1 && s.t == -3);
  cv_drive_eval(d, 100, &s);
  assert_true(s.yaw_deg == 10 && s.weights[2] == 1);
  cv_drive_eval(d, NAN, &s);
  assert_true(s.t == 0 && s.yaw_deg == 0);

  /* Light spec: zero-weight maps dropped, scale, attitude, sun extraction. */
  cv_light_spec l;
  cv_drive_eval(d, 2.0, &s);
  cv_drive_to_light_spec(d, &s, &l);
  assert_int_equal(l.kind, CV_LIGHT_ENV);
  assert_int_equal(l.n_env, 2);
  assert_string_equal(l.env[0], CAVE_BLENDER_WORLD_DIR "/forest.exr");
  assert_string_equal(l.env[1], CAVE_BLENDER_WORLD_DIR "/city.exr");
  assert_near(l.weight[0], 0.75, 1e-12);
  assert_near(l.weight[1], 0.25, 1e-12);
  assert_true(l.scale == 2.5 && l.extract_sun == 1);
  assert_near(l.yaw_deg, 45, 1e-12);
  assert_true(l.pitch_deg == 10);
  cv_drive_eval(d, 8.0, &s);
  cv_drive_to_light_spec(d, &s, &l);
  assert_int_equal(l.n_env, 1);
  assert_string_equal(l.env[0], CAVE_BLENDER_WORLD_DIR "/sunset.exr");
  cv_drive_destroy(d);
  cv_drive_destroy(NULL);
}

static void test_drive_loop_and_sky(void **state) {
  (void)state;
  const char *sky =
      "{\"loop\": true, \"sky\": true, \"ground_albedo\": 0.3, \"keyframes\": [\n"
      " {\"t\": 0, \"turbidity\": 2, \"sun_elevation\": 10, \"sun_azimuth\": 350},\n"
      " {\"t\": 10, \"yaw\": 180, \"turbidity\": 6, \"sun_elevation\": 60, \"sun_azimuth\": 30}]}";
  cv_drive *d = parse_ok(sky);
  assert_true(cv_drive_is_sky(d) && cv_drive_loops(d) && cv_drive_n_maps(d) == 0);
  cv_drive_state s, s2;
  cv_drive_eval(d, 2.5, &s);
  assert_true(s.is_sky && s.n_maps == 0);
  assert_near(s.turbidity, 3, 1e-12);
  assert_near(s.sun_elevation_deg, 22.5, 1e-12);
  assert_near(s.sun_azimuth_deg, 360, 1e-12); /* 350 -> 30 across north: +40 */
  /* 0 -> 180 is ambiguous (exactly half a turn): wrap180 picks -180. */
  assert_near(fabs(s.yaw_deg), 45, 1e-12);
  /* Loop: t + k * duration gives the same state (up to fmod rounding). */
  cv_drive_eval(d, 32.5, &s2);
  assert_near(s2.sun_elevation_deg, s.sun_elevation_deg, 1e-9);
  cv_drive_eval(d, -7.5, &s2);
  assert_near(s2.sun_elevation_deg, s.sun_elevation_deg, 1e-9);
  cv_drive_eval(d, 10.0, &s2); /* t = duration wraps to the first key */
  assert_true(s2.sun_elevation_deg == 10 && s2.turbidity == 2);
  cv_light_spec l;
  cv_drive_eval(d, 5.0, &s);
  cv_drive_to_light_spec(d, &s, &l);
  assert_int_equal(l.kind, CV_LIGHT_SKY);
  assert_near(l.turbidity, 4, 1e-12);
  assert_near(l.sun_elevation_deg, 35, 1e-12);
  assert_near(l.sun_azimuth_deg, 370, 1e-12);
  assert_true(l.ground_albedo == 0.3);
  assert_true(l.extract_sun == 1 && l.n_env == 0);
  cv_drive_destroy(d);

  /* A single keyframe is a constant drive. */
  d = parse_ok("{\"maps\": [\"night.exr\"], \"keyframes\": [{\"t\": 0, \"yaw\": 30}]}");
  assert_true(cv_drive_duration(d) == 0);
  cv_drive_eval(d, 5, &s);
  assert_true(s.yaw_deg == 30 && s.weights[0] == 1);
  cv_drive_destroy(d);
}

static void test_drive_state_key(void **state) {
  (void)state;
  cv_drive_state a, b;
  memset(&a, 0, sizeof a);
  a.n_maps = 2;
  a.weights[0] = 0.7;
  a.weights[1] = 0.3;
  a.yaw_deg = 10;
  b = a;
  b.t = 99; /* time does not matter */
  assert_true(cv_drive_state_key(&a, 1, 0.01) == cv_drive_state_key(&b, 1, 0.01));
  b.yaw_deg = 10.4; /* within the 1 degree step */
  assert_true(cv_drive_state_key(&a, 1, 0.01) == cv_drive_state_key(&b, 1, 0.01));
  b.yaw_deg = 10.6;
  assert_true(cv_drive_state_key(&a, 1, 0.01) != cv_drive_state_key(&b, 1, 0.01));
  assert_true(cv_drive_state_key(&a, 5, 0.01) == cv_drive_state_key(&b, 5, 0.01));
  b.yaw_deg = 370; /* the same attitude */
  assert_true(cv_drive_state_key(&a, 1, 0.01) == cv_drive_state_key(&b, 1, 0.01));
  a.yaw_deg = 359.8;
  b.yaw_deg = -0.1; /* both round to 0 on the circle */
  assert_true(cv_drive_state_key(&a, 1, 0.01) == cv_drive_state_key(&b, 1, 0.01));
  b.yaw_deg = 0.2;
  assert_true(cv_drive_state_key(&a, 1, 0.01) == cv_drive_state_key(&b, 1, 0.01));
  b = a;
  b.weights[0] = 0.702;
  b.weights[1] = 0.298;
  assert_true(cv_drive_state_key(&a, 1, 0.01) == cv_drive_state_key(&b, 1, 0.01));
  assert_true(cv_drive_state_key(&a, 1, 0.001) != cv_drive_state_key(&b, 1, 0.001));
  b = a;
  b.pitch_deg = 3;
  assert_true(cv_drive_state_key(&a, 1, 0.01) != cv_drive_state_key(&b, 1, 0.01));
  /* Sky states: 0.5 degree sun steps, 0.1 turbidity steps. */
  memset(&a, 0, sizeof a);
  a.is_sky = 1;
  a.turbidity = 3;
  a.sun_elevation_deg = 30;
  b = a;
  b.sun_elevation_deg = 30.2;
  b.turbidity = 3.04;
  assert_true(cv_drive_state_key(&a, 1, 0.01) == cv_drive_state_key(&b, 1, 0.01));
  b.sun_elevation_deg = 30.3;
  assert_true(cv_drive_state_key(&a, 1, 0.01) != cv_drive_state_key(&b, 1, 0.01));
  b = a;
  b.turbidity = 3.06;
  assert_true(cv_drive_state_key(&a, 1, 0.01) != cv_drive_state_key(&b, 1, 0.01));
  /* A sky state and a map state never share a key; bad steps fall back. */
  cv_drive_state m;
  memset(&m, 0, sizeof m);
  memset(&b, 0, sizeof b);
  b.is_sky = 1;
  assert_true(cv_drive_state_key(&m, 1, 0.01) != cv_drive_state_key(&b, 1, 0.01));
  assert_true(cv_drive_state_key(&a, 0, NAN) == cv_drive_state_key(&a, 1, 1e-3));
}

typedef struct bad_drive {
  const char *json;
  int status;
  const char *where; /* expected in the message */
} bad_drive;

static const bad_drive bad[] = {
    {"{\"maps\": [\"forest.exr\"], \"keyframes\": [{\"t\": 0}], \"speed\": 3}", CV_ERR_CONFIG,
     "test.json: speed: unknown field"},
    {"{\"maps\": [\"forest.exr\"], \"keyframes\": [{\"t\": 0, \"yaww\": 3}]}", CV_ERR_CONFIG,
     "keyframes[0].yaww: unknown field"},
    {"{\"maps\": [\"forest.exr\"], \"keyframes\": [{\"t\": 1}]}", CV_ERR_RANGE,
     "keyframes[0].t: the first keyframe must be at t = 0"},
    {"{\"maps\": [\"forest.exr\"], \"keyframes\": [{\"t\": 0}, {\"t\": 2}, {\"t\": 2}]}",
     CV_ERR_RANGE, "keyframes[2].t: t = 2 is not after"},
    {"{\"maps\": [\"forest.exr\"], \"keyframes\": [{\"t\": 0}, {\"yaw\": 2}]}", CV_ERR_CONFIG,
     "keyframes[1].t: missing"},
    {"{\"maps\": [\"forest.exr\", \"city.exr\"], \"keyframes\": [{\"t\": 0, \"weights\": [1]}]}",
     CV_ERR_CONFIG, "keyframes[0].weights: 1 weights for 2 maps"},
    {"{\"maps\": [\"forest.exr\", \"city.exr\"], \"keyframes\": [{\"t\": 0, \"weights\": [1, -1]}]}",
     CV_ERR_RANGE, "keyframes[0].weights[1]: -1 is outside"},
    {"{\"maps\": [\"forest.exr\", \"city.exr\"], \"keyframes\": [{\"t\": 0, \"weights\": [0, 0]}]}",
     CV_ERR_RANGE, "keyframes[0].weights: the weights sum to 0"},
    {"{\"maps\": [\"forest.exr\"], \"keyframes\": [{\"t\": 0, \"weights\": [\"a\"]}]}",
     CV_ERR_CONFIG, "keyframes[0].weights[0]: expected a number"},
    {"{\"maps\": [\"forest.exr\"], \"keyframes\": [{\"t\": 0, \"yaw\": 1e999}]}",
     CV_ERR_NONFINITE, "keyframes[0].yaw: expected a finite number"},
    {"{\"keyframes\": [{\"t\": 0}]}", CV_ERR_CONFIG, "maps: missing"},
    {"{\"maps\": [\"no-such-map.exr\"], \"keyframes\": [{\"t\": 0}]}", CV_ERR_NOT_FOUND,
     "maps[0]: environment map 'no-such-map.exr' not found"},
    {"{\"maps\": [\"a.exr\",\"a.exr\",\"a.exr\",\"a.exr\",\"a.exr\",\"a.exr\",\"a.exr\",\"a.exr\","
     "\"a.exr\"], \"keyframes\": [{\"t\": 0}]}",
     CV_ERR_CONFIG, "maps: expected an array of 1..8"},
    {"{\"maps\": [\"forest.exr\"], \"sky\": true, \"keyframes\": [{\"t\": 0}]}", CV_ERR_CONFIG,
     "maps: not allowed with \"sky\": true"},
    {"{\"sky\": true, \"keyframes\": [{\"t\": 0, \"weights\": [1]}]}", CV_ERR_CONFIG,
     "keyframes[0].weights: unknown field"},
    {"{\"maps\": [\"forest.exr\"], \"keyframes\": [{\"t\": 0, \"sun_elevation\": 20}]}",
     CV_ERR_CONFIG, "keyframes[0].sun_elevation: unknown field"},
    {"{\"sky\": true, \"keyframes\": [{\"t\": 0, \"turbidity\": 11}]}", CV_ERR_RANGE,
     "keyframes[0].turbidity: 11 is outside [2, 10]"},
    {"{\"sky\": true, \"keyframes\": [{\"t\": 0, \"sun_elevation\": 91}]}", CV_ERR_RANGE,
     "keyframes[0].sun_elevation"},
    {"{\"maps\": [\"forest.exr\"], \"scale\": 0, \"keyframes\": [{\"t\": 0}]}", CV_ERR_RANGE,
     "scale: expected a positive multiplier"},
    {"{\"maps\": [\"forest.exr\"], \"loop\": 1, \"keyframes\": [{\"t\": 0}]}", CV_ERR_CONFIG,
     "loop: expected true or false"},
    {"{\"maps\": [\"forest.exr\"], \"keyframes\": []}", CV_ERR_CONFIG,
     "keyframes: expected an array of 1..1024"},
    {"{\"maps\": [\"forest.exr\"], \"keyframes\": [3]}", CV_ERR_CONFIG,
     "keyframes[0]: expected an object"},
    {"{\"maps\": [\"forest.exr\"],\n \"keyframes\": [{\"t\": 0},]}", CV_ERR_CONFIG,
     "line 2, column 25: JSON syntax error near ']}'"},
    {"[1, 2]", CV_ERR_CONFIG, "expected a JSON object"},
    {"{\"maps\": [\"forest.exr\"], \"scale\": 2, \"illuminance\": 100, \"keyframes\": [{\"t\": 0}]}",
     CV_ERR_CONFIG, "illuminance: not together with \"scale\""},
    {"{\"sky\": true, \"illuminance\": \"auto\", \"keyframes\": [{\"t\": 0}]}", CV_ERR_CONFIG,
     "illuminance: only for map drives"},
    {"{\"maps\": [\"forest.exr\"], \"illuminance\": \"bright\", \"keyframes\": [{\"t\": 0}]}",
     CV_ERR_CONFIG, "illuminance: expected lux or \"auto\""},
    {"{\"maps\": [\"forest.exr\"], \"illuminance\": -3, \"keyframes\": [{\"t\": 0}]}",
     CV_ERR_RANGE, "illuminance"},
};

/* illuminance reaches the light spec (lux or auto) */
static void test_drive_illuminance(void **state) {
  (void)state;
  const char *json[2] = {"{\"maps\": [\"forest.exr\"], \"illuminance\": 12000, \"keyframes\": [{\"t\": 0}]}",
                         "{\"maps\": [\"forest.exr\"], \"illuminance\": \"auto\", \"keyframes\": [{\"t\": 0}]}"};
  const double want[2] = {12000, CV_ILLUMINANCE_AUTO};
  for (int i = 0; i < 2; i++) {
    cv_drive *d;
    cv_err err;
    assert_int_equal(cv_drive_parse(json[i], "test.json", NULL, &d, &err), CV_OK);
    cv_drive_state s;
    cv_drive_eval(d, 0, &s);
    cv_light_spec l;
    cv_drive_to_light_spec(d, &s, &l);
    assert_true(l.illuminance == want[i] && l.scale == 1.0);
    cv_drive_destroy(d);
  }
}

static void test_drive_errors(void **state) {
  (void)state;
  int n = (int)(sizeof bad / sizeof bad[0]);
  for (int i = 0; i < n; i++) {
    cv_drive *d = (cv_drive *)1;
    cv_err err;
    cv_err_clear(&err);
    int st = cv_drive_parse(bad[i].json, "test.json", NULL, &d, &err);
    if (st != bad[i].status || !strstr(err.msg, bad[i].where))
      fail_msg("case %d: got %d '%s', expected %d '%s'", i, st, err.msg, bad[i].status,
               bad[i].where);
    assert_null(d);
  }
  /* Every problem is listed, each with its path; load reports the first and
   * a count of the others. */
  const char *many =
      "{\"maps\": [\"forest.exr\", \"nope.exr\"], \"colour\": 1,\n"
      " \"keyframes\": [{\"t\": 0, \"weights\": [1, -2]}, {\"t\": 0, \"yaw\": \"x\"}]}";
  char buf[4096];
  int np = 0;
  assert_int_not_equal(cv_drive_validate_text(many, "m.json", NULL, buf, sizeof buf, &np),
                       CV_OK);
  assert_int_equal(np, 5);
  assert_non_null(strstr(buf, "m.json: colour: unknown field"));
  assert_non_null(strstr(buf, "m.json: maps[1]: environment map 'nope.exr' not found"));
  assert_non_null(strstr(buf, "m.json: keyframes[0].weights[1]"));
  assert_non_null(strstr(buf, "m.json: keyframes[1].t: t = 0 is not after"));
  assert_non_null(strstr(buf, "m.json: keyframes[1].yaw: expected a number"));
  cv_drive *d;
  cv_err err;
  assert_int_not_equal(cv_drive_parse(many, "m.json", NULL, &d, &err), CV_OK);
  assert_non_null(strstr(err.msg, "[+4 more problems]"));
  /* A truncated listing stays NUL-terminated. */
  char small[40];
  assert_int_not_equal(cv_drive_validate_text(many, "m.json", NULL, small, sizeof small, &np),
                       CV_OK);
  assert_true(strlen(small) < sizeof small);
  assert_int_equal(cv_drive_validate_text(maps_json, "ok.json", NULL, buf, sizeof buf, &np),
                   CV_OK);
  assert_int_equal(np, 0);
  assert_int_equal(cv_drive_load("/nonexistent/drive.json", &d, &err), CV_ERR_IO);
  assert_non_null(strstr(err.msg, "/nonexistent/drive.json"));
}

/* A map next to the drive file wins over blender-data's of the same name. */
static void test_drive_relative_map(void **state) {
  (void)state;
  char map[1024], drive[1024];
  snprintf(map, sizeof map, "%s/forest.exr", CV_TEST_TMP_DIR);
  snprintf(drive, sizeof drive, "%s/drive_rel.json", CV_TEST_TMP_DIR);
  FILE *f = fopen(map, "w");
  assert_non_null(f);
  fputs("not really an exr: only its existence is checked at load\n", f);
  fclose(f);
  f = fopen(drive, "w");
  assert_non_null(f);
  fputs("{\"maps\": [\"forest.exr\", \"city.exr\"], \"keyframes\": [{\"t\": 0}]}", f);
  fclose(f);
  cv_drive *d;
  cv_err err;
  if (cv_drive_load(drive, &d, &err)) fail_msg("%s", err.msg);
  assert_string_equal(cv_drive_map_path(d, 0), map);
  assert_string_equal(cv_drive_map_path(d, 1), CAVE_BLENDER_WORLD_DIR "/city.exr");
  cv_drive_destroy(d);
  int np = -1;
  assert_int_equal(cv_drive_validate_all(drive, NULL, 0, &np), CV_OK);
  assert_int_equal(np, 0);
  remove(map);
  remove(drive);
}

static void test_shipped_drives(void **state) {
  (void)state;
  cv_drive *d;
  cv_err err;
  if (cv_drive_load(CV_SOURCE_DIR "/configs/drives/default.json", &d, &err))
    fail_msg("%s", err.msg);
  assert_true(cv_drive_loops(d) && !cv_drive_is_sky(d));
  assert_near(cv_drive_duration(d), 20, 1e-12);
  assert_true(cv_drive_n_maps(d) >= 3 && cv_drive_n_maps(d) <= 4);
  for (int i = 0; i < cv_drive_n_maps(d); i++)
    assert_non_null(strstr(cv_drive_map_path(d, i), CAVE_BLENDER_WORLD_DIR));
  cv_drive_state s;
  const double yaw_at[5] = {0, 90, 180, 270, 360};
  for (int k = 0; k < 4; k++) {
    cv_drive_eval(d, 5.0 * k, &s);
    assert_near(s.yaw_deg, yaw_at[k], 1e-9);
  }
  /* Seamless loop: just before 20 s the state is close to t = 0. */
  cv_drive_state a, b;
  cv_drive_eval(d, 19.999, &a);
  cv_drive_eval(d, 0, &b);
  assert_near(fmod(a.yaw_deg - b.yaw_deg + 540, 360), 180, 0.1);
  assert_near(a.weights[0], b.weights[0], 1e-3);
  cv_drive_destroy(d);

  if (cv_drive_load(CV_SOURCE_DIR "/configs/drives/sky.json", &d, &err)) fail_msg("%s", err.msg);
  assert_true(cv_drive_is_sky(d) && cv_drive_loops(d));
  double lo = 1e9, hi = -1e9;
  for (double t = 0; t < 20; t += 0.05) {
    cv_drive_eval(d, t, &s);
    lo = fmin(lo, s.sun_elevation_deg);
    hi = fmax(hi, s.sun_elevation_deg);
  }
  assert_near(lo, 10, 1e-9);
  assert_near(hi, 60, 1e-9);
  cv_drive_destroy(d);
}

int run_drive_tests(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_drive_parse_eval),   cmocka_unit_test(test_drive_loop_and_sky),
      cmocka_unit_test(test_drive_state_key),    cmocka_unit_test(test_drive_errors), cmocka_unit_test(test_drive_illuminance),
      cmocka_unit_test(test_drive_relative_map), cmocka_unit_test(test_shipped_drives),
  };
  return cmocka_run_group_tests_name("drive", tests, NULL, NULL);
}
