/* Image <-> patch resampling and equation 7 (see resample.h). */
#include "compensate/resample.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/overlaps.h"

/* Boundaries of n cells: the given ones, or uniform ones in tmp. */
static const double *edges_or_uniform(const double *e, int n, double *tmp) {
  if (e) return e;
  for (int i = 0; i <= n; i++) tmp[i] = (double)i / n;
  return tmp;
}

int cv_downsample_to_patches(const cv_image *img, int nu, int nv, const double *eu,
                             const double *ev, double *out) {
  /* Exact area weights: pixel x covers [x/w, (x+1)/w) of the surface; the
   * overlaps of each column and row with the cells computed once (the
   * products and sums are those of a per-pixel computation, in its order). */
  double *tu = malloc((size_t)(nu + 1) * sizeof(double)), *tv = malloc((size_t)(nv + 1) * sizeof(double));
  double *wsum = calloc((size_t)nu * nv, sizeof(double));
  cv_overlaps ox = {0}, oy = {0};
  int st = !tu || !tv || !wsum ? -1 : 0;
  const double *U = st ? NULL : edges_or_uniform(eu, nu, tu), *V = st ? NULL : edges_or_uniform(ev, nv, tv);
  if (!st) st = cv_overlaps_make(U, nu, img->w, 1.0, 0, &ox);
  if (!st) st = cv_overlaps_make(V, nv, img->h, 1.0, 1, &oy); /* bottom-up */
  if (st) {
    free(tu), free(tv), free(wsum);
    cv_overlaps_free(&ox), cv_overlaps_free(&oy);
    return -1;
  }
  memset(out, 0, 3 * (size_t)nu * nv * sizeof(double));
  /* Rows, then the (one or two) patch rows a pixel row falls in, then the
   * pixels: each patch's sums still receive the pixels in raster order, so
   * the sums are bit for bit those of the per-pixel loop; most columns lie
   * in one patch column and take the loop without the inner one. */
  for (int y = 0; y < img->h; y++) {
    const float *p = cv_image_at(img, 0, y);
    for (int a = oy.first[y]; a < oy.first[y + 1]; a++) {
      const double wy = oy.len[a];
      double *orow = out + 3 * (size_t)oy.cell[a] * nu, *wrow = wsum + (size_t)oy.cell[a] * nu;
      for (int x = 0; x < img->w; x++) {
        const float *q = p + (size_t)img->c * x;
        const int b0 = ox.first[x], b1 = ox.first[x + 1];
        for (int b = b0; b < b1; b++) {
          const double w = ox.len[b] * wy;
          double *o = orow + 3 * (size_t)ox.cell[b];
          o[0] += w * q[0], o[1] += w * q[1], o[2] += w * q[2];
          wrow[ox.cell[b]] += w;
        }
      }
    }
  }
  for (size_t k = 0; k < (size_t)nu * nv; k++)
    for (int c = 0; c < 3; c++) out[3 * k + c] = wsum[k] > 0 ? out[3 * k + c] / wsum[k] : 0.0;
  free(tu);
  free(tv);
  free(wsum);
  cv_overlaps_free(&ox), cv_overlaps_free(&oy);
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
  int k = cv_cell_of(e, n, t); /* centre k or k-1 is below t */
  int a = 0.5 * (e[k] + e[k + 1]) <= t ? k : k - 1;
  double ca = 0.5 * (e[a] + e[a + 1]), cb = 0.5 * (e[a + 1] + e[a + 2]);
  *i0 = a;
  *i1 = a + 1;
  *f = (t - ca) / (cb - ca);
}

/* What upsampling from patches to a w-pixel-wide image needs once per
 * image: the patch edges (given or uniform) and each column's bracketing
 * patch centres and weight. */
typedef struct {
  double *tu, *tv;       /* uniform edges, when none are given */
  const double *U, *V;   /* the edges used */
  int *iu;               /* 2 per column: the bracketing patch columns */
  double *fu;            /* per column: the weight of the second */
} columns;

static void columns_free(columns *c) { free(c->tu), free(c->tv), free(c->iu), free(c->fu); }

static int columns_make(columns *c, int nu, int nv, const double *eu, const double *ev, int w) {
  c->tu = malloc((size_t)(nu + 1) * sizeof(double));
  c->tv = malloc((size_t)(nv + 1) * sizeof(double));
  c->iu = malloc(2 * (size_t)w * sizeof *c->iu);
  c->fu = malloc((size_t)w * sizeof *c->fu);
  if (!c->tu || !c->tv || !c->iu || !c->fu) {
    columns_free(c);
    return -1;
  }
  c->U = edges_or_uniform(eu, nu, c->tu), c->V = edges_or_uniform(ev, nv, c->tv);
  for (int x = 0; x < w; x++) bracket(c->U, nu, (x + 0.5) / w, &c->iu[2 * x], &c->iu[2 * x + 1], &c->fu[x]);
  return 0;
}

int cv_upsample_from_patches(const double *patches, int nu, int nv, const double *eu,
                             const double *ev, cv_image *out) {
  columns cb;
  if (columns_make(&cb, nu, nv, eu, ev, out->w)) return -1;
  for (int y = 0; y < out->h; y++) {
    int v0, v1;
    double fv;
    bracket(cb.V, nv, ((out->h - 1 - y) + 0.5) / out->h, &v0, &v1, &fv);
    const double *r0 = patches + 3 * (size_t)v0 * nu, *r1 = patches + 3 * (size_t)v1 * nu;
    for (int x = 0; x < out->w; x++) {
      const int u0 = cb.iu[2 * x], u1 = cb.iu[2 * x + 1];
      const double f = cb.fu[x];
      float *p = cv_image_at(out, x, y);
      for (int c = 0; c < 3; c++) {
        double a = r0[3 * u0 + c], b = r0[3 * u1 + c];
        double d = r1[3 * u0 + c], e = r1[3 * u1 + c];
        p[c] = (float)((1 - fv) * ((1 - f) * a + f * b) + fv * ((1 - f) * d + f * e));
      }
    }
  }
  columns_free(&cb);
  return 0;
}

/* Equation 7 with a patch delta in one pass: out = clamp(I0 - up(delta)),
 * up() exactly as cv_upsample_from_patches computes it (the same double
 * expressions, rounded to float, so the result is bit-identical to
 * upsampling and subtracting): the column interpolations of the two patch
 * rows that bracket a pixel row, (1 - f) a + f b, depend on those rows only,
 * so they are computed once per pair of patch rows (nv - 1 pairs, not one
 * per pixel row) and each pixel blends two of them. */
uint64_t cv_apply_patch_delta(const cv_image *I0, const double *delta, int nu, int nv,
                              const double *eu, const double *ev, cv_image *out) {
  const int w = out->w, h = out->h;
  columns cb;
  if (columns_make(&cb, nu, nv, eu, ev, w)) return 0;
  double *top = malloc(6 * (size_t)w * sizeof *top);
  if (!top) {
    columns_free(&cb);
    return 0;
  }
  double *bot = top + 3 * (size_t)w;
  const int *iu = cb.iu;
  const double *fu = cb.fu;
  uint64_t clamped = 0;
  int have0 = -1, have1 = -1;
  for (int y = 0; y < h; y++) {
    int v0, v1;
    double fv;
    bracket(cb.V, nv, ((h - 1 - y) + 0.5) / h, &v0, &v1, &fv);
    if (v0 != have0 || v1 != have1) {
      const double *r0 = delta + 3 * (size_t)v0 * nu, *r1 = delta + 3 * (size_t)v1 * nu;
      for (int x = 0; x < w; x++) {
        const int u0 = iu[2 * x], u1 = iu[2 * x + 1];
        const double f = fu[x];
        for (int c = 0; c < 3; c++) {
          top[3 * x + c] = (1 - f) * r0[3 * u0 + c] + f * r0[3 * u1 + c];
          bot[3 * x + c] = (1 - f) * r1[3 * u0 + c] + f * r1[3 * u1 + c];
        }
      }
      have0 = v0, have1 = v1;
    }
    const double gv = 1 - fv;
    const float *src = cv_image_at(I0, 0, y);
    float *dst = cv_image_at(out, 0, y);
    for (int i = 0; i < 3 * w; i++) {
      float v = src[i] - (float)(gv * top[i] + fv * bot[i]);
      const int lo = !(v >= 0.0f), hi = v > 1.0f; /* !(v >= 0): also NaN */
      clamped += (uint64_t)(lo | hi);
      v = lo ? 0.0f : v;
      dst[i] = hi ? 1.0f : v;
    }
  }
  columns_free(&cb);
  free(top);
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
