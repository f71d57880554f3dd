/* Writes the EXR inputs of the CLI tests into a folder: a small valid
 * lat-long map, the same map with one NaN pixel, and a truncated copy. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/exr.h"

int main(int argc, char **argv) {
  if (argc != 2) {
    fprintf(stderr, "usage: make_test_inputs DIR\n");
    return 2;
  }
  char path[1024];
  cv_image *img;
  if (cv_image_create(64, 32, 3, &img)) return 1;
  for (int y = 0; y < 32; y++)
    for (int x = 0; x < 64; x++)
      for (int c = 0; c < 3; c++) cv_image_at(img, x, y)[c] = 0.5f + 0.5f * (32 - y) / 32.0f;
  cv_err err;
  snprintf(path, sizeof path, "%s/good.exr", argv[1]);
  if (cv_exr_write(path, img, 1, CV_EXR_ZIP, &err)) goto fail;
  /* The writer refuses NaN, so write a sentinel into an uncompressed float
   * file and patch its bytes to a quiet NaN afterwards. */
  const float sentinel = 12345.678f;
  cv_image_at(img, 10, 5)[1] = sentinel;
  snprintf(path, sizeof path, "%s/nan.exr", argv[1]);
  if (cv_exr_write(path, img, 0, CV_EXR_NONE, &err)) goto fail;
  cv_image_destroy(img);
  {
    FILE *g = fopen(path, "r+b");
    if (!g) return 1;
    unsigned char b[65536];
    size_t n = fread(b, 1, sizeof b, g), hits = 0;
    const float qnan = NAN;
    for (size_t i = 0; i + 4 <= n; i++)
      if (memcmp(b + i, &sentinel, 4) == 0) {
        memcpy(b + i, &qnan, 4);
        hits++;
      }
    if (hits != 1) {
      fprintf(stderr, "make_test_inputs: sentinel found %zu times\n", hits);
      return 1;
    }
    fseek(g, 0, SEEK_SET);
    fwrite(b, 1, n, g);
    fclose(g);
  }
  /* Compensation inputs: a white wall, and white with a black band along the
   * left edge (next to a corner when it is the right wall of an L). */
  {
    cv_image *w;
    if (cv_image_create(96, 64, 3, &w)) return 1;
    for (size_t i = 0; i < (size_t)96 * 64 * 3; i++) w->px[i] = 1.0f;
    snprintf(path, sizeof path, "%s/white.exr", argv[1]);
    if (cv_exr_write(path, w, 1, CV_EXR_ZIP, &err)) goto fail;
    for (int y = 0; y < 64; y++)
      for (int x = 0; x < 12; x++) cv_image_at(w, x, y)[0] = cv_image_at(w, x, y)[1] = cv_image_at(w, x, y)[2] = 0.0f;
    snprintf(path, sizeof path, "%s/band.exr", argv[1]);
    if (cv_exr_write(path, w, 1, CV_EXR_ZIP, &err)) goto fail;
    /* an HDR input by mistake: the band image at 4.6 */
    for (size_t i = 0; i < (size_t)96 * 64 * 3; i++) w->px[i] *= 4.6f;
    snprintf(path, sizeof path, "%s/bright.exr", argv[1]);
    if (cv_exr_write(path, w, 1, CV_EXR_ZIP, &err)) goto fail;
    cv_image_destroy(w);
  }
  /* Truncated: the first 60% of the good file. */
  snprintf(path, sizeof path, "%s/good.exr", argv[1]);
  FILE *f = fopen(path, "rb");
  if (!f) return 1;
  fseek(f, 0, SEEK_END);
  long n = ftell(f);
  fseek(f, 0, SEEK_SET);
  char *buf = malloc((size_t)n);
  if (!buf || fread(buf, 1, (size_t)n, f) != (size_t)n) return 1;
  fclose(f);
  snprintf(path, sizeof path, "%s/trunc.exr", argv[1]);
  f = fopen(path, "wb");
  fwrite(buf, 1, (size_t)(n * 6 / 10), f);
  fclose(f);
  free(buf);
  return 0;
fail:
  fprintf(stderr, "%s\n", err.msg);
  return 1;
}
