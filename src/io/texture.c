/* Diffuse albedo textures (see texture.h). */
#include "io/texture.h"

#include <math.h>

#include "io/png.h"

static float srgb_to_linear(float v) {
  return v <= 0.04045f ? v / 12.92f : (float)pow((v + 0.055) / 1.055, 2.4);
}

int cv_texture_load(const char *path, cv_image **out, cv_err *err) {
  *out = NULL;
  cv_image *in = NULL, *t = NULL;
  int st = cv_png_read(path, &in, err);
  if (st) return st;
  if (cv_image_create(in->w, in->h, 3, &t)) {
    cv_image_destroy(in);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  }
  const size_t n = (size_t)in->w * (size_t)in->h;
  for (size_t i = 0; i < n; i++)
    for (int k = 0; k < 3; k++)
      t->px[3 * i + k] = srgb_to_linear(in->px[i * (size_t)in->c + (in->c >= 3 ? k : 0)]);
  cv_image_destroy(in);
  *out = t;
  return CV_OK;
}

static int wrap(long i, int n) {
  long r = i % n;
  return (int)(r < 0 ? r + n : r);
}

void cv_texture_sample(const cv_image *t, double u, double v, float rgb[3]) {
  if (!isfinite(u) || !isfinite(v)) u = v = 0;
  u -= floor(u); /* wrap first: no overflow converting to long below */
  v -= floor(v);
  double x = u * t->w - 0.5, y = (1.0 - v) * t->h - 0.5;
  double fx = floor(x), fy = floor(y), ax = x - fx, ay = y - fy;
  int x0 = wrap((long)fx, t->w), x1 = wrap((long)fx + 1, t->w);
  int y0 = wrap((long)fy, t->h), y1 = wrap((long)fy + 1, t->h);
  const float *a = cv_image_at(t, x0, y0), *b = cv_image_at(t, x1, y0),
              *c = cv_image_at(t, x0, y1), *d = cv_image_at(t, x1, y1);
  for (int k = 0; k < 3; k++)
    rgb[k] = (float)((1 - ay) * ((1 - ax) * a[k] + ax * b[k]) + ay * ((1 - ax) * c[k] + ax * d[k]));
}
