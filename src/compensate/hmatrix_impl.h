/* Internal layout of cv_hmatrix (hmatrix.h), shared by the build from a
 * CSR matrix (hmatrix.c) and the direct build (hmatrix_direct.c). */
#ifndef CV_COMPENSATE_HMATRIX_IMPL_H
#define CV_COMPENSATE_HMATRIX_IMPL_H

#include <stddef.h>
#include <stdint.h>

#include "compensate/hmatrix.h"

/* One stored block: rows [r0, r0 + m) and columns [c0, c0 + w) of the
 * matrix in cluster order (perm); every row range is a union of whole leaf
 * clusters. */
typedef struct hblock {
  uint32_t r0, m, c0, w;
  uint32_t rank;  /* 0: dense m x w row-major; else U (m x rank) then V (rank x w) */
  float *vals;    /* owned */
  size_t toff;    /* low rank: V x lands in t[toff .. toff + 3 rank) */
} hblock;

struct cv_hmatrix {
  size_t n, nc;       /* patches, leaf clusters */
  uint32_t *perm;     /* n: patch at each position of the cluster order */
  size_t *cstart;     /* nc + 1: positions of each leaf cluster */
  hblock *blocks;     /* nb, ordered by (first row, then build order) */
  size_t nb;
  size_t *lb_off;     /* nc + 1: blocks covering leaf r in lb[lb_off[r] ..] */
  uint32_t *lb;
  uint32_t *low;      /* nlow: indices of the low-rank blocks */
  size_t nlow;
  double *t;          /* 3 * sum of ranks */
  double *row_err;    /* n, by patch index: bound or estimate (see hmatrix.h) */
  double *row_sum;    /* n, by patch index: sum_j G~_ij of what is stored */
  size_t stored;
  size_t max_m;
  int max_rank;
  double *xp;         /* 3n planar scratch in cluster order */
  uint8_t *bact;      /* nb: block in use in a sparse update */
  size_t *apre;       /* n + 1: prefix count of active positions */
  cv_hmatrix_info info; /* what the build reported */
};

/* Allocates h with n patches and nc leaf clusters (perm, cstart, row_err,
 * row_sum, xp, apre; no blocks).  NULL when out of memory. */
cv_hmatrix *cv_hm_alloc(size_t n, size_t nc);

/* After perm, cstart and the blocks are set: sorts the blocks by first row,
 * builds the per-leaf lists and the low-rank scratch, computes the stored
 * row sums and the statistics.  CV_ERR_NOMEM. */
int cv_hm_finish(cv_hmatrix *h);

/* Fills the statistics shared by both builds (n_clusters = leaf clusters). */
void cv_hm_info(const cv_hmatrix *h, size_t source_nnz, double build_ms, cv_hmatrix_info *info);

#endif
