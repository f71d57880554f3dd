/* Block low-rank compression of the gather matrix: see hmatrix.h. */
#include "compensate/hmatrix.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

typedef struct hblock {
  uint32_t col;   /* column cluster */
  uint32_t rank;  /* 0: dense m x w; else U (m x rank) then V (rank x w) */
  size_t off;     /* into the row cluster's vals */
} hblock;

typedef struct hrow {
  uint32_t nblocks;
  hblock *blocks;
  float *vals;
  size_t nvals;
} hrow;

struct cv_hmatrix {
  size_t n, nc;
  uint32_t *perm;    /* n: patch at each position of the cluster order */
  size_t *cstart;    /* nc + 1: positions of each cluster */
  hrow *rows;        /* nc */
  double *row_err;   /* n, by patch index */
  size_t stored;
  size_t max_m;
  int max_rank;
  double *xp;        /* 3n planar scratch in cluster order */
  uint8_t *cact;     /* nc */
};

void cv_hmatrix_destroy(cv_hmatrix *h) {
  if (!h) return;
  if (h->rows)
    for (size_t r = 0; r < h->nc; r++) {
      free(h->rows[r].blocks);
      free(h->rows[r].vals);
    }
  free(h->rows);
  free(h->perm);
  free(h->cstart);
  free(h->row_err);
  free(h->xp);
  free(h->cact);
  free(h);
}

const double *cv_hmatrix_row_error(const cv_hmatrix *h) { return h ? h->row_err : NULL; }

/* Growable float array of a row cluster. */
static int vals_reserve(hrow *hr, size_t *cap, size_t extra) {
  if (hr->nvals + extra <= *cap) return 0;
  size_t nc = *cap ? *cap : 4096;
  while (nc < hr->nvals + extra) nc *= 2;
  float *v = realloc(hr->vals, nc * sizeof *v);
  if (!v) return -1;
  hr->vals = v;
  *cap = nc;
  return 0;
}

/* Scratch for one block's cross approximation. */
typedef struct aca_ws {
  double *E, *U, *V, *rowabs, *allowed, *err;
} aca_ws;

/* Adaptive cross approximation with full pivoting of the m x w block A
 * (row-major, double), until every row's absolute residual sum is within
 * allowed[i] or the rank reaches kmax.  Returns the rank, or -1 when kmax was
 * not enough.  U: m x kmax (column q at U[i * kmax + q]), V: kmax x w. */
static int aca(const double *A, size_t m, size_t w, int kmax, aca_ws *s) {
  double *E = s->E;
  memcpy(E, A, m * w * sizeof *E);
  size_t pi = 0, pj = 0;
  double pmax = -1;
  for (size_t i = 0; i < m; i++) {
    double ra = 0;
    for (size_t c = 0; c < w; c++) {
      const double a = fabs(E[i * w + c]);
      ra += a;
      if (a > pmax) {
        pmax = a;
        pi = i;
        pj = c;
      }
    }
    s->rowabs[i] = ra;
  }
  for (int k = 0;; k++) {
    int ok = 1;
    for (size_t i = 0; i < m && ok; i++) ok = s->rowabs[i] <= s->allowed[i];
    if (ok) return k;
    if (k == kmax || !(pmax > 0)) return -1;
    const double p = E[pi * w + pj];
    double *v = s->V + (size_t)k * w;
    for (size_t c = 0; c < w; c++) v[c] = E[pi * w + c] / p;
    for (size_t i = 0; i < m; i++) s->U[i * (size_t)kmax + k] = E[i * w + pj];
    pmax = -1;
    for (size_t i = 0; i < m; i++) {
      const double u = s->U[i * (size_t)kmax + k];
      double ra = 0;
      double *e = E + i * w;
      for (size_t c = 0; c < w; c++) {
        e[c] -= u * v[c];
        const double a = fabs(e[c]);
        ra += a;
        if (a > pmax) {
          pmax = a;
          pi = i;
          pj = c;
        }
      }
      s->rowabs[i] = ra;
    }
  }
}

int cv_hmatrix_build(const cv_ffmatrix *F, const uint32_t *cluster, size_t n_clusters,
                     double tol, cv_hmatrix **out, cv_hmatrix_info *info, cv_err *err) {
  const double t0 = omp_get_wtime();
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "hmatrix: out is NULL");
  *out = NULL;
  if (!F || !cluster || n_clusters == 0 || F->n == 0)
    return cv_err_set(err, CV_ERR_INVALID, "hmatrix: empty matrix or no clusters");
  if (!(tol > 0 && tol < 0.5))
    return cv_err_set(err, CV_ERR_INVALID, "hmatrix: tolerance %g, expected in (0, 0.5)", tol);
  const size_t n = F->n, nc = n_clusters;
  cv_hmatrix *h = calloc(1, sizeof *h);
  if (!h) return cv_err_set(err, CV_ERR_NOMEM, "hmatrix: out of memory");
  h->n = n;
  h->nc = nc;
  h->perm = malloc(n * sizeof *h->perm);
  h->cstart = calloc(nc + 1, sizeof *h->cstart);
  h->rows = calloc(nc, sizeof *h->rows);
  h->row_err = calloc(n, sizeof *h->row_err);
  h->xp = malloc(3 * n * sizeof *h->xp);
  h->cact = calloc(nc, 1);
  uint32_t *pos_of = malloc(n * sizeof *pos_of);
  double *rowsum = malloc(n * sizeof *rowsum);
  if (!h->perm || !h->cstart || !h->rows || !h->row_err || !h->xp || !h->cact || !pos_of ||
      !rowsum) {
    free(pos_of);
    free(rowsum);
    cv_hmatrix_destroy(h);
    return cv_err_set(err, CV_ERR_NOMEM, "hmatrix: out of memory (%zu patches)", n);
  }
  for (size_t i = 0; i < n; i++) {
    if (cluster[i] >= nc) {
      free(pos_of);
      free(rowsum);
      cv_hmatrix_destroy(h);
      return cv_err_set(err, CV_ERR_INVALID, "hmatrix: patch %zu has cluster %u, expected < %zu",
                        i, cluster[i], nc);
    }
    h->cstart[cluster[i] + 1]++;
  }
  for (size_t c = 0; c < nc; c++) {
    const size_t sz = h->cstart[c + 1];
    if (sz == 0 || sz > 4096) {
      free(pos_of);
      free(rowsum);
      cv_hmatrix_destroy(h);
      return cv_err_set(err, CV_ERR_INVALID, "hmatrix: cluster %zu has %zu patches, expected 1..4096",
                        c, sz);
    }
    if (sz > h->max_m) h->max_m = sz;
    h->cstart[c + 1] += h->cstart[c];
  }
  {
    size_t *cur = malloc(nc * sizeof *cur);
    if (!cur) {
      free(pos_of);
      free(rowsum);
      cv_hmatrix_destroy(h);
      return cv_err_set(err, CV_ERR_NOMEM, "hmatrix: out of memory");
    }
    memcpy(cur, h->cstart, nc * sizeof *cur);
    for (size_t i = 0; i < n; i++) {
      const size_t p = cur[cluster[i]]++;
      h->perm[p] = (uint32_t)i;
      pos_of[i] = (uint32_t)p;
    }
    free(cur);
  }
  for (size_t i = 0; i < n; i++) {
    double s = 0;
    for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) s += F->val[k];
    rowsum[i] = s;
  }

  int fail = 0, max_rank = 0;
  size_t n_blocks = 0, n_low = 0, n_dense = 0, rank_sum = 0;
  const size_t maxm = h->max_m;
#pragma omp parallel reduction(+ : n_blocks, n_low, n_dense, rank_sum) reduction(max : max_rank)
  {
    /* Per thread: the row cluster's slab (m x n, cluster-ordered columns),
     * one block in double and the cross-approximation scratch. */
    float *slab = malloc(maxm * n * sizeof *slab);
    double *A = malloc(maxm * maxm * sizeof *A);
    aca_ws s = {malloc(maxm * maxm * sizeof(double)), malloc(maxm * maxm * sizeof(double)),
                malloc(maxm * maxm * sizeof(double)), malloc(maxm * sizeof(double)),
                malloc(maxm * sizeof(double)), malloc(maxm * sizeof(double))};
    double *sblk = malloc(maxm * sizeof *sblk);
    uint8_t *nzc = malloc(nc);
    int ok = slab && A && s.E && s.U && s.V && s.rowabs && s.allowed && s.err && sblk && nzc;
    if (!ok) {
#pragma omp atomic write
      fail = 1;
    }
#pragma omp for schedule(dynamic, 1)
    for (size_t r = 0; r < nc; r++) {
      if (!ok) continue;
      const size_t r0 = h->cstart[r], m = h->cstart[r + 1] - r0;
      memset(slab, 0, m * n * sizeof *slab);
      memset(nzc, 0, nc);
      for (size_t ii = 0; ii < m; ii++) {
        const size_t i = h->perm[r0 + ii];
        for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) {
          if (F->val[k] == 0) continue;
          slab[ii * n + pos_of[F->col[k]]] = F->val[k];
          nzc[cluster[F->col[k]]] = 1;
        }
      }
      size_t nb = 0;
      for (size_t c = 0; c < nc; c++) nb += nzc[c];
      hrow *hr = &h->rows[r];
      hr->blocks = malloc((nb ? nb : 1) * sizeof *hr->blocks);
      size_t cap = 0;
      if (!hr->blocks) {
        ok = 0;
#pragma omp atomic write
        fail = 1;
        continue;
      }
      for (size_t c = 0; c < nc && ok; c++) {
        if (!nzc[c]) continue;
        const size_t c0 = h->cstart[c], wdt = h->cstart[c + 1] - c0;
        for (size_t ii = 0; ii < m; ii++) {
          double sb = 0;
          for (size_t jj = 0; jj < wdt; jj++) {
            const double a = slab[ii * n + c0 + jj];
            A[ii * wdt + jj] = a;
            sb += a;
          }
          sblk[ii] = sb;
          s.allowed[ii] = tol * 0.5 * (sb + rowsum[h->perm[r0 + ii]] / (double)nb);
        }
        /* Low rank only when the factors take at most half the dense block. */
        const int kmax = (int)(m * wdt / (2 * (m + wdt)));
        int k = kmax > 0 ? aca(A, m, wdt, kmax, &s) : -1;
        hblock *b = &hr->blocks[hr->nblocks++];
        b->col = (uint32_t)c;
        b->off = hr->nvals;
        if (k > 0) {
          if (vals_reserve(hr, &cap, (size_t)k * (m + wdt))) {
            ok = 0;
            break;
          }
          float *U = hr->vals + hr->nvals, *V = U + m * (size_t)k;
          for (size_t ii = 0; ii < m; ii++)
            for (int q = 0; q < k; q++) U[ii * (size_t)k + q] = (float)s.U[ii * (size_t)kmax + q];
          for (int q = 0; q < k; q++)
            for (size_t jj = 0; jj < wdt; jj++)
              V[(size_t)q * wdt + jj] = (float)s.V[(size_t)q * wdt + jj];
          /* The error of what is stored (float factors), exactly. */
          for (size_t ii = 0; ii < m; ii++) {
            double e = 0;
            for (size_t jj = 0; jj < wdt; jj++) {
              double a = A[ii * wdt + jj];
              for (int q = 0; q < k; q++)
                a -= (double)U[ii * (size_t)k + q] * (double)V[(size_t)q * wdt + jj];
              e += fabs(a);
            }
            h->row_err[h->perm[r0 + ii]] += e;
          }
          b->rank = (uint32_t)k;
          hr->nvals += (size_t)k * (m + wdt);
          n_low++;
          rank_sum += (size_t)k;
          if (k > max_rank) max_rank = k;
        } else if (k == 0) {
          /* All of the block is within the budget as zero: drop it, count
           * its whole content as error. */
          for (size_t ii = 0; ii < m; ii++) h->row_err[h->perm[r0 + ii]] += sblk[ii];
          hr->nblocks--;
          continue;
        } else {
          if (vals_reserve(hr, &cap, m * wdt)) {
            ok = 0;
            break;
          }
          float *D = hr->vals + hr->nvals;
          for (size_t ii = 0; ii < m; ii++)
            memcpy(D + ii * wdt, slab + ii * n + c0, wdt * sizeof *D);
          b->rank = 0;
          hr->nvals += m * wdt;
          n_dense++;
        }
        n_blocks++;
      }
      if (!ok) {
#pragma omp atomic write
        fail = 1;
      }
    }
    free(slab);
    free(A);
    free(s.E);
    free(s.U);
    free(s.V);
    free(s.rowabs);
    free(s.allowed);
    free(s.err);
    free(sblk);
    free(nzc);
  }
  if (fail) {
    free(pos_of);
    free(rowsum);
    cv_hmatrix_destroy(h);
    return cv_err_set(err, CV_ERR_NOMEM, "hmatrix: out of memory while compressing");
  }
  size_t stored = 0;
  for (size_t r = 0; r < nc; r++) stored += h->rows[r].nvals;
  h->stored = stored;
  h->max_rank = max_rank;
  if (info) {
    memset(info, 0, sizeof *info);
    info->n_clusters = nc;
    info->n_blocks = n_blocks;
    info->n_lowrank = n_low;
    info->n_dense = n_dense;
    info->stored_values = stored;
    info->source_nnz = F->nnz;
    info->max_rank = max_rank;
    info->mean_rank = n_low ? (double)rank_sum / (double)n_low : 0;
    for (size_t i = 0; i < n; i++) {
      if (h->row_err[i] > info->max_row_error) info->max_row_error = h->row_err[i];
      if (rowsum[i] > 0 && h->row_err[i] / rowsum[i] > info->max_rel_row_error)
        info->max_rel_row_error = h->row_err[i] / rowsum[i];
    }
    info->build_ms = (omp_get_wtime() - t0) * 1e3;
  }
  free(pos_of);
  free(rowsum);
  *out = h;
  return CV_OK;
}

/* acc (3m, planar by channel: acc[c * m + i]) += block b times the planar
 * cluster-ordered vector xp (columns c0 .. c0 + w). */
static void block_apply(const hrow *hr, const hblock *b, size_t m, size_t w, const double *xr,
                        const double *xg, const double *xb, double *acc, double *t) {
  const float *v = hr->vals + b->off;
  if (b->rank == 0) {
    for (size_t i = 0; i < m; i++) {
      const float *row = v + i * w;
      double a0 = 0, a1 = 0, a2 = 0;
      for (size_t j = 0; j < w; j++) {
        const double f = row[j];
        a0 += f * xr[j];
        a1 += f * xg[j];
        a2 += f * xb[j];
      }
      acc[i] += a0;
      acc[m + i] += a1;
      acc[2 * m + i] += a2;
    }
    return;
  }
  const size_t k = b->rank;
  const float *U = v, *V = v + m * k;
  for (size_t q = 0; q < k; q++) {
    const float *vr = V + q * w;
    double a0 = 0, a1 = 0, a2 = 0;
    for (size_t j = 0; j < w; j++) {
      const double f = vr[j];
      a0 += f * xr[j];
      a1 += f * xg[j];
      a2 += f * xb[j];
    }
    t[q] = a0;
    t[k + q] = a1;
    t[2 * k + q] = a2;
  }
  for (size_t i = 0; i < m; i++) {
    const float *ur = U + i * k;
    double a0 = 0, a1 = 0, a2 = 0;
    for (size_t q = 0; q < k; q++) {
      const double u = ur[q];
      a0 += u * t[q];
      a1 += u * t[k + q];
      a2 += u * t[2 * k + q];
    }
    acc[i] += a0;
    acc[m + i] += a1;
    acc[2 * m + i] += a2;
  }
}

/* Shared body of the two products: only blocks whose column cluster is
 * flagged in use (NULL: all) are applied; add = 1 adds to g. */
static void apply(const cv_hmatrix *h, const uint8_t *use, double *g, int add) {
  const size_t n = h->n;
  const double *xr = h->xp, *xg = h->xp + n, *xb = h->xp + 2 * n;
#pragma omp parallel
  {
    double *acc = malloc(3 * h->max_m * sizeof *acc);
    double *t = malloc(3 * ((size_t)h->max_rank + 1) * sizeof *t);
#pragma omp for schedule(dynamic, 1)
    for (size_t r = 0; r < h->nc; r++) {
      if (!acc || !t) continue; /* cannot happen in practice; g keeps its value */
      const size_t r0 = h->cstart[r], m = h->cstart[r + 1] - r0;
      memset(acc, 0, 3 * m * sizeof *acc);
      const hrow *hr = &h->rows[r];
      for (uint32_t bi = 0; bi < hr->nblocks; bi++) {
        const hblock *b = &hr->blocks[bi];
        if (use && !use[b->col]) continue;
        const size_t c0 = h->cstart[b->col], w = h->cstart[b->col + 1] - c0;
        block_apply(hr, b, m, w, xr + c0, xg + c0, xb + c0, acc, t);
      }
      for (size_t ii = 0; ii < m; ii++) {
        double *gi = g + 3 * (size_t)h->perm[r0 + ii];
        if (add) {
          gi[0] += acc[ii];
          gi[1] += acc[m + ii];
          gi[2] += acc[2 * m + ii];
        } else {
          gi[0] = acc[ii];
          gi[1] = acc[m + ii];
          gi[2] = acc[2 * m + ii];
        }
      }
    }
    free(acc);
    free(t);
  }
}

void cv_hmatrix_gather(const cv_hmatrix *h, const double *x, double *g) {
  const size_t n = h->n;
  double *xp = h->xp;
#pragma omp parallel for schedule(static)
  for (size_t p = 0; p < n; p++) {
    const size_t i = h->perm[p];
    xp[p] = x[3 * i];
    xp[n + p] = x[3 * i + 1];
    xp[2 * n + p] = x[3 * i + 2];
  }
  apply(h, NULL, g, 0);
}

double cv_hmatrix_gather_add_active(const cv_hmatrix *h, const uint8_t *active, const double *d,
                                    double *g) {
  const size_t n = h->n;
  double *xp = h->xp;
  uint8_t *use = h->cact;
  size_t any = 0;
#pragma omp parallel for schedule(static) reduction(+ : any)
  for (size_t c = 0; c < h->nc; c++) {
    uint8_t u = 0;
    for (size_t p = h->cstart[c]; p < h->cstart[c + 1]; p++) {
      const size_t i = h->perm[p];
      if (active[i]) {
        u = 1;
        xp[p] = d[3 * i];
        xp[n + p] = d[3 * i + 1];
        xp[2 * n + p] = d[3 * i + 2];
      } else {
        xp[p] = xp[n + p] = xp[2 * n + p] = 0;
      }
    }
    use[c] = u;
    any += u;
  }
  if (!any) return 0;
  apply(h, use, g, 1);
  size_t read = 0;
  for (size_t r = 0; r < h->nc; r++)
    for (uint32_t bi = 0; bi < h->rows[r].nblocks; bi++) {
      const hblock *b = &h->rows[r].blocks[bi];
      if (!use[b->col]) continue;
      const size_t m = h->cstart[r + 1] - h->cstart[r], w = h->cstart[b->col + 1] - h->cstart[b->col];
      read += b->rank ? b->rank * (m + w) : m * w;
    }
  return h->stored ? (double)read / (double)h->stored : 0;
}
