/* Unit tests of the scattering compensation solvers and display physics
 * (src/compensate/solve.h).  The systems are built here, independently of the
 * form-factor module: a 2-patch system with a closed-form answer, and patches
 * of a unit cube (closed box, 5-wall CAVE, two perpendicular walls) with the
 * point-to-point form factor, each sender's column scaled so that the closed
 * box conserves energy exactly (rows of K then have a known spectral radius:
 * for the closed box with uniform reflectance m, rho(K) = m). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>
#include "cv_test_near.h"

#include "compensate/solve.h"
#include "compensate/system.h"
#include "core/status.h"

typedef struct tsys {
  cv_ffmatrix *F;
  float *refl, *proj, *env;
  cv_scatter_system s;
  int m;      /* patches per face edge */
  int faces;  /* faces kept (in order of the mask) */
  int face_of[6];
} tsys;

static void tsys_free(tsys *t) {
  cv_ffmatrix_destroy(t->F);
  free(t->refl);
  free(t->proj);
  free(t->env);
  memset(t, 0, sizeof *t);
}

static void tsys_alloc_vectors(tsys *t, size_t n) {
  t->refl = malloc(3 * n * sizeof *t->refl);
  t->proj = malloc(n * sizeof *t->proj);
  t->env = malloc(3 * n * sizeof *t->env);
  assert_non_null(t->refl);
  assert_non_null(t->proj);
  assert_non_null(t->env);
  t->s.n = n;
  t->s.F = t->F;
  t->s.refl = t->refl;
  t->s.proj = t->proj;
  t->s.env = t->env;
}

/* Face f of the unit cube: plane x_a = side, a = f / 2, side = f % 2; inward
 * normal; u = e_(a+1), v = e_(a+2).  Faces: 0 x=0, 1 x=1, 2 y=0 (floor),
 * 3 y=1, 4 z=0 (front), 5 z=1 (back). */
static void patch_geom(int f, int m, int a, int b, double c[3], double nrm[3]) {
  const int ax = f / 2, side = f % 2;
  memset(c, 0, 3 * sizeof *c);
  memset(nrm, 0, 3 * sizeof *nrm);
  c[ax] = side;
  c[(ax + 1) % 3] = (a + 0.5) / m;
  c[(ax + 2) % 3] = (b + 0.5) / m;
  nrm[ax] = side ? -1 : 1;
}

/* Patches of the faces in face_mask (bit f = face f), m x m per face, index
 * (face rank, b, a); reflectance refl (RGB), environment env, proj 1. */
static void build_box(tsys *t, int m, unsigned face_mask, const float refl[3], float env) {
  memset(t, 0, sizeof *t);
  const int NF = 6 * m * m, mm = m * m;
  double *cen = malloc(3 * NF * sizeof *cen), *nor = malloc(3 * NF * sizeof *nor);
  double *Fall = calloc((size_t)NF * NF, sizeof *Fall); /* Fall[j * NF + i] = F_ji */
  assert_non_null(Fall);
  for (int f = 0; f < 6; f++)
    for (int b = 0; b < m; b++)
      for (int a = 0; a < m; a++) {
        const int p = f * mm + b * m + a;
        patch_geom(f, m, a, b, cen + 3 * p, nor + 3 * p);
      }
  const double area = 1.0 / mm;
  for (int j = 0; j < NF; j++) {
    double colsum = 0;
    for (int i = 0; i < NF; i++) {
      double d[3], r2 = 0;
      for (int k = 0; k < 3; k++) {
        d[k] = cen[3 * i + k] - cen[3 * j + k];
        r2 += d[k] * d[k];
      }
      const double r = sqrt(r2);
      double cj = 0, ci = 0;
      for (int k = 0; k < 3; k++) {
        cj += nor[3 * j + k] * d[k] / r;
        ci -= nor[3 * i + k] * d[k] / r;
      }
      if (i == j || cj <= 1e-12 || ci <= 1e-12) continue;
      const double ff = cj * ci * area / (M_PI * r2);
      Fall[(size_t)j * NF + i] = ff;
      colsum += ff;
    }
    for (int i = 0; i < NF; i++) Fall[(size_t)j * NF + i] /= colsum; /* closed box: sum 1 */
  }
  int keep[6], nk = 0;
  for (int f = 0; f < 6; f++)
    if (face_mask & (1u << f)) {
      t->face_of[nk] = f;
      keep[nk++] = f;
    }
  t->faces = nk;
  t->m = m;
  const size_t n = (size_t)nk * mm;
  size_t nnz = 0;
  for (int fi = 0; fi < nk; fi++)
    for (int fj = 0; fj < nk; fj++)
      if (fi != fj) nnz += (size_t)mm * mm;
  assert_int_equal(cv_ffmatrix_alloc(n, nnz, &t->F), CV_OK);
  size_t k = 0;
  for (size_t i = 0; i < n; i++) {
    const int gi = keep[i / mm] * mm + (int)(i % mm);
    for (size_t j = 0; j < n; j++) {
      const int gj = keep[j / mm] * mm + (int)(j % mm);
      const double ff = Fall[(size_t)gj * NF + gi];
      if (ff > 0) {
        t->F->col[k] = (uint32_t)j;
        t->F->val[k] = (float)ff;
        k++;
      }
    }
    t->F->row_off[i + 1] = k;
  }
  t->F->nnz = k;
  tsys_alloc_vectors(t, n);
  for (size_t i = 0; i < n; i++) {
    t->proj[i] = 1;
    for (int c = 0; c < 3; c++) {
      t->refl[3 * i + c] = refl[c];
      t->env[3 * i + c] = env;
    }
  }
  free(cen);
  free(nor);
  free(Fall);
}

/* Two patches: F_10 = 0.3 (patch 1 lights patch 0), F_01 = 0.2. */
static void build_two(tsys *t) {
  memset(t, 0, sizeof *t);
  assert_int_equal(cv_ffmatrix_alloc(2, 2, &t->F), CV_OK);
  t->F->row_off[0] = 0;
  t->F->row_off[1] = 1;
  t->F->row_off[2] = 2;
  t->F->col[0] = 1;
  t->F->val[0] = 0.3f;
  t->F->col[1] = 0;
  t->F->val[1] = 0.2f;
  tsys_alloc_vectors(t, 2);
  const float refl[6] = {0.9f, 0.5f, 0.7f, 0.8f, 0.6f, 0.3f};
  const float env[6] = {0.01f, 0.02f, 0.0f, 0.03f, 0.0f, 0.05f};
  memcpy(t->refl, refl, sizeof refl);
  memcpy(t->env, env, sizeof env);
  t->proj[0] = 0.9f;
  t->proj[1] = 0.7f;
}

static double rms_vs(const double *B, const float *R, size_t n3) {
  double s = 0;
  for (size_t p = 0; p < n3; p++) s += (B[p] - R[p]) * (B[p] - R[p]);
  return sqrt(s / (double)n3);
}

/* ---- Physics and spectral radius ------------------------------------------ */

static void test_physics_two_patch(void **state) {
  (void)state;
  tsys t;
  build_two(&t);
  const float I[6] = {0.8f, 0.1f, 0.5f, 0.3f, 1.0f, 0.0f};
  double B[6];
  int iters = 0;
  assert_int_equal(cv_scatter_physics(&t.s, I, B, 1e-12, &iters), CV_OK);
  assert_true(iters > 1);
  for (int c = 0; c < 3; c++) {
    /* (Id - K) B = D, K = [[0, M0 F10], [M1 F01, 0]]: 2x2 inverse by hand. */
    const double M0 = t.refl[c], M1 = t.refl[3 + c];
    const double D0 = (double)t.proj[0] * M0 * I[c] + (double)t.env[c] * M0;
    const double D1 = (double)t.proj[1] * M1 * I[3 + c] + (double)t.env[3 + c] * M1;
    const double k01 = M0 * (double)0.3f, k10 = M1 * (double)0.2f, det = 1 - k01 * k10;
    const double B0 = (D0 + k01 * D1) / det, B1 = (D1 + k10 * D0) / det;
    assert_near(B[c], B0, 1e-10 * fabs(B0) + 1e-15);
    assert_near(B[3 + c], B1, 1e-10 * fabs(B1) + 1e-15);
  }
  float bad[6];
  memcpy(bad, I, sizeof bad);
  bad[4] = NAN;
  assert_int_equal(cv_scatter_physics(&t.s, bad, B, 1e-9, NULL), CV_ERR_NONFINITE);
  tsys_free(&t);
}

static void test_spectral_radius(void **state) {
  (void)state;
  /* Two patches: eigenvalues +-sqrt(k01 k10) per channel (bipartite). */
  tsys t;
  build_two(&t);
  double want = 0;
  for (int c = 0; c < 3; c++) {
    const double r = sqrt(t.refl[c] * (double)0.3f * t.refl[3 + c] * (double)0.2f);
    if (r > want) want = r;
  }
  const double got = cv_scatter_spectral_radius(&t.s, 200);
  assert_near(got, want, 1e-8);
  tsys_free(&t);

  /* Closed box, column sums of the gather matrix 1: rho(K) = max reflectance. */
  const float refl[3] = {0.8f, 0.7f, 0.6f};
  build_box(&t, 4, 0x3f, refl, 0);
  const double rb = cv_scatter_spectral_radius(&t.s, 300);
  assert_near(rb, (double)0.8f, 1e-6);
  cv_scatter_workspace *w = NULL;
  assert_int_equal(cv_scatter_workspace_create(&t.s, &w, NULL), CV_OK);
  assert_near(cv_scatter_workspace_rho(w), (double)0.8f, 1e-6);
  cv_scatter_workspace_destroy(w);

  /* K^T is the adjoint of K: <K x, y> = <x, K^T y>. */
  const size_t n3 = 3 * t.s.n;
  double *x = malloc(n3 * sizeof *x), *y = malloc(n3 * sizeof *y);
  double *Kx = malloc(n3 * sizeof *Kx), *KTy = malloc(n3 * sizeof *KTy);
  srand(7);
  for (size_t p = 0; p < n3; p++) {
    x[p] = rand() / (double)RAND_MAX - 0.3;
    y[p] = rand() / (double)RAND_MAX - 0.6;
  }
  cv_scatter_apply_K(&t.s, x, Kx);
  cv_scatter_apply_KT(&t.s, y, KTy);
  double l = 0, r = 0, nrm = 0;
  for (size_t p = 0; p < n3; p++) {
    l += Kx[p] * y[p];
    r += x[p] * KTy[p];
    nrm += fabs(Kx[p] * y[p]);
  }
  assert_near(l, r, 1e-12 * nrm);
  free(x);
  free(y);
  free(Kx);
  free(KTy);
  tsys_free(&t);
}

/* ---- Exact, auto, Jacobi ---------------------------------------------------- */

static float *smooth_image(size_t n, float lo, float hi) {
  float *R = malloc(3 * n * sizeof *R);
  for (size_t p = 0; p < 3 * n; p++)
    R[p] = lo + (hi - lo) * (float)(0.5 + 0.5 * sin(0.37 * (double)p + 0.11 * (double)(p % 3)));
  return R;
}

static void test_exact_and_auto(void **state) {
  (void)state;
  tsys t;
  const float refl[3] = {0.8f, 0.6f, 0.45f};
  build_box(&t, 8, (1u << 0) | (1u << 4), refl, 0.01f); /* two perpendicular walls */
  const size_t n = t.s.n, n3 = 3 * n;
  cv_scatter_workspace *w = NULL;
  assert_int_equal(cv_scatter_workspace_create(&t.s, &w, NULL), CV_OK);
  float *R = smooth_image(n, 0.25f, 0.4f); /* reachable with reflectance 0.45 */
  float *I = malloc(n3 * sizeof *I), *Ia = malloc(n3 * sizeof *Ia);
  double *B = malloc(n3 * sizeof *B);
  cv_scatter_opts o;
  cv_scatter_opts_default(&o);
  o.solver = CV_SCATTER_EXACT;
  cv_scatter_stats st;
  assert_int_equal(cv_scatter_solve(w, R, &o, I, &st, NULL), CV_OK);
  assert_int_equal(st.clipped_channels, 0);
  assert_int_equal(st.solver, CV_SCATTER_EXACT);
  assert_int_equal(cv_scatter_physics(&t.s, I, B, 1e-12, NULL), CV_OK);
  double maxe = 0;
  for (size_t p = 0; p < n3; p++) maxe = fmax(maxe, fabs(B[p] - R[p]));
  print_message("exact: two walls 2x8x8, rho %.4f, max |B - R| %.2e\n", st.rho, maxe);
  assert_true(maxe < 1e-6);
  assert_true(st.rho > 0.05 && st.rho < 0.5);

  /* Auto picks exact when nothing clips: one product, the same I. */
  o.solver = CV_SCATTER_AUTO;
  assert_int_equal(cv_scatter_solve(w, R, &o, Ia, &st, NULL), CV_OK);
  assert_int_equal(st.solver, CV_SCATTER_EXACT);
  assert_int_equal(st.iterations, 1);
  assert_true(st.products == 1);
  for (size_t p = 0; p < n3; p++) assert_near(Ia[p], I[p], 1e-6);
  free(R);
  free(I);
  free(Ia);
  free(B);
  cv_scatter_workspace_destroy(w);
  tsys_free(&t);
}

static void test_jacobi_levels(void **state) {
  (void)state;
  tsys t;
  const float refl[3] = {0.8f, 0.8f, 0.8f};
  build_box(&t, 8, (1u << 0) | (1u << 4), refl, 0.0f);
  const size_t n = t.s.n, n3 = 3 * n;
  cv_scatter_workspace *w = NULL;
  assert_int_equal(cv_scatter_workspace_create(&t.s, &w, NULL), CV_OK);
  float *R = smooth_image(n, 0.3f, 0.7f);
  float *Iex = malloc(n3 * sizeof *Iex), *I = malloc(n3 * sizeof *I);
  cv_scatter_opts o;
  cv_scatter_opts_default(&o);
  o.solver = CV_SCATTER_EXACT;
  cv_scatter_stats st;
  assert_int_equal(cv_scatter_solve(w, R, &o, Iex, &st, NULL), CV_OK);
  assert_true(st.rho < 0.5);
  /* The fixed point with H levels is D = (Id + K + .. + K^H)^-1 R, which
   * differs from (Id - K) R by O(rho^(H+1)). */
  double prev = INFINITY, rho = st.rho;
  o.solver = CV_SCATTER_JACOBI;
  o.threshold = 1e-12;
  o.max_iters = 1000;
  for (int H = 1; H <= 7; H++) {
    o.levels = H;
    assert_int_equal(cv_scatter_solve(w, R, &o, I, &st, NULL), CV_OK);
    assert_int_equal(st.exit, CV_SCATTER_EXIT_CONVERGED);
    double e = 0;
    for (size_t p = 0; p < n3; p++) e = fmax(e, fabs((double)I[p] - Iex[p]));
    print_message("jacobi H=%d: %d passes, max |I - I_exact| %.3e (rho %.3f)\n", H,
                  st.iterations, e, st.rho);
    if (H > 1) assert_true(e <= 1.05 * rho * prev); /* one more level: rho times closer */
    prev = e;
  }
  assert_true(prev < 1e-4);
  /* Default exit (fewer than 1 patch changed by more than 1/255). */
  cv_scatter_opts_default(&o);
  o.solver = CV_SCATTER_JACOBI;
  o.levels = 7;
  assert_int_equal(cv_scatter_solve(w, R, &o, I, &st, NULL), CV_OK);
  print_message("jacobi H=7, exit at < 1 patch changed by 1/255: %d passes\n", st.iterations);
  assert_int_equal(st.exit, CV_SCATTER_EXIT_CONVERGED);
  assert_true(st.iterations <= 10);
  for (size_t p = 0; p < n3; p++) assert_near((double)I[p], Iex[p], 2.0 / 255);
  /* Time slot: exits after the first pass. */
  o.threshold = 0;
  o.time_ms = 1e-9;
  assert_int_equal(cv_scatter_solve(w, R, &o, I, &st, NULL), CV_OK);
  assert_int_equal(st.exit, CV_SCATTER_EXIT_TIME);
  assert_int_equal(st.iterations, 1);
  free(R);
  free(Iex);
  free(I);
  cv_scatter_workspace_destroy(w);
  tsys_free(&t);
}

static void test_jacobi_refuses_closed_box(void **state) {
  (void)state;
  tsys t;
  const float refl[3] = {0.8f, 0.8f, 0.8f};
  build_box(&t, 5, 0x3f, refl, 0.0f);
  const size_t n = t.s.n, n3 = 3 * n;
  cv_scatter_workspace *w = NULL;
  assert_int_equal(cv_scatter_workspace_create(&t.s, &w, NULL), CV_OK);
  float *R = smooth_image(n, 0.3f, 0.7f), *I = malloc(n3 * sizeof *I);
  for (size_t p = 0; p < n3; p++) I[p] = -7;
  cv_scatter_opts o;
  cv_scatter_opts_default(&o);
  o.solver = CV_SCATTER_JACOBI;
  cv_err err;
  cv_err_clear(&err);
  assert_int_equal(cv_scatter_solve(w, R, &o, I, NULL, &err), CV_ERR_RANGE);
  print_message("refused: %s\n", err.msg);
  assert_non_null(strstr(err.msg, "spectral radius"));
  /* Past the limit the divergence guard stops it (3 levels: 0.8+0.64+0.512 > 1). */
  o.jacobi_rho_limit = 2;
  o.levels = 3;
  cv_err_clear(&err);
  assert_int_equal(cv_scatter_solve(w, R, &o, I, NULL, &err), CV_ERR_RANGE);
  print_message("guard: %s\n", err.msg);
  assert_non_null(strstr(err.msg, "diverged"));
  for (size_t p = 0; p < n3; p++) assert_true(I[p] == -7); /* untouched */

  /* The bounded solver converges there and stays in [0, 1]. */
  o.solver = CV_SCATTER_BOUNDED;
  cv_scatter_stats st;
  assert_int_equal(cv_scatter_solve(w, R, &o, I, &st, NULL), CV_OK);
  assert_int_equal(st.exit, CV_SCATTER_EXIT_CONVERGED);
  double *B = malloc(n3 * sizeof *B);
  assert_int_equal(cv_scatter_physics(&t.s, I, B, 1e-10, NULL), CV_OK);
  for (size_t p = 0; p < n3; p++) {
    assert_true(I[p] >= 0 && I[p] <= 1);
    if (I[p] > 0 && I[p] < 1) assert_near(B[p], R[p], 1.0 / 255);
  }
  print_message("closed box rho %.3f: bounded %d sweeps, %zu clipped, residual %.2e\n", st.rho,
                st.iterations, st.clipped_channels, st.residual);
  free(B);
  free(R);
  free(I);
  cv_scatter_workspace_destroy(w);
  tsys_free(&t);
}

/* ---- Bounded ----------------------------------------------------------------- */

static void test_bounded_cave_band(void **state) {
  (void)state;
  tsys t;
  const float refl[3] = {0.8f, 0.8f, 0.8f};
  const int m = 8;
  build_box(&t, m, 0x1f, refl, 0.005f); /* 5-wall CAVE, back (z = 1) open */
  const size_t n = t.s.n, n3 = 3 * n, mm = (size_t)m * m;
  /* White, with a black band on the front wall (face 4) along the corner
   * with the left wall (face 0, x = 0): the first column of patches. */
  float *R = malloc(n3 * sizeof *R);
  for (size_t i = 0; i < n; i++) {
    const int f = t.face_of[i / mm];
    const int a = (int)(i % mm) % m;
    for (int c = 0; c < 3; c++) R[3 * i + c] = (f == 4 && a == 0) ? 0.0f : 0.9f;
  }
  cv_scatter_workspace *w = NULL;
  assert_int_equal(cv_scatter_workspace_create(&t.s, &w, NULL), CV_OK);
  float *Ib = malloc(n3 * sizeof *Ib), *In = malloc(n3 * sizeof *In), *Ia = malloc(n3 * sizeof *Ia);
  double *Bb = malloc(n3 * sizeof *Bb), *Bn = malloc(n3 * sizeof *Bn);
  cv_scatter_opts o;
  cv_scatter_opts_default(&o);
  cv_scatter_stats sn, sb, sa;

  o.solver = CV_SCATTER_EXACT;
  assert_int_equal(cv_scatter_solve(w, R, &o, In, &sn, NULL), CV_OK);
  assert_true(sn.clipped_channels > 0);
  o.solver = CV_SCATTER_BOUNDED;
  assert_int_equal(cv_scatter_solve(w, R, &o, Ib, &sb, NULL), CV_OK);
  assert_int_equal(sb.exit, CV_SCATTER_EXIT_CONVERGED);
  assert_int_equal(sb.solver, CV_SCATTER_BOUNDED);
  assert_true(sb.clipped_channels > 0);
  assert_true(sb.residual <= o.tol);
  assert_int_equal(cv_scatter_physics(&t.s, In, Bn, 1e-10, NULL), CV_OK);
  assert_int_equal(cv_scatter_physics(&t.s, Ib, Bb, 1e-10, NULL), CV_OK);
  double worst = 0;
  size_t unclipped = 0;
  for (size_t p = 0; p < n3; p++) {
    assert_true(isfinite(Ib[p]) && Ib[p] >= 0 && Ib[p] <= 1);
    if (Ib[p] > 0 && Ib[p] < 1) {
      worst = fmax(worst, fabs(Bb[p] - R[p]));
      unclipped++;
    }
  }
  const double rn = rms_vs(Bn, R, n3), rb = rms_vs(Bb, R, n3);
  print_message(
      "CAVE 5x%dx%d rho %.3f: naive RMS %.4f, bounded RMS %.4f (%.1f%% lower), %d sweeps, "
      "%.2f products, %zu clipped channels, worst unclipped |B-R| %.2e over %zu\n",
      m, m, sb.rho, rn, rb, 100 * (1 - rb / rn), sb.iterations, sb.products,
      sb.clipped_channels, worst, unclipped);
  assert_true(sb.rho > 0.5);
  assert_true(unclipped > n3 / 2);
  assert_true(worst <= 1.0 / 255);
  assert_true(rb < rn);
  assert_true(rb < 0.92 * rn); /* the figure: at least 8% below naive clipping */
  /* The solver's own error estimate is good to its residual bound. */
  assert_near(sb.rms_error, rb, sb.residual + 1e-9);

  /* Jacobi refuses here; auto gives the bounded result. */
  o.solver = CV_SCATTER_JACOBI;
  assert_int_equal(cv_scatter_solve(w, R, &o, Ia, NULL, NULL), CV_ERR_RANGE);
  o.solver = CV_SCATTER_AUTO;
  assert_int_equal(cv_scatter_solve(w, R, &o, Ia, &sa, NULL), CV_OK);
  assert_int_equal(sa.solver, CV_SCATTER_BOUNDED);
  for (size_t p = 0; p < n3; p++) assert_near(Ia[p], Ib[p], 1e-6);

  /* Warm start from the previous frame: fewer products, same answer. */
  o.warm_start = 1;
  assert_int_equal(cv_scatter_solve(w, R, &o, Ia, &sa, NULL), CV_OK);
  print_message("warm start: %d sweeps, %.2f products (cold %d, %.2f)\n", sa.iterations,
                sa.products, sb.iterations, sb.products);
  assert_true(sa.products <= sb.products);
  for (size_t p = 0; p < n3; p++) assert_near(Ia[p], Ib[p], 4.0 / 255);

  free(R);
  free(Ib);
  free(In);
  free(Ia);
  free(Bb);
  free(Bn);
  cv_scatter_workspace_destroy(w);
  tsys_free(&t);
}

/* Half-precision storage, SIMD and portable kernels: same answers to the
 * stated storage error, and the bounded guarantee still holds. */
static void test_half_storage(void **state) {
  (void)state;
  tsys t;
  const float refl[3] = {0.8f, 0.7f, 0.6f};
  const int m = 8;
  build_box(&t, m, 0x1f, refl, 0.005f);
  const size_t n = t.s.n, n3 = 3 * n, mm = (size_t)m * m;
  float *R = malloc(n3 * sizeof *R);
  for (size_t i = 0; i < n; i++)
    for (int c = 0; c < 3; c++)
      R[3 * i + c] = (t.face_of[i / mm] == 4 && (int)(i % mm) % m < 2) ? 0.0f : 0.6f;
  cv_scatter_workspace *wf = NULL;
  assert_int_equal(cv_scatter_workspace_create(&t.s, &wf, NULL), CV_OK);
  float *If = malloc(n3 * sizeof *If), *Ih = malloc(n3 * sizeof *Ih);
  double *B = malloc(n3 * sizeof *B);
  cv_scatter_opts o;
  cv_scatter_opts_default(&o);
  o.solver = CV_SCATTER_BOUNDED;
  cv_scatter_stats sf, sh;
  assert_int_equal(cv_scatter_solve(wf, R, &o, If, &sf, NULL), CV_OK);
  const unsigned flags[2] = {CV_SCATTER_WS_HALF, CV_SCATTER_WS_HALF | CV_SCATTER_WS_PORTABLE};
  for (int k = 0; k < 2; k++) {
    cv_scatter_workspace *wh = NULL;
    assert_int_equal(cv_scatter_workspace_create_ex(&t.s, flags[k], &wh, NULL), CV_OK);
    assert_near(cv_scatter_workspace_rho(wh), cv_scatter_workspace_rho(wf), 1e-3 * cv_scatter_workspace_rho(wf));
    o.solver = CV_SCATTER_BOUNDED;
    assert_int_equal(cv_scatter_solve(wh, R, &o, Ih, &sh, NULL), CV_OK);
    assert_int_equal(sh.exit, CV_SCATTER_EXIT_CONVERGED);
    assert_int_equal(cv_scatter_physics(&t.s, Ih, B, 1e-10, NULL), CV_OK);
    double worst = 0, dI = 0;
    for (size_t p = 0; p < n3; p++) {
      dI = fmax(dI, fabs((double)Ih[p] - If[p]));
      if (Ih[p] > 0 && Ih[p] < 1) worst = fmax(worst, fabs(B[p] - R[p]));
    }
    print_message("half (flags %u): max |I_half - I_float| %.2e, worst unclipped %.2e, "
                  "residual bound %.2e, %zu clipped (float %zu)\n",
                  flags[k], dI, worst, sh.residual, sh.clipped_channels, sf.clipped_channels);
    assert_true(worst <= sh.residual && worst <= 1.0 / 255);
    assert_true(dI < 2e-3);
    /* Exact: within the storage bound 2^-11 |K R| / (1 - q) of R. */
    o.solver = CV_SCATTER_EXACT;
    float *Rs = smooth_image(n, 0.45f, 0.55f);
    assert_int_equal(cv_scatter_solve(wh, Rs, &o, Ih, &sh, NULL), CV_OK);
    assert_int_equal(sh.clipped_channels, 0);
    assert_int_equal(cv_scatter_physics(&t.s, Ih, B, 1e-10, NULL), CV_OK);
    const double q = cv_scatter_workspace_norm_inf(wh);
    for (size_t p = 0; p < n3; p++)
      assert_near(B[p], Rs[p], ldexp(q * 0.55, -11) / (1 - q) + 1e-6);
    free(Rs);
    cv_scatter_workspace_destroy(wh);
  }
  free(R);
  free(If);
  free(Ih);
  free(B);
  cv_scatter_workspace_destroy(wf);
  tsys_free(&t);
}

/* ---- Bad input and stereo ------------------------------------------------------ */

static void test_nan_and_bad_system(void **state) {
  (void)state;
  tsys t;
  const float refl[3] = {0.5f, 0.5f, 0.5f};
  build_box(&t, 4, (1u << 0) | (1u << 4), refl, 0);
  const size_t n3 = 3 * t.s.n;
  cv_scatter_workspace *w = NULL;
  cv_err err;
  assert_int_equal(cv_scatter_workspace_create(&t.s, &w, &err), CV_OK);
  float *R = smooth_image(t.s.n, 0.2f, 0.8f), *I = malloc(n3 * sizeof *I);
  for (size_t p = 0; p < n3; p++) I[p] = -3;
  R[3 * 5 + 1] = NAN;
  const cv_scatter_solver solvers[] = {CV_SCATTER_AUTO, CV_SCATTER_EXACT, CV_SCATTER_JACOBI,
                                       CV_SCATTER_BOUNDED};
  cv_scatter_opts o;
  cv_scatter_opts_default(&o);
  for (int k = 0; k < 4; k++) {
    o.solver = solvers[k];
    cv_err_clear(&err);
    assert_int_equal(cv_scatter_solve(w, R, &o, I, NULL, &err), CV_ERR_NONFINITE);
    assert_non_null(strstr(err.msg, "patch 5 channel 1"));
  }
  R[3 * 5 + 1] = 0.5f;
  float *R2 = smooth_image(t.s.n, 0.2f, 0.8f);
  R2[3 * 9] = INFINITY;
  cv_err_clear(&err);
  assert_int_equal(cv_scatter_solve_stereo(w, R, R2, &o, I, NULL, &err), CV_ERR_NONFINITE);
  assert_non_null(strstr(err.msg, "R_right: patch 9"));
  for (size_t p = 0; p < n3; p++) assert_true(I[p] == -3);
  cv_scatter_workspace_destroy(w);

  /* Reflectance above 1 and a wrong matrix size are refused, naming the field. */
  t.refl[3 * 2 + 2] = 1.5f;
  cv_err_clear(&err);
  assert_int_equal(cv_scatter_workspace_create(&t.s, &w, &err), CV_ERR_RANGE);
  assert_null(w);
  assert_non_null(strstr(err.msg, "refl of patch 2 channel 2"));
  t.refl[3 * 2 + 2] = 0.5f;
  t.s.n = t.s.n - 1;
  assert_int_equal(cv_scatter_workspace_create(&t.s, &w, &err), CV_ERR_INVALID);
  print_message("bad system: %s\n", err.msg);
  t.s.n = t.s.n + 1;
  free(R);
  free(R2);
  free(I);
  tsys_free(&t);
}

static void test_stereo_average(void **state) {
  (void)state;
  tsys t;
  const float refl[3] = {0.7f, 0.7f, 0.7f};
  build_box(&t, 6, 0x1f, refl, 0.01f);
  const size_t n = t.s.n, n3 = 3 * n;
  cv_scatter_workspace *w = NULL;
  assert_int_equal(cv_scatter_workspace_create(&t.s, &w, NULL), CV_OK);
  float *L = smooth_image(n, 0.0f, 1.0f), *Rr = malloc(n3 * sizeof *Rr), *A = malloc(n3 * sizeof *A);
  for (size_t p = 0; p < n3; p++) {
    Rr[p] = L[(p + 3) % n3]; /* a one-patch parallax shift */
    A[p] = 0.5f * (L[p] + Rr[p]);
  }
  float *Is = malloc(n3 * sizeof *Is), *Ia = malloc(n3 * sizeof *Ia);
  cv_scatter_stats ss, sa;
  assert_int_equal(cv_scatter_solve_stereo(w, L, Rr, NULL, Is, &ss, NULL), CV_OK);
  assert_int_equal(cv_scatter_solve(w, A, NULL, Ia, &sa, NULL), CV_OK);
  assert_int_equal(ss.stereo, 1);
  assert_int_equal(sa.stereo, 0);
  assert_int_equal(ss.clipped_channels, sa.clipped_channels);
  for (size_t p = 0; p < n3; p++) assert_near(Is[p], Ia[p], 1e-5);
  free(L);
  free(Rr);
  free(A);
  free(Is);
  free(Ia);
  cv_scatter_workspace_destroy(w);
  tsys_free(&t);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_physics_two_patch),
      cmocka_unit_test(test_spectral_radius),
      cmocka_unit_test(test_exact_and_auto),
      cmocka_unit_test(test_jacobi_levels),
      cmocka_unit_test(test_jacobi_refuses_closed_box),
      cmocka_unit_test(test_bounded_cave_band),
      cmocka_unit_test(test_half_storage),
      cmocka_unit_test(test_nan_and_bad_system),
      cmocka_unit_test(test_stereo_average),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
