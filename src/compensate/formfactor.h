/* Form factors between display patches (Bimber et al. 2006, section 3.1;
 * ../shared/REFERENCES.md "Scattering compensation") and the sparse gather
 * matrix of the scattering system (system.h).
 *
 * The paper's point-to-point factor F_ji = A_i cos cos / (pi r^2) is about
 * 60% too high for patches that touch (1/pi = 0.318 against 0.200 for two
 * perpendicular squares sharing an edge).  Here:
 *  - the receiver is integrated exactly: the form factor from a differential
 *    area at x (unit normal n) to a polygon q_1..q_k is Lambert's contour
 *    integral (Hottel & Sarofim; Baum, Rushmeier & Winget 1989, eq. 3)
 *        F = -(1 / 2 pi) sum_k  gamma_k  n . (a_k x b_k) / |a_k x b_k|,
 *        a_k = q_k - x,  b_k = q_{k+1} - x,  gamma_k = angle(a_k, b_k),
 *    positive for a polygon wound counter-clockwise as seen from x (the
 *    patches' winding seen from their front).  The polygon is first clipped
 *    to the half-space n . (q - x) > 0 (Sutherland-Hodgman): the contour
 *    formula integrates the signed cosine and is wrong for the part behind x.
 *  - the sender is integrated numerically, F_ji = (1/A_j) int_j F(x -> i) dA,
 *    with tensor Gauss-Legendre rules on its bilinear (s, t) parameters whose
 *    order grows as the gap to the receiver shrinks relative to the sender's
 *    size, and recursive 2x2 subdivision of the sender where the gap is
 *    below its size (shared edges and corners), up to 6 levels (4x4 Gauss
 *    in the last).
 *  - every unordered pair is evaluated once (both directions).  Lambertian
 *    pairs (cosine exponent 1 and no tilt on both sides) integrate over the
 *    smaller patch (ties: the lower index) and take the other direction from
 *    A_j F_ji = A_i F_ij: reciprocity holds to float rounding.
 *  - light-directing screens (paper section 3.6; display.h): the sender emits
 *    lobe_norm * max(0, cos about its tilted axis)^c into its front
 *    hemisphere (normalised to 1 there), the receiver collects with its
 *    geometric cosine (irradiance).  Exponent 1 with a tilt uses the contour
 *    integral about the tilted axis clipped to both half-spaces.  Other
 *    exponents: F_c = F_1 + D, F_1 the Lambertian factor above (exact at
 *    shared edges) and D the integral over both patches of the difference
 *    of the two lobes' kernels, by product Gauss rules with the closer pair
 *    of sub-quads split first; both lobes integrate to 1, so D is small
 *    exactly where the product rule is weak (closed cube with cos^4 senders:
 *    sums within 1e-5 of 1, against 5e-3 integrating F_c directly).
 *  - visibility: "none" assumes every pair sees each other; "auto" proves it
 *    when every surface lies in the closed inner region (front half-space,
 *    inside the cylinder, inside the sphere) of every other one (then no
 *    segment between two patches can cross a third: a CAVE, the two-sided
 *    wall, a lone cylinder or dome) and otherwise traces rays; "rays" always
 *    traces: one segment per sender quadrature point to the receiver's
 *    centre, both ends moved off their surfaces, against a cv_rt mesh of all
 *    patch quads.  The fraction of unoccluded segments weights the samples.
 *
 * Sparsification is relative to each row's energy (never absolute): with
 * S_i = sum_j F_ji (everything that patch i gathers),
 *  - rel_threshold t drops every F_ji < t * S_i;
 *  - drop_budget b then drops the smallest remaining entries of the row as
 *    long as everything dropped stays <= b * S_i.
 * The dropped fraction per row (dropped / S_i) is reported.  Rows are
 * independent and built in parallel (OpenMP), so the result does not depend
 * on the thread count. */
#ifndef CV_COMPENSATE_FORMFACTOR_H
#define CV_COMPENSATE_FORMFACTOR_H

#include <stddef.h>
#include <stdint.h>

#include "compensate/display.h"
#include "compensate/system.h"
#include "core/status.h"

typedef enum cv_ff_visibility {
  CV_FF_VIS_AUTO = 0,
  CV_FF_VIS_NONE = 1,
  CV_FF_VIS_RAYS = 2,
} cv_ff_visibility;

typedef struct cv_ff_params {
  cv_ff_visibility visibility; /* default CV_FF_VIS_AUTO */
  double rel_threshold;        /* default 0 (see above) */
  double drop_budget;          /* default 1e-3: 0.1% of each row's energy */
  int quiet;                   /* 1: no progress output (default 0) */
} cv_ff_params;

void cv_ff_params_default(cv_ff_params *p);

typedef struct cv_ff_report {
  size_t n;               /* patches */
  size_t nnz_full;        /* nonzero F_ji before sparsification */
  size_t nnz;             /* stored entries */
  double row_sum_min, row_sum_max, row_sum_mean;  /* S_i before sparsification */
  double col_sum_max;     /* max_j sum_i F_ji over the stored entries (what a sender
                             spreads; <= 1 physically) */
  double dropped_max;     /* max over rows of dropped_i / S_i */
  double dropped_mean;    /* mean over rows with S_i > 0 */
  double dropped_total;   /* sum_i dropped_i / sum_i S_i */
  int visibility_traced;  /* 1 when rays were traced */
  uint64_t rays;          /* segments traced */
  uint64_t point_evals;   /* point-to-polygon (or point-to-point) evaluations */
  size_t refined_pairs;   /* pair evaluations that needed subdivision */
  size_t clamped_pairs;   /* pair values below -1e-9 or non-finite, set to 0 */
  double seconds;         /* wall time of the build */
} cv_ff_report;

/* Form factor from a differential area at x with unit normal n to the
 * polygon q[0..k-1] (planar, convex or not, wound counter-clockwise seen from
 * its front; 3 <= k <= 16), clipped to the half-space in front of x.  The
 * caller checks that x is in front of the polygon (else the value is
 * negative: the polygon is seen from behind). */
double cv_ff_point_polygon(const double x[3], const double n[3], const double (*q)[3], int k);

/* The paper's point-to-point estimate A_i cos_j cos_i / (pi r^2) between
 * the centres (0 when facing away); for comparison only. */
double cv_ff_point_to_point(const cv_patch *sender, const cv_patch *receiver);

/* F_ji: fraction of the light leaving patch j that reaches patch i, without
 * visibility (j == i gives 0). */
double cv_ff_patch_pair(const cv_display *d, size_t j, size_t i);

/* One entry of the gather matrix on demand (for builds that never hold the
 * whole matrix: hmatrix.h cv_hmatrix_build_direct).  The kernel holds what
 * the dense build decides once: the visibility mode (the ray-traced mesh
 * when "rays", or "auto" cannot prove that no surface occludes another) and
 * the planar surface pairs that never exchange light.  Entries are exactly
 * what cv_formfactors_build computes before sparsification and its rounding
 * to float.  Evaluation is thread-safe; when cv_ff_kernel_traces() is 1,
 * every thread calls cv_ff_kernel_thread_init() once before evaluating.
 * The kernel borrows d.  Errors: CV_ERR_INVALID (bad parameters or no
 * patches), CV_ERR_NOMEM, CV_ERR_BACKEND (ray tracer). */
typedef struct cv_ff_kernel cv_ff_kernel;
int cv_ff_kernel_create(const cv_display *d, const cv_ff_params *p, cv_ff_kernel **out,
                        cv_err *err);
void cv_ff_kernel_destroy(cv_ff_kernel *k);
int cv_ff_kernel_traces(const cv_ff_kernel *k);
const cv_display *cv_ff_kernel_display(const cv_ff_kernel *k);
void cv_ff_kernel_thread_init(const cv_ff_kernel *k);
/* 0 when surfaces a and b provably exchange no light (whole planar surfaces
 * behind each other's plane, or a planar surface with itself). */
int cv_ff_kernel_surfaces_exchange(const cv_ff_kernel *k, size_t a, size_t b);
/* G_ij = (A_j / A_i) F_ji, the gather entry of row i (receiver), column j
 * (sender), in double (0 for i == j). */
double cv_ff_kernel_gather(const cv_ff_kernel *k, size_t i, size_t j);

/* Builds the gather matrix of the display: row i (receiver) holds
 * (j, G_ij = (A_j / A_i) F_ji) for every sender j != i that survives
 * sparsification, columns ascending (F_ji as in cv_ff_patch_pair; G_ij =
 * F_ij for Lambertian patches; see system.h).
 * *F_gather owned by the caller (cv_ffmatrix_destroy).  rep and p may be
 * NULL (p NULL = defaults).  Prints progress on stderr for large displays
 * unless p->quiet.  Errors: CV_ERR_INVALID (bad parameters), CV_ERR_NOMEM,
 * CV_ERR_BACKEND (ray tracer). */
int cv_formfactors_build(const cv_display *d, const cv_ff_params *p, cv_ffmatrix **F_gather,
                         cv_ff_report *rep, cv_err *err);

#endif
