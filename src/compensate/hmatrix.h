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
 * cv_hmatrix_build: not a hierarchical matrix in the strict sense: one level
 * of clusters (a flat block partition) of a matrix already built.  At
 * 2 x 64 x 64 patches with 8 x 8 tiles that is 128 clusters and enough to
 * make the product bandwidth-light.
 *
 * cv_hmatrix_build_direct: hierarchical, and built from the display without
 * the dense matrix (see there): far blocks are pairs of large clusters (up to
 * wall quadrants), found by partially pivoted ACA on entries evaluated on
 * demand; its per-row error is an estimate, not the exact figure above.
 *
 * Storage (both builds): blocks of any cluster-aligned row and column range;
 * a product first forms V x for every low-rank block, then sums each leaf
 * cluster's rows over the blocks that cover it in a fixed order. */
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

/* Direct build: the compressed gather matrix of a display without ever
 * forming the dense (or CSR) matrix, entries evaluated on demand by the
 * form-factor kernel (formfactor.h cv_ff_kernel: the same quadrature and
 * visibility as cv_formfactors_build, without its sparsification).
 *  - clusters: per surface a quadtree of its patch grid (halving each side
 *    longer than `leaf` patches), patches numbered leaf by leaf;
 *  - blocks: a block tree over pairs of clusters of surfaces that exchange
 *    light; a pair is far (admissible) when the larger bounding-box diagonal
 *    is at most eta times the distance between the boxes, then it is one
 *    low-rank block (whole quadrants of opposite walls at a time); two near
 *    leaves (seams) are a dense block, evaluated entry by entry;
 *  - far blocks: adaptive cross approximation with partial pivoting
 *    (Bebendorf 2000): rank one step = one evaluated row and one column of
 *    the residual, so a rank-k block of m x w costs k (m + w) entries.  It
 *    stops when for every row i of the block the newest term is within
 *    tol / 2 of the row's block sum:  |u_k(i)| sum_j |v_k(j)| <= tol/2 s~_ib
 *    (rows under 1e-6 of the block's largest row sum are held to that
 *    floor), and then four check rows (nearest to and farthest from the
 *    column cluster, first and last) meet the same rule with their residual
 *    evaluated in full (one that fails becomes the next pivot).  The newest
 *    term estimates the remaining error (the standard ACA criterion): the
 *    bound is ESTIMATED, not proven (the dense path's is exact); the error
 *    against the dense build is measured in tests/compensate/test_hmatrix.c
 *    and docs/benchmarks.md (true errors within tol, the estimate up to
 *    7x below them).  A block whose factors would take more than half its dense
 *    size (or a rank above 128) is split again; a leaf pair is then dense.
 *  - row error: per row the sum of the estimates of its blocks (plus float
 *    rounding of the factors), <= tol/2 s~_i when every block met the rule;
 *    cv_hmatrix_row_error returns it for the solvers' error bounds.
 * tol in (0, 0.5); eta > 0 (1 is a good default); leaf in 2..64.  fp may be
 * NULL (defaults; rel_threshold and drop_budget are not used).  quiet = 0
 * shows progress for large displays.  info->source_nnz is the number of
 * pairs of the dense build (n^2 less the pairs of surfaces that exchange no
 * light).  Errors: CV_ERR_INVALID, CV_ERR_NOMEM, CV_ERR_BACKEND. */
struct cv_display;
struct cv_ff_params;
typedef struct cv_hmatrix_direct_params {
  double tol;   /* default CV_HMATRIX_DIRECT_TOL */
  double eta;   /* default 1 */
  int leaf;     /* default 8 (CV_DISPLAY_TILE) */
  int quiet;    /* default 0 */
} cv_hmatrix_direct_params;
#define CV_HMATRIX_DIRECT_TOL 1e-3
void cv_hmatrix_direct_params_default(cv_hmatrix_direct_params *p);
int cv_hmatrix_build_direct(const struct cv_display *d, const struct cv_ff_params *fp,
                            const cv_hmatrix_direct_params *p, cv_hmatrix **out,
                            cv_hmatrix_info *info, cv_err *err);

/* n values: sum_j |G_ij - G~_ij| for the stored approximation G~
 * (cv_hmatrix_build: exact; cv_hmatrix_build_direct: estimated, see there). */
const double *cv_hmatrix_row_error(const cv_hmatrix *h);
/* n values: sum_j G~_ij of the stored approximation. */
const double *cv_hmatrix_row_sum(const cv_hmatrix *h);
/* row (n values) = row i of the stored approximation G~ (for checks). */
void cv_hmatrix_row_values(const cv_hmatrix *h, size_t i, double *row);
/* The statistics the build reported. */
void cv_hmatrix_get_info(const cv_hmatrix *h, cv_hmatrix_info *info);
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
