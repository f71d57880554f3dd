/* Resampling between image and patch resolution, and equation 7. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include <cmocka.h>

#include "compensate/resample.h"

static cv_image *ramp(int w, int h) {
  cv_image *img;
  cv_image_create(w, h, 3, &img);
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      float *p = cv_image_at(img, x, y);
      p[0] = (float)x / w;
      p[1] = (float)(h - 1 - y) / h; /* grows upwards: row 0 is the top */
      p[2] = 0.5f;
    }
  return img;
}

/* Down-sampling is an exact area mean (also for sizes that do not divide):
 * a constant stays constant, a ramp's patch means are the ramp at the patch
 * centres, and the bottom image row lands in patch row v = 0. */
static void test_downsample(void **state) {
  (void)state;
  cv_image *img = ramp(100, 60);
  const int nu = 7, nv = 5;
  double P[3 * 35];
  cv_downsample_to_patches(img, nu, nv, NULL, NULL, P);
  for (int v = 0; v < nv; v++)
    for (int u = 0; u < nu; u++) {
      const double *p = P + 3 * (v * nu + u);
      /* mean of x/w over the patch's pixel centres, ~ (u + 0.5)/nu - 0.5/w */
      assert_true(fabs(p[0] - ((u + 0.5) / nu - 0.5 / 100)) < 2e-3);
      assert_true(fabs(p[1] - ((v + 0.5) / nv - 0.5 / 60)) < 2e-3);
      assert_true(fabs(p[2] - 0.5) < 1e-12);
    }
  cv_image_destroy(img);
}

/* Bilinear up-sampling reproduces a linear function of the patch centres
 * away from the border half-patch, and constants everywhere. */
static void test_upsample_linear(void **state) {
  (void)state;
  const int nu = 8, nv = 6;
  double P[3 * 48];
  for (int v = 0; v < nv; v++)
    for (int u = 0; u < nu; u++) {
      P[3 * (v * nu + u)] = (u + 0.5) / nu;
      P[3 * (v * nu + u) + 1] = (v + 0.5) / nv;
      P[3 * (v * nu + u) + 2] = 0.25;
    }
  cv_image *out;
  cv_image_create(80, 60, 3, &out);
  cv_upsample_from_patches(P, nu, nv, NULL, NULL, out);
  for (int y = 5; y < 55; y++)
    for (int x = 5; x < 75; x++) {
      const float *p = cv_image_at(out, x, y);
      assert_true(fabs(p[0] - (x + 0.5) / 80) < 1e-5);
      assert_true(fabs(p[1] - ((60 - 1 - y) + 0.5) / 60) < 1e-5);
    }
  for (size_t i = 2; i < (size_t)80 * 60 * 3; i += 3) assert_true(fabs(out->px[i] - 0.25) < 1e-6);
  cv_image_destroy(out);
}

/* Equation 7: with I_P = down(I0) nothing changes; a uniform correction
 * delta on the patches shifts every pixel by delta; results are clamped to
 * [0, 1] and counted. */
static void test_equation7(void **state) {
  (void)state;
  cv_image *I0 = ramp(64, 48), *out;
  cv_image_create(64, 48, 3, &out);
  const int nu = 8, nv = 6;
  double P[3 * 48];
  cv_downsample_to_patches(I0, nu, nv, NULL, NULL, P);
  assert_int_equal(cv_apply_patch_correction(I0, P, nu, nv, NULL, NULL, out), 0);
  for (size_t i = 0; i < (size_t)64 * 48 * 3; i++) assert_true(fabs(out->px[i] - I0->px[i]) < 1e-6);
  for (int k = 0; k < 3 * 48; k++) P[k] -= 0.1; /* the solve lowered every patch by 0.1 */
  uint64_t clamped = cv_apply_patch_correction(I0, P, nu, nv, NULL, NULL, out);
  size_t expect = 0;
  for (size_t i = 0; i < (size_t)64 * 48 * 3; i++) {
    double want = I0->px[i] - 0.1;
    if (want < 0) {
      expect++;
      assert_true(out->px[i] == 0.0f);
    } else {
      assert_true(fabs(out->px[i] - want) < 1e-6);
    }
  }
  assert_int_equal(clamped, expect);
  assert_true(expect > 0);
  cv_image_destroy(I0);
  cv_image_destroy(out);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_downsample),
      cmocka_unit_test(test_upsample_linear),
      cmocka_unit_test(test_equation7),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
