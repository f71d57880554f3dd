/* Seam error estimate of the up-sampled correction: see seam.h. */
#include "compensate/seam.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/vec3d.h"

/* Estimates along one line of m centres x[0..m-1] with values f (stride
 * `stride` in f), maxed into est[i * est_stride]. */
static void line_estimate(const double *x, const double *f, size_t stride, int m, double *est,
                          size_t est_stride) {
  if (m < 2) return;
  /* second divided differences at interior centres */
  for (int i = 0; i + 1 < m; i++) {
    const double h = x[i + 1] - x[i];
    double f2 = 0;
    for (int j = i; j <= i + 1; j++) {
      if (j < 1 || j + 1 >= m) continue;
      const double a = (f[(size_t)j * stride] - f[(size_t)(j - 1) * stride]) / (x[j] - x[j - 1]);
      const double b = (f[(size_t)(j + 1) * stride] - f[(size_t)j * stride]) / (x[j + 1] - x[j]);
      const double d2 = fabs(2 * (b - a) / (x[j + 1] - x[j - 1]));
      if (d2 > f2) f2 = d2;
    }
    const double e = h * h / 8 * f2;
    if (e > est[(size_t)i * est_stride]) est[(size_t)i * est_stride] = e;
    if (e > est[(size_t)(i + 1) * est_stride]) est[(size_t)(i + 1) * est_stride] = e;
  }
  /* ends: held constant between the edge and the outer centre */
  const double s0 = fabs(f[stride] - f[0]) / (x[1] - x[0]);
  const double e0 = s0 * x[0];
  if (e0 > est[0]) est[0] = e0;
  const size_t l = (size_t)(m - 1), k = (size_t)(m - 2);
  const double s1 = fabs(f[l * stride] - f[k * stride]) / (x[l] - x[k]);
  const double e1 = s1 * (1 - x[l]);
  if (e1 > est[l * est_stride]) est[l * est_stride] = e1;
}

int cv_seam_estimate_error(const cv_display *d, const double *delta, double dist_m,
                           cv_seam_estimate *out) {
  if (!d || !delta || !out || !(dist_m >= 0)) return CV_ERR_INVALID;
  memset(out, 0, sizeof *out);
  double sq = 0;
  for (size_t k = 0; k < d->n_surfaces; k++) {
    const cv_display_surface *s = &d->surfaces[k];
    const int nu = s->nu, nv = s->nv;
    const size_t np = (size_t)nu * nv;
    double *est = calloc(np, sizeof *est);
    double *xu = malloc((size_t)nu * sizeof *xu), *xv = malloc((size_t)nv * sizeof *xv);
    if (!est || !xu || !xv) {
      free(est);
      free(xu);
      free(xv);
      return CV_ERR_NOMEM;
    }
    for (int u = 0; u < nu; u++) xu[u] = 0.5 * (s->edge_u[u] + s->edge_u[u + 1]);
    for (int v = 0; v < nv; v++) xv[v] = 0.5 * (s->edge_v[v] + s->edge_v[v + 1]);
    const double *base = delta + 3 * s->offset;
    for (int c = 0; c < 3; c++) {
      for (int v = 0; v < nv; v++)
        line_estimate(xu, base + 3 * (size_t)v * nu + c, 3, nu, est + (size_t)v * nu, 1);
      for (int u = 0; u < nu; u++)
        line_estimate(xv, base + 3 * (size_t)u + c, 3 * (size_t)nu, nv, est + u, (size_t)nu);
    }
    /* Lengths along u and v (metres): sums of the patch edges of the first
     * row and column (exact for planes, chords for curved surfaces). */
    double lu = 0, lv = 0, dd[3];
    for (int u = 0; u < nu; u++) {
      const cv_patch *p = &d->patches[s->offset + (size_t)u];
      sub3(p->q[1], p->q[0], dd);
      lu += len3(dd);
    }
    for (int v = 0; v < nv; v++) {
      const cv_patch *p = &d->patches[s->offset + (size_t)v * nu];
      sub3(p->q[3], p->q[0], dd);
      lv += len3(dd);
    }
    const unsigned seams = cv_display_seam_edges(d, k);
    for (int v = 0; v < nv; v++)
      for (int u = 0; u < nu; u++) {
        double dmin = INFINITY;
        if (seams & CV_EDGE_LEFT) dmin = fmin(dmin, xu[u] * lu);
        if (seams & CV_EDGE_RIGHT) dmin = fmin(dmin, (1 - xu[u]) * lu);
        if (seams & CV_EDGE_BOTTOM) dmin = fmin(dmin, xv[v] * lv);
        if (seams & CV_EDGE_TOP) dmin = fmin(dmin, (1 - xv[v]) * lv);
        const double e = est[(size_t)v * nu + u];
        if (dmin <= dist_m) {
          out->seam_patches++;
          sq += e * e;
          if (e > out->seam_max) out->seam_max = e;
        } else if (e > out->rest_max) {
          out->rest_max = e;
        }
      }
    free(est);
    free(xu);
    free(xv);
  }
  out->seam_rms = out->seam_patches ? sqrt(sq / (double)out->seam_patches) : 0;
  return CV_OK;
}
