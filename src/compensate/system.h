/* The linear system of inter-screen scattering (Bimber et al. 2006; see
 * ../shared/REFERENCES.md "Scattering compensation"), shared by the
 * form-factor code (which builds it) and the solvers (which use it).
 *
 * P patches, 3 colour channels.  What a viewer sees (radiosity B) for
 * projector input I in [0, 1]:
 *     B = D + K B,   D_i = F_i M_i I_i + E_i M_i,   (K B)_i = M_i sum_j G_ij B_j
 * G_ij = (A_j / A_i) F_{j->i}: the light that sender j (with its own
 * reflection lobe) puts on patch i, per unit of i's area, where F_{j->i} is
 * the fraction of the light leaving j that arrives at i.  For Lambertian
 * patches reciprocity (A_i F_{i->j} = A_j F_{j->i}) makes G_ij = F_{i->j}.
 * The paper's "F_ji" (REFERENCES.md: K_ij = M_i F_ji) is the same number
 * when patches have equal areas; graded patches need the area ratio.
 * F_i: projector-to-patch factor
 * (1 for "ideal" projectors); M_i: reflectance (RGB); E_i: uncontrolled light
 * arriving at patch i (stray light and projector black level, RGB).
 * The exact compensation for a wanted image R is D = (I - K) R. */
#ifndef CV_COMPENSATE_SYSTEM_H
#define CV_COMPENSATE_SYSTEM_H

#include <stddef.h>
#include <stdint.h>

/* Sparse gather matrix in CSR form: row i (the receiver) lists the patches j
 * it sees with value G_ij = F_{i->j}.  Values are float (storage), sums are
 * done in double. */
typedef struct cv_ffmatrix {
  size_t n;          /* patches (rows and columns) */
  size_t nnz;
  size_t *row_off;   /* n + 1 */
  uint32_t *col;     /* nnz, ascending within a row */
  float *val;        /* nnz */
} cv_ffmatrix;

/* Allocates an n-row matrix with room for nnz entries (row_off zeroed);
 * *out owned by the caller.  CV_ERR_NOMEM. */
int cv_ffmatrix_alloc(size_t n, size_t nnz, cv_ffmatrix **out);
void cv_ffmatrix_destroy(cv_ffmatrix *m);

struct cv_hmatrix;

typedef struct cv_scatter_system {
  size_t n;                /* patches */
  const cv_ffmatrix *F;    /* gather form factors F_ji (borrowed); may be NULL when H is set */
  /* Optional (NULL: none): the gather matrix already compressed (hmatrix.h,
   * e.g. built directly from the display); used for every product when F
   * is NULL (borrowed). */
  const struct cv_hmatrix *H;
  const float *refl;       /* 3n: M_i (r, g, b) in [0, 1] */
  const float *proj;       /* n: F_i projector-to-patch factor (> 0) */
  const float *env;        /* 3n: E_i (r, g, b) >= 0 */
  /* Optional (NULL when unknown): groups of nearby patches, cluster[i] in
   * [0, n_clusters), used only to compress K (hmatrix.h,
   * CV_SCATTER_WS_COMPRESS). */
  const uint32_t *cluster;
  size_t n_clusters;
} cv_scatter_system;

/* y = K x for 3-channel vectors (x, y: 3n, interleaved per patch, distinct);
 * from F, or from H when F is NULL. */
void cv_scatter_apply_K(const cv_scatter_system *s, const double *x, double *y);

#endif
