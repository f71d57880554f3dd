/* A wall-eye's per-pixel CPU work in `cave run` after the read-back of its
 * display image (cluster/walleye.c): the compensation's patch means
 * (cv_downsample_to_patches, sent to the master), equation 7 with the
 * master's patch delta (cv_apply_patch_delta) and the 8-bit Rec.709 codes
 * the projector gets (cv_rec709_codes), one thread, wall ms per image (the
 * median of --reps), at the sizes given, on 24 x 24 patches (cave5.json's).
 * The results are bit-identical to the straightforward loops they replaced
 * (tests/compensate test_apply_delta_exact, test_downsample_exact;
 * tests/tonemap test_rec709_code_table), so the error column is 0 by test.
 *
 * usage: bench_post [--sizes 360,720,1440] [--reps 9] */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_cabin.h"
#include "bench_util.h"
#include "compensate/resample.h"
#include "tonemap/drago.h"

#define MAXR 64

int main(int argc, char **argv) {
  const char *sizes = "360,720,1440";
  int reps = 9;
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--sizes") && i + 1 < argc) sizes = argv[++i];
    else if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
    else {
      fprintf(stderr, "usage: bench_post [--sizes 360,720,1440] [--reps 9]\n");
      return strcmp(argv[i], "--help") ? 2 : 0;
    }
  }
  if (reps < 1 || reps > MAXR) {
    fprintf(stderr, "bench_post: --reps: expected 1..%d\n", MAXR);
    return 2;
  }
  const int P = 24;
  double eu[P + 1], ev[P + 1];
  for (int k = 0; k <= P; k++) eu[k] = ev[k] = (double)k / P;
  double patch[3 * P * P], delta[3 * P * P];
  for (int i = 0; i < 3 * P * P; i++) delta[i] = 0.02 * (i % 7) - 0.03;
  static cv_rec709_lut lut;
  cv_rec709_lut_init(&lut);
  printf("| size | patch means ms | equation 7 ms | 8-bit codes ms | sum ms |\n|---|---|---|---|---|\n");
  char buf[256];
  snprintf(buf, sizeof buf, "%s", sizes);
  for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
    const int S = atoi(tok);
    if (S < 8 || S > 8192) {
      fprintf(stderr, "bench_post: --sizes: %s is not in 8..8192\n", tok);
      return 2;
    }
    cv_image *a, *o;
    if (cv_image_create(S, S, 3, &a) || cv_image_create(S, S, 3, &o)) return 1;
    uint8_t *code = malloc(3 * (size_t)S * S);
    if (!code) return 1;
    /* display values k / 255, as read back from the 8-bit target */
    uint32_t x = 1;
    for (size_t i = 0; i < 3 * (size_t)S * S; i++) {
      x = x * 1664525u + 1013904223u;
      a->px[i] = (float)(x >> 24) / 255.0f;
    }
    double t[3][MAXR];
    for (int r = 0; r < reps; r++) {
      double t0 = bench_now_ms();
      cv_downsample_to_patches(a, P, P, eu, ev, patch);
      double t1 = bench_now_ms();
      cv_apply_patch_delta(a, delta, P, P, eu, ev, o);
      double t2 = bench_now_ms();
      cv_rec709_codes(&lut, o->px, 3 * (size_t)S * S, code);
      double t3 = bench_now_ms();
      t[0][r] = t1 - t0, t[1][r] = t2 - t1, t[2][r] = t3 - t2;
    }
    const double m0 = bench_median(t[0], reps), m1 = bench_median(t[1], reps), m2 = bench_median(t[2], reps);
    printf("| %d | %.2f | %.2f | %.2f | %.2f |\n", S, m0, m1, m2, m0 + m1 + m2);
    cv_image_destroy(a);
    cv_image_destroy(o);
    free(code);
  }
  return 0;
}
