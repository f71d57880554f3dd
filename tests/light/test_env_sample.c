/* Unit tests of light/env_sample.h: the cell probabilities reproduce the
 * map's luminance x solid-angle distribution, directions drawn by the
 * sampler fall in the cells with those frequencies (chi-square), the density
 * it returns equals cv_env_sampler_pdf and integrates to 1 over the sphere,
 * and a black map draws nothing.  Tolerances are stated at each check. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include <cmocka.h>
#include "cv_test_near.h"

#include "core/status.h"
#include "light/env_sample.h"
#include "light/envmap.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* A w x h map: a smooth sky brighter towards the zenith, a bright disc
 * (sun-like, 2000x) near (x, y) = (w/3, h/4), a black lower half but for one
 * dim row (so that zero cells occur). */
static cv_envmap *test_map(int w, int h) {
  cv_envmap *e;
  assert_int_equal(cv_envmap_create(w, h, &e), CV_OK);
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      float *p = e->img->px + 3 * ((size_t)y * w + x);
      double v = (y + 0.5) / h, L = v < 0.5 ? 1.0 + 2.0 * (0.5 - v) : (y == h - 2 ? 0.05 : 0.0);
      double dx = x - w / 3.0, dy = y - h / 4.0;
      if (dx * dx + dy * dy < 4) L *= 2000;
      p[0] = (float)(L * (1 + 0.3 * sin(x))), p[1] = (float)L, p[2] = (float)(L * 0.7);
    }
  return e;
}

static double cell_sa(int y, int w, int h) {
  return 2 * M_PI / w * (cos(M_PI * y / h) - cos(M_PI * (y + 1) / h));
}

/* The table's cell probabilities equal Y * Omega / sum(Y * Omega). */
static void test_cell_probabilities(void **state) {
  (void)state;
  const int w = 64, h = 32;
  cv_envmap *e = test_map(w, h);
  cv_env_sampler *s;
  assert_int_equal(cv_env_sampler_create(e, &s), CV_OK);
  double tot = 0, worst = 0, sum = 0;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      const float *p = e->img->px + 3 * ((size_t)y * w + x);
      tot += cv_luminance(p[0], p[1], p[2]) * cell_sa(y, w, h);
    }
  assert_near(s->total, tot, 1e-5 * tot);
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      const float *p = e->img->px + 3 * ((size_t)y * w + x);
      const double want = cv_luminance(p[0], p[1], p[2]) * cell_sa(y, w, h) / tot;
      const double got = cv_env_sampler_cell_prob(s, x, y);
      sum += got;
      if (want == 0) assert_true(got == 0);
      /* float CDFs: absolute error a few float ulps of 1 */
      worst = fmax(worst, fabs(got - want));
    }
  print_message("cell probabilities: worst absolute error %.3g, sum %.9f\n", worst, sum);
  assert_true(worst < 1e-6);
  assert_near(sum, 1, 1e-6);
  cv_env_sampler_destroy(s);
  cv_envmap_destroy(e);
}

/* A map wider than CV_ENV_SAMPLE_MAX_W: cells of f x f pixels whose
 * probabilities are the sums of their pixels' Y * Omega over the total. */
static void test_block_cells(void **state) {
  (void)state;
  const int w = 1024, h = 512;
  cv_envmap *e = test_map(w, h);
  cv_env_sampler *s;
  assert_int_equal(cv_env_sampler_create(e, &s), CV_OK);
  assert_int_equal(s->f, 4);
  assert_int_equal(s->w, 256);
  assert_int_equal(s->h, 128);
  double *cell = calloc((size_t)s->w * s->h, sizeof(double)), tot = 0, worst = 0;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      const float *p = e->img->px + 3 * ((size_t)y * w + x);
      const double v = cv_luminance(p[0], p[1], p[2]) * cell_sa(y, w, h);
      cell[(size_t)(y / 4) * s->w + x / 4] += v;
      tot += v;
    }
  for (int y = 0; y < s->h; y++)
    for (int x = 0; x < s->w; x++)
      worst = fmax(worst, fabs(cv_env_sampler_cell_prob(s, x, y) - cell[(size_t)y * s->w + x] / tot));
  print_message("4x4-pixel cells: worst absolute error %.3g\n", worst);
  assert_true(worst < 1e-6);
  free(cell);
  cv_env_sampler_destroy(s);
  cv_envmap_destroy(e);
}

static uint64_t rng_next(uint64_t *st) { /* splitmix64 */
  uint64_t z = (*st += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
static float rng_float(uint64_t *st) { return (float)(rng_next(st) >> 40) * 0x1p-24f; }

/* Restricted to a hemisphere: kept cells keep their relative probabilities,
 * cells wholly behind get 0, the density still integrates to 1, and drawn
 * directions lie in front but for the cells the plane cuts. */
static void test_restrict(void **state) {
  (void)state;
  const int w = 64, h = 32;
  cv_envmap *e = test_map(w, h);
  cv_env_sampler *s, *r;
  assert_int_equal(cv_env_sampler_create(e, &s), CV_OK);
  const float n[3] = {0.6f, 0.0f, 0.8f};
  assert_int_equal(cv_env_sampler_restrict(s, n, &r), CV_OK);
  assert_true(r->total > 0 && r->total < s->total);
  const double keep = r->total / s->total;
  double worst = 0;
  int zeroed = 0;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      const double p = cv_env_sampler_cell_prob(s, x, y), q = cv_env_sampler_cell_prob(r, x, y);
      if (q == 0 && p > 0) {
        zeroed++;
        /* the cell's centre must then be behind the plane */
        const double ct = cos(M_PI * (y + 0.5) / h), st = sqrt(1 - ct * ct);
        const double ph = 2 * M_PI * ((x + 0.5) / w - 0.5);
        assert_true(st * sin(ph) * n[0] + ct * n[1] - st * cos(ph) * n[2] <= 0);
      } else if (q > 0) {
        worst = fmax(worst, fabs(q - p / keep));
      }
    }
  uint64_t rs = 7;
  int behind = 0;
  const int N = 200000;
  for (int i = 0; i < N; i++) {
    float u[2] = {rng_float(&rs), rng_float(&rs)}, d[3], pdf;
    assert_int_equal(cv_env_sampler_sample(r, u, d, &pdf), 1);
    behind += d[0] * n[0] + d[1] * n[1] + d[2] * n[2] <= 0;
  }
  print_message("restricted: kept %.1f%% of the luminance, %d cells cut, worst kept-cell error "
                "%.3g, %.2f%% of the draws behind the plane (cut cells)\n",
                100 * keep, zeroed, worst, 100.0 * behind / N);
  assert_true(zeroed > 0);
  assert_true(worst < 2e-6);
  assert_true(behind < N / 20);
  cv_env_sampler_destroy(r);
  cv_env_sampler_destroy(s);
  cv_envmap_destroy(e);
}

/* Drawn directions land in the cells with the table's frequencies, and the
 * density returned with each sample is cv_env_sampler_pdf of it. */
static void test_sampling_histogram(void **state) {
  (void)state;
  const int w = 32, h = 16;
  cv_envmap *e = test_map(w, h);
  cv_env_sampler *s;
  assert_int_equal(cv_env_sampler_create(e, &s), CV_OK);
  const int N = 1 << 21;
  double *count = calloc((size_t)w * h, sizeof(double));
  uint64_t rs = 12345;
  double worst_pdf = 0;
  int zero_hits = 0;
  for (int i = 0; i < N; i++) {
    float u[2] = {rng_float(&rs), rng_float(&rs)}, d[3], pdf;
    assert_int_equal(cv_env_sampler_sample(s, u, d, &pdf), 1);
    assert_near(d[0] * d[0] + d[1] * d[1] + d[2] * d[2], 1, 1e-5f);
    const float q = cv_env_sampler_pdf(s, d);
    worst_pdf = fmax(worst_pdf, fabs(q - pdf) / pdf);
    /* the cell the direction lies in, in double */
    int y = (int)(acos(fmax(-1, fmin(1, d[1]))) / M_PI * h);
    double uu = 0.5 + atan2(d[0], -d[2]) / (2 * M_PI);
    int x = (int)(uu * w);
    y = y < 0 ? 0 : (y >= h ? h - 1 : y);
    x = ((x % w) + w) % w;
    count[(size_t)y * w + x] += 1;
    if (cv_env_sampler_cell_prob(s, x, y) == 0) zero_hits++;
  }
  /* chi-square over cells with an expected count >= 5, the rest pooled */
  double chi2 = 0, pool_e = 0, pool_o = 0;
  int dof = 0;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      const double ex = N * cv_env_sampler_cell_prob(s, x, y), ob = count[(size_t)y * w + x];
      if (ex >= 5) {
        chi2 += (ob - ex) * (ob - ex) / ex;
        dof++;
      } else {
        pool_e += ex;
        pool_o += ob;
      }
    }
  if (pool_e >= 5) {
    chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
    dof++;
  }
  dof -= 1;
  /* mean dof, sd sqrt(2 dof): 6 sd is a p-value far below 1e-6 */
  const double lim = dof + 6 * sqrt(2.0 * dof);
  print_message("histogram: chi2 %.1f on %d dof (limit %.1f); samples in zero cells %d "
                "(boundary rounding); pdf mismatch worst %.3g\n",
                chi2, dof, lim, zero_hits, worst_pdf);
  assert_true(chi2 < lim);
  assert_true(zero_hits <= N / 100000);
  /* rounding at cell edges may move a direction to the neighbour cell */
  double bad = 0;
  rs = 999;
  for (int i = 0; i < 100000; i++) {
    float u[2] = {rng_float(&rs), rng_float(&rs)}, d[3], pdf;
    cv_env_sampler_sample(s, u, d, &pdf);
    bad += fabs(cv_env_sampler_pdf(s, d) - pdf) > 1e-4 * pdf;
  }
  assert_true(bad <= 10);
  free(count);
  cv_env_sampler_destroy(s);
  cv_envmap_destroy(e);
}

/* int pdf dw = 1: uniform directions over the sphere, E[4 pi pdf] = 1. */
static void test_pdf_normalised(void **state) {
  (void)state;
  cv_envmap *e = test_map(48, 24);
  cv_env_sampler *s;
  assert_int_equal(cv_env_sampler_create(e, &s), CV_OK);
  /* stratified in (cos theta, phi): a 1024 x 2048 grid of cell centres */
  const int nt = 1024, np = 2048;
  double acc = 0;
  for (int i = 0; i < nt; i++) {
    const double ct = 1 - 2 * (i + 0.5) / nt, st = sqrt(1 - ct * ct);
    for (int j = 0; j < np; j++) {
      const double ph = 2 * M_PI * ((j + 0.5) / np - 0.5);
      const float d[3] = {(float)(st * sin(ph)), (float)ct, (float)(-st * cos(ph))};
      acc += cv_env_sampler_pdf(s, d);
    }
  }
  const double integral = acc * 4 * M_PI / ((double)nt * np);
  print_message("integral of the density over the sphere: %.6f\n", integral);
  assert_near(integral, 1, 2e-3);
  cv_env_sampler_destroy(s);
  cv_envmap_destroy(e);
}

static void test_black_and_invalid(void **state) {
  (void)state;
  cv_envmap *e;
  assert_int_equal(cv_envmap_create(16, 8, &e), CV_OK);
  cv_env_sampler *s;
  assert_int_equal(cv_env_sampler_create(e, &s), CV_OK);
  float u[2] = {0.3f, 0.6f}, d[3], pdf = -1;
  assert_int_equal(cv_env_sampler_sample(s, u, d, &pdf), 0);
  const float up[3] = {0, 1, 0};
  assert_true(cv_env_sampler_pdf(s, up) == 0);
  assert_true(s->total == 0);
  cv_env_sampler_destroy(s);
  cv_envmap_destroy(e);
  assert_int_equal(cv_env_sampler_create(NULL, &s), CV_ERR_INVALID);
  assert_null(s);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_cell_probabilities), cmocka_unit_test(test_block_cells),
      cmocka_unit_test(test_sampling_histogram), cmocka_unit_test(test_restrict),
      cmocka_unit_test(test_pdf_normalised), cmocka_unit_test(test_black_and_invalid)};
  return cmocka_run_group_tests(tests, NULL, NULL);
}
