/* Image-space error of a `cave shade --view` image against a `cave reference`
 * image of the same view (docs/reference.md, docs/benchmarks.md).
 *
 *   ref_compare shade.exr ref.exr ref_se.exr ids.exr [ID[,ID...] ...]
 *
 * Compared pixels: those whose camera ray hits geometry (ids.exr from
 * `cave reference --ids` holds material index + 1, 0 for none) and whose reference luminance is > 0;
 * pixels that see the environment through a window are the same in both
 * renderers and are left out.  Per pixel, e = |Y_shade - Y_ref| / Y_ref on
 * Rec.709 luminance.  Prints one line for all compared pixels and one per
 * extra argument (a comma-separated set of material ids: a region):
 *   region pixels mean_ratio median_err p90_err noise_median
 * mean_ratio = sum Y_shade / sum Y_ref over the region; noise_median =
 * median of se(Y_ref)/Y_ref (the reference's own noise floor, luminance se
 * taken as the channel-weighted sum of channel se, an upper bound). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/exr.h"

static double lum(const float *p) { return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]; }

static int cmp(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

static double quant(double *v, size_t n, double q) {
  if (!n) return NAN;
  qsort(v, n, sizeof *v, cmp);
  return v[(size_t)(q * (double)(n - 1) + 0.5)];
}

static int in_set(const char *set, int id) {
  if (!set) return id >= 0;
  char buf[512];
  snprintf(buf, sizeof buf, "%s", set);
  for (char *save = NULL, *t = strtok_r(buf, ",", &save); t; t = strtok_r(NULL, ",", &save))
    if (atoi(t) == id) return 1;
  return 0;
}

static void report(const char *name, const char *set, const cv_image *a, const cv_image *r,
                   const cv_image *se, const cv_image *ids) {
  size_t np = (size_t)a->w * a->h, n = 0;
  double *e = malloc(np * sizeof *e), *nz = malloc(np * sizeof *nz), sa = 0, sr = 0;
  if (!e || !nz) {
    fprintf(stderr, "ref_compare: out of memory\n");
    exit(1);
  }
  for (size_t i = 0; i < np; i++) {
    int id = (int)lrintf(ids->px[(size_t)ids->c * i]) - 1;
    if (!in_set(set, id)) continue;
    double ya = lum(a->px + 3 * i), yr = lum(r->px + 3 * i);
    if (!(yr > 0)) continue;
    sa += ya;
    sr += yr;
    e[n] = fabs(ya - yr) / yr;
    nz[n] = lum(se->px + 3 * i) / yr;
    n++;
  }
  printf("%-12s %7zu %10.4f %10.4f %10.4f %12.4f\n", name, n, sr > 0 ? sa / sr : NAN,
         quant(e, n, 0.5), quant(e, n, 0.9), quant(nz, n, 0.5));
  free(e);
  free(nz);
}

int main(int argc, char **argv) {
  if (argc < 5) {
    fprintf(stderr, "usage: ref_compare shade.exr ref.exr ref_se.exr ids.exr [ID[,ID...] ...]\n");
    return 2;
  }
  cv_image *img[4] = {0};
  cv_err err;
  for (int k = 0; k < 4; k++)
    if (cv_exr_read(argv[1 + k], &img[k], &err)) {
      fprintf(stderr, "ref_compare: %s\n", err.msg);
      return 1;
    }
  for (int k = 1; k < 4; k++)
    if (img[k]->w != img[0]->w || img[k]->h != img[0]->h || (k < 3 && img[k]->c != 3)) {
      fprintf(stderr, "ref_compare: %s is %dx%dx%d, expected %dx%d (RGB)\n", argv[1 + k],
              img[k]->w, img[k]->h, img[k]->c, img[0]->w, img[0]->h);
      return 1;
    }
  if (img[0]->c != 3) {
    fprintf(stderr, "ref_compare: %s has %d channels, expected RGB\n", argv[1], img[0]->c);
    return 1;
  }
  printf("%-12s %7s %10s %10s %10s %12s\n", "region", "pixels", "mean_ratio", "median_err",
         "p90_err", "noise_median");
  report("all", NULL, img[0], img[1], img[2], img[3]);
  for (int k = 5; k < argc; k++) {
    char name[32];
    snprintf(name, sizeof name, "ids:%s", argv[k]);
    report(name, argv[k], img[0], img[1], img[2], img[3]);
  }
  for (int k = 0; k < 4; k++) cv_image_destroy(img[k]);
  return 0;
}
