/* Small helpers shared by the benchmark programs. */
#ifndef CV_BENCH_UTIL_H
#define CV_BENCH_UTIL_H

/* Median of v[0..n) (sorts v in place); 0 for n = 0. */
static inline double bench_median(double *v, int n) {
  if (n <= 0) return 0;
  for (int i = 1; i < n; i++)
    for (int j = i; j > 0 && v[j] < v[j - 1]; j--) {
      double t = v[j];
      v[j] = v[j - 1];
      v[j - 1] = t;
    }
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* qsort comparator of doubles (ascending). */
static inline int bench_cmp_double(const void *a, const void *b) {
  const double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

#endif
