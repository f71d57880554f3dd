/* Scattering compensation solvers and the display physics that judges them
 * (Bimber et al. 2006, "Compensating Indirect Scattering for Immersive and
 * Semi-Immersive Projection Displays"; ../shared/REFERENCES.md "Scattering
 * compensation").  Notation as in system.h: B = D + K B with
 * D = a I + e, a_i = F_i M_i (per channel), e_i = E_i M_i.
 *
 * Given the radiosity R a viewer should see, the solvers compute the
 * projector input I in [0, 1] (3n floats, interleaved RGB per patch):
 *   exact    D = (Id - K) R (one product), I = (D - e) / a, out-of-range
 *            values clamped and counted ("naive clipping").
 *   jacobi   the paper's algorithm 2: H scatter levels per pass (eq. 2, 5, 6)
 *            with its two exit conditions (section 3.3).  Converges only while
 *            rho(K) < 0.5, so it is refused above that, and stopped with an
 *            error when its updates grow.
 *   bounded  clipping-aware: the complementarity solution of the projector
 *            limits.  Every patch whose I is strictly inside (0, 1) displays
 *            R (to opts.tol); a patch at a limit displays as close to R as the
 *            limit allows given the light of all the others.  Computed by a
 *            projected Jacobi iteration on the displayed radiosity
 *                B <- median(R, e + K B, e + a + K B)
 *            which contracts with factor ||K||_inf (< 1 physically) for every
 *            rho(K) < 1, i.e. also where the paper's iteration diverges.  After
 *            the first sweep only clipped patches change, so later sweeps
 *            update K B from the changed senders only (a transposed copy of
 *            the matrix).  See solve.c for why this rather than the
 *            least-squares minimiser of ||B(I) - R||.
 *   auto     bounded started from B = R: its first sweep is the exact solve,
 *            and it stops there when nothing clips (reported as exact).
 * Stereo: one solve on (left + right) / 2, the same I for both eyes (paper,
 * section 3.4).
 *
 * All vectors are 3n, interleaved (r, g, b) per patch; sums are in double.
 * No NaN or Inf is ever written to an output. */
#ifndef CV_COMPENSATE_SOLVE_H
#define CV_COMPENSATE_SOLVE_H

#include <stddef.h>

#include "compensate/system.h"
#include "core/status.h"

/* ---- Display physics (independent of the solvers) ---------------------- */

/* What a viewer sees for projector input I (3n, finite; values are used as
 * given, callers model projector limits by passing I in [0, 1]): solves
 * B = D + K B, D_i = F_i M_i I_i + E_i M_i, by Jacobi iteration with the
 * system's own product cv_scatter_apply_K until the update (= residual
 * D + K B - B) is below tol * max|B| (e.g. tol = 1e-9).  B: 3n, caller-owned.
 * *iters (may be NULL) receives the iterations used.
 * Errors: CV_ERR_INVALID (NULL or inconsistent system, tol <= 0),
 * CV_ERR_NONFINITE (I not finite), CV_ERR_RANGE (no convergence: spectral
 * radius >= 1 or iteration cap; B then holds zeros), CV_ERR_NOMEM. */
int cv_scatter_physics(const cv_scatter_system *s, const float *I, double *B,
                       double tol, int *iters);

/* Power-iteration estimate of the spectral radius of K (maximum over the
 * three channels).  K >= 0, so the Perron vector is non-negative; the
 * iteration runs on Id + K from ones (the shift makes it converge also for
 * bipartite K such as two walls, whose eigenvalues come in +-rho pairs) and
 * stops after iters steps or when the estimate is stable to 1e-12.
 * Returns a negative value on invalid input or out of memory. */
double cv_scatter_spectral_radius(const cv_scatter_system *s, int iters);

/* y = K^T x for 3-channel vectors (x, y: 3n, distinct), i.e.
 * y_j = sum_i M_i F_ji x_i.  Serial scatter; a reference for adjoint uses.
 * Needs F: a system with only H gets y = 0. */
void cv_scatter_apply_KT(const cv_scatter_system *s, const double *x, double *y);

/* ---- Solvers ----------------------------------------------------------- */

typedef enum cv_scatter_solver {
  CV_SCATTER_AUTO = 0,
  CV_SCATTER_EXACT,
  CV_SCATTER_JACOBI,
  CV_SCATTER_BOUNDED
} cv_scatter_solver;

/* Name of a solver ("auto", "exact", "jacobi", "bounded"); never NULL. */
const char *cv_scatter_solver_name(cv_scatter_solver s);

typedef enum cv_scatter_exit {
  CV_SCATTER_EXIT_CONVERGED = 0, /* exact, or an exit threshold was met */
  CV_SCATTER_EXIT_TIME,          /* the time slot (opts.time_ms) ran out */
  CV_SCATTER_EXIT_MAX_ITERS      /* opts.max_iters passes */
} cv_scatter_exit;

typedef struct cv_scatter_opts {
  cv_scatter_solver solver;  /* default CV_SCATTER_AUTO */
  int levels;                /* jacobi: scatter levels H >= 1 (default 2) */
  double threshold;          /* jacobi: a patch "changed" when a channel of I
                                moved by more than this (default 1/255) */
  size_t max_changed;        /* jacobi: exit when fewer patches changed
                                (default 1, i.e. none changed) */
  double time_ms;            /* jacobi, bounded: time slot, <= 0 none (default 0) */
  int max_iters;             /* jacobi, bounded: cap on passes (default 500) */
  double tol;                /* bounded: allowed displayed error on patches not
                                at a limit (default 0.5/255) */
  double jacobi_rho_limit;   /* jacobi refused when rho(K) >= this (default
                                0.5, the paper's limit; raising it is for
                                experiments, the divergence guard still acts) */
  int warm_start;            /* start from the workspace's previous solve of
                                the same solver (previous frame) */
} cv_scatter_opts;

/* Fills o with the defaults above. */
void cv_scatter_opts_default(cv_scatter_opts *o);

typedef struct cv_scatter_stats {
  cv_scatter_solver solver;  /* the solver that produced I (auto: exact or bounded) */
  cv_scatter_exit exit;
  int iterations;            /* jacobi passes / bounded sweeps (exact: 1) */
  double products;           /* work in full K products (sparse updates count
                                by their share of the nonzeros) */
  size_t clipped_channels;   /* patch channels the solution wanted outside [0, 1]
                                (exact: clamped; bounded: held at a limit) */
  size_t clipped_patches;    /* patches with at least one clipped channel */
  double ms;                 /* wall time of the solve */
  double residual;           /* exact: 0; jacobi: last max change of I;
                                bounded: bound on |B - R| on patches not at a
                                limit (and on the error of rms/max_error),
                                including the half-storage error if any */
  double rms_error;          /* bounded and unclipped exact: displayed RMS
                                error over all 3n values; -1 when not known
                                (judge with cv_scatter_physics) */
  double max_error;          /* as rms_error, maximum */
  double rho;                /* spectral radius estimate of K */
  int stereo;                /* 1 when solved for a stereo pair's average */
} cv_scatter_stats;

/* Everything a system needs to be solved fast, built once and reused for
 * every frame: validated copies of a = F M and e = E M, a run-length form of
 * the gather matrix, its transpose, rho(K), ||K||_inf, scratch vectors and
 * the previous frame's state.  The workspace borrows s and the arrays it
 * points to (they must outlive it and not change).  One solve at a time per
 * workspace (solves use OpenMP inside). */
typedef struct cv_scatter_workspace cv_scatter_workspace;

/* cv_scatter_workspace_create_ex flag: the solvers read a half-precision
 * copy of F (2 bytes per nonzero instead of 4; products are memory-bound, so
 * about twice as fast on dense K).  Each form factor is then off by at most
 * 2^-11 relative, so a product K x by at most 2^-11 ||K|x|||; the bounded
 * solver adds this to stats.residual (which may then exceed opts.tol).  The
 * exact solve reproduces R to about 1e-4 instead of 1e-7.  Physics and
 * cv_scatter_spectral_radius always use F itself. */
#define CV_SCATTER_WS_HALF 1u
/* Flag: portable (non-SIMD) kernels even where AVX2/F16C exist (for tests). */
#define CV_SCATTER_WS_PORTABLE 2u
/* Flag: compress F into dense near-field and low-rank far-field blocks
 * (hmatrix.h) when the system has patch clusters (cv_display_scatter_system
 * gives tiles of 8 x 8 patches) and the compressed form takes at most half the
 * bytes; every product then errs by at most tol (default
 * CV_SCATTER_COMPRESS_TOL) times each row's sum, which the solvers add to
 * stats.residual.  Otherwise the flag is ignored (see the model). */
#define CV_SCATTER_WS_COMPRESS 4u
#define CV_SCATTER_COMPRESS_TOL 1e-3

#include "compensate/hmatrix.h"

/* Which storage of K the workspace picked, and what it costs. */
typedef struct cv_scatter_model {
  const char *storage;       /* "float", "half", "block low-rank" or "block
                                low-rank (direct)" (the system has only H) */
  double bytes;              /* bytes of matrix values a product reads */
  double source_bytes;       /* the same for the plain (float or half) storage */
  int compress_tried;        /* CV_SCATTER_WS_COMPRESS and clusters given */
  double compressed_bytes;   /* what the compressed form took (also if rejected) */
  cv_hmatrix_info compress_info;
  double error_bound;        /* bound on |K~ x - K x| / max|x| of a product */
} cv_scatter_model;

/* Validates s and builds the workspace; *out owned by the caller (destroy).
 * Errors (err names the field and index): CV_ERR_INVALID (NULL, n == 0,
 * F->n != n, bad row offsets or columns), CV_ERR_NONFINITE, CV_ERR_RANGE
 * (reflectance outside [0, 1], negative form factor, projector factor or
 * environment), CV_ERR_NOMEM. */
int cv_scatter_workspace_create(const cv_scatter_system *s,
                                cv_scatter_workspace **out, cv_err *err);
/* As cv_scatter_workspace_create, with flags (CV_SCATTER_WS_*, or-ed). */
int cv_scatter_workspace_create_ex(const cv_scatter_system *s, unsigned flags,
                                   cv_scatter_workspace **out, cv_err *err);
/* As create_ex with an explicit compression tolerance in (0, 0.5). */
int cv_scatter_workspace_create_tol(const cv_scatter_system *s, unsigned flags, double tol,
                                    cv_scatter_workspace **out, cv_err *err);
void cv_scatter_workspace_destroy(cv_scatter_workspace *w);
/* The storage model the workspace picked.  CV_ERR_INVALID on NULL. */
int cv_scatter_workspace_get_model(const cv_scatter_workspace *w, cv_scatter_model *out);

/* The spectral radius estimate and ||K||_inf (max row sum over channels)
 * computed at creation. */
double cv_scatter_workspace_rho(const cv_scatter_workspace *w);
double cv_scatter_workspace_norm_inf(const cv_scatter_workspace *w);

/* Solves for projector input I (3n floats in [0, 1], caller-owned) that
 * displays R (3n floats, finite; negative or unreachable values are clipped).
 * opts may be NULL (defaults); stats may be NULL.
 * Errors: CV_ERR_INVALID (NULL argument, bad option), CV_ERR_NONFINITE (R not
 * finite: err names the patch and channel), CV_ERR_RANGE (jacobi refused for
 * rho(K) >= opts.jacobi_rho_limit or stopped because it diverged; bounded
 * with rho(K) >= 1).  On error I is left untouched. */
int cv_scatter_solve(cv_scatter_workspace *w, const float *R,
                     const cv_scatter_opts *opts, float *I,
                     cv_scatter_stats *stats, cv_err *err);

/* Stereo pair: one solve on (R_left + R_right) / 2, whose I serves both eyes
 * (paper, section 3.4); stats->stereo = 1.  Errors as cv_scatter_solve (a
 * non-finite value names R_left or R_right). */
int cv_scatter_solve_stereo(cv_scatter_workspace *w, const float *R_left,
                            const float *R_right, const cv_scatter_opts *opts,
                            float *I, cv_scatter_stats *stats, cv_err *err);

#endif
