/* Sobol sampler: Joe-Kuo expansion, known unscrambled values, and the
 * (0,m,2)-net stratification that Owen scrambling must preserve. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "core/sobol.h"

/* Dimension 1 (Joe-Kuo d=2, m=1) in direct index order: 0, 1/2, 3/4, 1/4, 5/8, 1/8, 3/8, 7/8. */
static void test_known_points(void **state) {
  (void)state;
  const double dim0[8] = {0, .5, .25, .75, .125, .625, .375, .875};
  const double dim1[8] = {0, .5, .75, .25, .625, .125, .375, .875}; /* direct (non-Gray) order */
  for (uint32_t i = 0; i < 8; i++) {
    assert_true(cv_sobol_u32(i, 0) * 0x1p-32 == dim0[i]);
    assert_true(cv_sobol_u32(i, 1) * 0x1p-32 == dim1[i]);
  }
}

/* Every pair of dimensions (0,1) and (2,3) of the first 2^m points is a
 * (0,m,2)-net: each elementary interval of area 2^-m holds exactly one
 * point.  Owen scrambling preserves this; a wrong scramble breaks it. */
static int is_net(int m, int d0, int d1, uint32_t seed, int scrambled) {
  uint32_t n = 1u << m;
  for (int a = 0; a <= m; a++) { /* intervals 2^-a x 2^-(m-a) */
    int *cnt = calloc(n, sizeof(int));
    for (uint32_t i = 0; i < n; i++) {
      float u[8];
      double x, y;
      if (scrambled) {
        cv_sobol_owen_n(i, seed, 8, u);
        x = u[d0];
        y = u[d1];
      } else {
        x = cv_sobol_u32(i, d0) * 0x1p-32;
        y = cv_sobol_u32(i, d1) * 0x1p-32;
      }
      uint32_t cx = (uint32_t)(x * (1u << a)), cy = (uint32_t)(y * (1u << (m - a)));
      cnt[(cx << (m - a)) | cy]++;
    }
    for (uint32_t k = 0; k < n; k++)
      if (cnt[k] != 1) {
        free(cnt);
        return 0;
      }
    free(cnt);
  }
  return 1;
}

static void test_nets(void **state) {
  (void)state;
  for (int m = 1; m <= 10; m++) {
    assert_true(is_net(m, 0, 1, 0, 0));
    assert_true(is_net(m, 0, 1, 12345u, 1));
    assert_true(is_net(m, 0, 1, 777u, 1));
  }
}

/* Scrambled points: in [0,1), deterministic, different for different seeds,
 * and a 1D integral of x^2 converges far faster than 1/sqrt(N). */
static void test_scrambled(void **state) {
  (void)state;
  double sum = 0;
  const uint32_t n = 4096;
  for (uint32_t i = 0; i < n; i++) {
    float a = cv_sobol_owen(i, 2, 99u), b = cv_sobol_owen(i, 2, 99u), c = cv_sobol_owen(i, 2, 98u);
    assert_true(a >= 0.0f && a < 1.0f);
    assert_true(a == b);
    (void)c;
    sum += (double)a * a;
  }
  double err = sum / n - 1.0 / 3.0;
  assert_true(err < 1e-4 && err > -1e-4); /* random sampling: ~4.7e-3 */
  int differ = 0;
  for (uint32_t i = 0; i < 16; i++) differ += cv_sobol_owen(i, 0, 1u) != cv_sobol_owen(i, 0, 2u);
  assert_true(differ >= 14);
}

/* The table path gives bit-identical values to the reference loop. */
static void test_table_matches(void **state) {
  (void)state;
  cv_sobol_tab *tab = malloc(sizeof *tab);
  cv_sobol_tab_init(tab);
  for (uint32_t seed = 0; seed < 50; seed += 7) {
    uint32_t ds[8];
    cv_sobol_dim_seeds(seed, 8, ds);
    for (uint32_t i = 0; i < 5000; i += 3) {
      float a[8], b[8];
      cv_sobol_owen_n(i, seed, 8, a);
      cv_sobol_owen_tab(tab, i, seed, ds, 8, b);
      assert_memory_equal(a, b, sizeof a);
    }
  }
  free(tab);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_known_points),
      cmocka_unit_test(test_nets),
      cmocka_unit_test(test_scrambled),
      cmocka_unit_test(test_table_matches),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
