/* Overlaps of equal intervals with a partition's cells (see overlaps.h). */
#include "core/overlaps.h"

#include <math.h>
#include <stdlib.h>

int cv_cell_of(const double *e, int n, double t) {
  int lo = 0, hi = n - 1;
  while (lo < hi) {
    int mid = (lo + hi + 1) / 2;
    if (e[mid] <= t) lo = mid;
    else hi = mid - 1;
  }
  return lo;
}

int cv_overlaps_make(const double *E, int ne, int n, double span, int flip, cv_overlaps *o) {
  size_t cap = (size_t)n + (size_t)ne + 1, k = 0;
  o->first = malloc(((size_t)n + 1) * sizeof *o->first);
  o->cell = malloc(cap * sizeof *o->cell);
  o->len = malloc(cap * sizeof *o->len);
  if (!o->first || !o->cell || !o->len) return -1;
  for (int i = 0; i < n; i++) {
    const double t0 = (double)(flip ? n - 1 - i : i) * span / n, t1 = t0 + span / n;
    o->first[i] = (int)k;
    for (int c = cv_cell_of(E, ne, t0); c < ne && E[c] < t1; c++) {
      const double ov = fmin(t1, E[c + 1]) - fmax(t0, E[c]);
      if (ov <= 0) continue;
      if (k == cap) {
        cap *= 2;
        int *nc = realloc(o->cell, cap * sizeof *nc);
        if (nc) o->cell = nc;
        double *nl = realloc(o->len, cap * sizeof *nl);
        if (nl) o->len = nl;
        if (!nc || !nl) return -1;
      }
      o->cell[k] = c, o->len[k] = ov, k++;
    }
  }
  o->first[n] = (int)k;
  return 0;
}

void cv_overlaps_free(cv_overlaps *o) {
  free(o->first), free(o->cell), free(o->len);
  o->first = o->cell = NULL, o->len = NULL;
}
