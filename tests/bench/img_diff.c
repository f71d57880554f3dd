/* Pixel-by-pixel difference of two renders of the same view (e.g. the same
 * `cave render` on a GPU's EGL device and on llvmpipe, docs/benchmarks.md),
 * on Rec.709 luminance:
 *
 *   img_diff a.exr|a.png b.exr|b.png [floor]
 *
 * EXR: linear radiance; PNG: 8-bit codes (then also the largest code
 * difference of any channel and the fraction of pixels with one > 1).
 * Pixels where both luminances are <= floor (default 1e-6 of the larger
 * image's peak) are left out.  Per pixel e = |Y_a - Y_b| / max(Y_a, Y_b).
 * Prints: pixels compared, median, p99, p99.9 and max of e, the fractions of
 * pixels with e > 1% and > 5%, the ratio of the luminance sums (a / b), and
 * NaN/Inf pixels of each image (left out, counted).  Exit 1 on bad input. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "bench_util.h"
#include <string.h>
#include <strings.h>

#include "io/exr.h"
#include "io/png.h"

static double lum(const float *p) { return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]; }

static int is_png(const char *p) {
  const size_t n = strlen(p);
  return n > 4 && !strcasecmp(p + n - 4, ".png");
}

static int read_any(const char *p, cv_image **out, cv_err *err) {
  return is_png(p) ? cv_png_read(p, out, err) : cv_exr_read(p, out, err);
}

static double quant(const double *v, size_t n, double q) {
  return n ? v[(size_t)(q * (double)(n - 1) + 0.5)] : NAN;
}

int main(int argc, char **argv) {
  if (argc < 3 || argc > 4) {
    fprintf(stderr, "usage: img_diff a.exr|a.png b.exr|b.png [floor]\n");
    return 1;
  }
  cv_image *a, *b;
  cv_err err;
  if (read_any(argv[1], &a, &err) || read_any(argv[2], &b, &err)) {
    fprintf(stderr, "img_diff: %s\n", err.msg);
    return 1;
  }
  if (a->w != b->w || a->h != b->h || a->c < 3 || b->c < 3) {
    fprintf(stderr, "img_diff: %s is %dx%dx%d, %s is %dx%dx%d: expected the same size, RGB\n",
            argv[1], a->w, a->h, a->c, argv[2], b->w, b->h, b->c);
    return 1;
  }
  const size_t n = (size_t)a->w * a->h;
  double peak = 0, sa = 0, sb = 0;
  size_t bad_a = 0, bad_b = 0;
  for (size_t i = 0; i < n; i++) {
    const double ya = lum(a->px + i * a->c), yb = lum(b->px + i * b->c);
    if (isfinite(ya) && ya > peak) peak = ya;
    if (isfinite(yb) && yb > peak) peak = yb;
  }
  const double floor_y = argc > 3 ? atof(argv[3]) : 1e-6 * peak;
  double *e = malloc(n * sizeof *e);
  if (!e) return 1;
  size_t m = 0, over1 = 0, over5 = 0;
  for (size_t i = 0; i < n; i++) {
    const double ya = lum(a->px + i * a->c), yb = lum(b->px + i * b->c);
    if (!isfinite(ya) || !isfinite(yb)) {
      bad_a += !isfinite(ya), bad_b += !isfinite(yb);
      continue;
    }
    if (ya <= floor_y && yb <= floor_y) continue;
    const double d = fabs(ya - yb) / fmax(ya, yb);
    e[m++] = d;
    over1 += d > 0.01, over5 += d > 0.05;
    sa += ya, sb += yb;
  }
  qsort(e, m, sizeof *e, bench_cmp_double);
  printf("%s vs %s: %dx%d, %zu pixels compared (floor %.3g); relative luminance difference median "
         "%.3g, p99 %.3g, p99.9 %.3g, max %.3g; %.4f%% of pixels > 1%%, %.4f%% > 5%%; sum ratio %.6f; "
         "non-finite pixels %zu / %zu\n",
         argv[1], argv[2], a->w, a->h, m, floor_y, quant(e, m, 0.5), quant(e, m, 0.99),
         quant(e, m, 0.999), m ? e[m - 1] : NAN, m ? 100.0 * over1 / m : 0, m ? 100.0 * over5 / m : 0,
         sb > 0 ? sa / sb : NAN, bad_a, bad_b);
  if (is_png(argv[1]) && is_png(argv[2])) {
    int maxd = 0;
    size_t over = 0;
    for (size_t i = 0; i < n; i++) {
      int pd = 0;
      for (int k = 0; k < 3; k++) {
        const int d = abs((int)lrintf(255 * a->px[i * a->c + k]) - (int)lrintf(255 * b->px[i * b->c + k]));
        if (d > pd) pd = d;
      }
      if (pd > maxd) maxd = pd;
      over += pd > 1;
    }
    printf("8-bit codes: largest difference %d; %.4f%% of pixels differ by more than 1 code\n", maxd,
           100.0 * over / n);
  }
  free(e);
  cv_image_destroy(a);
  cv_image_destroy(b);
  return 0;
}
