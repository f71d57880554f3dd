/* Block low-rank compression of the gather matrix: see hmatrix.h. */
#include "compensate/hmatrix.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "compensate/hmatrix_impl.h"

void cv_hmatrix_destroy(cv_hmatrix *h) {
  if (!h) return;
  for (size_t b = 0; b < h->nb; b++) free(h->blocks[b].vals);
  free(h->blocks);
  free(h->lb_off);
  free(h->lb);
  free(h->low);
  free(h->t);
  free(h->perm);
  free(h->cstart);
  free(h->row_err);
  free(h->row_sum);
  free(h->xp);
  free(h->bact);
  free(h->apre);
  free(h);
}

const double *cv_hmatrix_row_error(const cv_hmatrix *h) { return h ? h->row_err : NULL; }
const double *cv_hmatrix_row_sum(const cv_hmatrix *h) { return h ? h->row_sum : NULL; }
size_t cv_hmatrix_size(const cv_hmatrix *h) { return h ? h->n : 0; }

cv_hmatrix *cv_hm_alloc(size_t n, size_t nc) {
  cv_hmatrix *h = calloc(1, sizeof *h);
  if (!h) return NULL;
  h->n = n;
  h->nc = nc;
  h->perm = malloc(n * sizeof *h->perm);
  h->cstart = calloc(nc + 1, sizeof *h->cstart);
  h->row_err = calloc(n, sizeof *h->row_err);
  h->row_sum = calloc(n, sizeof *h->row_sum);
  h->xp = malloc(3 * n * sizeof *h->xp);
  h->apre = malloc((n + 1) * sizeof *h->apre);
  if (!h->perm || !h->cstart || !h->row_err || !h->row_sum || !h->xp || !h->apre) {
    cv_hmatrix_destroy(h);
    return NULL;
  }
  return h;
}

static int cmp_block(const void *a, const void *b) {
  const hblock *x = a, *y = b;
  if (x->r0 != y->r0) return x->r0 < y->r0 ? -1 : 1;
  if (x->c0 != y->c0) return x->c0 < y->c0 ? -1 : 1;
  return 0;
}

/* Leaf cluster holding position p (binary search in cstart). */
static size_t leaf_of(const cv_hmatrix *h, size_t p) {
  size_t lo = 0, hi = h->nc;
  while (hi - lo > 1) {
    const size_t mid = (lo + hi) / 2;
    if (h->cstart[mid] <= p)
      lo = mid;
    else
      hi = mid;
  }
  return lo;
}

int cv_hm_finish(cv_hmatrix *h) {
  /* Row ranges and column ranges never overlap twice for one (row, column),
   * so (r0, c0) orders the blocks uniquely. */
  qsort(h->blocks, h->nb, sizeof *h->blocks, cmp_block);
  h->lb_off = calloc(h->nc + 1, sizeof *h->lb_off);
  h->bact = calloc(h->nb + 1, 1);
  if (!h->lb_off || !h->bact) return CV_ERR_NOMEM;
  size_t tlen = 0, nlow = 0, stored = 0;
  for (size_t b = 0; b < h->nb; b++) {
    hblock *bl = &h->blocks[b];
    const size_t l0 = leaf_of(h, bl->r0), l1 = leaf_of(h, bl->r0 + bl->m - 1);
    for (size_t l = l0; l <= l1; l++) h->lb_off[l + 1]++;
    if (bl->m > h->max_m) h->max_m = bl->m;
    if (bl->rank) {
      bl->toff = tlen;
      tlen += 3 * (size_t)bl->rank;
      nlow++;
      if ((int)bl->rank > h->max_rank) h->max_rank = (int)bl->rank;
      stored += (size_t)bl->rank * (bl->m + bl->w);
    } else {
      stored += (size_t)bl->m * bl->w;
    }
  }
  for (size_t l = 0; l < h->nc; l++) {
    const size_t sz = h->cstart[l + 1] - h->cstart[l];
    if (sz > h->max_m) h->max_m = sz;
    h->lb_off[l + 1] += h->lb_off[l];
  }
  h->lb = malloc((h->lb_off[h->nc] + 1) * sizeof *h->lb);
  h->low = malloc((nlow + 1) * sizeof *h->low);
  h->t = malloc((tlen + 1) * sizeof *h->t);
  size_t *cur = malloc((h->nc + 1) * sizeof *cur);
  if (!h->lb || !h->low || !h->t || !cur) {
    free(cur);
    return CV_ERR_NOMEM;
  }
  memcpy(cur, h->lb_off, h->nc * sizeof *cur);
  nlow = 0;
  for (size_t b = 0; b < h->nb; b++) {
    const hblock *bl = &h->blocks[b];
    const size_t l0 = leaf_of(h, bl->r0), l1 = leaf_of(h, bl->r0 + bl->m - 1);
    for (size_t l = l0; l <= l1; l++) h->lb[cur[l]++] = (uint32_t)b;
    if (bl->rank) h->low[nlow++] = (uint32_t)b;
  }
  free(cur);
  h->nlow = nlow;
  h->stored = stored;
  /* Row sums of what is stored (in double, from the float values). */
  memset(h->row_sum, 0, h->n * sizeof *h->row_sum);
  for (size_t b = 0; b < h->nb; b++) {
    const hblock *bl = &h->blocks[b];
    for (size_t ii = 0; ii < bl->m; ii++) {
      double s = 0;
      if (bl->rank == 0) {
        for (size_t jj = 0; jj < bl->w; jj++) s += bl->vals[ii * bl->w + jj];
      } else {
        const float *U = bl->vals, *V = bl->vals + (size_t)bl->m * bl->rank;
        for (size_t q = 0; q < bl->rank; q++) {
          double vs = 0;
          for (size_t jj = 0; jj < bl->w; jj++) vs += V[q * bl->w + jj];
          s += (double)U[ii * bl->rank + q] * vs;
        }
      }
      h->row_sum[h->perm[bl->r0 + ii]] += s;
    }
  }
  return CV_OK;
}

void cv_hm_info(const cv_hmatrix *h, size_t source_nnz, double build_ms, cv_hmatrix_info *info) {
  memset(info, 0, sizeof *info);
  info->n_clusters = h->nc;
  info->n_blocks = h->nb;
  size_t rank_sum = 0;
  for (size_t b = 0; b < h->nb; b++) {
    if (h->blocks[b].rank) {
      info->n_lowrank++;
      rank_sum += h->blocks[b].rank;
    } else {
      info->n_dense++;
    }
  }
  info->stored_values = h->stored;
  info->source_nnz = source_nnz;
  info->max_rank = h->max_rank;
  info->mean_rank = info->n_lowrank ? (double)rank_sum / (double)info->n_lowrank : 0;
  for (size_t i = 0; i < h->n; i++) {
    if (h->row_err[i] > info->max_row_error) info->max_row_error = h->row_err[i];
    if (h->row_sum[i] > 0 && h->row_err[i] / h->row_sum[i] > info->max_rel_row_error)
      info->max_rel_row_error = h->row_err[i] / h->row_sum[i];
  }
  info->build_ms = build_ms;
}

/* The blocks of one row cluster while building from a CSR matrix. */
typedef struct hrow {
  uint32_t nblocks;
  hblock *blocks;
} hrow;

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

/* Per-thread scratch of the compression: the row cluster's slab (m x n,
 * cluster-ordered columns), one block in double, the cross-approximation
 * workspace, the block sums and which column clusters the slab touches. */
typedef struct hm_scratch {
  float *slab;
  double *A, *sblk;
  aca_ws s;
  uint8_t *nzc;
} hm_scratch;

static void hm_scratch_free(hm_scratch *t) {
  free(t->slab);
  free(t->A);
  free(t->s.E);
  free(t->s.U);
  free(t->s.V);
  free(t->s.rowabs);
  free(t->s.allowed);
  free(t->s.err);
  free(t->sblk);
  free(t->nzc);
}

/* Returns 1 when every buffer was allocated. */
static int hm_scratch_alloc(hm_scratch *t, size_t maxm, size_t n, size_t nc) {
  t->slab = malloc(maxm * n * sizeof *t->slab);
  t->A = malloc(maxm * maxm * sizeof *t->A);
  t->s = (aca_ws){malloc(maxm * maxm * sizeof(double)), malloc(maxm * maxm * sizeof(double)),
                  malloc(maxm * maxm * sizeof(double)), malloc(maxm * sizeof(double)),
                  malloc(maxm * sizeof(double)), malloc(maxm * sizeof(double))};
  t->sblk = malloc(maxm * sizeof *t->sblk);
  t->nzc = malloc(nc);
  return t->slab && t->A && t->s.E && t->s.U && t->s.V && t->s.rowabs && t->s.allowed && t->s.err &&
         t->sblk && t->nzc;
}

/* The cluster order: h->cstart (cluster offsets), h->perm (patches in
 * cluster order) and pos_of (each patch's place in it); *maxm the largest
 * cluster.  Errors: a cluster index out of range, a cluster of 0 or more
 * than 4096 patches, out of memory. */
static int cluster_layout(const uint32_t *cluster, size_t n, size_t nc, cv_hmatrix *h,
                          uint32_t *pos_of, size_t *maxm, cv_err *err) {
  for (size_t i = 0; i < n; i++) {
    if (cluster[i] >= nc)
      return cv_err_set(err, CV_ERR_INVALID, "hmatrix: patch %zu has cluster %u, expected < %zu",
                        i, cluster[i], nc);
    h->cstart[cluster[i] + 1]++;
  }
  *maxm = 0;
  for (size_t c = 0; c < nc; c++) {
    const size_t sz = h->cstart[c + 1];
    if (sz == 0 || sz > 4096)
      return cv_err_set(err, CV_ERR_INVALID,
                        "hmatrix: cluster %zu has %zu patches, expected 1..4096", c, sz);
    if (sz > *maxm) *maxm = sz;
    h->cstart[c + 1] += h->cstart[c];
  }
  size_t *cur = malloc(nc * sizeof *cur);
  if (!cur) return cv_err_set(err, CV_ERR_NOMEM, "hmatrix: out of memory");
  memcpy(cur, h->cstart, nc * sizeof *cur);
  for (size_t i = 0; i < n; i++) {
    const size_t p = cur[cluster[i]]++;
    h->perm[p] = (uint32_t)i;
    pos_of[i] = (uint32_t)p;
  }
  free(cur);
  return CV_OK;
}

/* Row cluster r's rows of F into the slab (cluster-ordered columns), and
 * which column clusters they touch (t->nzc); returns how many. */
static size_t slab_fill(const cv_ffmatrix *F, const uint32_t *cluster, const cv_hmatrix *h,
                        size_t nc, const uint32_t *pos_of, size_t r, hm_scratch *t) {
  const size_t n = F->n, r0 = h->cstart[r], m = h->cstart[r + 1] - r0;
  memset(t->slab, 0, m * n * sizeof *t->slab);
  memset(t->nzc, 0, nc);
  for (size_t ii = 0; ii < m; ii++) {
    const size_t i = h->perm[r0 + ii];
    for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) {
      if (F->val[k] == 0) continue;
      t->slab[ii * n + pos_of[F->col[k]]] = F->val[k];
      t->nzc[cluster[F->col[k]]] = 1;
    }
  }
  size_t nb = 0;
  for (size_t c = 0; c < nc; c++) nb += t->nzc[c];
  return nb;
}

/* Block (row cluster r, column cluster c) of the slab: dropped when all of
 * it fits the error budget as zero (counted as error), stored as float
 * factors of rank k when they take at most half the dense block (their
 * exact error counted), else dense, appended to hr.  Returns 1 when out of
 * memory. */
static int compress_block(cv_hmatrix *h, const double *rowsum, double tol, size_t nb, size_t r,
                          size_t c, hm_scratch *t, hrow *hr) {
  const size_t n = h->n, r0 = h->cstart[r], m = h->cstart[r + 1] - r0;
  const size_t c0 = h->cstart[c], wdt = h->cstart[c + 1] - c0;
  double *A = t->A;
  aca_ws *s = &t->s;
  for (size_t ii = 0; ii < m; ii++) {
    double sb = 0;
    for (size_t jj = 0; jj < wdt; jj++) {
      const double a = t->slab[ii * n + c0 + jj];
      A[ii * wdt + jj] = a;
      sb += a;
    }
    t->sblk[ii] = sb;
    s->allowed[ii] = tol * 0.5 * (sb + rowsum[h->perm[r0 + ii]] / (double)nb);
  }
  /* Low rank only when the factors take at most half the dense block. */
  const int kmax = (int)(m * wdt / (2 * (m + wdt)));
  int k = kmax > 0 ? aca(A, m, wdt, kmax, s) : -1;
  if (k == 0) {
    /* All of the block is within the budget as zero: drop it, count
     * its whole content as error. */
    for (size_t ii = 0; ii < m; ii++) h->row_err[h->perm[r0 + ii]] += t->sblk[ii];
    return 0;
  }
  hblock *b = &hr->blocks[hr->nblocks++];
  memset(b, 0, sizeof *b);
  b->r0 = (uint32_t)r0;
  b->m = (uint32_t)m;
  b->c0 = (uint32_t)c0;
  b->w = (uint32_t)wdt;
  b->vals = malloc((k > 0 ? (size_t)k * (m + wdt) : m * wdt) * sizeof *b->vals);
  if (!b->vals) {
    hr->nblocks--;
    return 1;
  }
  if (k <= 0) {
    for (size_t ii = 0; ii < m; ii++)
      memcpy(b->vals + ii * wdt, t->slab + ii * n + c0, wdt * sizeof *b->vals);
    return 0;
  }
  float *U = b->vals, *V = U + m * (size_t)k;
  for (size_t ii = 0; ii < m; ii++)
    for (int q = 0; q < k; q++) U[ii * (size_t)k + q] = (float)s->U[ii * (size_t)kmax + q];
  for (int q = 0; q < k; q++)
    for (size_t jj = 0; jj < wdt; jj++) V[(size_t)q * wdt + jj] = (float)s->V[(size_t)q * wdt + jj];
  /* The error of what is stored (float factors), exactly. */
  for (size_t ii = 0; ii < m; ii++) {
    double e = 0;
    for (size_t jj = 0; jj < wdt; jj++) {
      double a = A[ii * wdt + jj];
      for (int q = 0; q < k; q++) a -= (double)U[ii * (size_t)k + q] * (double)V[(size_t)q * wdt + jj];
      e += fabs(a);
    }
    h->row_err[h->perm[r0 + ii]] += e;
  }
  b->rank = (uint32_t)k;
  return 0;
}

/* Every row cluster's blocks into rows[] (in parallel, one row cluster at a
 * time per thread).  Returns 1 when out of memory. */
static int compress_rows(const cv_ffmatrix *F, const uint32_t *cluster, size_t nc, double tol,
                         const uint32_t *pos_of, const double *rowsum, size_t maxm, cv_hmatrix *h,
                         hrow *rows) {
  int fail = 0;
#pragma omp parallel
  {
    hm_scratch t;
    int ok = hm_scratch_alloc(&t, maxm, F->n, nc);
    if (!ok) {
#pragma omp atomic write
      fail = 1;
    }
#pragma omp for schedule(dynamic, 1)
    for (size_t r = 0; r < nc; r++) {
      if (!ok) continue;
      const size_t nb = slab_fill(F, cluster, h, nc, pos_of, r, &t);
      hrow *hr = &rows[r];
      hr->blocks = malloc((nb ? nb : 1) * sizeof *hr->blocks);
      if (!hr->blocks) ok = 0;
      for (size_t c = 0; c < nc && ok; c++)
        if (t.nzc[c] && compress_block(h, rowsum, tol, nb, r, c, &t, hr)) ok = 0;
      if (!ok) {
#pragma omp atomic write
        fail = 1;
      }
    }
    hm_scratch_free(&t);
  }
  return fail;
}

/* The blocks of all row clusters into h (rows freed).  Returns 1 when out
 * of memory. */
static int gather_blocks(cv_hmatrix *h, hrow *rows, size_t nc) {
  size_t total = 0;
  for (size_t r = 0; r < nc; r++) total += rows[r].nblocks;
  h->blocks = malloc((total + 1) * sizeof *h->blocks);
  for (size_t r = 0; r < nc; r++) {
    for (uint32_t b = 0; b < rows[r].nblocks; b++) {
      if (h->blocks)
        h->blocks[h->nb++] = rows[r].blocks[b];
      else
        free(rows[r].blocks[b].vals);
    }
    free(rows[r].blocks);
  }
  free(rows);
  return h->blocks == NULL;
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
  cv_hmatrix *h = cv_hm_alloc(n, nc);
  uint32_t *pos_of = malloc(n * sizeof *pos_of);
  double *rowsum = malloc(n * sizeof *rowsum);
  hrow *rows = calloc(nc, sizeof *rows);
  size_t maxm = 0;
  int st = (!h || !pos_of || !rowsum || !rows)
               ? cv_err_set(err, CV_ERR_NOMEM, "hmatrix: out of memory (%zu patches)", n)
               : cluster_layout(cluster, n, nc, h, pos_of, &maxm, err);
  if (st) {
    free(pos_of);
    free(rowsum);
    free(rows);
    cv_hmatrix_destroy(h);
    return st;
  }
  for (size_t i = 0; i < n; i++) {
    double s = 0;
    for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) s += F->val[k];
    rowsum[i] = s;
  }
  int fail = compress_rows(F, cluster, nc, tol, pos_of, rowsum, maxm, h, rows);
  if (gather_blocks(h, rows, nc)) fail = 1;
  if (!fail && cv_hm_finish(h)) fail = 1;
  if (fail) {
    free(pos_of);
    free(rowsum);
    cv_hmatrix_destroy(h);
    return cv_err_set(err, CV_ERR_NOMEM, "hmatrix: out of memory while compressing");
  }
  cv_hm_info(h, F->nnz, (omp_get_wtime() - t0) * 1e3, &h->info);
  /* relative to the rows of the source matrix */
  h->info.max_rel_row_error = 0;
  for (size_t i = 0; i < n; i++)
    if (rowsum[i] > 0 && h->row_err[i] / rowsum[i] > h->info.max_rel_row_error)
      h->info.max_rel_row_error = h->row_err[i] / rowsum[i];
  if (info) *info = h->info;
  free(pos_of);
  free(rowsum);
  *out = h;
  return CV_OK;
}

void cv_hmatrix_get_info(const cv_hmatrix *h, cv_hmatrix_info *info) { *info = h->info; }

/* Phase 1 of a product: t = V x[c0 .. c0 + w) of a low-rank block, for the
 * three channels (t[q], t[k + q], t[2k + q]). */
static void block_vx(const hblock *b, const double *xr, const double *xg, const double *xb,
                     double *t) {
  const size_t k = b->rank, w = b->w;
  const float *V = b->vals + (size_t)b->m * k;
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
}

/* Phase 2: acc (3m, planar by channel: acc[c * m + i]) += rows ii0 ..
 * ii0 + m of block b times x (dense) or U t (low rank). */
static void block_rows(const cv_hmatrix *h, const hblock *b, size_t ii0, size_t m,
                       const double *xr, const double *xg, const double *xb, double *acc) {
  if (b->rank == 0) {
    const size_t w = b->w;
    for (size_t i = 0; i < m; i++) {
      const float *row = b->vals + (ii0 + i) * w;
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
  const double *t = h->t + b->toff;
  for (size_t i = 0; i < m; i++) {
    const float *ur = b->vals + (ii0 + i) * k;
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

/* Shared body of the two products: only blocks flagged in use (NULL: all)
 * are applied; add = 1 adds to g.  Phase 1 forms V x of every low-rank
 * block, phase 2 sums each leaf cluster's rows over the blocks covering it
 * in a fixed order, so the result does not depend on the threads. */
static void apply(const cv_hmatrix *h, const uint8_t *use, double *g, int add) {
  const size_t n = h->n;
  const double *xr = h->xp, *xg = h->xp + n, *xb = h->xp + 2 * n;
#pragma omp parallel
  {
#pragma omp for schedule(dynamic, 4)
    for (size_t q = 0; q < h->nlow; q++) {
      const hblock *b = &h->blocks[h->low[q]];
      if (use && !use[h->low[q]]) continue;
      block_vx(b, xr + b->c0, xg + b->c0, xb + b->c0, h->t + b->toff);
    }
    double *acc = malloc(3 * h->max_m * sizeof *acc);
#pragma omp for schedule(dynamic, 1)
    for (size_t r = 0; r < h->nc; r++) {
      if (!acc) continue; /* cannot happen in practice; g keeps its value */
      const size_t r0 = h->cstart[r], m = h->cstart[r + 1] - r0;
      memset(acc, 0, 3 * m * sizeof *acc);
      for (size_t e = h->lb_off[r]; e < h->lb_off[r + 1]; e++) {
        if (use && !use[h->lb[e]]) continue;
        const hblock *b = &h->blocks[h->lb[e]];
        block_rows(h, b, r0 - b->r0, m, xr + b->c0, xg + b->c0, xb + b->c0, acc);
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
  size_t *pre = h->apre;
#pragma omp parallel for schedule(static)
  for (size_t p = 0; p < n; p++) {
    const size_t i = h->perm[p];
    if (active[i]) {
      xp[p] = d[3 * i];
      xp[n + p] = d[3 * i + 1];
      xp[2 * n + p] = d[3 * i + 2];
    } else {
      xp[p] = xp[n + p] = xp[2 * n + p] = 0;
    }
  }
  pre[0] = 0;
  for (size_t p = 0; p < n; p++) pre[p + 1] = pre[p] + (active[h->perm[p]] != 0);
  if (!pre[n]) return 0;
  uint8_t *use = h->bact;
  size_t read = 0;
  for (size_t b = 0; b < h->nb; b++) {
    const hblock *bl = &h->blocks[b];
    use[b] = pre[bl->c0 + bl->w] > pre[bl->c0];
    if (use[b]) read += bl->rank ? (size_t)bl->rank * (bl->m + bl->w) : (size_t)bl->m * bl->w;
  }
  apply(h, use, g, 1);
  return h->stored ? (double)read / (double)h->stored : 0;
}

void cv_hmatrix_row_values(const cv_hmatrix *h, size_t i, double *row) {
  memset(row, 0, h->n * sizeof *row);
  size_t p = 0;
  while (p < h->n && h->perm[p] != i) p++;
  if (p == h->n) return;
  const size_t l = leaf_of(h, p);
  for (size_t e = h->lb_off[l]; e < h->lb_off[l + 1]; e++) {
    const hblock *b = &h->blocks[h->lb[e]];
    const size_t ii = p - b->r0;
    for (size_t jj = 0; jj < b->w; jj++) {
      double v;
      if (b->rank == 0) {
        v = b->vals[ii * b->w + jj];
      } else {
        const float *U = b->vals + ii * b->rank, *V = b->vals + (size_t)b->m * b->rank;
        v = 0;
        for (size_t q = 0; q < b->rank; q++) v += (double)U[q] * V[q * b->w + jj];
      }
      row[h->perm[b->c0 + jj]] += v;
    }
  }
}
