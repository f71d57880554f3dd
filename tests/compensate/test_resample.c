/* Resampling between image and patch resolution, and equation 7. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>
#include "cv_test_near.h"

#include "compensate/resample.h"
#include "core/overlaps.h"

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
      assert_near(p[0], ((u + 0.5) / nu - 0.5 / 100), 2e-3);
      assert_near(p[1], ((v + 0.5) / nv - 0.5 / 60), 2e-3);
      assert_near(p[2], 0.5, 1e-12);
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
      assert_near(p[0], (x + 0.5) / 80, 1e-5);
      assert_near(p[1], ((60 - 1 - y) + 0.5) / 60, 1e-5);
    }
  for (size_t i = 2; i < (size_t)80 * 60 * 3; i += 3) assert_near(out->px[i], 0.25, 1e-6);
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
  for (size_t i = 0; i < (size_t)64 * 48 * 3; i++) assert_near(out->px[i], I0->px[i], 1e-6);
  for (int k = 0; k < 3 * 48; k++) P[k] -= 0.1; /* the solve lowered every patch by 0.1 */
  uint64_t clamped = cv_apply_patch_correction(I0, P, nu, nv, NULL, NULL, out);
  size_t expect = 0;
  for (size_t i = 0; i < (size_t)64 * 48 * 3; i++) {
    double want = I0->px[i] - 0.1;
    if (want < 0) {
      expect++;
      assert_true(out->px[i] == 0.0f);
    } else {
      assert_near(out->px[i], want, 1e-6);
    }
  }
  assert_int_equal(clamped, expect);
  assert_true(expect > 0);
  cv_image_destroy(I0);
  cv_image_destroy(out);
}

/* cv_apply_patch_delta (one pass, column interpolations per pair of patch
 * rows) is bit for bit the upsampling of cv_upsample_from_patches
 * subtracted and clamped per value, with the same clamp count: uneven
 * patch edges, sizes that do not divide, values above 1, below 0 and NaN,
 * in place too. */
static void test_apply_delta_exact(void **state) {
  (void)state;
  const int sizes[3][4] = {{97, 61, 7, 5}, {64, 48, 1, 1}, {33, 130, 24, 24}};
  for (int t = 0; t < 3; t++) {
    const int w = sizes[t][0], h = sizes[t][1], nu = sizes[t][2], nv = sizes[t][3];
    double eu[32], ev[32], *delta = malloc(3 * (size_t)nu * nv * sizeof *delta);
    eu[0] = ev[0] = 0;
    for (int k = 1; k <= nu; k++) eu[k] = eu[k - 1] + 1.0 + 0.37 * (k % 3);
    for (int k = 1; k <= nv; k++) ev[k] = ev[k - 1] + 1.0 + 0.21 * (k % 4);
    for (int k = 0; k <= nu; k++) eu[k] /= eu[nu];
    for (int k = 0; k <= nv; k++) ev[k] /= ev[nv];
    for (int k = 0; k < 3 * nu * nv; k++) delta[k] = 0.3 * sin(0.7 * k) - 0.05;
    cv_image *I0, *up, *out, *inplace;
    cv_image_create(w, h, 3, &I0);
    cv_image_create(w, h, 3, &up);
    cv_image_create(w, h, 3, &out);
    cv_image_create(w, h, 3, &inplace);
    for (size_t i = 0; i < 3 * (size_t)w * h; i++)
      I0->px[i] = i % 97 == 0 ? NAN : (float)(1.3 * fabs(sin(0.013 * (double)i)) - 0.1);
    assert_int_equal(cv_upsample_from_patches(delta, nu, nv, eu, ev, up), 0);
    uint64_t want_clamped = 0;
    for (size_t i = 0; i < 3 * (size_t)w * h; i++) {
      float v = I0->px[i] - up->px[i];
      if (!(v >= 0.0f)) v = 0.0f, want_clamped++;
      else if (v > 1.0f) v = 1.0f, want_clamped++;
      up->px[i] = v;
    }
    assert_int_equal(cv_apply_patch_delta(I0, delta, nu, nv, eu, ev, out), want_clamped);
    assert_memory_equal(out->px, up->px, 3 * (size_t)w * h * sizeof(float));
    memcpy(inplace->px, I0->px, 3 * (size_t)w * h * sizeof(float));
    assert_int_equal(cv_apply_patch_delta(inplace, delta, nu, nv, eu, ev, inplace), want_clamped);
    assert_memory_equal(inplace->px, up->px, 3 * (size_t)w * h * sizeof(float));
    assert_true(want_clamped > 0);
    cv_image_destroy(I0);
    cv_image_destroy(up);
    cv_image_destroy(out);
    cv_image_destroy(inplace);
    free(delta);
  }
}

/* The per-pixel loop cv_downsample_to_patches had (each pixel's overlaps,
 * in raster order): the reference its faster loop must equal bit for bit. */
static void downsample_reference(const cv_image *img, int nu, int nv, const double *U,
                                 const double *V, double *out) {
  cv_overlaps ox = {0}, oy = {0};
  assert_int_equal(cv_overlaps_make(U, nu, img->w, 1.0, 0, &ox), 0);
  assert_int_equal(cv_overlaps_make(V, nv, img->h, 1.0, 1, &oy), 0);
  double *wsum = calloc((size_t)nu * nv, sizeof *wsum);
  memset(out, 0, 3 * (size_t)nu * nv * sizeof *out);
  for (int y = 0; y < img->h; y++)
    for (int x = 0; x < img->w; x++) {
      const float *p = cv_image_at(img, x, y);
      for (int a = oy.first[y]; a < oy.first[y + 1]; a++)
        for (int b = ox.first[x]; b < ox.first[x + 1]; b++) {
          const double w = ox.len[b] * oy.len[a];
          const size_t k = (size_t)oy.cell[a] * nu + (size_t)ox.cell[b];
          for (int c = 0; c < 3; c++) out[3 * k + c] += w * p[c];
          wsum[k] += w;
        }
    }
  for (size_t k = 0; k < (size_t)nu * nv; k++)
    for (int c = 0; c < 3; c++) out[3 * k + c] = wsum[k] > 0 ? out[3 * k + c] / wsum[k] : 0.0;
  free(wsum);
  cv_overlaps_free(&ox), cv_overlaps_free(&oy);
}

static void test_downsample_exact(void **state) {
  (void)state;
  const int sizes[3][4] = {{97, 61, 7, 5}, {50, 40, 50, 40}, {33, 130, 24, 24}};
  for (int t = 0; t < 3; t++) {
    const int w = sizes[t][0], h = sizes[t][1], nu = sizes[t][2], nv = sizes[t][3];
    double eu[64], ev[64];
    eu[0] = ev[0] = 0;
    for (int k = 1; k <= nu; k++) eu[k] = eu[k - 1] + 1.0 + 0.37 * (k % 3);
    for (int k = 1; k <= nv; k++) ev[k] = ev[k - 1] + 1.0 + 0.21 * (k % 4);
    for (int k = 0; k <= nu; k++) eu[k] /= eu[nu];
    for (int k = 0; k <= nv; k++) ev[k] /= ev[nv];
    cv_image *img;
    cv_image_create(w, h, 3, &img);
    for (size_t i = 0; i < 3 * (size_t)w * h; i++) img->px[i] = (float)fabs(sin(0.013 * (double)i));
    double *got = malloc(3 * (size_t)nu * nv * sizeof *got), *want = malloc(3 * (size_t)nu * nv * sizeof *want);
    assert_int_equal(cv_downsample_to_patches(img, nu, nv, eu, ev, got), 0);
    downsample_reference(img, nu, nv, eu, ev, want);
    assert_memory_equal(got, want, 3 * (size_t)nu * nv * sizeof *got);
    free(got), free(want);
    cv_image_destroy(img);
  }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_downsample),
      cmocka_unit_test(test_upsample_linear),
      cmocka_unit_test(test_equation7),
      cmocka_unit_test(test_apply_delta_exact),
      cmocka_unit_test(test_downsample_exact),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
