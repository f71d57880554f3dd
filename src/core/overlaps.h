/* Overlaps of equal intervals with the cells of a partition: the area
 * weights of resampling an image onto cells (compensate/resample.c: pixels
 * onto the screen's patches; tonemap/foveal.c: a frame's pixels under the
 * pixels of its luminance image). */
#ifndef CV_CORE_OVERLAPS_H
#define CV_CORE_OVERLAPS_H

/* Index of the cell of edges e[0..n] (ascending) that contains t: the last
 * c with e[c] <= t, 0 below e[0]. */
int cv_cell_of(const double *e, int n, double t);

/* For each of n intervals [t0(i), t0(i) + span / n), t0(i) = (flip ? n - 1 -
 * i : i) span / n, the cells of edges E[0..ne] it overlaps and the lengths
 * of those overlaps: entries first[i] .. first[i + 1] - 1 of cell[] and
 * len[] (cells with no overlap left out). */
typedef struct cv_overlaps {
  int *first, *cell;
  double *len;
} cv_overlaps;

/* Fills *o (zero it first); 0, or -1 when out of memory (*o then holds what
 * was allocated: cv_overlaps_free it). */
int cv_overlaps_make(const double *E, int ne, int n, double span, int flip, cv_overlaps *o);
void cv_overlaps_free(cv_overlaps *o);

#endif
