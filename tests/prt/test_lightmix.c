/* The per-frame light mixer (prt/lightmix.h) against the reference path
 * cv_scene_light_build: one map gives the same SH, sun and background; a
 * blend keeps the total energy of blending the maps first; bad weights are
 * refused. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>
#include "cv_test_near.h"

#include "light/envmap.h"
#include "prt/lightmix.h"
#include "prt/scene_light.h"

#define MAP(name) CAVE_BLENDER_WORLD_DIR "/" name

static cv_scene_light *reference(const char *const *maps, const double *w, int n, double yaw,
                                 double pitch, double roll) {
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  spec.kind = CV_LIGHT_ENV;
  spec.n_env = n;
  for (int i = 0; i < n; i++) {
    snprintf(spec.env[i], sizeof spec.env[i], "%s", maps[i]);
    spec.weight[i] = w[i];
  }
  spec.yaw_deg = yaw;
  spec.pitch_deg = pitch;
  spec.roll_deg = roll;
  cv_scene_light *sl;
  cv_err err;
  if (cv_scene_light_build(&spec, 5, &sl, &err)) fail_msg("%s", err.msg);
  return sl;
}

static void test_one_map(void **state) {
  (void)state;
  const char *maps[1] = {MAP("sunrise.exr")};
  const double w[1] = {1};
  cv_lightmix *m;
  cv_err err;
  assert_int_equal(cv_lightmix_create(maps, 1, 1.0, 5, &m, &err), CV_OK);
  cv_scene_light *sl = reference(maps, w, 1, 37, 5, -3);
  cv_lighting a, b = cv_scene_light_sh(sl);
  assert_int_equal(cv_lightmix_lighting(m, w, 37, 5, -3, &a), CV_OK);
  double worst = 0, scale = fabs(b.sh[0]);
  for (int k = 0; k < 3 * 25; k++) worst = fmax(worst, fabs(a.sh[k] - b.sh[k]));
  printf("  sunrise, yaw 37: largest SH difference %.3g (DC %.4g); sun %d / %d\n", worst, scale,
         a.has_sun, b.has_sun);
  assert_true(worst <= 1e-9 * scale);
  assert_int_equal(a.has_sun, b.has_sun);
  if (a.has_sun)
    for (int i = 0; i < 3; i++) {
      assert_near(a.sun_dir[i], b.sun_dir[i], 1e-12);
      assert_near(a.sun_E[i], b.sun_E[i], 1e-12 * fabs(b.sun_E[i]) + 1e-15);
    }
  /* Background: the same lookup at every texel centre. */
  cv_image *bg;
  assert_int_equal(cv_lightmix_background(m, w, 37, 5, -3, 64, &bg), CV_OK);
  double bw = 0;
  for (int y = 0; y < 32; y++)
    for (int x = 0; x < 64; x++) {
      const double th = M_PI * (y + 0.5) / 32, ph = 2 * M_PI * ((x + 0.5) / 64 - 0.5);
      const float d[3] = {(float)(sin(th) * sin(ph)), (float)cos(th), (float)(-sin(th) * cos(ph))};
      float r[3];
      cv_scene_light_background(sl, d, r);
      for (int c = 0; c < 3; c++)
        bw = fmax(bw, fabs(cv_image_at(bg, x, y)[c] - r[c]) / (fabs(r[c]) + 1e-6));
    }
  printf("  background: largest relative difference %.3g\n", bw);
  assert_true(bw < 1e-4);
  cv_image_destroy(bg);
  cv_scene_light_destroy(sl);
  cv_lightmix_destroy(m);
}

/* Energy of a lighting: integral of the SH (DC) plus the sun's luminance. */
static double energy(const cv_lighting *l) {
  double e = 0;
  for (int c = 0; c < 3; c++) e += (c == 0 ? 0.2126 : c == 1 ? 0.7152 : 0.0722) * l->sh[c];
  e *= sqrt(4 * M_PI);
  if (l->has_sun) e += 0.2126 * l->sun_E[0] + 0.7152 * l->sun_E[1] + 0.0722 * l->sun_E[2];
  return e;
}

static void test_blend(void **state) {
  (void)state;
  const char *maps[2] = {MAP("forest.exr"), MAP("sunset.exr")};
  const double w[2] = {0.3, 0.7};
  cv_lightmix *m;
  cv_err err;
  assert_int_equal(cv_lightmix_create(maps, 2, 1.0, 5, &m, &err), CV_OK);
  cv_scene_light *sl = reference(maps, w, 2, 120, 0, 0);
  cv_lighting a, b = cv_scene_light_sh(sl);
  assert_int_equal(cv_lightmix_lighting(m, w, 120, 0, 0, &a), CV_OK);
  const double ea = energy(&a), eb = energy(&b);
  printf("  forest 0.3 + sunset 0.7, yaw 120: energy %.5g (mixer) vs %.5g (blend first): %+.3f%%\n",
         ea, eb, 100 * (ea - eb) / eb);
  assert_near(ea, eb, 0.02 * eb);
  /* Weights are normalised: (3, 7) is the same as (0.3, 0.7). */
  cv_lighting c;
  const double w2[2] = {3, 7};
  assert_int_equal(cv_lightmix_lighting(m, w2, 120, 0, 0, &c), CV_OK);
  for (int k = 0; k < 75; k++) assert_near(c.sh[k], a.sh[k], 1e-12 * fabs(a.sh[0]));
  const double bad1[2] = {-1, 2}, bad2[2] = {0, 0}, bad3[2] = {NAN, 1};
  assert_int_equal(cv_lightmix_lighting(m, bad1, 0, 0, 0, &c), CV_ERR_INVALID);
  assert_int_equal(cv_lightmix_lighting(m, bad2, 0, 0, 0, &c), CV_ERR_INVALID);
  assert_int_equal(cv_lightmix_lighting(m, bad3, 0, 0, 0, &c), CV_ERR_INVALID);
  const char *missing[1] = {"no-such-map.exr"};
  cv_lightmix *mm;
  assert_int_not_equal(cv_lightmix_create(missing, 1, 1.0, 5, &mm, &err), CV_OK);
  printf("  missing map: %s\n", err.msg);
  assert_non_null(strstr(err.msg, "no-such-map.exr"));
  cv_scene_light_destroy(sl);
  cv_lightmix_destroy(m);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_one_map),
      cmocka_unit_test(test_blend),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
