/* assert_near(a, b, tol): the numeric tests' closeness check.  Passes when
 * |a - b| <= tol (in double); fails on a larger difference or on a NaN in
 * either value, and then prints both expressions with their values, the
 * difference and the tolerance, so a failure says by how much it missed:
 *
 *   test_foo.c:42: assert_near failed: |a - b| = 3.1e-05 > tol 1e-06
 *     a: h.pos[0] = 0.10003100000000001
 *     b: 0.1 = 0.10000000000000001
 *
 * Include after <cmocka.h>.  Header only: each test is one executable. */
#ifndef CV_TEST_NEAR_H
#define CV_TEST_NEAR_H

#include <math.h>

static inline void cv_test_near(double a, double b, double tol, const char *ea, const char *eb,
                                const char *file, int line) {
  double d = fabs(a - b);
  if (d <= tol) return; /* false for a NaN: a NaN always fails */
  print_error("%s:%d: assert_near failed: |a - b| = %.6g > tol %g\n  a: %s = %.17g\n  b: %s = %.17g\n",
              file, line, d, tol, ea, a, eb, b);
  _fail(file, line);
}

#define assert_near(a, b, tol)                                                                     \
  cv_test_near((double)(a), (double)(b), (double)(tol), #a, #b, __FILE__, __LINE__)

#endif
