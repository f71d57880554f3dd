/* Merges independent `cave reference` runs of the same view (different
 * --seed, each with --error) into one estimate with more samples:
 *
 *   ref_merge out.exr out_se.exr a.exr a_se.exr N_a b.exr b_se.exr N_b [...]
 *
 * N = each run's samples per pixel.  Per pixel and channel the merged mean is
 * the spp-weighted mean sum N_k m_k / sum N_k, and its standard error
 * sqrt(sum N_k^2 se_k^2) / sum N_k (independent runs).  Two 1024-spp runs give
 * what one 2048-spp run would, up to the seeds (docs/reference.md). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "io/exr.h"

static cv_image *load(const char *path) {
  cv_image *img = NULL;
  cv_err err;
  cv_err_clear(&err);
  if (cv_exr_read(path, &img, &err)) {
    fprintf(stderr, "ref_merge: %s\n", err.msg);
    exit(1);
  }
  return img;
}

int main(int argc, char **argv) {
  if (argc < 6 || (argc - 3) % 3) {
    fprintf(stderr, "usage: ref_merge out.exr out_se.exr a.exr a_se.exr N_a [b.exr b_se.exr N_b ...]\n");
    return 2;
  }
  const int runs = (argc - 3) / 3;
  cv_image *m = NULL, *s = NULL;
  double total = 0;
  for (int k = 0; k < runs; k++) {
    char *end;
    const double n = strtod(argv[5 + 3 * k], &end);
    if (*end || !(n >= 1)) {
      fprintf(stderr, "ref_merge: samples per pixel: expected a number >= 1, got '%s'\n",
              argv[5 + 3 * k]);
      return 2;
    }
    cv_image *a = load(argv[3 + 3 * k]), *e = load(argv[4 + 3 * k]);
    if (!m && (cv_image_create(a->w, a->h, 3, &m) || cv_image_create(a->w, a->h, 3, &s))) {
      fprintf(stderr, "ref_merge: out of memory\n");
      return 1;
    }
    if (a->w != m->w || a->h != m->h || e->w != m->w || e->h != m->h || a->c < 3 || e->c < 3) {
      fprintf(stderr, "ref_merge: %s or %s is not %d x %d RGB\n", argv[3 + 3 * k],
              argv[4 + 3 * k], m->w, m->h);
      return 1;
    }
    const size_t np = (size_t)m->w * m->h;
    for (size_t i = 0; i < np; i++)
      for (int c = 0; c < 3; c++) {
        const double x = a->px[(size_t)a->c * i + c], se = e->px[(size_t)e->c * i + c];
        m->px[3 * i + c] += (float)(n * x);
        s->px[3 * i + c] += (float)(n * n * se * se);
      }
    total += n;
    cv_image_destroy(a);
    cv_image_destroy(e);
  }
  const size_t np = 3 * (size_t)m->w * m->h;
  for (size_t i = 0; i < np; i++) {
    m->px[i] = (float)(m->px[i] / total);
    s->px[i] = (float)(sqrt(s->px[i]) / total);
  }
  cv_err err;
  cv_err_clear(&err);
  if (cv_exr_write(argv[1], m, 0, CV_EXR_ZIP, &err) || cv_exr_write(argv[2], s, 0, CV_EXR_ZIP, &err)) {
    fprintf(stderr, "ref_merge: %s\n", err.msg);
    return 1;
  }
  printf("merged %d runs, %.0f samples per pixel\n", runs, total);
  cv_image_destroy(m);
  cv_image_destroy(s);
  return 0;
}
