/* Block low-rank compression of the gather matrix (hmatrix.h) and the
 * workspace that uses it: the compressed product stays within its recorded
 * per-row error bound (and that bound within tol of each row's sum), the
 * sparse update equals a masked full product, the bounded solve through the
 * compressed K displays the target within tol + bound on unclipped patches
 * as judged by the exact physics, and the workspace refuses compression that
 * does not pay. */
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

#include "compensate/display.h"
#include "compensate/formfactor.h"
#include "compensate/hmatrix.h"
#include "compensate/solve.h"

typedef struct fixture {
  cv_display *d;
  cv_ffmatrix *F;
  cv_scatter_system s;
} fixture;

/* Two 3 m x 2 m walls at 90 degrees (the paper's two-sided wall). */
static void make(fixture *f, int np, double refl) {
  char json[2048];
  snprintf(json, sizeof json,
           "{\"surfaces\": ["
           "{\"name\": \"left\", \"corners\": [[-2.1213,0,0],[0,0,-2.1213],[-2.1213,2,0]], "
           "\"patches\": [%d,%d], \"reflectance\": [%g,%g,%g]},"
           "{\"name\": \"right\", \"corners\": [[0,0,-2.1213],[2.1213,0,0],[0,2,-2.1213]], "
           "\"patches\": [%d,%d], \"reflectance\": [%g,%g,%g]}], \"projectors\": \"ideal\"}",
           np, np, refl, refl, refl, np, np, refl, refl, refl);
  cv_err err;
  if (cv_display_parse(json, "walls", &f->d, &err)) fail_msg("%s", err.msg);
  cv_ff_params fp;
  cv_ff_params_default(&fp);
  fp.quiet = 1;
  assert_int_equal(cv_formfactors_build(f->d, &fp, &f->F, NULL, &err), CV_OK);
  cv_display_scatter_system(f->d, f->F, &f->s);
}

static void unmake(fixture *f) {
  cv_ffmatrix_destroy(f->F);
  cv_display_destroy(f->d);
}

/* Exact gather g = F x (3 channels) in double from the CSR matrix. */
static void exact_gather(const cv_ffmatrix *F, const double *x, double *g) {
  for (size_t i = 0; i < F->n; i++) {
    double a[3] = {0, 0, 0};
    for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++)
      for (int c = 0; c < 3; c++) a[c] += (double)F->val[k] * x[3 * F->col[k] + c];
    for (int c = 0; c < 3; c++) g[3 * i + c] = a[c];
  }
}

static void test_product_within_bound(void **state) {
  (void)state;
  fixture f;
  make(&f, 32, 0.475);
  const double tol = 1e-3;
  cv_hmatrix *h;
  cv_hmatrix_info info;
  cv_err err;
  assert_int_equal(cv_hmatrix_build(f.F, f.s.cluster, f.s.n_clusters, tol, &h, &info, &err), CV_OK);
  printf("  2 x 32 x 32: %zu clusters, %zu blocks (%zu low-rank, mean rank %.2f, max %d; %zu dense), "
         "%zu values stored for %zu nonzeros (%.1fx), max row error %.3e = %.3e of the row\n",
         info.n_clusters, info.n_blocks, info.n_lowrank, info.mean_rank, info.max_rank,
         info.n_dense, info.stored_values, info.source_nnz,
         (double)info.source_nnz / (double)info.stored_values, info.max_row_error,
         info.max_rel_row_error);
  assert_true(info.max_rel_row_error <= tol * 1.0001);
  assert_true(info.n_lowrank > 0 && info.n_dense > 0); /* near seam dense, far field low rank */
  assert_true(info.stored_values * 2 < info.source_nnz);
  const size_t n = f.s.n;
  double *x = malloc(3 * n * sizeof *x), *g = malloc(3 * n * sizeof *g),
         *ge = malloc(3 * n * sizeof *ge), *g2 = malloc(3 * n * sizeof *g2);
  uint8_t *act = malloc(n);
  srand(7);
  for (int trial = 0; trial < 3; trial++) {
    for (size_t p = 0; p < 3 * n; p++) x[p] = (double)rand() / RAND_MAX * (trial == 2 ? -1 : 1);
    cv_hmatrix_gather(h, x, g);
    exact_gather(f.F, x, ge);
    const double *re = cv_hmatrix_row_error(h);
    double xmax = 0, worst = 0;
    for (size_t p = 0; p < 3 * n; p++) xmax = fabs(x[p]) > xmax ? fabs(x[p]) : xmax;
    for (size_t p = 0; p < 3 * n; p++) {
      const double e = fabs(g[p] - ge[p]);
      assert_true(e <= re[p / 3] * xmax + 1e-12);
      if (re[p / 3] > 0 && e / (re[p / 3] * xmax) > worst) worst = e / (re[p / 3] * xmax);
    }
    printf("  trial %d: largest product error is %.2f of its bound\n", trial, worst);
  }
  /* Sparse update = masked full product (to rounding). */
  for (size_t i = 0; i < n; i++) act[i] = (i % 97) < 9 || (i > n / 2 && i < n / 2 + 40);
  for (size_t p = 0; p < 3 * n; p++) x[p] = act[p / 3] ? (double)rand() / RAND_MAX : 0;
  cv_hmatrix_gather(h, x, ge);
  for (size_t p = 0; p < 3 * n; p++) g2[p] = 0.25;
  double share = cv_hmatrix_gather_add_active(h, act, x, g2);
  assert_true(share > 0 && share <= 1);
  for (size_t p = 0; p < 3 * n; p++) assert_near(g2[p] - 0.25, ge[p], 1e-12);
  /* Deterministic: the same product twice is bit-identical. */
  cv_hmatrix_gather(h, x, g);
  cv_hmatrix_gather(h, x, g2);
  assert_memory_equal(g, g2, 3 * n * sizeof *g);
  free(x);
  free(g);
  free(ge);
  free(g2);
  free(act);
  cv_hmatrix_destroy(h);
  unmake(&f);
}

static void test_bounded_solve_compressed(void **state) {
  (void)state;
  fixture f;
  make(&f, 32, 0.8);
  const size_t n = f.s.n;
  cv_scatter_workspace *wc, *wp;
  cv_err err;
  assert_int_equal(cv_scatter_workspace_create_ex(&f.s, CV_SCATTER_WS_COMPRESS, &wc, &err), CV_OK);
  assert_int_equal(cv_scatter_workspace_create_ex(&f.s, 0, &wp, &err), CV_OK);
  cv_scatter_model m;
  assert_int_equal(cv_scatter_workspace_get_model(wc, &m), CV_OK);
  printf("  model: %s, %.2f MB against %.2f MB plain, product error bound %.2e\n", m.storage,
         m.bytes / 1e6, m.source_bytes / 1e6, m.error_bound);
  assert_string_equal(m.storage, "block low-rank");
  assert_true(m.error_bound > 0 && m.error_bound < 1e-3);
  /* White with a black band next to the corner (clips). */
  float *T = malloc(3 * n * sizeof *T), *Ic = malloc(3 * n * sizeof *Ic),
        *Ip = malloc(3 * n * sizeof *Ip);
  for (size_t i = 0; i < n; i++) {
    const cv_patch *p = cv_display_patch(f.d, i);
    const double v = (p->surface == 1 && p->u < 5) ? 0.0 : 0.8;
    for (int c = 0; c < 3; c++) T[3 * i + c] = (float)v;
  }
  cv_scatter_opts o;
  cv_scatter_opts_default(&o);
  cv_scatter_stats sc, sp;
  assert_int_equal(cv_scatter_solve(wc, T, &o, Ic, &sc, &err), CV_OK);
  assert_int_equal(cv_scatter_solve(wp, T, &o, Ip, &sp, &err), CV_OK);
  printf("  bounded: compressed %zu clipped patches, %d sweeps, residual bound %.2e; plain %zu, %d\n",
         sc.clipped_patches, sc.iterations, sc.residual, sp.clipped_patches, sp.iterations);
  assert_true(sc.clipped_patches > 0);
  assert_true(sc.residual <= o.tol + 2 * m.error_bound / (1 - cv_scatter_workspace_norm_inf(wc)));
  /* Judge with the exact physics: unclipped patches show T within the bound. */
  double *B = malloc(3 * n * sizeof *B);
  assert_int_equal(cv_scatter_physics(&f.s, Ic, B, 1e-9, NULL), CV_OK);
  double worst = 0, dI = 0;
  for (size_t p = 0; p < 3 * n; p++) {
    if (Ic[p] > 1e-6 && Ic[p] < 1 - 1e-6) {
      const double e = fabs(B[p] - T[p]);
      worst = e > worst ? e : worst;
    }
    dI = fabs(Ic[p] - Ip[p]) > dI ? fabs(Ic[p] - Ip[p]) : dI;
  }
  printf("  worst displayed error on unclipped patches %.2e (bound %.2e); max |I_c - I_plain| %.2e\n",
         worst, sc.residual, dI);
  assert_true(worst <= sc.residual + 1e-6);
  assert_true(worst <= 1.0 / 255);
  assert_true(dI < 2.0 / 255);
  free(B);
  free(T);
  free(Ic);
  free(Ip);
  cv_scatter_workspace_destroy(wc);
  cv_scatter_workspace_destroy(wp);
  unmake(&f);
}

static void test_compression_not_picked(void **state) {
  (void)state;
  /* 4 x 4 patches per wall: one tile per wall, a single near-field block
   * each way, nothing to gain: the workspace keeps the plain storage. */
  fixture f;
  make(&f, 4, 0.5);
  cv_scatter_workspace *w;
  cv_err err;
  assert_int_equal(cv_scatter_workspace_create_ex(&f.s, CV_SCATTER_WS_COMPRESS, &w, &err), CV_OK);
  cv_scatter_model m;
  cv_scatter_workspace_get_model(w, &m);
  printf("  4 x 4: picked %s (compressed form %.0f bytes against %.0f)\n", m.storage,
         m.compressed_bytes, m.source_bytes);
  assert_int_equal(m.compress_tried, 1);
  assert_string_equal(m.storage, "float");
  cv_scatter_workspace_destroy(w);
  /* Without clusters the flag is ignored. */
  cv_scatter_system s = f.s;
  s.cluster = NULL;
  assert_int_equal(cv_scatter_workspace_create_ex(&s, CV_SCATTER_WS_COMPRESS, &w, &err), CV_OK);
  cv_scatter_workspace_get_model(w, &m);
  assert_int_equal(m.compress_tried, 0);
  cv_scatter_workspace_destroy(w);
  /* Bad input. */
  cv_hmatrix *h;
  uint32_t bad[32];
  for (int i = 0; i < 32; i++) bad[i] = 0;
  bad[3] = 9;
  assert_int_equal(cv_hmatrix_build(f.F, bad, 2, 1e-3, &h, NULL, &err), CV_ERR_INVALID);
  printf("  bad cluster: %s\n", err.msg);
  assert_int_equal(cv_hmatrix_build(f.F, f.s.cluster, f.s.n_clusters, 0.7, &h, NULL, &err),
                   CV_ERR_INVALID);
  assert_null(h);
  unmake(&f);
}

/* The 5-wall CAVE (3 m cube without its back wall) at np x np per wall. */
static cv_display *cave5(int np) {
  char json[4096];
  snprintf(json, sizeof json,
           "{\"surfaces\": ["
           "{\"name\":\"front\",\"corners\":[[-1.5,0,-1.5],[1.5,0,-1.5],[-1.5,3,-1.5]],\"patches\":[%d,%d],\"reflectance\":[0.8,0.8,0.8]},"
           "{\"name\":\"left\",\"corners\":[[-1.5,0,1.5],[-1.5,0,-1.5],[-1.5,3,1.5]],\"patches\":[%d,%d],\"reflectance\":[0.8,0.8,0.8]},"
           "{\"name\":\"right\",\"corners\":[[1.5,0,-1.5],[1.5,0,1.5],[1.5,3,-1.5]],\"patches\":[%d,%d],\"reflectance\":[0.8,0.8,0.8]},"
           "{\"name\":\"floor\",\"corners\":[[-1.5,0,1.5],[1.5,0,1.5],[-1.5,0,-1.5]],\"patches\":[%d,%d],\"reflectance\":[0.8,0.8,0.8]},"
           "{\"name\":\"ceiling\",\"corners\":[[-1.5,3,-1.5],[1.5,3,-1.5],[-1.5,3,1.5]],\"patches\":[%d,%d],\"reflectance\":[0.8,0.8,0.8]}],"
           "\"projectors\":\"ideal\"}",
           np, np, np, np, np, np, np, np, np, np);
  cv_display *d;
  cv_err err;
  if (cv_display_parse(json, "cave5", &d, &err)) fail_msg("%s", err.msg);
  return d;
}

/* Direct build against the dense build without sparsification: the whole
 * approximated matrix (column by column through products with unit
 * vectors) errs per row by at most tol of the row's sum, and the row error
 * estimate is checked against the true error. */
static void check_direct(cv_display *d, const char *name, double tol) {
  cv_ff_params fp;
  cv_ff_params_default(&fp);
  fp.quiet = 1;
  fp.drop_budget = 0;
  cv_ffmatrix *F;
  cv_err err;
  assert_int_equal(cv_formfactors_build(d, &fp, &F, NULL, &err), CV_OK);
  cv_hmatrix_direct_params hp;
  cv_hmatrix_direct_params_default(&hp);
  hp.tol = tol;
  hp.quiet = 1;
  cv_hmatrix *h;
  cv_hmatrix_info info;
  assert_int_equal(cv_hmatrix_build_direct(d, &fp, &hp, &h, &info, &err), CV_OK);
  const size_t n = F->n;
  assert_int_equal(cv_hmatrix_size(h), n);
  /* dense copy of G and of G~ (column j = G~ e_j) */
  double *G = calloc(n * n, sizeof *G), *x = calloc(3 * n, sizeof *x), *g = malloc(3 * n * sizeof *g);
  double *rerr = calloc(n, sizeof *rerr), *rsum = calloc(n, sizeof *rsum);
  for (size_t i = 0; i < n; i++)
    for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) {
      G[i * n + F->col[k]] = F->val[k];
      rsum[i] += F->val[k];
    }
  for (size_t j = 0; j < n; j++) {
    x[3 * j] = 1;
    cv_hmatrix_gather(h, x, g);
    x[3 * j] = 0;
    for (size_t i = 0; i < n; i++) rerr[i] += fabs(g[3 * i] - G[i * n + j]);
  }
  /* the row read-out agrees with the product */
  for (size_t i = 0; i < n; i += 97) {
    double e = 0;
    cv_hmatrix_row_values(h, i, g);
    for (size_t j = 0; j < n; j++) e += fabs(g[j] - G[i * n + j]);
    assert_near(e, rerr[i], 1e-9 + 1e-6 * rerr[i]);
  }
  const double *est = cv_hmatrix_row_error(h);
  const double *hs = cv_hmatrix_row_sum(h);
  double worst = 0, worst_est = 0, under = 0, sum_dev = 0;
  for (size_t i = 0; i < n; i++) {
    if (!(rsum[i] > 0)) continue;
    worst = fmax(worst, rerr[i] / rsum[i]);
    worst_est = fmax(worst_est, est[i] / rsum[i]);
    under = fmax(under, (rerr[i] - est[i]) / rsum[i]);
    sum_dev = fmax(sum_dev, fabs(hs[i] - rsum[i]) / rsum[i]);
  }
  printf("  %s direct: %zu leaves, %zu blocks (%zu low-rank, mean rank %.2f, max %d; %zu dense), "
         "%zu values for %zu pairs (%.1fx), %.0f ms\n"
         "    true max row error %.3e of the row, estimated %.3e, estimate short by <= %.3e; "
         "row sums within %.2e\n",
         name, info.n_clusters, info.n_blocks, info.n_lowrank, info.mean_rank, info.max_rank,
         info.n_dense, info.stored_values, info.source_nnz,
         (double)info.source_nnz / (double)info.stored_values, info.build_ms, worst, worst_est,
         under, sum_dev);
  assert_true(info.n_lowrank > 0 && info.n_dense > 0);
  assert_true(info.stored_values < info.source_nnz);
  assert_true(worst <= tol);     /* the per-row target holds */
  assert_true(worst_est <= tol); /* and so does the estimate the solvers use */
  assert_true(sum_dev <= tol);
  free(G);
  free(x);
  free(g);
  free(rerr);
  free(rsum);
  cv_hmatrix_destroy(h);
  cv_ffmatrix_destroy(F);
}

static void test_direct_equals_dense(void **state) {
  (void)state;
  fixture f;
  make(&f, 24, 0.5);
  check_direct(f.d, "2 x 24 x 24", 1e-3);
  unmake(&f);
  cv_display *d = cave5(16);
  check_direct(d, "5 x 16 x 16", 1e-3);
  cv_err err;
  cv_hmatrix *h;
  cv_hmatrix_direct_params hp;
  cv_hmatrix_direct_params_default(&hp);
  hp.tol = 0.7;
  assert_int_equal(cv_hmatrix_build_direct(d, NULL, &hp, &h, NULL, &err), CV_ERR_INVALID);
  printf("  bad tolerance: %s\n", err.msg);
  assert_null(h);
  cv_display_destroy(d);
}

/* A system that carries only the directly built H: the workspace uses it
 * (storage "block low-rank (direct)"), and the bounded solve's input is
 * that of the dense system within 2/255, judged by the dense physics. */
static void test_solve_direct_only(void **state) {
  (void)state;
  fixture f;
  make(&f, 24, 0.8);
  const size_t n = f.s.n;
  cv_hmatrix *h;
  cv_err err;
  assert_int_equal(cv_hmatrix_build_direct(f.d, NULL, NULL, &h, NULL, &err), CV_OK);
  cv_scatter_system sd;
  cv_display_scatter_system(f.d, NULL, &sd);
  sd.H = h;
  cv_scatter_workspace *wd, *wp;
  assert_int_equal(cv_scatter_workspace_create(&sd, &wd, &err), CV_OK);
  assert_int_equal(cv_scatter_workspace_create(&f.s, &wp, &err), CV_OK);
  cv_scatter_model m;
  cv_scatter_workspace_get_model(wd, &m);
  printf("  direct-only system: %s, %.2f MB (dense %.2f MB), product error bound %.2e, rho %.4f "
         "(dense %.4f)\n", m.storage, m.bytes / 1e6, m.source_bytes / 1e6, m.error_bound,
         cv_scatter_workspace_rho(wd), cv_scatter_workspace_rho(wp));
  assert_string_equal(m.storage, "block low-rank (direct)");
  assert_true(m.error_bound > 0 && m.error_bound < 1e-3);
  assert_near(cv_scatter_workspace_rho(wd), cv_scatter_workspace_rho(wp), 2e-3);
  float *T = malloc(3 * n * sizeof *T), *Id = malloc(3 * n * sizeof *Id),
        *Ip = malloc(3 * n * sizeof *Ip);
  for (size_t i = 0; i < n; i++) {
    const cv_patch *p = cv_display_patch(f.d, i);
    const double v = (p->surface == 1 && p->u < 4) ? 0.0 : 0.8;
    for (int c = 0; c < 3; c++) T[3 * i + c] = (float)v;
  }
  cv_scatter_opts o;
  cv_scatter_opts_default(&o);
  cv_scatter_stats sd_st, sp_st;
  assert_int_equal(cv_scatter_solve(wd, T, &o, Id, &sd_st, &err), CV_OK);
  assert_int_equal(cv_scatter_solve(wp, T, &o, Ip, &sp_st, &err), CV_OK);
  double dI = 0;
  for (size_t p = 0; p < 3 * n; p++) dI = fmax(dI, fabs((double)Id[p] - Ip[p]));
  double *B = malloc(3 * n * sizeof *B);
  assert_int_equal(cv_scatter_physics(&f.s, Id, B, 1e-9, NULL), CV_OK);
  double worst = 0;
  for (size_t p = 0; p < 3 * n; p++)
    if (Id[p] > 1e-6 && Id[p] < 1 - 1e-6) worst = fmax(worst, fabs(B[p] - T[p]));
  printf("  bounded: %zu clipped patches (dense %zu), max |I_direct - I_dense| %.2e, worst "
         "displayed error on unclipped patches %.2e (dense physics)\n",
         sd_st.clipped_patches, sp_st.clipped_patches, dI, worst);
  assert_true(sd_st.clipped_patches > 0);
  assert_true(dI < 2.0 / 255);
  assert_true(worst <= 1.0 / 255);
  /* the physics runs on H alone too */
  assert_int_equal(cv_scatter_physics(&sd, Id, B, 1e-9, NULL), CV_OK);
  free(B);
  free(T);
  free(Id);
  free(Ip);
  cv_scatter_workspace_destroy(wd);
  cv_scatter_workspace_destroy(wp);
  cv_hmatrix_destroy(h);
  unmake(&f);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_product_within_bound),
      cmocka_unit_test(test_bounded_solve_compressed),
      cmocka_unit_test(test_compression_not_picked),
      cmocka_unit_test(test_direct_equals_dense),
      cmocka_unit_test(test_solve_direct_only),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
