/* Image <-> patch resampling and equation 7 (see resample.h). */
#include "compensate/resample.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Boundaries of n cells: the given ones, or uniform ones in tmp. */
static const double *edges_or_uniform(const double *e, int n, double *tmp) {
  if (e) return e;
  for (int i = 0; i <= n; i++) tmp[i] = (double)i / n;
  return tmp;
}

/* Index of the cell containing t (edges ascending, e[0] = 0, e[n] = 1). */
static int cell_of(const double *e, int n, double t) {
  int lo = 0, hi = n - 1;
  while (lo < hi) {
    int mid = (lo + hi + 1) / 2;
    if (e[mid] <= t) lo = mid;
    else hi = mid - 1;
  }
  return lo;
}

int cv_downsample_to_patches(const cv_image *img, int nu, int nv, const double *eu,
                             const double *ev, double *out) {
  /* Exact area weights: pixel x covers [x/w, (x+1)/w) of the surface. */
  double *tu = malloc((size_t)(nu + 1) * sizeof(double)), *tv = malloc((size_t)(nv + 1) * sizeof(double));
  double *wsum = calloc((size_t)nu * nv, sizeof(double));
  if (!tu || !tv || !wsum) {
    free(tu);
    free(tv);
    free(wsum);
    return -1;
  }
  const double *U = edges_or_uniform(eu, nu, tu), *V = edges_or_uniform(ev, nv, tv);
  memset(out, 0, 3 * (size_t)nu * nv * sizeof(double));
  for (int y = 0; y < img->h; y++) {
    double y0 = (double)(img->h - 1 - y) / img->h, y1 = y0 + 1.0 / img->h; /* bottom-up */
    for (int x = 0; x < img->w; x++) {
      double x0 = (double)x / img->w, x1 = x0 + 1.0 / img->w;
      const float *p = cv_image_at(img, x, y);
      for (int v = cell_of(V, nv, y0); v < nv && V[v] < y1; v++) {
        double oy = fmin(y1, V[v + 1]) - fmax(y0, V[v]);
        if (oy <= 0) continue;
        for (int u = cell_of(U, nu, x0); u < nu && U[u] < x1; u++) {
          double ox = fmin(x1, U[u + 1]) - fmax(x0, U[u]);
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
  free(tu);
  free(tv);
  free(wsum);
  return 0;
}

/* Bracketing patch centres of t: indices i0 <= i1 and weight of i1. */
static void bracket(const double *e, int n, double t, int *i0, int *i1, double *f) {
  double c0 = 0.5 * (e[0] + e[1]), cn = 0.5 * (e[n - 1] + e[n]);
  if (n == 1 || t <= c0) {
    *i0 = *i1 = 0;
    *f = 0;
    return;
  }
  if (t >= cn) {
    *i0 = *i1 = n - 1;
    *f = 0;
    return;
  }
  int k = cell_of(e, n, t); /* centre k or k-1 is below t */
  int a = 0.5 * (e[k] + e[k + 1]) <= t ? k : k - 1;
  double ca = 0.5 * (e[a] + e[a + 1]), cb = 0.5 * (e[a + 1] + e[a + 2]);
  *i0 = a;
  *i1 = a + 1;
  *f = (t - ca) / (cb - ca);
}

int cv_upsample_from_patches(const double *patches, int nu, int nv, const double *eu,
                             const double *ev, cv_image *out) {
  double *tu = malloc((size_t)(nu + 1) * sizeof(double)), *tv = malloc((size_t)(nv + 1) * sizeof(double));
  if (!tu || !tv) {
    free(tu);
    free(tv);
    return -1;
  }
  const double *U = edges_or_uniform(eu, nu, tu), *V = edges_or_uniform(ev, nv, tv);
  for (int y = 0; y < out->h; y++) {
    int v0, v1;
    double fv;
    bracket(V, nv, ((out->h - 1 - y) + 0.5) / out->h, &v0, &v1, &fv);
    for (int x = 0; x < out->w; x++) {
      int u0, u1;
      double fu;
      bracket(U, nu, (x + 0.5) / out->w, &u0, &u1, &fu);
      float *p = cv_image_at(out, x, y);
      for (int c = 0; c < 3; c++) {
        double a = patches[3 * ((size_t)v0 * nu + u0) + c], b = patches[3 * ((size_t)v0 * nu + u1) + c];
        double d = patches[3 * ((size_t)v1 * nu + u0) + c], e = patches[3 * ((size_t)v1 * nu + u1) + c];
        p[c] = (float)((1 - fv) * ((1 - fu) * a + fu * b) + fv * ((1 - fu) * d + fu * e));
      }
    }
  }
  free(tu);
  free(tv);
  return 0;
}

uint64_t cv_apply_patch_delta(const cv_image *I0, const double *delta, int nu, int nv,
                              const double *eu, const double *ev, cv_image *out) {
  cv_upsample_from_patches(delta, nu, nv, eu, ev, out);
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
                                   const double *eu, const double *ev, cv_image *out) {
  size_t np = (size_t)nu * nv;
  double *diff = malloc(3 * np * sizeof(double));
  if (!diff) return 0;
  cv_downsample_to_patches(I0, nu, nv, eu, ev, diff);
  for (size_t k = 0; k < 3 * np; k++) diff[k] -= IP[k];
  uint64_t clamped = cv_apply_patch_delta(I0, diff, nu, nv, eu, ev, out);
  free(diff);
  return clamped;
}
