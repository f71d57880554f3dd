/* Sparse scattering matrix storage and the K product (see system.h). */
#include "compensate/system.h"

#include <stdlib.h>

#include "compensate/hmatrix.h"
#include "core/status.h"

int cv_ffmatrix_alloc(size_t n, size_t nnz, cv_ffmatrix **out) {
  *out = NULL;
  cv_ffmatrix *m = calloc(1, sizeof *m);
  if (!m) return CV_ERR_NOMEM;
  m->n = n;
  m->nnz = nnz;
  m->row_off = calloc(n + 1, sizeof *m->row_off);
  m->col = malloc((nnz + 1) * sizeof *m->col);
  m->val = malloc((nnz + 1) * sizeof *m->val);
  if (!m->row_off || !m->col || !m->val) {
    cv_ffmatrix_destroy(m);
    return CV_ERR_NOMEM;
  }
  *out = m;
  return CV_OK;
}

void cv_ffmatrix_destroy(cv_ffmatrix *m) {
  if (!m) return;
  free(m->row_off);
  free(m->col);
  free(m->val);
  free(m);
}

void cv_scatter_apply_K(const cv_scatter_system *s, const double *x, double *y) {
  const cv_ffmatrix *F = s->F;
  if (!F) {
    cv_hmatrix_gather(s->H, x, y);
#pragma omp parallel for schedule(static)
    for (size_t p = 0; p < 3 * s->n; p++) y[p] *= s->refl[p];
    return;
  }
#pragma omp parallel for schedule(static)
  for (size_t i = 0; i < s->n; i++) {
    double a0 = 0, a1 = 0, a2 = 0;
    for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) {
      const double f = F->val[k];
      const double *xj = x + 3 * (size_t)F->col[k];
      a0 += f * xj[0];
      a1 += f * xj[1];
      a2 += f * xj[2];
    }
    y[3 * i] = s->refl[3 * i] * a0;
    y[3 * i + 1] = s->refl[3 * i + 1] * a1;
    y[3 * i + 2] = s->refl[3 * i + 2] * a2;
  }
}
