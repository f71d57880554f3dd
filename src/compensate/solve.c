/* Scattering compensation: display physics, spectral radius, and the exact,
 * paper (Jacobi), bounded and automatic solvers (see solve.h).
 *
 * Why the bounded solver computes the complementarity solution rather than
 * the least-squares minimiser of ||B(I) - R||^2 over 0 <= I <= 1: at the
 * least-squares optimum the error of a clipped patch is traded against its
 * neighbours, so patches that are not at a limit do not display R (next to a
 * black band in a corner they are off by several 1/255 steps), which breaks
 * the guarantee asked of this solver ("every patch whose I is strictly inside
 * (0, 1) displays R within 1/255").  The complementarity solution keeps that
 * guarantee, is unique (Id - K is an M-matrix for rho(K) < 1), is never worse
 * than naive clipping where only one limit is hit (by monotonicity of
 * (Id - K)^-1 >= 0, every displayed error shrinks), and is reached by a
 * projected Jacobi iteration whose cost after the first sweep is proportional
 * to the number of clipped patches.
 *
 * Speed: the products are memory-bound, so the workspace stores the gather
 * matrix as runs of consecutive senders (no per-entry column index: the
 * values of F are read in place, or from a half-precision copy with
 * CV_SCATTER_WS_HALF) and gathers from a planar copy of x; a transposed copy
 * lets a sweep update K B from the few senders that changed.  Measured on the
 * 2-core machine, 8192 patches with 4096 nonzeros per row: one product 15 ms
 * (float values), 5 ms (half values, the copy then fits the last-level cache). */
#include "compensate/solve.h"

#include "compensate/hmatrix.h"

#include "io/exr.h"

#include <math.h>
#include <omp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* gcc only: clang 14 (the fuzz build) rejects __builtin_cpu_supports("f16c"). */
#if defined(__GNUC__) && !defined(__clang__) && (defined(__x86_64__) || defined(__i386__))
#include <immintrin.h>
#define CV_HAVE_X86_F16C 1
#endif

struct cv_scatter_workspace {
  cv_scatter_system s;  /* borrowed pointers */
  size_t n, nnz;
  size_t *rrun_off;     /* n + 1: runs of row i are rrun[2*rrun_off[i] ..] */
  uint32_t *rrun;       /* (first sender, length) per run */
  size_t *cval_off;     /* n + 1: receivers of sender j in cval[cval_off[j] ..] */
  float *cval;          /* nnz: F_ji in column-major order */
  size_t *crun_off;     /* n + 1 */
  uint32_t *crun;       /* (first receiver, length) per run */
  double *a, *e;        /* 3n: F_i M_i and E_i M_i */
  double *xp;           /* 3n: planar copy of the vector being gathered */
  double *R, *B, *g, *U, *T, *T2, *D; /* 3n scratch and state */
  uint8_t *active;      /* n */
  uint32_t *alist;      /* n */
  uint8_t *clip;        /* 3n: channel held at a limit (bounded) */
  double *B_prev, *D_prev;
  uint8_t *clip_prev;
  int have_B_prev, have_D_prev;
  double rho, qinf;
  /* CV_SCATTER_WS_HALF: half-precision copies of F (scaled by 1 / inv_scale
   * into the normal range), replacing val-in-place and cval. */
  int half, simd;
  uint16_t *hval, *hcval;
  float *h2f;           /* 65536: half -> float table (portable kernels) */
  double inv_scale;
  /* CV_SCATTER_WS_COMPRESS, when it paid: the block low-rank form of F that
   * every product then uses; ek = max_i,c M_i sum_j |F_ji - F~_ji|. */
  cv_hmatrix *hm;
  int hm_borrowed;      /* 1: hm is s->H (system without F) */
  cv_hmatrix_info hinfo;
  double ek;
  cv_scatter_model model;
};

const char *cv_scatter_solver_name(cv_scatter_solver s) {
  switch (s) {
    case CV_SCATTER_AUTO: return "auto";
    case CV_SCATTER_EXACT: return "exact";
    case CV_SCATTER_JACOBI: return "jacobi";
    case CV_SCATTER_BOUNDED: return "bounded";
  }
  return "unknown";
}

void cv_scatter_opts_default(cv_scatter_opts *o) {
  memset(o, 0, sizeof *o);
  o->solver = CV_SCATTER_AUTO;
  o->levels = 2;
  o->threshold = 1.0 / 255.0;
  o->max_changed = 1;
  o->time_ms = 0;
  o->max_iters = 500;
  o->tol = 0.5 / 255.0;
  o->jacobi_rho_limit = 0.5;
  o->warm_start = 0;
}

/* ---- Physics and reference products ------------------------------------ */

static int system_ok(const cv_scatter_system *s) {
  if (s && !s->F && s->H)
    return s->n > 0 && cv_hmatrix_size(s->H) == s->n && s->refl && s->proj && s->env;
  return s && s->n > 0 && s->F && s->F->n == s->n && s->F->row_off && s->refl &&
         s->proj && s->env && (s->F->nnz == 0 || (s->F->col && s->F->val));
}

int cv_scatter_physics(const cv_scatter_system *s, const float *I, double *B,
                       double tol, int *iters) {
  if (iters) *iters = 0;
  if (!system_ok(s) || !I || !B || !(tol > 0)) return CV_ERR_INVALID;
  const size_t n3 = 3 * s->n;
  for (size_t p = 0; p < n3; p++)
    if (!isfinite(I[p])) return CV_ERR_NONFINITE;
  double *D = malloc(n3 * sizeof *D), *T = malloc(n3 * sizeof *T);
  if (!D || !T) {
    free(D);
    free(T);
    return CV_ERR_NOMEM;
  }
  for (size_t p = 0; p < n3; p++) {
    D[p] = (double)s->proj[p / 3] * s->refl[p] * I[p] + (double)s->env[p] * s->refl[p];
    B[p] = D[p];
  }
  /* Jacobi: B <- D + K B.  The update equals the residual D + K B - B. */
  const int max_it = 20000;
  int status = CV_ERR_RANGE, grow = 0, it;
  double r_prev = INFINITY;
  for (it = 1; it <= max_it; it++) {
    cv_scatter_apply_K(s, B, T);
    double r = 0, bmax = 0;
    for (size_t p = 0; p < n3; p++) {
      const double bn = D[p] + T[p];
      const double d = fabs(bn - B[p]);
      if (!(d <= r)) r = d; /* also catches NaN */
      if (fabs(bn) > bmax) bmax = fabs(bn);
      B[p] = bn;
    }
    if (!isfinite(r) || !isfinite(bmax)) break;
    if (r <= tol * bmax) {
      status = CV_OK;
      break;
    }
    grow = r > r_prev ? grow + 1 : 0;
    if (grow >= 50) break; /* spectral radius >= 1 */
    r_prev = r;
  }
  if (iters) *iters = it > max_it ? max_it : it;
  if (status != CV_OK) memset(B, 0, n3 * sizeof *B);
  free(D);
  free(T);
  return status;
}

void cv_scatter_apply_KT(const cv_scatter_system *s, const double *x, double *y) {
  const cv_ffmatrix *F = s->F;
  memset(y, 0, 3 * s->n * sizeof *y);
  if (!F) return; /* not available for a compressed-only system (documented) */
  for (size_t i = 0; i < s->n; i++) {
    const double x0 = s->refl[3 * i] * x[3 * i], x1 = s->refl[3 * i + 1] * x[3 * i + 1],
                 x2 = s->refl[3 * i + 2] * x[3 * i + 2];
    for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) {
      const double f = F->val[k];
      double *yj = y + 3 * (size_t)F->col[k];
      yj[0] += f * x0;
      yj[1] += f * x1;
      yj[2] += f * x2;
    }
  }
}

typedef void (*apply_fn)(void *ctx, const double *x, double *y);

/* Power iteration on Id + K from ones, per channel (K does not mix channels).
 * Estimate per channel: sum(K x) / sum(x), which tends to rho for x -> the
 * non-negative Perron vector.  x, y: 3n scratch.  Returns max over channels. */
static double power_rho(size_t n, apply_fn apply, void *ctx, int iters, double tol, double *x,
                        double *y) {
  const size_t n3 = 3 * n;
  for (size_t p = 0; p < n3; p++) x[p] = 1.0 / (double)n;
  double est[3] = {0, 0, 0}, prev[3] = {-1, -1, -1};
  for (int it = 0; it < iters; it++) {
    apply(ctx, x, y);
    double sx[3] = {0, 0, 0}, sy[3] = {0, 0, 0};
    for (size_t p = 0; p < n3; p++) {
      sx[p % 3] += x[p];
      sy[p % 3] += y[p];
    }
    int stable = 1;
    for (int c = 0; c < 3; c++) {
      est[c] = sx[c] > 0 ? sy[c] / sx[c] : 0;
      if (fabs(est[c] - prev[c]) > tol * (est[c] > 1e-300 ? est[c] : 1e-300)) stable = 0;
      prev[c] = est[c];
    }
    const double scale[3] = {sx[0] + sy[0] > 0 ? 1 / (sx[0] + sy[0]) : 0,
                             sx[1] + sy[1] > 0 ? 1 / (sx[1] + sy[1]) : 0,
                             sx[2] + sy[2] > 0 ? 1 / (sx[2] + sy[2]) : 0};
    for (size_t p = 0; p < n3; p++) x[p] = (x[p] + y[p]) * scale[p % 3];
    if (stable && it >= 8) break;
  }
  double r = est[0];
  if (est[1] > r) r = est[1];
  if (est[2] > r) r = est[2];
  return isfinite(r) ? r : -1;
}

static void apply_K_ref(void *ctx, const double *x, double *y) {
  cv_scatter_apply_K((const cv_scatter_system *)ctx, x, y);
}

double cv_scatter_spectral_radius(const cv_scatter_system *s, int iters) {
  if (!system_ok(s) || iters < 1) return -1;
  double *x = malloc(3 * s->n * sizeof *x), *y = malloc(3 * s->n * sizeof *y);
  double r = -1;
  if (x && y) r = power_rho(s->n, apply_K_ref, (void *)s, iters, 1e-12, x, y);
  free(x);
  free(y);
  return r;
}

/* ---- Workspace kernels --------------------------------------------------- */

/* One row of the gather: acc[c] = sum over the row's runs of v * x_c. */
static void row_float(const float *v, const uint32_t *run, size_t nrun, const double *xr,
                      const double *xg, const double *xb, double acc[3]) {
  double a0 = 0, a1 = 0, a2 = 0, b0 = 0, b1 = 0, b2 = 0;
  for (size_t r = 0; r < nrun; r++) {
    const size_t c = run[2 * r], len = run[2 * r + 1];
    const double *pr = xr + c, *pg = xg + c, *pb = xb + c;
    size_t k = 0;
    for (; k + 2 <= len; k += 2) {
      const double f = v[k], h = v[k + 1];
      a0 += f * pr[k];
      a1 += f * pg[k];
      a2 += f * pb[k];
      b0 += h * pr[k + 1];
      b1 += h * pg[k + 1];
      b2 += h * pb[k + 1];
    }
    if (k < len) {
      const double f = v[k];
      a0 += f * pr[k];
      a1 += f * pg[k];
      a2 += f * pb[k];
    }
    v += len;
  }
  acc[0] = a0 + b0;
  acc[1] = a1 + b1;
  acc[2] = a2 + b2;
}

static void row_half_tab(const uint16_t *v, const float *tab, const uint32_t *run, size_t nrun,
                         const double *xr, const double *xg, const double *xb, double acc[3]) {
  double a0 = 0, a1 = 0, a2 = 0;
  for (size_t r = 0; r < nrun; r++) {
    const size_t c = run[2 * r], len = run[2 * r + 1];
    for (size_t k = 0; k < len; k++) {
      const double f = tab[v[k]];
      a0 += f * xr[c + k];
      a1 += f * xg[c + k];
      a2 += f * xb[c + k];
    }
    v += len;
  }
  acc[0] = a0;
  acc[1] = a1;
  acc[2] = a2;
}

#ifdef CV_HAVE_X86_F16C
/* AVX2 + F16C: 8 halves -> 8 floats -> 2 x 4 doubles, fused multiply-add in
 * double.  Bandwidth, not arithmetic, bounds it: 2 bytes per nonzero. */
__attribute__((target("avx2,fma,f16c"))) static void row_half_avx2(
    const uint16_t *v, const uint32_t *run, size_t nrun, const double *xr, const double *xg,
    const double *xb, double acc[3]) {
  __m256d a0 = _mm256_setzero_pd(), a1 = a0, a2 = a0, b0 = a0, b1 = a0, b2 = a0;
  double s0 = 0, s1 = 0, s2 = 0;
  for (size_t r = 0; r < nrun; r++) {
    const size_t c = run[2 * r], len = run[2 * r + 1];
    const double *pr = xr + c, *pg = xg + c, *pb = xb + c;
    size_t k = 0;
    for (; k + 8 <= len; k += 8) {
      const __m256 f8 = _mm256_cvtph_ps(_mm_loadu_si128((const __m128i *)(const void *)(v + k)));
      const __m256d f = _mm256_cvtps_pd(_mm256_castps256_ps128(f8));
      const __m256d h = _mm256_cvtps_pd(_mm256_extractf128_ps(f8, 1));
      a0 = _mm256_fmadd_pd(f, _mm256_loadu_pd(pr + k), a0);
      a1 = _mm256_fmadd_pd(f, _mm256_loadu_pd(pg + k), a1);
      a2 = _mm256_fmadd_pd(f, _mm256_loadu_pd(pb + k), a2);
      b0 = _mm256_fmadd_pd(h, _mm256_loadu_pd(pr + k + 4), b0);
      b1 = _mm256_fmadd_pd(h, _mm256_loadu_pd(pg + k + 4), b1);
      b2 = _mm256_fmadd_pd(h, _mm256_loadu_pd(pb + k + 4), b2);
    }
    for (; k < len; k++) {
      const double f = _cvtsh_ss(v[k]);
      s0 += f * pr[k];
      s1 += f * pg[k];
      s2 += f * pb[k];
    }
    v += len;
  }
  double t[4];
  _mm256_storeu_pd(t, _mm256_add_pd(a0, b0));
  acc[0] = s0 + ((t[0] + t[1]) + (t[2] + t[3]));
  _mm256_storeu_pd(t, _mm256_add_pd(a1, b1));
  acc[1] = s1 + ((t[0] + t[1]) + (t[2] + t[3]));
  _mm256_storeu_pd(t, _mm256_add_pd(a2, b2));
  acc[2] = s2 + ((t[0] + t[1]) + (t[2] + t[3]));
}
#endif

/* g_i = sum_j F_ji x_j for the three channels (no M_i). */
static void ws_gather(cv_scatter_workspace *w, const double *x, double *g) {
  if (w->hm) {
    cv_hmatrix_gather(w->hm, x, g);
    return;
  }
  const size_t n = w->n;
  double *xr = w->xp, *xg = w->xp + n, *xb = w->xp + 2 * n;
  const float *val = w->s.F->val;
  const size_t *row_off = w->s.F->row_off;
#pragma omp parallel
  {
#pragma omp for schedule(static)
    for (size_t j = 0; j < n; j++) {
      xr[j] = x[3 * j];
      xg[j] = x[3 * j + 1];
      xb[j] = x[3 * j + 2];
    }
#pragma omp for schedule(dynamic, 32)
    for (size_t i = 0; i < n; i++) {
      const uint32_t *run = w->rrun + 2 * w->rrun_off[i];
      const size_t nrun = w->rrun_off[i + 1] - w->rrun_off[i];
      double acc[3];
      if (!w->half) {
        row_float(val + row_off[i], run, nrun, xr, xg, xb, acc);
      } else {
#ifdef CV_HAVE_X86_F16C
        if (w->simd)
          row_half_avx2(w->hval + row_off[i], run, nrun, xr, xg, xb, acc);
        else
#endif
          row_half_tab(w->hval + row_off[i], w->h2f, run, nrun, xr, xg, xb, acc);
        for (int c = 0; c < 3; c++) acc[c] *= w->inv_scale;
      }
      g[3 * i] = acc[0];
      g[3 * i + 1] = acc[1];
      g[3 * i + 2] = acc[2];
    }
  }
}

/* y = K x (x, y distinct). */
static void ws_apply_K(cv_scatter_workspace *w, const double *x, double *y) {
  ws_gather(w, x, y);
  const float *refl = w->s.refl;
  const size_t n3 = 3 * w->n;
#pragma omp parallel for schedule(static)
  for (size_t p = 0; p < n3; p++) y[p] *= refl[p];
}

static void ws_apply_K_ctx(void *ctx, const double *x, double *y) {
  ws_apply_K((cv_scatter_workspace *)ctx, x, y);
}

/* g_i += sum_{j in alist} F_ji delta_j, from the transposed copy.  Each
 * thread owns a range of receivers, so the sums are deterministic. */
static void ws_scatter_update(cv_scatter_workspace *w, size_t na, const double *delta, double *g) {
  const size_t n = w->n;
#pragma omp parallel
  {
    const size_t nt = (size_t)omp_get_num_threads(), t = (size_t)omp_get_thread_num();
    const size_t t0 = n * t / nt, t1 = n * (t + 1) / nt;
    for (size_t q = 0; q < na; q++) {
      const size_t j = w->alist[q];
      const double sc = w->half ? w->inv_scale : 1.0;
      const double d0 = sc * delta[3 * j], d1 = sc * delta[3 * j + 1], d2 = sc * delta[3 * j + 2];
      size_t off = w->cval_off[j];
      for (size_t r = w->crun_off[j]; r < w->crun_off[j + 1]; r++) {
        const size_t i0 = w->crun[2 * r], len = w->crun[2 * r + 1];
        const size_t lo = i0 > t0 ? i0 : t0, hi = i0 + len < t1 ? i0 + len : t1;
        if (w->half) {
          const uint16_t *v = w->hcval + off;
          for (size_t i = lo; i < hi; i++) {
            const double f = w->h2f[v[i - i0]];
            g[3 * i] += f * d0;
            g[3 * i + 1] += f * d1;
            g[3 * i + 2] += f * d2;
          }
        } else {
          const float *v = w->cval + off;
          for (size_t i = lo; i < hi; i++) {
            const double f = v[i - i0];
            g[3 * i] += f * d0;
            g[3 * i + 1] += f * d1;
            g[3 * i + 2] += f * d2;
          }
        }
        off += len;
      }
    }
  }
}

/* ---- Workspace ------------------------------------------------------------ */

void cv_scatter_workspace_destroy(cv_scatter_workspace *w) {
  if (!w) return;
  free(w->rrun_off);
  free(w->rrun);
  free(w->cval_off);
  free(w->cval);
  free(w->crun_off);
  free(w->crun);
  free(w->a);
  free(w->e);
  free(w->xp);
  free(w->R);
  free(w->B);
  free(w->g);
  free(w->U);
  free(w->T);
  free(w->T2);
  free(w->D);
  free(w->active);
  free(w->alist);
  free(w->clip);
  free(w->B_prev);
  free(w->D_prev);
  free(w->clip_prev);
  free(w->hval);
  free(w->hcval);
  free(w->h2f);
  if (!w->hm_borrowed) cv_hmatrix_destroy(w->hm);
  free(w);
}

/* The per-patch arrays of a system: proj >= 0, refl in [0, 1], env >= 0. */
static int validate_arrays(const cv_scatter_system *s, cv_err *err) {
  for (size_t i = 0; i < s->n; i++) {
    if (!isfinite(s->proj[i]) || s->proj[i] < 0)
      return cv_err_set(err, isfinite(s->proj[i]) ? CV_ERR_RANGE : CV_ERR_NONFINITE,
                        "scatter system: proj[%zu] = %g, expected a finite value >= 0", i,
                        (double)s->proj[i]);
    for (int c = 0; c < 3; c++) {
      const float m = s->refl[3 * i + c], e = s->env[3 * i + c];
      if (!isfinite(m) || m < 0 || m > 1)
        return cv_err_set(err, isfinite(m) ? CV_ERR_RANGE : CV_ERR_NONFINITE,
                          "scatter system: refl of patch %zu channel %d = %g, expected [0, 1]", i,
                          c, (double)m);
      if (!isfinite(e) || e < 0)
        return cv_err_set(err, isfinite(e) ? CV_ERR_RANGE : CV_ERR_NONFINITE,
                          "scatter system: env of patch %zu channel %d = %g, expected >= 0", i, c,
                          (double)e);
    }
  }
  return CV_OK;
}

static int validate(const cv_scatter_system *s, cv_err *err) {
  if (!s) return cv_err_set(err, CV_ERR_INVALID, "scatter system: NULL");
  if (s->n == 0) return cv_err_set(err, CV_ERR_INVALID, "scatter system: n = 0 patches");
  if ((!s->F && !s->H) || !s->refl || !s->proj || !s->env)
    return cv_err_set(err, CV_ERR_INVALID, "scatter system: F (and H), refl, proj or env is NULL");
  if (!s->F && cv_hmatrix_size(s->H) != s->n)
    return cv_err_set(err, CV_ERR_INVALID, "scatter system: H has %zu rows, expected n = %zu",
                      cv_hmatrix_size(s->H), s->n);
  if (s->n >= UINT32_MAX)
    return cv_err_set(err, CV_ERR_INVALID, "scatter system: n = %zu patches, at most 2^32 - 2",
                      s->n);
  const cv_ffmatrix *F = s->F;
  if (!F) return validate_arrays(s, err);
  if (F->n != s->n)
    return cv_err_set(err, CV_ERR_INVALID, "scatter system: F has %zu rows, expected n = %zu",
                      F->n, s->n);
  if (!F->row_off || (F->nnz > 0 && (!F->col || !F->val)) || F->row_off[0] != 0 ||
      F->row_off[s->n] != F->nnz)
    return cv_err_set(err, CV_ERR_INVALID,
                      "scatter system: F.row_off must run from 0 to nnz = %zu", F->nnz);
  if (s->n >= UINT32_MAX)
    return cv_err_set(err, CV_ERR_INVALID, "scatter system: n = %zu patches, at most 2^32 - 2",
                      s->n);
  for (size_t i = 0; i < s->n; i++) {
    if (F->row_off[i + 1] < F->row_off[i])
      return cv_err_set(err, CV_ERR_INVALID, "scatter system: F.row_off[%zu] decreases", i + 1);
    for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) {
      if (F->col[k] >= s->n || (k > F->row_off[i] && F->col[k] <= F->col[k - 1]))
        return cv_err_set(err, CV_ERR_INVALID,
                          "scatter system: F row %zu: column %u out of range or not ascending",
                          i, (unsigned)F->col[k]);
      if (!isfinite(F->val[k]))
        return cv_err_set(err, CV_ERR_NONFINITE, "scatter system: F row %zu, column %u not finite",
                          i, (unsigned)F->col[k]);
      if (F->val[k] < 0)
        return cv_err_set(err, CV_ERR_RANGE, "scatter system: F row %zu, column %u negative (%g)",
                          i, (unsigned)F->col[k], (double)F->val[k]);
    }
  }
  return validate_arrays(s, err);
}

/* The plain storage of F: runs of consecutive senders per row, a transposed
 * copy for sparse updates, and (CV_SCATTER_WS_HALF) half-precision copies.
 * On failure the caller destroys w. */
static int build_plain(cv_scatter_workspace *w, unsigned flags, cv_err *err) {
  const cv_ffmatrix *F = w->s.F;
  const size_t n = w->n, nnz = w->nnz;
  /* Runs of consecutive senders in each row. */
  size_t nruns = 0;
  for (size_t k = 0, i = 0; i < n; i++)
    for (k = F->row_off[i]; k < F->row_off[i + 1]; k++)
      if (k == F->row_off[i] || F->col[k] != F->col[k - 1] + 1) nruns++;
  w->rrun_off = malloc((n + 1) * sizeof *w->rrun_off);
  w->rrun = malloc((2 * nruns + 2) * sizeof *w->rrun);
  /* Transpose: receivers of each sender, rows ascending within a column. */
  w->cval_off = calloc(n + 1, sizeof *w->cval_off);
  w->cval = malloc((nnz + 1) * sizeof *w->cval);
  w->crun_off = calloc(n + 1, sizeof *w->crun_off);
  size_t *cursor = malloc((n + 1) * sizeof *cursor);
  uint32_t *last = malloc((n + 1) * sizeof *last);
  int ok = w->rrun_off && w->rrun && w->cval_off && w->cval && w->crun_off && cursor && last;
  if (!ok) {
    free(cursor);
    free(last);
    return cv_err_set(err, CV_ERR_NOMEM, "scatter workspace: out of memory (%zu nonzeros)", nnz);
  }
  nruns = 0;
  w->rrun_off[0] = 0;
  for (size_t i = 0; i < n; i++) {
    for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) {
      if (k == F->row_off[i] || F->col[k] != F->col[k - 1] + 1) {
        w->rrun[2 * nruns] = F->col[k];
        w->rrun[2 * nruns + 1] = 0;
        nruns++;
      }
      w->rrun[2 * nruns - 1]++;
      w->cval_off[F->col[k] + 1]++;
    }
    w->rrun_off[i + 1] = nruns;
  }
  for (size_t j = 0; j < n; j++) w->cval_off[j + 1] += w->cval_off[j];
  /* Count column runs, then fill values and runs. */
  const uint32_t none = UINT32_MAX;
  for (size_t j = 0; j < n; j++) last[j] = none;
  for (size_t i = 0; i < n; i++)
    for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) {
      const size_t j = F->col[k];
      if (last[j] == none || (size_t)last[j] + 1 != i) w->crun_off[j + 1]++;
      last[j] = (uint32_t)i;
    }
  for (size_t j = 0; j < n; j++) w->crun_off[j + 1] += w->crun_off[j];
  w->crun = malloc((2 * w->crun_off[n] + 2) * sizeof *w->crun);
  if (!w->crun) {
    free(cursor);
    free(last);
    return cv_err_set(err, CV_ERR_NOMEM, "scatter workspace: out of memory");
  }
  size_t *rcur = malloc((n + 1) * sizeof *rcur);
  if (!rcur) {
    free(cursor);
    free(last);
    return cv_err_set(err, CV_ERR_NOMEM, "scatter workspace: out of memory");
  }
  for (size_t j = 0; j < n; j++) {
    last[j] = none;
    cursor[j] = w->cval_off[j];
    rcur[j] = w->crun_off[j];
  }
  for (size_t i = 0; i < n; i++)
    for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) {
      const size_t j = F->col[k];
      w->cval[cursor[j]++] = F->val[k];
      if (last[j] == none || (size_t)last[j] + 1 != i) {
        w->crun[2 * rcur[j]] = (uint32_t)i;
        w->crun[2 * rcur[j] + 1] = 0;
        rcur[j]++;
      }
      w->crun[2 * rcur[j] - 1]++;
      last[j] = (uint32_t)i;
    }
  free(rcur);
  free(cursor);
  free(last);

  if (flags & CV_SCATTER_WS_HALF) {
    /* Scale by a power of two so the largest value sits near 2^15 and the
     * small ones stay in half's normal range (>= 6.1e-5). */
    float vmax = 0;
    for (size_t k = 0; k < nnz; k++) vmax = F->val[k] > vmax ? F->val[k] : vmax;
    int ex = 0;
    if (vmax > 0) frexpf(vmax, &ex);
    const float scale = ldexpf(1.0f, 15 - ex); /* vmax * scale in [2^14, 2^15) */
    w->inv_scale = 1.0 / (double)scale;
    w->hval = malloc((nnz + 1) * sizeof *w->hval);
    w->hcval = malloc((nnz + 1) * sizeof *w->hcval);
    w->h2f = malloc(65536 * sizeof *w->h2f);
    if (!w->hval || !w->hcval || !w->h2f) {
        return cv_err_set(err, CV_ERR_NOMEM, "scatter workspace: out of memory (half copies)");
    }
    for (size_t k = 0; k < nnz; k++) {
      /* half storage: values are finite, >= 0 and at most 65504 after scaling */
      w->hval[k] = cv_float_to_half(F->val[k] * scale);
      w->hcval[k] = cv_float_to_half(w->cval[k] * scale);
    }
    for (uint32_t h = 0; h < 65536; h++) w->h2f[h] = cv_half_to_float((uint16_t)h);
    free(w->cval);
    w->cval = NULL;
    w->half = 1;
#ifdef CV_HAVE_X86_F16C
    w->simd = !(flags & CV_SCATTER_WS_PORTABLE) && __builtin_cpu_supports("avx2") &&
              __builtin_cpu_supports("fma") && __builtin_cpu_supports("f16c");
#endif
  }

  return CV_OK;
}

int cv_scatter_workspace_create(const cv_scatter_system *s, cv_scatter_workspace **out,
                                cv_err *err) {
  return cv_scatter_workspace_create_ex(s, 0, out, err);
}

int cv_scatter_workspace_create_ex(const cv_scatter_system *s, unsigned flags,
                                   cv_scatter_workspace **out, cv_err *err) {
  return cv_scatter_workspace_create_tol(s, flags, CV_SCATTER_COMPRESS_TOL, out, err);
}

int cv_scatter_workspace_create_tol(const cv_scatter_system *s, unsigned flags, double tol,
                                    cv_scatter_workspace **out, cv_err *err) {
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "scatter workspace: out is NULL");
  *out = NULL;
  int st = validate(s, err);
  if (st) return st;
  cv_scatter_workspace *w = calloc(1, sizeof *w);
  if (!w) return cv_err_set(err, CV_ERR_NOMEM, "scatter workspace: out of memory");
  const cv_ffmatrix *F = s->F;
  const size_t n = s->n, n3 = 3 * n, nnz = F ? F->nnz : 0;
  w->s = *s;
  w->n = n;
  w->nnz = nnz;

  w->a = malloc(n3 * sizeof *w->a);
  w->e = malloc(n3 * sizeof *w->e);
  double **vecs[] = {&w->xp, &w->R, &w->B, &w->g, &w->U, &w->T, &w->T2, &w->D, &w->B_prev,
                     &w->D_prev};
  int ok = w->a && w->e;
  for (size_t v = 0; v < sizeof vecs / sizeof vecs[0]; v++) {
    *vecs[v] = calloc(n3, sizeof **vecs[v]);
    ok = ok && *vecs[v];
  }
  w->active = calloc(n, 1);
  w->alist = malloc(n * sizeof *w->alist);
  w->clip = calloc(n3, 1);
  w->clip_prev = calloc(n3, 1);
  ok = ok && w->active && w->alist && w->clip && w->clip_prev;
  if (!ok) {
    cv_scatter_workspace_destroy(w);
    return cv_err_set(err, CV_ERR_NOMEM, "scatter workspace: out of memory (%zu patches)", n);
  }

  /* Plain storage bytes (what compression competes against). */
  w->model.storage = (flags & CV_SCATTER_WS_HALF) ? "half" : "float";
  w->model.bytes = (double)nnz * ((flags & CV_SCATTER_WS_HALF) ? 2 : 4);
  w->model.source_bytes = w->model.bytes;
  if (!F) {
    /* Only the compressed form exists (built from the display directly):
     * the plain figures are what a dense float matrix would take. */
    w->hm = (cv_hmatrix *)s->H; /* borrowed; products only write its scratch */
    w->hm_borrowed = 1;
    cv_hmatrix_get_info(w->hm, &w->hinfo);
    w->model.storage = "block low-rank (direct)";
    w->model.bytes = 4.0 * (double)w->hinfo.stored_values;
    w->model.source_bytes = 4.0 * (double)w->hinfo.source_nnz;
    w->model.compressed_bytes = w->model.bytes;
    const double *re = cv_hmatrix_row_error(w->hm);
    for (size_t i = 0; i < n; i++)
      for (int c = 0; c < 3; c++)
        if (re[i] * s->refl[3 * i + c] > w->ek) w->ek = re[i] * s->refl[3 * i + c];
  } else if ((flags & CV_SCATTER_WS_COMPRESS) && s->cluster && s->n_clusters > 0 && nnz > 0) {
    /* Block low-rank form, kept only when it takes at most half the bytes of
     * the plain storage (else the products would not get faster). */
    st = cv_hmatrix_build(F, s->cluster, s->n_clusters, tol, &w->hm, &w->hinfo, err);
    if (st) {
      cv_scatter_workspace_destroy(w);
      return st;
    }
    const double hb = 4.0 * (double)w->hinfo.stored_values;
    w->model.compress_tried = 1;
    w->model.compressed_bytes = hb;
    if (hb <= 0.5 * w->model.bytes) {
      w->model.storage = "block low-rank";
      w->model.bytes = hb;
      const double *re = cv_hmatrix_row_error(w->hm);
      double ek = 0;
      for (size_t i = 0; i < n; i++)
        for (int c = 0; c < 3; c++)
          if (re[i] * s->refl[3 * i + c] > ek) ek = re[i] * s->refl[3 * i + c];
      w->ek = ek;
    } else {
      cv_hmatrix_destroy(w->hm);
      w->hm = NULL;
    }
  }
  if (!w->hm) {
    st = build_plain(w, flags, err);
    if (st) {
      cv_scatter_workspace_destroy(w);
      return st;
    }
  }
  w->model.compress_info = w->hinfo;
  w->model.error_bound = w->hm ? w->ek : (w->half ? ldexp(1.0, -11) : 0);

  /* a = F M, e = E M, ||K||_inf = max_i M_i sum_j F_ji. */
  double qinf = 0;
  const double *hsum = F ? NULL : cv_hmatrix_row_sum(w->hm);
  for (size_t i = 0; i < n; i++) {
    double rs = 0;
    if (F)
      for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) rs += F->val[k];
    else
      rs = hsum[i] > 0 ? hsum[i] : 0;
    for (int c = 0; c < 3; c++) {
      const size_t p = 3 * i + c;
      w->a[p] = (double)s->proj[i] * s->refl[p];
      w->e[p] = (double)s->env[p] * s->refl[p];
      if (rs * s->refl[p] > qinf) qinf = rs * s->refl[p];
    }
  }
  w->qinf = qinf;
  /* rho decides whether the paper's iteration may run (limit 0.5) and is
   * reported: 1e-7 relative stability (at most 150 products) is plenty. */
  w->rho = (nnz || !F) ? power_rho(n, ws_apply_K_ctx, w, 150, 1e-7, w->T, w->T2) : 0;
  if (w->rho < 0) w->rho = qinf; /* cannot happen for validated input */
  *out = w;
  return CV_OK;
}

double cv_scatter_workspace_rho(const cv_scatter_workspace *w) { return w ? w->rho : -1; }

int cv_scatter_workspace_get_model(const cv_scatter_workspace *w, cv_scatter_model *out) {
  if (!w || !out) return CV_ERR_INVALID;
  *out = w->model;
  return CV_OK;
}
double cv_scatter_workspace_norm_inf(const cv_scatter_workspace *w) { return w ? w->qinf : -1; }

/* ---- Solvers -------------------------------------------------------------- */

static void stats_init(cv_scatter_stats *st, const cv_scatter_workspace *w) {
  memset(st, 0, sizeof *st);
  st->rho = w->rho;
  st->rms_error = -1;
  st->max_error = -1;
}

/* I = clamp((D - e) / a) with clipping counted; D holds direct light incl. e. */
static void output_from_D(const cv_scatter_workspace *w, const double *D, float *I,
                          cv_scatter_stats *st) {
  size_t nclip = 0, nclip_p = 0;
  const size_t n = w->n;
#pragma omp parallel for schedule(static) reduction(+ : nclip, nclip_p)
  for (size_t i = 0; i < n; i++) {
    int any = 0;
    for (int c = 0; c < 3; c++) {
      const size_t p = 3 * i + c;
      const double d = D[p] - w->e[p];
      double v;
      if (w->a[p] > 0) {
        v = d / w->a[p];
      } else {
        v = 0;
        if (d != 0) v = d > 0 ? 2 : -1; /* uncontrollable patch: counted as clipped */
      }
      if (v < 0 || v > 1) {
        nclip++;
        any = 1;
        v = v < 0 ? 0 : 1;
      }
      I[p] = (float)v;
    }
    nclip_p += any;
  }
  st->clipped_channels = nclip;
  st->clipped_patches = nclip_p;
}

static int solve_exact(cv_scatter_workspace *w, float *I, cv_scatter_stats *st) {
  const size_t n3 = 3 * w->n;
  ws_apply_K(w, w->R, w->T); /* T = K R */
  for (size_t p = 0; p < n3; p++) w->D[p] = w->R[p] - w->T[p];
  output_from_D(w, w->D, I, st);
  st->solver = CV_SCATTER_EXACT;
  st->iterations = 1;
  st->products = 1;
  st->exit = CV_SCATTER_EXIT_CONVERGED;
  if (w->hm) {
    /* D errs by at most ek max|R|; through the physics B by 1 / (1 - q) that. */
    double rmax = 0;
    for (size_t p = 0; p < n3; p++) rmax = fabs(w->R[p]) > rmax ? fabs(w->R[p]) : rmax;
    st->residual = w->ek * rmax / (w->qinf < 0.999 ? 1 - w->qinf : 1e-3);
  }
  /* Unclipped: R is displayed exactly (compressed: unknown within residual). */
  if (st->clipped_channels == 0 && !w->hm) st->rms_error = st->max_error = 0;
  return CV_OK;
}

static int solve_jacobi(cv_scatter_workspace *w, const cv_scatter_opts *o, float *I,
                        cv_scatter_stats *st, double t_start, cv_err *err) {
  if (w->rho >= o->jacobi_rho_limit)
    return cv_err_set(err, CV_ERR_RANGE,
                      "jacobi: spectral radius of K is %.4f >= %.4g, where the paper's iteration "
                      "diverges; use the exact or bounded solver",
                      w->rho, o->jacobi_rho_limit);
  const size_t n = w->n, n3 = 3 * n;
  const int H = o->levels;
  double *D = w->D, *T = w->T, *T2 = w->T2, *U = w->U;
  double rmax = 0;
  for (size_t p = 0; p < n3; p++) rmax = fmax(rmax, fabs(w->R[p]));
  /* I^0 = (R - E M) / (F M), i.e. D^0 = R (paper, section 3.1), or the last frame. */
  memcpy(D, o->warm_start && w->have_D_prev ? w->D_prev : w->R, n3 * sizeof *D);
  double upd_prev = INFINITY, upd_first = -1;
  int grow = 0;
  st->solver = CV_SCATTER_JACOBI;
  st->exit = CV_SCATTER_EXIT_MAX_ITERS;
  for (int it = 1; it <= o->max_iters; it++) {
    /* Scatter levels for the current direct light: S^1 = K D (eq. 2),
     * S^h = K S^(h-1) (eq. 5); U = sum_h S^h. */
    ws_apply_K(w, D, T);
    memcpy(U, T, n3 * sizeof *U);
    for (int h = 2; h <= H; h++) {
      ws_apply_K(w, T, T2);
      double *tmp = T;
      T = T2;
      T2 = tmp;
      for (size_t p = 0; p < n3; p++) U[p] += T[p];
    }
    /* Eq. 6: I^(l+1) = (R - E M - sum S^h) / (F M), i.e. D^(l+1) = R - U. */
    double upd = 0, dI = 0;
    size_t changed = 0;
#pragma omp parallel for schedule(static) reduction(max : upd, dI) reduction(+ : changed)
    for (size_t i = 0; i < n; i++) {
      int ch = 0;
      for (int c = 0; c < 3; c++) {
        const size_t p = 3 * i + c;
        const double dn = w->R[p] - U[p];
        const double du = fabs(dn - D[p]);
        if (!(du <= upd)) upd = isnan(du) ? INFINITY : du;
        if (w->a[p] > 0) {
          const double di = du / w->a[p];
          if (di > dI) dI = di;
          if (di > o->threshold) ch = 1;
        }
        D[p] = dn;
      }
      changed += (size_t)ch;
    }
    st->iterations = it;
    st->products += H;
    st->residual = dI;
    if (upd_first < 0) upd_first = upd;
    grow = upd > upd_prev ? grow + 1 : 0;
    if (!isfinite(upd) || upd > 1e6 * (1 + rmax) || (grow >= 4 && upd > upd_first))
      return cv_err_set(err, CV_ERR_RANGE,
                        "jacobi: diverged after %d passes (update %.3g growing; spectral radius "
                        "estimate %.4f); use the exact or bounded solver",
                        it, upd, w->rho);
    upd_prev = upd;
    if (changed < o->max_changed) {
      st->exit = CV_SCATTER_EXIT_CONVERGED;
      break;
    }
    if (o->time_ms > 0 && (omp_get_wtime() - t_start) * 1e3 >= o->time_ms) {
      st->exit = CV_SCATTER_EXIT_TIME;
      break;
    }
  }
  memcpy(w->D_prev, D, n3 * sizeof *D);
  w->have_D_prev = 1;
  output_from_D(w, D, I, st);
  return CV_OK;
}

/* Projected Jacobi on the displayed radiosity (see solve.h):
 *   B^(k+1)_p = median(R_p, e_p + (K B^k)_p, e_p + a_p + (K B^k)_p),
 * I_p = (B^(k+1)_p - e_p - (K B^k)_p) / a_p.  With d the resulting direct
 * light, the displayed B' = d + e + K B' satisfies B' - B^(k+1) = K (B' - B^k),
 * so ||B' - B^(k+1)||_inf <= q / (1 - q) ||B^(k+1) - B^k||_inf, q = ||K||_inf;
 * B^(k+1) = R on every patch not at a limit.  g holds F-gathered B (K B = M g)
 * and is updated from the changed senders only. */
static int solve_bounded(cv_scatter_workspace *w, const cv_scatter_opts *o, int is_auto,
                         float *I, cv_scatter_stats *st, double t_start, cv_err *err) {
  const size_t n = w->n, n3 = 3 * n;
  double fac;
  if (w->qinf < 0.999)
    fac = w->qinf / (1 - w->qinf);
  else if (w->rho < 0.999)
    fac = 2 * w->rho / (1 - w->rho); /* estimate only; cannot happen for rows of a closed box */
  else
    return cv_err_set(err, CV_ERR_RANGE,
                      "bounded: spectral radius of K is %.4f >= 1: the display has no bounded "
                      "radiosity (reflectance 1 in a closed room?)",
                      w->rho);
  double *B = w->B, *g = w->g, *U = w->U;
  const double *R = w->R;
  const float *refl = w->s.refl;
  const int warm = o->warm_start && w->have_B_prev;
  for (size_t p = 0; p < n3; p++) B[p] = warm && w->clip_prev[p] ? w->B_prev[p] : R[p];
  ws_gather(w, B, g);
  st->products = 1;
  st->exit = CV_SCATTER_EXIT_MAX_ITERS;
  const int max_it = o->max_iters;
  size_t nclip = 0, nclip_p = 0;
  for (int it = 1; it <= max_it; it++) {
    double maxd = 0, bmax = 0;
    nclip = nclip_p = 0;
#pragma omp parallel for schedule(static) reduction(max : maxd, bmax) reduction(+ : nclip, nclip_p)
    for (size_t i = 0; i < n; i++) {
      int act = 0, any = 0;
      for (int c = 0; c < 3; c++) {
        const size_t p = 3 * i + c;
        const double s = refl[p] * g[p];
        const double lo = w->e[p] + s, hi = lo + w->a[p], r = R[p];
        double bn = r;
        uint8_t cl = 0;
        if (r < lo) {
          bn = lo;
          cl = 1;
        } else if (r > hi) {
          bn = hi;
          cl = 1;
        }
        if (fabs(B[p]) > bmax) bmax = fabs(B[p]);
        const double dl = bn - B[p];
        U[p] = dl;
        if (dl != 0) act = 1;
        if (fabs(dl) > maxd) maxd = fabs(dl);
        B[p] = bn;
        double v = w->a[p] > 0 ? (bn - lo) / w->a[p] : 0;
        v = v < 0 ? 0 : (v > 1 ? 1 : v); /* rounding only */
        I[p] = (float)v;
        w->clip[p] = cl;
        nclip += cl;
        any |= cl;
      }
      w->active[i] = (uint8_t)act;
      nclip_p += (size_t)any;
    }
    st->iterations = it;
    /* Half storage: K_h = K + dK, |dK| <= 2^-11 K, adds ||dK B|| / (1 - q). */
    st->residual = fac * maxd;
    if (w->hm)
      st->residual += w->ek * bmax / (1 - (w->qinf < 0.999 ? w->qinf : w->rho));
    else if (w->half)
      st->residual += fac * ldexp(bmax, -11);
    if (fac * maxd <= o->tol) {
      st->exit = CV_SCATTER_EXIT_CONVERGED;
      break;
    }
    if (it == max_it) break;
    if (o->time_ms > 0 && (omp_get_wtime() - t_start) * 1e3 >= o->time_ms) {
      st->exit = CV_SCATTER_EXIT_TIME;
      break;
    }
    /* g += F-gather of the change: from the changed senders when cheaper. */
    if (w->hm) {
      st->products += cv_hmatrix_gather_add_active(w->hm, w->active, U, g);
      continue;
    }
    size_t na = 0, cost = 0;
    for (size_t j = 0; j < n; j++)
      if (w->active[j]) {
        w->alist[na++] = (uint32_t)j;
        cost += w->cval_off[j + 1] - w->cval_off[j];
      }
    if (cost < w->nnz / 10 * 7) {
      ws_scatter_update(w, na, U, g);
      st->products += w->nnz ? (double)cost / (double)w->nnz : 0;
    } else {
      ws_gather(w, B, g);
      st->products += 1;
    }
  }
  /* Displayed error estimate (accurate to st->residual). */
  double sq = 0, mx = 0;
#pragma omp parallel for schedule(static) reduction(+ : sq) reduction(max : mx)
  for (size_t p = 0; p < n3; p++) {
    const double d = fabs(B[p] - R[p]);
    sq += d * d;
    if (d > mx) mx = d;
  }
  st->rms_error = sqrt(sq / (double)n3);
  st->max_error = mx;
  st->clipped_channels = nclip;
  st->clipped_patches = nclip_p;
  st->solver = (is_auto && nclip == 0) ? CV_SCATTER_EXACT : CV_SCATTER_BOUNDED;
  memcpy(w->B_prev, B, n3 * sizeof *B);
  memcpy(w->clip_prev, w->clip, n3);
  w->have_B_prev = 1;
  return CV_OK;
}

/* Runs the selected solver on w->R (already filled and checked). */
static int solve_core(cv_scatter_workspace *w, const cv_scatter_opts *opts, float *I,
                      cv_scatter_stats *stats, double t_start, cv_err *err) {
  cv_scatter_opts o;
  if (opts)
    o = *opts;
  else
    cv_scatter_opts_default(&o);
  if (o.solver == CV_SCATTER_JACOBI && o.levels < 1)
    return cv_err_set(err, CV_ERR_INVALID, "jacobi: levels = %d, expected >= 1", o.levels);
  if (o.max_iters < 1)
    return cv_err_set(err, CV_ERR_INVALID, "scatter solve: max_iters = %d, expected >= 1",
                      o.max_iters);
  if (!(o.tol > 0) || !(o.threshold >= 0) || isnan(o.time_ms) || isnan(o.jacobi_rho_limit))
    return cv_err_set(err, CV_ERR_INVALID,
                      "scatter solve: tol must be > 0, threshold >= 0, time_ms and "
                      "jacobi_rho_limit numbers");
  cv_scatter_stats st;
  stats_init(&st, w);
  int rc;
  switch (o.solver) {
    case CV_SCATTER_EXACT: rc = solve_exact(w, I, &st); break;
    case CV_SCATTER_JACOBI: rc = solve_jacobi(w, &o, I, &st, t_start, err); break;
    case CV_SCATTER_BOUNDED: rc = solve_bounded(w, &o, 0, I, &st, t_start, err); break;
    case CV_SCATTER_AUTO: rc = solve_bounded(w, &o, 1, I, &st, t_start, err); break;
    default:
      return cv_err_set(err, CV_ERR_INVALID, "scatter solve: unknown solver %d", (int)o.solver);
  }
  st.ms = (omp_get_wtime() - t_start) * 1e3;
  if (stats) *stats = st;
  return rc;
}

static int load_R(cv_scatter_workspace *w, const float *A, const float *Bv, const char *na,
                  const char *nb, cv_err *err) {
  const size_t n3 = 3 * w->n;
  for (size_t p = 0; p < n3; p++) {
    if (!isfinite(A[p]))
      return cv_err_set(err, CV_ERR_NONFINITE, "%s: patch %zu channel %d is %g, expected finite",
                        na, p / 3, (int)(p % 3), (double)A[p]);
    if (Bv && !isfinite(Bv[p]))
      return cv_err_set(err, CV_ERR_NONFINITE, "%s: patch %zu channel %d is %g, expected finite",
                        nb, p / 3, (int)(p % 3), (double)Bv[p]);
    w->R[p] = Bv ? 0.5 * ((double)A[p] + (double)Bv[p]) : (double)A[p];
  }
  return CV_OK;
}

int cv_scatter_solve(cv_scatter_workspace *w, const float *R, const cv_scatter_opts *opts,
                     float *I, cv_scatter_stats *stats, cv_err *err) {
  const double t0 = omp_get_wtime();
  if (!w || !R || !I) return cv_err_set(err, CV_ERR_INVALID, "scatter solve: NULL argument");
  int rc = load_R(w, R, NULL, "R", NULL, err);
  if (rc) return rc;
  return solve_core(w, opts, I, stats, t0, err);
}

int cv_scatter_solve_stereo(cv_scatter_workspace *w, const float *R_left, const float *R_right,
                            const cv_scatter_opts *opts, float *I, cv_scatter_stats *stats,
                            cv_err *err) {
  const double t0 = omp_get_wtime();
  if (!w || !R_left || !R_right || !I)
    return cv_err_set(err, CV_ERR_INVALID, "scatter stereo solve: NULL argument");
  int rc = load_R(w, R_left, R_right, "R_left", "R_right", err);
  if (rc) return rc;
  rc = solve_core(w, opts, I, stats, t0, err);
  if (rc == CV_OK && stats) stats->stereo = 1;
  return rc;
}
