/* Block low-rank compression of the gather matrix G (system.h), for the
 * products K x that every compensation solve is made of.
 *
 * Why: on a two-sided wall the walls see each other whole, so G is dense
 * (2 x 4096 x 4096 pairs at 64 x 64 patches, 66 MB even in half precision)
 * and a product streams all of it.  But the form factor between two groups
 * of patches that are far apart compared with their size is a smooth kernel:
 * that block of G has low numerical rank (the far field of fast multipole and
 * H-matrix methods).  Patches are grouped into clusters (tiles of a surface's
 * patch grid, given by the display); each block (row cluster, column
 * cluster) is stored either dense (near field: next to a seam) or as U V^T of
 * rank k found by adaptive cross approximation with full pivoting (Bebendorf
 * 2000; here on the block, which is at hand, so the pivoting is complete),
 * whichever is smaller.
 *
 * Error control, rigorous and per row: block b of row i may err by at most
 *     e_ib <= tol * (s_ib + s_i / nb) / 2
 * (sum of absolute errors over the block's columns; s_ib the block's row sum,
 * s_i the full row sum, nb the row cluster's number of nonzero blocks), so
 * the whole row errs by at most tol * s_i.  After rounding the factors to
 * float the actual error sum_j |G_ij - G~_ij| is recomputed and kept per row
 * (cv_hmatrix_row_error): a product then errs by at most row_error_i *
 * max|x|, and the solvers add that to their error bound.
 *
 * Not a hierarchical matrix in the strict sense: one level of clusters (a
 * flat block partition).  At 2 x 64 x 64 patches with 8 x 8 tiles that is
 * 128 clusters and enough to make the product bandwidth-light. */
#ifndef CV_COMPENSATE_HMATRIX_H
#define CV_COMPENSATE_HMATRIX_H

#include <stddef.h>
#include <stdint.h>

#include "compensate/system.h"
#include "core/status.h"

typedef struct cv_hmatrix cv_hmatrix;

typedef struct cv_hmatrix_info {
  size_t n_clusters;
  size_t n_blocks;        /* nonzero blocks */
  size_t n_lowrank;       /* blocks stored as U V^T */
  size_t n_dense;         /* blocks stored dense */
  size_t stored_values;   /* floats stored (dense entries + factor entries) */
  size_t source_nnz;      /* nonzeros of the uncompressed matrix */
  int max_rank;
  double mean_rank;       /* over low-rank blocks */
  double max_row_error;   /* max_i sum_j |G_ij - G~_ij| */
  double max_rel_row_error; /* max_i of that / sum_j G_ij (<= tol) */
  double build_ms;
} cv_hmatrix_info;

/* Compresses F (n x n, CSR gather matrix) with clusters cluster[i] in
 * [0, n_clusters) (every cluster non-empty, at most 4096 patches) and
 * per-row tolerance tol in (0, 0.5).  *out owned by the caller; info (may be
 * NULL) receives the statistics.  Uses OpenMP.
 * Errors: CV_ERR_INVALID (NULL, bad cluster ids, empty or oversized cluster,
 * tol out of range), CV_ERR_NOMEM. */
int cv_hmatrix_build(const cv_ffmatrix *F, const uint32_t *cluster, size_t n_clusters,
                     double tol, cv_hmatrix **out, cv_hmatrix_info *info, cv_err *err);
void cv_hmatrix_destroy(cv_hmatrix *h);

/* n values: sum_j |G_ij - G~_ij| for the stored approximation G~
 * (cv_hmatrix_build: exact; cv_hmatrix_build_direct: estimated, see there). */
const double *cv_hmatrix_row_error(const cv_hmatrix *h);
/* n values: sum_j G~_ij of the stored approximation. */
const double *cv_hmatrix_row_sum(const cv_hmatrix *h);
/* Patches (rows = columns). */
size_t cv_hmatrix_size(const cv_hmatrix *h);

/* g = G~ x for 3-channel vectors (x, g: 3n interleaved, distinct).
 * Deterministic: each row's sum has a fixed order whatever the threads. */
void cv_hmatrix_gather(const cv_hmatrix *h, const double *x, double *g);

/* g += G~ d restricted to the senders j with active[j] != 0 (d is read only
 * there): the update after only some senders changed.  Blocks whose column
 * cluster has no active sender are skipped.  Returns the share of the stored
 * values that were read (the cost in products). */
double cv_hmatrix_gather_add_active(const cv_hmatrix *h, const uint8_t *active, const double *d,
                                    double *g);

#endif
