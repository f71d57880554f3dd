/* Image <-> patch resampling and equation 7 (see resample.h). */
#include "compensate/resample.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void cv_downsample_to_patches(const cv_image *img, int nu, int nv, double *out) {
  /* Exact area weights: patch u covers x in [u w/nu, (u+1) w/nu). */
  memset(out, 0, 3 * (size_t)nu * nv * sizeof(double));
  double *wsum = calloc((size_t)nu * nv, sizeof(double));
  if (!wsum) return;
  const double sx = (double)nu / img->w, sy = (double)nv / img->h;
  for (int y = 0; y < img->h; y++) {
    double y0 = (img->h - 1 - y) * sy, y1 = y0 + sy; /* bottom-up in patch units */
    for (int x = 0; x < img->w; x++) {
      double x0 = x * sx, x1 = x0 + sx;
      const float *p = cv_image_at(img, x, y);
      for (int v = (int)floor(y0); v < nv && v < y1; v++) {
        double oy = fmin(y1, v + 1.0) - fmax(y0, (double)v);
        if (oy <= 0) continue;
        for (int u = (int)floor(x0); u < nu && u < x1; u++) {
          double ox = fmin(x1, u + 1.0) - fmax(x0, (double)u);
          if (ox <= 0) continue;
          double w = ox * oy;
          size_t k = (size_t)v * nu + u;
          for (int c = 0; c < 3; c++) out[3 * k + c] += w * p[c];
          wsum[k] += w;
        }
      }
    }
  }
  for (size_t k = 0; k < (size_t)nu * nv; k++)
    for (int c = 0; c < 3; c++) out[3 * k + c] = wsum[k] > 0 ? out[3 * k + c] / wsum[k] : 0.0;
  free(wsum);
}

void cv_upsample_from_patches(const double *patches, int nu, int nv, cv_image *out) {
  for (int y = 0; y < out->h; y++) {
    double fv = ((out->h - 1 - y) + 0.5) * nv / out->h - 0.5; /* patch coordinate */
    fv = fmin(fmax(fv, 0.0), nv - 1.0);
    int v0 = (int)floor(fv), v1 = v0 + 1 < nv ? v0 + 1 : v0;
    double tv = fv - v0;
    for (int x = 0; x < out->w; x++) {
      double fu = (x + 0.5) * nu / out->w - 0.5;
      fu = fmin(fmax(fu, 0.0), nu - 1.0);
      int u0 = (int)floor(fu), u1 = u0 + 1 < nu ? u0 + 1 : u0;
      double tu = fu - u0;
      float *p = cv_image_at(out, x, y);
      for (int c = 0; c < 3; c++) {
        double a = patches[3 * ((size_t)v0 * nu + u0) + c], b = patches[3 * ((size_t)v0 * nu + u1) + c];
        double d = patches[3 * ((size_t)v1 * nu + u0) + c], e = patches[3 * ((size_t)v1 * nu + u1) + c];
        p[c] = (float)((1 - tv) * ((1 - tu) * a + tu * b) + tv * ((1 - tu) * d + tu * e));
      }
    }
  }
}

uint64_t cv_apply_patch_delta(const cv_image *I0, const double *delta, int nu, int nv,
                              cv_image *out) {
  cv_upsample_from_patches(delta, nu, nv, out);
  uint64_t clamped = 0;
  size_t n = (size_t)I0->w * I0->h * 3;
  for (size_t i = 0; i < n; i++) {
    float v = I0->px[i] - out->px[i];
    if (!(v >= 0.0f)) { /* also catches NaN */
      v = 0.0f;
      clamped++;
    } else if (v > 1.0f) {
      v = 1.0f;
      clamped++;
    }
    out->px[i] = v;
  }
  return clamped;
}

uint64_t cv_apply_patch_correction(const cv_image *I0, const double *IP, int nu, int nv,
                                   cv_image *out) {
  size_t np = (size_t)nu * nv;
  double *diff = malloc(3 * np * sizeof(double));
  if (!diff) return 0;
  cv_downsample_to_patches(I0, nu, nv, diff);
  for (size_t k = 0; k < 3 * np; k++) diff[k] -= IP[k];
  uint64_t clamped = cv_apply_patch_delta(I0, diff, nu, nv, out);
  free(diff);
  return clamped;
}
