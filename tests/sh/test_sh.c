/* Unit tests of the SH module (cv_sh): basis against an independent
 * trigonometric reference and orthonormality by quadrature, lat-long
 * projection with exact pixel weights, the clamped-cosine factors, rotation
 * (Ivanic-Ruedenberg) against re-projection of rotated functions, and
 * windowing.  Tolerances are stated at each check; measured figures are
 * printed. */
#include <math.h>
#include <omp.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <cmocka.h>
#include "cv_test_near.h"

#include "core/image.h"
#include "core/status.h"
#include "sh/latlong.h"
#include "sh/sh.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* ---- helpers ------------------------------------------------------------ */

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static double rnd(void) { /* xorshift64*, uniform [0, 1) */
  rng_state ^= rng_state >> 12;
  rng_state ^= rng_state << 25;
  rng_state ^= rng_state >> 27;
  return (double)((rng_state * 0x2545F4914F6CDD1Dull) >> 11) * (1.0 / 9007199254740992.0);
}
static void rnd_dir(double d[3]) {
  const double z = 2.0 * rnd() - 1.0, ph = 2.0 * M_PI * rnd(), s = sqrt(1.0 - z * z);
  d[0] = s * cos(ph);
  d[1] = s * sin(ph);
  d[2] = z;
}
/* Uniform random rotation from a random unit quaternion (row-major). */
static void rnd_rotation(double R[9]) {
  double q[4], n = 0.0;
  do {
    n = 0.0;
    for (int k = 0; k < 4; k++) {
      q[k] = 2.0 * rnd() - 1.0;
      n += q[k] * q[k];
    }
  } while (n > 1.0 || n < 1e-3);
  n = sqrt(n);
  const double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
  R[0] = 1 - 2 * (y * y + z * z); R[1] = 2 * (x * y - w * z);     R[2] = 2 * (x * z + w * y);
  R[3] = 2 * (x * y + w * z);     R[4] = 1 - 2 * (x * x + z * z); R[5] = 2 * (y * z - w * x);
  R[6] = 2 * (x * z - w * y);     R[7] = 2 * (y * z + w * x);     R[8] = 1 - 2 * (x * x + y * y);
}
static void matmul3(const double A[9], const double B[9], double C[9]) {
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      double s = 0.0;
      for (int k = 0; k < 3; k++) s += A[3 * i + k] * B[3 * k + j];
      C[3 * i + j] = s;
    }
}
static void mat_t_vec(const double R[9], const double v[3], double out[3]) { /* R^T v */
  for (int i = 0; i < 3; i++) out[i] = R[i] * v[0] + R[3 + i] * v[1] + R[6 + i] * v[2];
}

/* Independent reference basis: spherical angles, un-normalised associated
 * Legendre recurrence, factorial normalisation, libm trigonometry. */
static double fact(int k) {
  double r = 1.0;
  for (int i = 2; i <= k; i++) r *= i;
  return r;
}
static double assoc_legendre(int l, int m, double x) { /* no Condon-Shortley phase */
  double pmm = 1.0;
  const double s = sqrt(fmax(0.0, 1.0 - x * x));
  for (int i = 1; i <= m; i++) pmm *= (2.0 * i - 1.0) * s;
  if (l == m) return pmm;
  double pm1 = x * (2.0 * m + 1.0) * pmm;
  if (l == m + 1) return pm1;
  double pl = 0.0;
  for (int ll = m + 2; ll <= l; ll++) {
    pl = ((2.0 * ll - 1.0) * x * pm1 - (ll + m - 1.0) * pmm) / (ll - m);
    pmm = pm1;
    pm1 = pl;
  }
  return pl;
}
static double ref_sh(int l, int m, const double d[3]) {
  const double th = acos(fmax(-1.0, fmin(1.0, d[2]))), ph = atan2(d[1], d[0]);
  const int am = abs(m);
  const double K = sqrt((2.0 * l + 1.0) / (4.0 * M_PI) * fact(l - am) / fact(l + am));
  const double P = assoc_legendre(l, am, cos(th));
  if (m == 0) return K * P;
  if (m > 0) return sqrt(2.0) * K * P * cos(m * ph);
  return sqrt(2.0) * K * P * sin(am * ph);
}

/* ---- basis -------------------------------------------------------------- */

static void test_basis_reference(void **state) {
  (void)state;
  double worst = 0.0, worst_f = 0.0;
  for (int t = 0; t < 2000; t++) {
    double d[3];
    rnd_dir(d);
    if (t == 0) { d[0] = 0; d[1] = 0; d[2] = 1; }   /* poles */
    if (t == 1) { d[0] = 0; d[1] = 0; d[2] = -1; }
    const float df[3] = {(float)d[0], (float)d[1], (float)d[2]};
    double y[CV_SH_MAX_COEFFS], yd[CV_SH_MAX_COEFFS];
    float yf[CV_SH_MAX_COEFFS];
    cv_sh_eval_d(8, d, y);
    /* the float path sees the float-rounded direction; compare against the
     * double path evaluated at exactly that direction */
    const double dr[3] = {df[0], df[1], df[2]};
    cv_sh_eval_d(8, dr, yd);
    cv_sh_eval(8, df, yf);
    for (int l = 0; l < 8; l++)
      for (int m = -l; m <= l; m++) {
        const int i = cv_sh_index(l, m);
        worst = fmax(worst, fabs(y[i] - ref_sh(l, m, d)));
        worst_f = fmax(worst_f, fabs((double)yf[i] - yd[i]));
      }
    /* lower n gives the prefix of the n = 8 values */
    double y3[9];
    cv_sh_eval_d(3, d, y3);
    for (int i = 0; i < 9; i++) assert_true(y3[i] == y[i]);
  }
  printf("  basis vs trig reference (n=8, 2000 dirs): max |diff| %.2e (tol 1e-12)\n", worst);
  printf("  float vs double basis (n=8): max |diff| %.2e (tol 2e-6)\n", worst_f);
  assert_true(worst < 1e-12);
  assert_true(worst_f < 2e-6);

  /* hand-checked values: band 1 is sqrt(3/4pi) (y, z, x); y_20, y_22, y_2-2 */
  const double d[3] = {0.48, -0.6, 0.64};
  double y[9];
  cv_sh_eval_d(3, d, y);
  const double k1 = sqrt(3.0 / (4.0 * M_PI));
  assert_near(y[0], 0.5 / sqrt(M_PI), 1e-15);
  assert_near(y[1], k1 * d[1], 1e-15);
  assert_near(y[2], k1 * d[2], 1e-15);
  assert_near(y[3], k1 * d[0], 1e-15);
  assert_near(y[4], 0.5 * sqrt(15.0 / M_PI) * d[0] * d[1], 1e-15);
  assert_near(y[6], 0.25 * sqrt(5.0 / M_PI) * (3 * d[2] * d[2] - 1), 1e-15);
  assert_near(y[8], 0.25 * sqrt(15.0 / M_PI) * (d[0] * d[0] - d[1] * d[1]), 1e-15);

  /* speed of the hot path (printed, not asserted) */
  float yf[CV_SH_MAX_COEFFS];
  volatile float sink = 0.0f; /* keeps the calls alive */
  const int reps = 2000000;
  for (int n = 3; n <= 8; n += 5) {
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (int r = 0; r < reps; r++) {
      const float a = (float)r * 1e-6f;
      const float df[3] = {0.6f * cosf(a), 0.6f * sinf(a), 0.8f};
      cv_sh_eval(n, df, yf);
      sink += yf[n * n - 1];
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    const double ns = ((t1.tv_sec - t0.tv_sec) * 1e9 + (t1.tv_nsec - t0.tv_nsec)) / reps;
    printf("  cv_sh_eval n=%d: %.1f ns/call, including the test loop's cosf/sinf\n", n, ns);
  }
}

static void test_orthonormality(void **state) {
  (void)state;
  /* Gauss-Legendre in z (16 nodes) x 32 uniform azimuths is exact for the
   * products y_i y_j of degree <= 14; tolerance 1e-6 (measured ~1e-15). */
  enum { NT = 16, NP = 32, NC = 64 };
  double gx[NT], gw[NT];
  assert_int_equal(cv_gauss_legendre(NT, gx, gw), CV_OK);
  static double G[NC][NC];
  memset(G, 0, sizeof G);
  for (int k = 0; k < NT; k++)
    for (int j = 0; j < NP; j++) {
      const double ph = 2.0 * M_PI * (j + 0.5) / NP, s = sqrt(1.0 - gx[k] * gx[k]);
      const double d[3] = {s * cos(ph), s * sin(ph), gx[k]};
      double y[NC];
      cv_sh_eval_d(8, d, y);
      const double wgt = gw[k] * 2.0 * M_PI / NP;
      for (int a = 0; a < NC; a++)
        for (int b = 0; b < NC; b++) G[a][b] += wgt * y[a] * y[b];
    }
  double worst = 0.0;
  for (int a = 0; a < NC; a++)
    for (int b = 0; b < NC; b++) worst = fmax(worst, fabs(G[a][b] - (a == b ? 1.0 : 0.0)));
  printf("  orthonormality n=8: max |G - I| = %.2e (tol 1e-6)\n", worst);
  assert_true(worst < 1e-6);

  /* Gauss-Legendre weights sum to 2 and integrate x^(2k) exactly */
  double s = 0.0, s4 = 0.0;
  for (int k = 0; k < NT; k++) {
    s += gw[k];
    s4 += gw[k] * pow(gx[k], 4);
  }
  assert_near(s, 2.0, 1e-14);
  assert_near(s4, 0.4, 1e-14);
}

/* ---- projection --------------------------------------------------------- */

/* Fills a w x h x 3 map with the constant L and projects it on 8 bands;
 * returns the relative error of c0 and the largest other |c| over c0. */
static cv_image *constant_map(int w, int h, const float L[3], double *c8, double *rel0,
                              double *relo) {
  cv_image *img = NULL;
  assert_int_equal(cv_image_create(w, h, 3, &img), CV_OK);
  for (int i = 0; i < w * h; i++)
    for (int c = 0; c < 3; c++) img->px[3 * i + c] = L[c];
  assert_int_equal(cv_sh_project_latlong(img, 8, c8), CV_OK);
  *rel0 = *relo = 0.0;
  for (int ch = 0; ch < 3; ch++) {
    const double expect = L[ch] * sqrt(4.0 * M_PI);
    *rel0 = fmax(*rel0, fabs(c8[ch] - expect) / expect);
    for (int i = 1; i < 64; i++) *relo = fmax(*relo, fabs(c8[3 * i + ch]) / expect);
  }
  return img;
}

static void test_project_constant(void **state) {
  (void)state;
  /* c0 = L sqrt(4 pi) to rounding, because the exact row weights sum to
   * 4 pi.  The other coefficients vanish only up to the pixel-centre rule's
   * O(1/h^2) error in the polar direction (the basis is evaluated at the
   * pixel centre, not averaged over the pixel): measured 9.9e-4 of c0 at
   * 64x32 and 6e-5 at 256x128; tolerances 2e-3 and 1e-4. */
  const float L[3] = {2.0f, 0.5f, 1.25f};
  double c8[3 * 64], rel0, relo;
  cv_image_destroy(constant_map(256, 128, L, c8, &rel0, &relo));
  printf("  constant 256x128 map: c0 rel err %.2e (tol 1e-12), others max |c|/c0 %.2e (tol 1e-4)\n",
         rel0, relo);
  assert_true(rel0 < 1e-12);
  assert_true(relo < 1e-4);
  cv_image *img = constant_map(64, 32, L, c8, &rel0, &relo);
  printf("  constant 64x32 map: c0 rel err %.2e (tol 1e-12), others max |c|/c0 %.2e (tol 2e-3)\n",
         rel0, relo);
  assert_true(rel0 < 1e-12);
  assert_true(relo < 2e-3);

  /* Irradiance of a constant environment is pi L for every normal: exactly
   * (1e-14) from the exact expansion c0 = L sqrt(4 pi), and to the map's
   * quadrature error (measured 4.7e-4, tol 1e-3) from the 64x32 projection. */
  double exact[3 * 9] = {0};
  for (int ch = 0; ch < 3; ch++) exact[ch] = L[ch] * sqrt(4.0 * M_PI);
  cv_sh_convolve_cosine(3, exact, 3);
  cv_sh_convolve_cosine(3, c8, 3); /* only bands 0..2 are touched */
  double worst = 0.0, worst_exact = 0.0;
  for (int t = 0; t < 100; t++) {
    double nrm[3], E[3], Ee[3];
    rnd_dir(nrm);
    cv_sh_eval_sum(3, c8, 3, nrm, E);
    cv_sh_eval_sum(3, exact, 3, nrm, Ee);
    for (int ch = 0; ch < 3; ch++) {
      worst = fmax(worst, fabs(E[ch] - M_PI * L[ch]) / (M_PI * L[ch]));
      worst_exact = fmax(worst_exact, fabs(Ee[ch] - M_PI * L[ch]) / (M_PI * L[ch]));
    }
  }
  printf("  constant env irradiance vs pi*L: exact expansion %.2e (tol 1e-14), "
         "64x32 map %.2e (tol 1e-3)\n", worst_exact, worst);
  assert_true(worst_exact < 1e-14);
  assert_true(worst < 1e-3);

  /* a 1-channel map is treated as grey RGB */
  cv_image *g = NULL;
  assert_int_equal(cv_image_create(16, 8, 1, &g), CV_OK);
  for (int i = 0; i < 16 * 8; i++) g->px[i] = 3.0f;
  double cg[3 * 4];
  assert_int_equal(cv_sh_project_latlong(g, 2, cg), CV_OK);
  for (int ch = 0; ch < 3; ch++) assert_near(cg[ch], 3.0 * sqrt(4 * M_PI), 1e-12);
  cv_image_destroy(g);

  /* errors */
  assert_int_equal(cv_sh_project_latlong(img, 0, c8), CV_ERR_INVALID);
  assert_int_equal(cv_sh_project_latlong(img, 9, c8), CV_ERR_INVALID);
  img->px[100] = NAN;
  assert_int_equal(cv_sh_project_latlong(img, 2, c8), CV_ERR_NONFINITE);
  for (int i = 0; i < 12; i++) assert_true(c8[i] == 0.0);
  cv_image_destroy(img);
}

static void smooth_fn(const double d[3], void *user, double rgb[3]) {
  (void)user;
  rgb[0] = exp(0.9 * d[0] - 0.3 * d[1] + 0.4 * d[2]);
  rgb[1] = 1.0 + 0.5 * pow(0.6 * d[0] + 0.8 * d[2], 3) + d[1] * d[0];
  rgb[2] = 1.0 / (1.3 - 0.5 * d[1]);
}

static void test_project_latlong_vs_fn(void **state) {
  (void)state;
  /* A smooth function sampled into a 512x256 map: the pixel-centre rule with
   * exact row weights converges as 1/h^2; against Gauss-Legendre (exact to
   * ~1e-15) the n=8 coefficients agree to 1e-4 of |c0|. */
  const int w = 512, h = 256;
  cv_image *img = NULL;
  assert_int_equal(cv_image_create(w, h, 3, &img), CV_OK);
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      double d[3], rgb[3];
      cv_latlong_pixel_dir(x, y, w, h, d);
      smooth_fn(d, NULL, rgb);
      float *p = cv_image_at(img, x, y);
      for (int c = 0; c < 3; c++) p[c] = (float)rgb[c];
    }
  double a[3 * 64], b[3 * 64];
  assert_int_equal(cv_sh_project_latlong(img, 8, a), CV_OK);
  assert_int_equal(cv_sh_project_fn(8, 40, smooth_fn, NULL, b), CV_OK);
  double worst = 0.0;
  for (int i = 0; i < 64; i++)
    for (int ch = 0; ch < 3; ch++) worst = fmax(worst, fabs(a[3 * i + ch] - b[3 * i + ch]) / fabs(b[ch]));
  printf("  lat-long 512x256 vs Gauss-Legendre projection, n=8: max |diff|/c0 %.2e (tol 1e-4)\n", worst);
  assert_true(worst < 1e-4);

  /* deterministic whatever the thread count: bit-identical */
  const int nthr = omp_get_max_threads();
  double c1[3 * 64], c3[3 * 64];
  omp_set_num_threads(1);
  assert_int_equal(cv_sh_project_latlong(img, 8, c1), CV_OK);
  omp_set_num_threads(3);
  assert_int_equal(cv_sh_project_latlong(img, 8, c3), CV_OK);
  omp_set_num_threads(nthr);
  assert_memory_equal(c1, c3, sizeof c1);
  assert_memory_equal(c1, a, sizeof c1);
  cv_image_destroy(img);
}

/* ---- clamped cosine ----------------------------------------------------- */

static double lobe_axis[3];
static void lobe_fn(const double d[3], void *user, double rgb[3]) {
  (void)user;
  const double c = d[0] * lobe_axis[0] + d[1] * lobe_axis[1] + d[2] * lobe_axis[2];
  rgb[0] = rgb[1] = rgb[2] = c > 0.0 ? c : 0.0;
}

static void test_cosine_lobe(void **state) {
  (void)state;
  /* closed values */
  const double expect[9] = {M_PI, 2 * M_PI / 3, M_PI / 4, 0, -M_PI / 24, 0, M_PI / 64, 0,
                            -M_PI / 128};
  for (int l = 0; l < 9; l++) assert_near(cv_sh_cosine_lobe_factor(l), expect[l], 1e-15);
  /* independent: A_l = 2 pi int_0^1 t P_l(t) dt by 64-node Gauss-Legendre on
   * [0, 1] (exact: polynomial of degree l + 1) */
  double gx[64], gw[64];
  cv_gauss_legendre(64, gx, gw);
  for (int l = 0; l < 20; l++) {
    double s = 0.0;
    for (int k = 0; k < 64; k++) {
      const double t = 0.5 * (gx[k] + 1.0);
      s += 0.5 * gw[k] * t * assoc_legendre(l, 0, t);
    }
    assert_near(2 * M_PI * s, cv_sh_cosine_lobe_factor(l), 1e-13);
  }

  /* The lobe max(d.z, 0) projects to A_l y_l0(+Z) = A_l sqrt((2l+1)/4pi),
   * m != 0 vanish.  The kink at z = 0 limits Gauss-Legendre to algebraic
   * convergence: 400 nodes give ~1e-6. */
  lobe_axis[0] = 0; lobe_axis[1] = 0; lobe_axis[2] = 1;
  double c[3 * 64];
  assert_int_equal(cv_sh_project_fn(8, 400, lobe_fn, NULL, c), CV_OK);
  double worst = 0.0;
  for (int l = 0; l < 8; l++)
    for (int m = -l; m <= l; m++) {
      const double e = (m == 0) ? cv_sh_cosine_lobe_factor(l) * sqrt((2 * l + 1) / (4 * M_PI)) : 0.0;
      worst = fmax(worst, fabs(c[3 * cv_sh_index(l, m)] - e));
    }
  printf("  lobe about +Z vs A_l y_l0: max |diff| %.2e (tol 1e-5)\n", worst);
  assert_true(worst < 1e-5);

  /* The same lobe about a tilted axis a: coefficients A_l y_lm(a); projected
   * through a 1024x512 lat-long map (tolerance 2e-4, pixel-centre rule with
   * a kink). */
  const double ax[3] = {0.36, 0.48, 0.8};
  const int w = 1024, h = 512;
  cv_image *img = NULL;
  assert_int_equal(cv_image_create(w, h, 1, &img), CV_OK);
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      double d[3];
      cv_latlong_pixel_dir(x, y, w, h, d);
      const double t = d[0] * ax[0] + d[1] * ax[1] + d[2] * ax[2];
      *cv_image_at(img, x, y) = (float)(t > 0 ? t : 0);
    }
  double cl[3 * 64], ya[64];
  assert_int_equal(cv_sh_project_latlong(img, 8, cl), CV_OK);
  cv_sh_eval_d(8, ax, ya);
  worst = 0.0;
  for (int l = 0; l < 8; l++)
    for (int m = -l; m <= l; m++) {
      const int i = cv_sh_index(l, m);
      worst = fmax(worst, fabs(cl[3 * i] - cv_sh_cosine_lobe_factor(l) * ya[i]));
    }
  printf("  lobe about tilted axis, 1024x512 lat-long: max |diff| %.2e (tol 2e-4)\n", worst);
  assert_true(worst < 2e-4);
  cv_image_destroy(img);
}

/* ---- rotation ----------------------------------------------------------- */

static double rot_R[9];
static void rotated_smooth_fn(const double d[3], void *user, double rgb[3]) {
  (void)user;
  double q[3];
  mat_t_vec(rot_R, d, q); /* f'(d) = f(R^T d) */
  smooth_fn(q, NULL, rgb);
}

static void test_rotation_vs_projection(void **state) {
  (void)state;
  /* f is smooth but not band-limited; rotation preserves bands, so the n=8
   * coefficients of f(R^T d) must equal the rotated coefficients of f.
   * 48-node Gauss-Legendre makes the projections exact to ~1e-15. */
  double c[3 * 64];
  assert_int_equal(cv_sh_project_fn(8, 48, smooth_fn, NULL, c), CV_OK);
  double worst = 0.0;
  for (int t = 0; t < 6; t++) {
    rnd_rotation(rot_R);
    cv_sh_rotation *rot = NULL;
    assert_int_equal(cv_sh_rotation_create(8, rot_R, &rot), CV_OK);
    double cr[3 * 64], cp[3 * 64];
    cv_sh_rotate(rot, c, cr, 3);
    assert_int_equal(cv_sh_project_fn(8, 48, rotated_smooth_fn, NULL, cp), CV_OK);
    for (int i = 0; i < 3 * 64; i++) worst = fmax(worst, fabs(cr[i] - cp[i]));
    /* in-place gives the same */
    double ci[3 * 64];
    memcpy(ci, c, sizeof ci);
    cv_sh_rotate(rot, ci, ci, 3);
    assert_memory_equal(ci, cr, sizeof ci);
    cv_sh_rotation_destroy(rot);
  }
  printf("  rotate(coeffs) vs projection of rotated f, n=8, 6 random R: max |diff| %.2e (tol 1e-9)\n",
         worst);
  assert_true(worst < 1e-9);
}

static void test_rotation_algebra(void **state) {
  (void)state;
  double worst_comp = 0.0, worst_orth = 0.0, worst_z = 0.0;
  for (int t = 0; t < 10; t++) {
    double A[9], B[9], AB[9];
    rnd_rotation(A);
    rnd_rotation(B);
    matmul3(A, B, AB);
    cv_sh_rotation *ra = NULL, *rb = NULL, *rab = NULL;
    assert_int_equal(cv_sh_rotation_create(8, A, &ra), CV_OK);
    assert_int_equal(cv_sh_rotation_create(8, B, &rb), CV_OK);
    assert_int_equal(cv_sh_rotation_create(8, AB, &rab), CV_OK);
    assert_int_equal(cv_sh_rotation_bands(ra), 8);
    for (int l = 0; l < 8; l++) {
      const int s = 2 * l + 1;
      const double *Ma = cv_sh_rotation_band(ra, l), *Mb = cv_sh_rotation_band(rb, l),
                   *Mab = cv_sh_rotation_band(rab, l);
      for (int i = 0; i < s; i++)
        for (int j = 0; j < s; j++) {
          double p = 0.0, o = 0.0;
          for (int k = 0; k < s; k++) {
            p += Ma[i * s + k] * Mb[k * s + j];
            o += Ma[i * s + k] * Ma[j * s + k];
          }
          worst_comp = fmax(worst_comp, fabs(p - Mab[i * s + j]));
          worst_orth = fmax(worst_orth, fabs(o - (i == j ? 1.0 : 0.0)));
        }
    }
    cv_sh_rotation_destroy(ra);
    cv_sh_rotation_destroy(rb);
    cv_sh_rotation_destroy(rab);
  }
  /* rotation about +Z by alpha mixes (m, -m) by cos/sin(m alpha) */
  const double al = 0.7;
  const double Rz[9] = {cos(al), -sin(al), 0, sin(al), cos(al), 0, 0, 0, 1};
  cv_sh_rotation *rz = NULL;
  assert_int_equal(cv_sh_rotation_create(8, Rz, &rz), CV_OK);
  for (int l = 0; l < 8; l++) {
    const int s = 2 * l + 1;
    const double *M = cv_sh_rotation_band(rz, l);
    for (int m = -l; m <= l; m++)
      for (int k = -l; k <= l; k++) {
        double e = 0.0;
        const int am = abs(m);
        if (m == 0 && k == 0) e = 1.0;
        else if (m != 0 && k == m) e = cos(am * al);
        else if (m > 0 && k == -m) e = -sin(am * al); /* c'_{+m} = a cos - b sin */
        else if (m < 0 && k == -m) e = sin(am * al);  /* c'_{-m} = a sin + b cos */
        worst_z = fmax(worst_z, fabs(M[(m + l) * s + (k + l)] - e));
      }
  }
  cv_sh_rotation_destroy(rz);
  printf("  rotation(AB) vs rotation(A)rotation(B): %.2e; M M^T - I: %.2e; about Z: %.2e (tol 1e-12)\n",
         worst_comp, worst_orth, worst_z);
  assert_true(worst_comp < 1e-12);
  assert_true(worst_orth < 1e-12);
  assert_true(worst_z < 1e-12);

  /* identity */
  const double I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  cv_sh_rotation *ri = NULL;
  assert_int_equal(cv_sh_rotation_create(8, I, &ri), CV_OK);
  double c[64], o[64];
  for (int i = 0; i < 64; i++) c[i] = rnd() - 0.5;
  cv_sh_rotate(ri, c, o, 1);
  for (int i = 0; i < 64; i++) assert_near(o[i], c[i], 1e-15);
  cv_sh_rotation_destroy(ri);

  /* errors: reflection, non-orthonormal, NaN, bad n */
  cv_sh_rotation *bad = (cv_sh_rotation *)&bad;
  const double refl[9] = {-1, 0, 0, 0, 1, 0, 0, 0, 1};
  assert_int_equal(cv_sh_rotation_create(4, refl, &bad), CV_ERR_INVALID);
  assert_null(bad);
  const double skew[9] = {1, 0.01, 0, 0, 1, 0, 0, 0, 1};
  assert_int_equal(cv_sh_rotation_create(4, skew, &bad), CV_ERR_INVALID);
  const double nan9[9] = {NAN, 0, 0, 0, 1, 0, 0, 0, 1};
  assert_int_equal(cv_sh_rotation_create(4, nan9, &bad), CV_ERR_INVALID);
  assert_int_equal(cv_sh_rotation_create(9, I, &bad), CV_ERR_INVALID);
  cv_sh_rotation_destroy(NULL);
}

/* ---- windowing ---------------------------------------------------------- */

static void cap_fn(const double d[3], void *user, double rgb[3]) {
  (void)user;
  rgb[0] = rgb[1] = rgb[2] = d[2] > cos(30.0 * M_PI / 180.0) ? 1.0 : 0.0;
}

/* Most negative value of a 1-channel expansion over a dense set of
 * directions (the functions are zonal about +Z, so a meridian suffices). */
static double expansion_min(int n, const double *c3) {
  double mn = 1e300;
  for (int k = 0; k <= 2000; k++) {
    const double th = M_PI * k / 2000.0;
    const double d[3] = {sin(th), 0.0, cos(th)};
    double v[3];
    cv_sh_eval_sum(n, c3, 3, d, v);
    mn = fmin(mn, v[0]);
  }
  return mn;
}

static void test_window(void **state) {
  (void)state;
  double c[3 * 64];
  assert_int_equal(cv_sh_project_fn(8, 200, cap_fn, NULL, c), CV_OK);
  const double c0 = c[0];
  const double mn_none = expansion_min(8, c);
  double ch[3 * 64], cl[3 * 64];
  memcpy(ch, c, sizeof c);
  memcpy(cl, c, sizeof c);
  cv_sh_window(8, ch, 3, CV_SH_WINDOW_HANN);
  cv_sh_window(8, cl, 3, CV_SH_WINDOW_LANCZOS);
  const double mn_hann = expansion_min(8, ch), mn_lanc = expansion_min(8, cl);
  printf("  30-degree cap, n=8: most negative value none %.4f, Hann %.4f, Lanczos %.4f\n", mn_none,
         mn_hann, mn_lanc);
  assert_true(mn_none < -0.02);                 /* truncation rings */
  assert_near(mn_hann, 0, 0.25 * fabs(mn_none));
  assert_near(mn_lanc, 0, 0.5 * fabs(mn_none));
  assert_true(ch[0] == c0 && cl[0] == c0);      /* mean kept */

  /* clamped cosine at n=3 and n=8 */
  lobe_axis[0] = 0; lobe_axis[1] = 0; lobe_axis[2] = 1;
  double cc[3 * 64];
  assert_int_equal(cv_sh_project_fn(8, 200, lobe_fn, NULL, cc), CV_OK);
  const double lob_none = expansion_min(8, cc);
  cv_sh_window(8, cc, 3, CV_SH_WINDOW_HANN);
  const double lob_hann = expansion_min(8, cc);
  printf("  clamped cosine, n=8: most negative value none %.5f, Hann %.5f\n", lob_none, lob_hann);
  assert_true(lob_none < 0.0);
  assert_near(lob_hann, 0, fabs(lob_none));

  /* weights */
  assert_true(cv_sh_window_weight(8, 0, CV_SH_WINDOW_HANN) == 1.0);
  assert_near(cv_sh_window_weight(4, 2, CV_SH_WINDOW_HANN), 0.5, 1e-15);
  assert_near(cv_sh_window_weight(4, 2, CV_SH_WINDOW_LANCZOS), 2.0 / M_PI, 1e-15);
  assert_true(cv_sh_window_weight(4, 3, CV_SH_WINDOW_NONE) == 1.0);
}

static void test_latlong_mapping(void **state) {
  (void)state;
  /* front, right, zenith per the conventions */
  double u, v;
  const double front[3] = {0, 0, -1}, right[3] = {1, 0, 0}, up[3] = {0, 1, 0}, back[3] = {0, 0, 1};
  cv_latlong_uv(front, &u, &v);
  assert_near(u, 0.5, 1e-15);
  assert_near(v, 0.5, 1e-15);
  cv_latlong_uv(right, &u, &v);
  assert_near(u, 0.75, 1e-15);
  cv_latlong_uv(up, &u, &v);
  assert_near(v, 0, 1e-15);
  cv_latlong_uv(back, &u, &v);
  assert_true(u >= 0.0 && u < 1.0);
  /* round trip */
  for (int t = 0; t < 1000; t++) {
    double d[3], e[3];
    rnd_dir(d);
    cv_latlong_uv(d, &u, &v);
    cv_latlong_dir(u, v, e);
    for (int k = 0; k < 3; k++) assert_near(d[k], e[k], 1e-12);
  }
  /* row weights sum to 4 pi */
  double s = 0.0;
  for (int y = 0; y < 37; y++) s += 53 * cv_latlong_pixel_solid_angle(y, 53, 37);
  assert_near(s, 4 * M_PI, 1e-12);
}


/* cv_latlong_trig + cv_latlong_trig_dir give cv_latlong_pixel_dir's
 * directions bit for bit (the projections use them to skip two sincos a
 * pixel). */
static void test_latlong_trig_exact(void **state) {
  (void)state;
  const int sizes[][2] = {{512, 256}, {64, 32}, {7, 3}, {1, 2}};
  for (int k = 0; k < 4; k++) {
    const int w = sizes[k][0], h = sizes[k][1];
    double *t = malloc(2 * (size_t)(w + h) * sizeof *t);
    cv_latlong_trig(w, h, t, t + w, t + 2 * w, t + 2 * w + h);
    long differ = 0;
    for (int y = 0; y < h; y++)
      for (int x = 0; x < w; x++) {
        double a[3], b[3];
        cv_latlong_pixel_dir(x, y, w, h, a);
        cv_latlong_trig_dir(t[x], t[w + x], t[2 * w + y], t[2 * w + h + y], b);
        differ += memcmp(a, b, sizeof a) != 0;
      }
    assert_int_equal(differ, 0);
    free(t);
  }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_latlong_mapping),
      cmocka_unit_test(test_basis_reference),
      cmocka_unit_test(test_orthonormality),
      cmocka_unit_test(test_project_constant),
      cmocka_unit_test(test_project_latlong_vs_fn),
      cmocka_unit_test(test_cosine_lobe),
      cmocka_unit_test(test_rotation_vs_projection),
      cmocka_unit_test(test_rotation_algebra),
      cmocka_unit_test(test_window),
      cmocka_unit_test(test_latlong_trig_exact),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
