/* Tests of the frame on the GPU (src/render/render_post.c, issue 29) on
 * whatever EGL gives (llvmpipe in CI; a failure to start EGL fails):
 *  - patch means reduced on the GPU equal cv_downsample_to_patches of the
 *    read-back display image within 1e-6 relative, on a non-uniform grid
 *    whose edges cut pixels, with and without 2x supersampling;
 *  - the projector codes of the GPU post pass (equation 7, clamp, Rec.709)
 *    equal the CPU path's (cv_apply_patch_delta + cv_rec709_codes) within 1
 *    code on every pixel, with a delta that makes pixels clip at 0 and at
 *    1, seams between patches, and both eyes (slot 0 kept while slot 1 is
 *    shaded);
 *  - without a delta the codes are the clamped display image's;
 *  - a frame that writes nothing reads back only the luminance image, its
 *    blocks and the patch means (the read-back counter);
 *  - argument errors. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "compensate/resample.h"
#include "mesh/cabin.h"
#include "prt/bake.h"
#include "render/renderer.h"
#include "tonemap/drago.h"

static struct {
  cv_prt *prt;
  cv_cabin_info info;
  cv_renderer *r;
  cv_rec709_lut lut;
} F;

#define OK(call)                                            \
  do {                                                      \
    int st_ = (call);                                       \
    if (st_) printf("%s -> %d: %s\n", #call, st_, err.msg); \
    assert_int_equal(st_, CV_OK);                           \
  } while (0)

static int setup(void **state) {
  (void)state;
  cv_cabin_params cp;
  cv_cabin_default_params(&cp);
  cp.tess = 1;
  cv_mesh *m = NULL;
  cv_err err;
  if (cv_cabin_generate_ex(&cp, &m, &F.info, &err)) return -1;
  cv_bake_params bp = {.bands = 3, .rays = 16, .bounces = 1, .seed = 5,
                       .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  if (cv_prt_bake(m, &bp, &F.prt, NULL, &err)) return -1;
  cv_mesh_destroy(m);
  cv_render_opts o;
  cv_render_default_opts(&o);
  o.display_float = 1;
  if (cv_renderer_create(F.prt, &o, &F.r, &err)) {
    fprintf(stderr, "cannot start the renderer: %s\n", err.msg);
    return -1;
  }
  char why[200];
  if (!cv_renderer_post_available(F.r, why, sizeof why)) {
    fprintf(stderr, "GPU post pass not available: %s\n", why);
    return -1;
  }
  printf("GL: %s\n", cv_renderer_gl_name(F.r));
  cv_rec709_lut_init(&F.lut);
  /* bright, coloured lighting with a background: Drago's top is reached */
  cv_lighting l;
  memset(&l, 0, sizeof l);
  l.bands = 3;
  for (int c = 0; c < 3; c++) {
    l.sh[c] = (3.0 + c) * sqrt(4 * M_PI);
    l.sh[3 + c] = 2.0 - 0.5 * c;
    l.sh[6 + c] = -1.0;
  }
  if (cv_renderer_set_lighting(F.r, &l, NULL, NULL, &err)) return -1;
  cv_image *bg;
  if (cv_image_create(8, 4, 3, &bg)) return -1;
  for (int i = 0; i < 32; i++)
    for (int c = 0; c < 3; c++) bg->px[3 * i + c] = 40.0f * (1 + c);
  int st = cv_renderer_set_background(F.r, bg, &err);
  cv_image_destroy(bg);
  return st;
}

static int teardown(void **state) {
  (void)state;
  cv_renderer_destroy(F.r);
  cv_prt_destroy(F.prt);
  return 0;
}

/* An off-axis wall ahead of the driver (k = 0) or to the left (k = 1). */
static cv_render_view view(int k, int w, int h, int ss) {
  const float *e = F.info.eye;
  double pa[3], pb[3], pc[3], eye[3];
  const double d[2][3][3] = {{{-0.8, -0.6, -1}, {0.8, -0.6, -1}, {-0.8, 0.6, -1}},
                             {{-1, -0.6, 0.5}, {-1, -0.6, -1}, {-1, 0.6, 0.5}}};
  for (int j = 0; j < 3; j++) {
    pa[j] = e[j] + d[k][0][j], pb[j] = e[j] + d[k][1][j], pc[j] = e[j] + d[k][2][j];
    eye[j] = e[j] + (k ? 0.03 : 0.0);
  }
  cv_render_view v;
  memset(&v, 0, sizeof v);
  assert_int_equal(cv_offaxis_compute(pa, pb, pc, eye, 0.02, 20, &v.proj), CV_OK);
  v.w = w, v.h = h, v.supersample = ss;
  return v;
}

static cv_drago_consts drago(double lwa) {
  cv_drago d;
  cv_drago_default(&d);
  d.lwa = lwa;
  d.lwmax = 50 * lwa;
  cv_drago_consts dc;
  cv_drago_prepare(&d, &dc);
  return dc;
}

/* Grid: non-uniform edges that do not fall on pixel boundaries. */
enum { NU = 7, NV = 5 };
static const double EU[NU + 1] = {0, 0.09, 0.21, 0.4, 0.55, 0.71, 0.87, 1};
static const double EV[NV + 1] = {0, 0.13, 0.37, 0.5, 0.81, 1};

/* GPU patch means against the CPU's of the read-back display image. */
static void check_means(const cv_image *disp) {
  cv_err err;
  double gpu[3 * NU * NV], cpu[3 * NU * NV];
  OK(cv_renderer_patch_means(F.r, gpu, &err));
  assert_int_equal(cv_downsample_to_patches(disp, NU, NV, EU, EV, cpu), 0);
  double worst = 0, lo = 1e9, hi = 0;
  for (int i = 0; i < 3 * NU * NV; i++) {
    worst = fmax(worst, fabs(gpu[i] - cpu[i]) / fmax(fabs(cpu[i]), 1e-12));
    lo = fmin(lo, cpu[i]), hi = fmax(hi, cpu[i]);
  }
  printf("patch means %dx%d of %dx%d: GPU vs CPU max relative difference %.2e (means %.3g..%.3g)\n", NU, NV,
         disp->w, disp->h, worst, lo, hi);
  assert_true(worst <= 1e-6);
  assert_true(hi > lo); /* not a flat image */
}

/* A delta that clips: large positive (I < 0) and negative (I > 1) patches. */
static void make_delta(float *d, double scale) {
  for (int i = 0; i < NU * NV; i++)
    for (int c = 0; c < 3; c++) d[3 * i + c] = (float)(scale * sin(1.7 * i + c));
}

/* Slot's codes against the CPU path's on disp with delta (NULL: none). */
static void check_codes(int slot, const cv_image *disp, const float *delta, const char *what) {
  cv_err err;
  const int w = disp->w, h = disp->h;
  const size_t n = 3 * (size_t)w * h;
  uint8_t *gpu = malloc(n), *cpu = malloc(n);
  cv_image *out;
  assert_int_equal(cv_image_create(w, h, 3, &out), CV_OK);
  uint64_t clamped = 0;
  if (delta) {
    double dd[3 * NU * NV];
    for (int i = 0; i < 3 * NU * NV; i++) dd[i] = delta[i];
    clamped = cv_apply_patch_delta(disp, dd, NU, NV, EU, EV, out);
  } else {
    memcpy(out->px, disp->px, n * sizeof(float));
  }
  cv_rec709_codes(&F.lut, out->px, n, cpu);
  OK(cv_renderer_post_read(F.r, slot, gpu, &err));
  int worst = 0;
  size_t equal = 0, zero = 0, full = 0;
  for (size_t i = 0; i < n; i++) {
    const int d = abs((int)gpu[i] - (int)cpu[i]);
    worst = d > worst ? d : worst;
    equal += d == 0;
    zero += cpu[i] == 0;
    full += cpu[i] == 255;
  }
  printf("%s: slot %d, %dx%d: codes differ by at most %d, %.4f%% equal; %llu values clamped by eq. 7, "
         "%zu at 0, %zu at 255\n", what, slot, w, h, worst, 100.0 * equal / n, (unsigned long long)clamped,
         zero, full);
  assert_true(worst <= 1);
  if (delta) assert_true(clamped > 0 && zero > 0 && full > 0); /* the image clips at both ends */
  cv_image_destroy(out);
  free(gpu);
  free(cpu);
}

static void test_means_and_codes(void **state) {
  (void)state;
  cv_err err;
  const int w = 203, h = 151;
  OK(cv_renderer_post_grid(F.r, NU, NV, EU, EV, w, h, &err));
  cv_image *d0, *d1, *lum;
  assert_int_equal(cv_image_create(w, h, 3, &d0), CV_OK);
  assert_int_equal(cv_image_create(w, h, 3, &d1), CV_OK);
  assert_int_equal(cv_image_create(32, 24, 1, &lum), CV_OK);
  float delta[3 * NU * NV];
  make_delta(delta, 0.6);
  const cv_drago_consts dc = drago(3.0);
  /* eye 0: shaded, measured, kept; eye 1 shaded over it; both posted */
  cv_render_view v0 = view(0, w, h, 1), v1 = view(1, w, h, 1);
  OK(cv_renderer_shade_gpu(F.r, &v0, &dc, NULL, lum, NULL, NULL, NULL, &err));
  OK(cv_renderer_display_read(F.r, d0, &err));
  check_means(d0);
  OK(cv_renderer_display_keep(F.r, 0, &err));
  OK(cv_renderer_shade_gpu(F.r, &v1, &dc, NULL, lum, NULL, NULL, NULL, &err));
  OK(cv_renderer_display_read(F.r, d1, &err));
  check_means(d1);
  OK(cv_renderer_post(F.r, 1, 0, delta, &err));
  OK(cv_renderer_post(F.r, 0, 1, delta, &err));
  check_codes(0, d0, delta, "eye 0 (kept)");
  check_codes(1, d1, delta, "eye 1");
  /* without a correction: the display image clamped and encoded */
  OK(cv_renderer_post(F.r, 1, 0, NULL, &err));
  check_codes(1, d1, NULL, "no delta");
  /* 2x supersampled: the resolved image */
  cv_render_view v2 = view(0, w, h, 2);
  OK(cv_renderer_shade_gpu(F.r, &v2, &dc, NULL, lum, NULL, NULL, NULL, &err));
  OK(cv_renderer_display_read(F.r, d0, &err));
  check_means(d0);
  OK(cv_renderer_post(F.r, 0, 0, delta, &err));
  check_codes(0, d0, delta, "2x supersampled");
  cv_image_destroy(d0);
  cv_image_destroy(d1);
  cv_image_destroy(lum);
}

/* A frame that writes nothing: the luminance image (4 bytes a pixel), its
 * blocks (8 bytes per 8 x 8) and the patch means (24 bytes a patch) come
 * back, nothing else; the delta (12 bytes a patch) goes up. */
static void test_readback_bytes(void **state) {
  (void)state;
  cv_err err;
  const int w = 360, h = 360;
  OK(cv_renderer_post_grid(F.r, NU, NV, EU, EV, w, h, &err));
  cv_image *lum;
  assert_int_equal(cv_image_create(128, 128, 1, &lum), CV_OK);
  float delta[3 * NU * NV];
  make_delta(delta, 0.1);
  const cv_drago_consts dc = drago(3.0);
  cv_render_view v = view(0, w, h, 1);
  double means[3 * NU * NV], mx = 0;
  uint64_t bad = 1, r0, u0, r1, u1;
  OK(cv_renderer_shade_gpu(F.r, &v, &dc, NULL, lum, &mx, &bad, NULL, &err)); /* tables built */
  cv_renderer_io(F.r, &r0, &u0);
  OK(cv_renderer_shade_gpu(F.r, &v, &dc, NULL, lum, &mx, &bad, NULL, &err));
  OK(cv_renderer_patch_means(F.r, means, &err));
  OK(cv_renderer_post(F.r, 0, 0, delta, &err));
  cv_renderer_io(F.r, &r1, &u1);
  const uint64_t want = 128 * 128 * 4 + 16 * 16 * 8 + NU * NV * 24;
  printf("a 360^2 frame that writes nothing: %llu bytes read back (want %llu), %llu uploaded\n",
         (unsigned long long)(r1 - r0), (unsigned long long)want, (unsigned long long)(u1 - u0));
  assert_int_equal(r1 - r0, want);
  assert_true(r1 - r0 < 100000);
  assert_int_equal(u1 - u0, NU * NV * 12);
  assert_true(mx > 0 && bad == 0);
  /* a written frame reads the codes back too */
  uint8_t *codes = malloc(3 * (size_t)w * h);
  OK(cv_renderer_post_read(F.r, 0, codes, &err));
  uint64_t r2;
  cv_renderer_io(F.r, &r2, NULL);
  assert_int_equal(r2 - r1, 4 * (uint64_t)w * h);
  free(codes);
  cv_image_destroy(lum);
}

static void test_errors(void **state) {
  (void)state;
  cv_err err;
  double m[3];
  assert_int_equal(cv_renderer_post_grid(F.r, 0, 3, NULL, NULL, 10, 10, &err), CV_ERR_INVALID);
  assert_int_equal(cv_renderer_post_grid(F.r, 11, 3, NULL, NULL, 10, 10, &err), CV_ERR_INVALID);
  assert_non_null(strstr(err.msg, "patches"));
  OK(cv_renderer_post_grid(F.r, 1, 1, NULL, NULL, 12, 10, &err));
  /* the last display image is another size: refused, named */
  assert_int_equal(cv_renderer_patch_means(F.r, m, &err), CV_ERR_INVALID);
  assert_non_null(strstr(err.msg, "12x10"));
  assert_int_equal(cv_renderer_post(F.r, 2, 0, NULL, &err), CV_ERR_INVALID);
  assert_int_equal(cv_renderer_post(F.r, 1, 1, NULL, &err), CV_ERR_INVALID); /* nothing kept */
  /* a renderer without float display targets cannot keep the display */
  cv_renderer *r;
  OK(cv_renderer_create(F.prt, NULL, &r, &err));
  cv_lighting l = {.bands = 3};
  l.sh[0] = l.sh[1] = l.sh[2] = 1;
  OK(cv_renderer_set_lighting(r, &l, NULL, NULL, &err));
  cv_render_view v = view(0, 12, 10, 1);
  const cv_drago_consts dc = drago(1.0);
  assert_int_equal(cv_renderer_shade_gpu(r, &v, &dc, NULL, NULL, NULL, NULL, NULL, &err), CV_ERR_INVALID);
  assert_non_null(strstr(err.msg, "display_float"));
  assert_true(isnan(cv_renderer_gpu_timer_result(r))); /* no query ran */
  cv_renderer_gpu_timer_begin(r);
  cv_renderer_gpu_timer_end(r);
  assert_true(cv_renderer_gpu_timer_result(r) >= 0);
  cv_renderer_destroy(r);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_means_and_codes),
      cmocka_unit_test(test_readback_bytes),
      cmocka_unit_test(test_errors),
  };
  return cmocka_run_group_tests(tests, setup, teardown);
}
