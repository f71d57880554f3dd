/* Unit tests of the form factors (src/compensate/formfactor.h): the
 * point-to-polygon contour integral against closed forms and a brute-force
 * integral, patch pairs against the tabulated values for unit squares, the
 * point-to-point formula's error next to a corner, reciprocity, closed-cube
 * row and column sums (Lambertian and light-directing), sparsification and
 * its reported energy, visibility with an occluder, projector factors. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include "cv_test_near.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "compensate/display.h"
#include "compensate/formfactor.h"
#include "compensate/system.h"
#include "core/status.h"

#define PI 3.14159265358979323846

static cv_display *parse(const char *json) {
  cv_display *d = NULL;
  cv_err err = {0};
  int st = cv_display_parse(json, "test.json", &d, &err);
  if (st) fprintf(stderr, "parse failed: %s\n", err.msg);
  assert_int_equal(st, CV_OK);
  return d;
}

static cv_ffmatrix *build(const cv_display *d, double budget, double rel, cv_ff_visibility vis,
                          cv_ff_report *rep) {
  cv_ff_params p;
  cv_ff_params_default(&p);
  p.drop_budget = budget;
  p.rel_threshold = rel;
  p.visibility = vis;
  p.quiet = 1;
  cv_ffmatrix *F = NULL;
  cv_err err = {0};
  int st = cv_formfactors_build(d, &p, &F, rep, &err);
  if (st) fprintf(stderr, "build failed: %s\n", err.msg);
  assert_int_equal(st, CV_OK);
  return F;
}

static double entry(const cv_ffmatrix *F, size_t i, size_t j) {
  for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++)
    if (F->col[k] == j) return F->val[k];
  return 0;
}

/* --- point to polygon ------------------------------------------------------ */

/* Differential area on the axis of a centred 2a x 2a square at distance h,
 * facing it: F = (4/pi) X/sqrt(1+X^2) atan(X/sqrt(1+X^2)), X = a/h (four
 * corner rectangles of the standard dA-to-parallel-rectangle form). */
static double square_on_axis(double a, double h) {
  double X = a / h, s = sqrt(1 + X * X);
  return 4.0 / PI * X / s * atan(X / s);
}

/* Differential area to a parallel a x b rectangle at distance c, the
 * normal through a corner (Howell's catalogue, B-3). */
static double corner_rect(double a, double b, double c) {
  double X = a / c, Y = b / c;
  return 1.0 / (2 * PI) *
         (X / sqrt(1 + X * X) * atan(Y / sqrt(1 + X * X)) +
          Y / sqrt(1 + Y * Y) * atan(X / sqrt(1 + Y * Y)));
}

static void test_point_polygon_closed_form(void **state) {
  (void)state;
  const double x[3] = {0, 0, 0}, n[3] = {0, 0, 1};
  const double cases[][2] = {{0.5, 1}, {1, 1}, {3, 0.5}, {0.01, 2}, {10, 0.1}};
  for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
    double a = cases[c][0], h = cases[c][1];
    /* front faces -z (towards x): counter-clockwise seen from below */
    const double q[4][3] = {{-a, -a, h}, {-a, a, h}, {a, a, h}, {a, -a, h}};
    double f = cv_ff_point_polygon(x, n, q, 4), ref = square_on_axis(a, h);
    printf("  square 2a=%g at h=%g: contour %.12f closed form %.12f\n", 2 * a, h, f, ref);
    assert_near(f, ref, 1e-9);
    /* reversed winding = seen from behind: negative */
    const double r[4][3] = {{-a, -a, h}, {a, -a, h}, {a, a, h}, {-a, a, h}};
    assert_true(cv_ff_point_polygon(x, n, r, 4) < 0);
  }
  /* off-axis rectangle with the normal through its corner */
  const double a = 0.7, b = 1.9, h = 0.8;
  const double q[4][3] = {{0, 0, h}, {0, b, h}, {a, b, h}, {a, 0, h}};
  double f = cv_ff_point_polygon(x, n, q, 4), ref = corner_rect(a, b, h);
  printf("  corner rectangle %gx%g at %g: %.12f vs %.12f\n", a, b, h, f, ref);
  assert_near(f, ref, 1e-9);
}

/* A rectangle straddling the receiver's plane: only the part in front
 * counts.  Reference: brute-force midpoint integral of cos cos / (pi r^2)
 * over the front part. */
static void test_point_polygon_clipping(void **state) {
  (void)state;
  const double x[3] = {0, 0, 0}, n[3] = {0, 0, 1};
  /* plane y = 1, front facing -y (towards x); x in [-1, 1], z in [-1, 1] */
  const double full[4][3] = {{-1, 1, -1}, {1, 1, -1}, {1, 1, 1}, {-1, 1, 1}};
  const double half[4][3] = {{-1, 1, 0}, {1, 1, 0}, {1, 1, 1}, {-1, 1, 1}};
  double ff = cv_ff_point_polygon(x, n, full, 4), fh = cv_ff_point_polygon(x, n, half, 4);
  const int N = 2000;
  double brute = 0;
  for (int i = 0; i < N; i++)
    for (int k = 0; k < N; k++) {
      double px = -1 + 2.0 * (i + 0.5) / N, pz = (k + 0.5) / N, r2 = px * px + 1 + pz * pz;
      brute += (pz / sqrt(r2)) * (1 / sqrt(r2)) / (PI * r2) * (2.0 / N) * (1.0 / N);
    }
  printf("  straddling rectangle: clipped %.10f, upper half %.10f, brute force %.10f\n", ff, fh,
         brute);
  assert_near(ff, fh, 1e-12);
  assert_near(ff, brute, 1e-6);
  /* unclipped, the contour integral would give a different (wrong) value */
  assert_true(ff > 0);
}

/* --- patch pairs ----------------------------------------------------------- */

static const char *PERP =
    "{\"surfaces\": ["
    " {\"name\": \"floor\", \"corners\": [[0,0,1],[1,0,1],[0,0,0]], \"patches\": [1,1], "
    "\"reflectance\": [1,1,1]},"
    " {\"name\": \"wall\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": [1,1], "
    "\"reflectance\": [1,1,1]}]}";

static void test_perpendicular_squares(void **state) {
  (void)state;
  cv_display *d = parse(PERP);
  const double exact = 0.2000437761; /* Howell C-14, W = H = 1 */
  double f01 = cv_ff_patch_pair(d, 0, 1), f10 = cv_ff_patch_pair(d, 1, 0);
  double pp = cv_ff_point_to_point(&d->patches[0], &d->patches[1]);
  printf("  perpendicular unit squares sharing an edge: F = %.7f (exact %.7f, rel. err %.2e); "
         "point-to-point %.5f (%+.0f%%)\n",
         f01, exact, f01 / exact - 1, pp, 100 * (pp / exact - 1));
  assert_near(f01 / exact, 1, 1e-3);
  assert_near(f10 / exact, 1, 1e-3);
  /* the paper's point-to-point formula is ~60% off next to the corner */
  assert_true(pp / exact > 1.5);
  cv_ff_report rep;
  cv_ffmatrix *F = build(d, 0, 0, CV_FF_VIS_AUTO, &rep);
  assert_int_equal(rep.visibility_traced, 0);
  assert_near(entry(F, 1, 0), f01, 1e-7);
  cv_ffmatrix_destroy(F);
  cv_display_destroy(d);
}

/* The same corner split into 8 x 8 patches per square: the point-to-point
 * formula overestimates the patches next to the shared edge, ours sums to
 * the exact square-to-square value. */
static void test_corner_point_to_point(void **state) {
  (void)state;
  const char *js =
      "{\"surfaces\": ["
      " {\"name\": \"floor\", \"corners\": [[0,0,1],[1,0,1],[0,0,0]], \"patches\": [8,8], "
      "\"reflectance\": [1,1,1]},"
      " {\"name\": \"wall\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": [8,8], "
      "\"reflectance\": [1,1,1]}]}";
  cv_display *d = parse(js);
  /* floor patch (u=3, v=7) touches the wall along the edge; wall patch (3, 0) */
  size_t j = cv_display_patch_index(d, 0, 3, 7), i = cv_display_patch_index(d, 1, 3, 0);
  double ours = cv_ff_patch_pair(d, j, i), pp = cv_ff_point_to_point(&d->patches[j], &d->patches[i]);
  printf("  edge-adjacent patches: ours %.5f, point-to-point %.5f (%+.0f%%)\n", ours, pp,
         100 * (pp / ours - 1));
  assert_near(ours / 0.2000437761, 1, 1e-3); /* same shape as the unit squares */
  assert_true(pp / ours > 1.5);
  /* total floor -> wall, area weighted: equals the unit-square value */
  double tot = 0, tot_pp = 0;
  for (size_t a = 0; a < 64; a++)
    for (size_t b = 64; b < 128; b++) {
      tot += cv_ff_patch_pair(d, a, b) / 64;
      tot_pp += cv_ff_point_to_point(&d->patches[a], &d->patches[b]) / 64;
    }
  printf("  floor -> wall from 8x8 patches: ours %.6f, point-to-point %.6f (exact 0.200044)\n",
         tot, tot_pp);
  assert_near(tot / 0.2000437761, 1, 1e-3);
  cv_display_destroy(d);
}

static void test_parallel_squares(void **state) {
  (void)state;
  const char *js =
      "{\"surfaces\": ["
      " {\"name\": \"floor\", \"corners\": [[0,0,1],[1,0,1],[0,0,0]], \"patches\": [1,1], "
      "\"reflectance\": [1,1,1]},"
      " {\"name\": \"ceiling\", \"corners\": [[0,1,0],[1,1,0],[0,1,1]], \"patches\": [1,1], "
      "\"reflectance\": [1,1,1]}]}";
  cv_display *d = parse(js);
  const double exact = 0.1998248957; /* Howell C-11, X = Y = 1 */
  double f = cv_ff_patch_pair(d, 0, 1);
  printf("  parallel unit squares 1 m apart: F = %.7f (exact %.7f, rel. err %.2e)\n", f, exact,
         f / exact - 1);
  assert_near(f / exact, 1, 5e-3);
  cv_display_destroy(d);
}

/* --- closed cube -------------------------------------------------------------- */

static char *cube_json(int np, const char *extra_floor, const char *extra_front) {
  static char buf[4096];
  snprintf(buf, sizeof buf,
           "{\"surfaces\": ["
           "{\"name\":\"front\",\"corners\":[[-1,0,-1],[1,0,-1],[-1,2,-1]],\"patches\":[%d,%d],"
           "\"reflectance\":[0.8,0.8,0.8]%s},"
           "{\"name\":\"left\",\"corners\":[[-1,0,1],[-1,0,-1],[-1,2,1]],\"patches\":[%d,%d],"
           "\"reflectance\":[0.8,0.8,0.8]},"
           "{\"name\":\"right\",\"corners\":[[1,0,-1],[1,0,1],[1,2,-1]],\"patches\":[%d,%d],"
           "\"reflectance\":[0.8,0.8,0.8]},"
           "{\"name\":\"floor\",\"corners\":[[-1,0,1],[1,0,1],[-1,0,-1]],\"patches\":[%d,%d],"
           "\"reflectance\":[0.8,0.8,0.8]%s},"
           "{\"name\":\"ceiling\",\"corners\":[[-1,2,-1],[1,2,-1],[-1,2,1]],\"patches\":[%d,%d],"
           "\"reflectance\":[0.8,0.8,0.8]},"
           "{\"name\":\"back\",\"corners\":[[1,0,1],[-1,0,1],[1,2,1]],\"patches\":[%d,%d],"
           "\"reflectance\":[0.8,0.8,0.8]}],"
           "\"viewer\": [0, 1, 0]}",
           np, np, extra_front, np, np, np, np, np, np, extra_floor, np, np, np, np);
  return buf;
}

static void sums(const cv_ffmatrix *F, double *rmin, double *rmax, double *cmin, double *cmax) {
  double *col = calloc(F->n, sizeof *col);
  *rmin = INFINITY;
  *rmax = 0;
  for (size_t i = 0; i < F->n; i++) {
    double s = 0;
    for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) {
      s += F->val[k];
      col[F->col[k]] += F->val[k];
    }
    *rmin = fmin(*rmin, s);
    *rmax = fmax(*rmax, s);
  }
  *cmin = INFINITY;
  *cmax = 0;
  for (size_t j = 0; j < F->n; j++) {
    *cmin = fmin(*cmin, col[j]);
    *cmax = fmax(*cmax, col[j]);
  }
  free(col);
}

static void test_closed_cube(void **state) {
  (void)state;
  cv_display *d = parse(cube_json(4, "", ""));
  cv_ff_report rep;
  cv_ffmatrix *F = build(d, 0, 0, CV_FF_VIS_AUTO, &rep);
  double rmin, rmax, cmin, cmax;
  sums(F, &rmin, &rmax, &cmin, &cmax);
  printf("  closed cube 6 x 4x4: rows sum to [%.7f, %.7f], columns to [%.7f, %.7f]; "
         "%zu entries, %llu evaluations, %zu refined pairs, %.3f s\n",
         rmin, rmax, cmin, cmax, F->nnz, (unsigned long long)rep.point_evals, rep.refined_pairs,
         rep.seconds);
  assert_int_equal(rep.visibility_traced, 0);
  assert_int_equal(rep.clamped_pairs, 0);
  assert_near(rmin, 1, 1e-3);
  assert_near(rmax, 1, 1e-3);
  assert_true(rmax <= 1 + 1e-6 && cmax <= 1 + 1e-6);
  assert_near(cmin, 1, 1e-3);
  /* reciprocity A_i F_ij = A_j F_ji; here all areas are equal */
  size_t pairs[][2] = {{0, 17}, {5, 40}, {3, 90}, {12, 66}, {30, 31}};
  for (size_t k = 0; k < 5; k++) {
    size_t i = pairs[k][0], j = pairs[k][1];
    double a = d->patches[i].area * entry(F, j, i), b = d->patches[j].area * entry(F, i, j);
    if (a == 0 && b == 0) continue;
    assert_near(a, b, 1e-6 * fmax(a, b));
  }
  cv_ffmatrix_destroy(F);
  cv_display_destroy(d);
}

/* Reciprocity between patches of different sizes and shapes. */
static void test_reciprocity_unequal(void **state) {
  (void)state;
  const char *js =
      "{\"surfaces\": ["
      " {\"name\": \"floor\", \"corners\": [[0,0,2],[3,0,2],[0,0,0]], \"patches\": [5,3], "
      "\"reflectance\": [1,1,1]},"
      " {\"name\": \"wall\", \"corners\": [[0,0,0],[3,0,0],[0,2,0]], \"patches\": [2,7], "
      "\"reflectance\": [1,1,1]},"
      " {\"name\": \"side\", \"type\": \"cylinder\", \"center\": [1.5, 0, 1], \"radius\": 2.5,"
      "  \"angle_deg\": [60, 120], \"height\": [0, 2], \"patches\": [3, 4], \"reflectance\": [1,1,1]}"
      "]}";
  cv_display *d = parse(js);
  cv_ff_report rep;
  cv_ffmatrix *F = build(d, 0, 0, CV_FF_VIS_NONE, &rep);
  double worst = 0;
  size_t checked = 0;
  for (size_t i = 0; i < d->n_patches; i++)
    for (size_t j = 0; j < d->n_patches; j++) {
      /* the gather matrix holds G_ij = F_{i->j}: reciprocity A_i F_{i->j} = A_j F_{j->i} */
      double a = d->patches[i].area * entry(F, i, j), b = d->patches[j].area * entry(F, j, i);
      if (a == 0 && b == 0) continue;
      worst = fmax(worst, fabs(a - b) / fmax(a, b));
      checked++;
    }
  printf("  reciprocity over %zu pairs of unequal patches: worst relative %.2e\n", checked, worst);
  assert_true(checked > 100);
  assert_true(worst < 1e-6);
  cv_ffmatrix_destroy(F);
  cv_display_destroy(d);
}

/* Light-directing screens: the exponent and the tilt move the light but a
 * sender still spreads everything it reflects over the closed cube. */
static void test_light_directing(void **state) {
  (void)state;
  cv_display *d = parse(cube_json(3, ",\"cosine_exponent\": 4", ",\"normal_tilt_deg\": 25"));
  cv_ff_report rep;
  cv_ffmatrix *F = build(d, 0, 0, CV_FF_VIS_AUTO, &rep);
  double *col = calloc(F->n, sizeof *col);
  for (size_t i = 0; i < F->n; i++)
    for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) col[F->col[k]] += F->val[k];
  int ffront = cv_display_find_surface(d, "front"), ffloor = cv_display_find_surface(d, "floor");
  double wmin = INFINITY, wmax = 0, fmn = INFINITY, fmx = 0;
  for (size_t j = 0; j < F->n; j++) {
    if ((int)d->patches[j].surface == ffront) {
      wmin = fmin(wmin, col[j]);
      wmax = fmax(wmax, col[j]);
    }
    if ((int)d->patches[j].surface == ffloor) {
      fmn = fmin(fmn, col[j]);
      fmx = fmax(fmx, col[j]);
    }
  }
  printf("  senders on a wall tilted 25 deg: sums [%.5f, %.5f]; on a floor with cos^4: "
         "[%.5f, %.5f]\n",
         wmin, wmax, fmn, fmx);
  assert_near(wmin, 1, 1e-4);
  assert_near(wmax, 1, 1e-4);
  assert_near(fmn, 1, 1e-4);
  assert_near(fmx, 1, 1e-4);
  /* the front wall's axis is tilted up: it sends more to the ceiling than
   * to the floor (equal without tilt, by symmetry) */
  double to_ceil = 0, to_floor = 0;
  int fceil0 = cv_display_find_surface(d, "ceiling");
  for (size_t i = 0; i < F->n; i++)
    for (size_t j = 0; j < F->n; j++) {
      if ((int)d->patches[j].surface != ffront) continue;
      if ((int)d->patches[i].surface == fceil0) to_ceil += entry(F, i, j);
      if ((int)d->patches[i].surface == ffloor) to_floor += entry(F, i, j);
    }
  printf("  tilted front wall sends %.4f to the ceiling and %.4f to the floor\n", to_ceil / 9,
         to_floor / 9);
  assert_true(to_ceil > 1.2 * to_floor);
  /* cos^4 sends more straight up (to the ceiling) than a Lambertian floor */
  size_t fl = cv_display_patch_index(d, (size_t)ffloor, 1, 1);
  int fceil = cv_display_find_surface(d, "ceiling");
  double up = 0;
  for (size_t i = 0; i < F->n; i++)
    if ((int)d->patches[i].surface == fceil) up += entry(F, i, fl);
  printf("  centre floor patch with cos^4 sends %.3f to the ceiling (Lambertian: about 0.2)\n", up);
  assert_true(up > 0.3);
  free(col);
  cv_ffmatrix_destroy(F);
  cv_display_destroy(d);
}

static void test_sparsification(void **state) {
  (void)state;
  cv_display *d = parse(cube_json(8, "", ""));
  cv_ff_report r0, r1, r2;
  cv_ffmatrix *F0 = build(d, 0, 0, CV_FF_VIS_NONE, &r0);
  cv_ffmatrix *F1 = build(d, 0.01, 0, CV_FF_VIS_NONE, &r1);
  cv_ffmatrix *F2 = build(d, 0, 0.002, CV_FF_VIS_NONE, &r2);
  printf("  sparsification of %zu patches: dense %zu entries; drop_budget 1%%: %zu entries, "
         "dropped max %.4f mean %.4f total %.4f; rel_threshold 0.002: %zu entries, dropped max "
         "%.4f\n",
         F0->n, F0->nnz, F1->nnz, r1.dropped_max, r1.dropped_mean, r1.dropped_total, F2->nnz,
         r2.dropped_max);
  assert_int_equal(r0.nnz, r0.nnz_full);
  assert_true(r0.dropped_total == 0);
  assert_true(F1->nnz < F0->nnz);
  assert_true(r1.dropped_max <= 0.01 + 1e-12 && r1.dropped_max > 0.005);
  assert_true(F2->nnz < F0->nnz);
  /* the reported dropped energy is what is missing from the stored rows */
  double worst = 0, tot0 = 0, tot1 = 0;
  for (size_t i = 0; i < F0->n; i++) {
    double s0 = 0, s1 = 0, s2 = 0;
    for (size_t k = F0->row_off[i]; k < F0->row_off[i + 1]; k++) s0 += F0->val[k];
    for (size_t k = F1->row_off[i]; k < F1->row_off[i + 1]; k++) s1 += F1->val[k];
    for (size_t k = F2->row_off[i]; k < F2->row_off[i + 1]; k++) {
      s2 += F2->val[k];
      assert_true(F2->val[k] >= 0.002 * s0 * (1 - 1e-6)); /* relative, never absolute */
    }
    worst = fmax(worst, (s0 - s1) / s0);
    tot0 += s0;
    tot1 += s1;
    assert_true((s0 - s1) / s0 <= 0.01 + 1e-6);
  }
  printf("  measured from the matrices: max dropped %.4f, total %.4f\n", worst,
         (tot0 - tot1) / tot0);
  assert_near(worst, r1.dropped_max, 1e-5);
  assert_near((tot0 - tot1) / tot0, r1.dropped_total, 1e-5);
  cv_ffmatrix_destroy(F0);
  cv_ffmatrix_destroy(F1);
  cv_ffmatrix_destroy(F2);
  cv_display_destroy(d);
}

/* Two facing squares with an opaque partition between them. */
static void test_visibility(void **state) {
  (void)state;
  const char *js =
      "{\"surfaces\": ["
      " {\"name\": \"floor\", \"corners\": [[0,0,1],[1,0,1],[0,0,0]], \"patches\": [2,2], "
      "\"reflectance\": [1,1,1]},"
      " {\"name\": \"ceiling\", \"corners\": [[0,2,0],[1,2,0],[0,2,1]], \"patches\": [2,2], "
      "\"reflectance\": [1,1,1]},"
      " {\"name\": \"partition\", \"corners\": [[-%s,1,%s],[%s,1,%s],[-%s,1,-%s]], \"patches\": [1,1], "
      "\"reflectance\": [1,1,1]}]}";
  char buf[1024];
  /* a 7 x 7 m partition blocks everything; a half partition (x < 0.5) some */
  snprintf(buf, sizeof buf, js, "3", "3.5", "4", "3.5", "3", "3.5");
  cv_display *d = parse(buf);
  cv_ff_report rn, ra;
  cv_ffmatrix *Fn = build(d, 0, 0, CV_FF_VIS_NONE, &rn);
  cv_ffmatrix *Fa = build(d, 0, 0, CV_FF_VIS_AUTO, &ra);
  double sn = 0, sa = 0;
  for (size_t i = 4; i < 8; i++)
    for (size_t j = 0; j < 4; j++) {
      sn += entry(Fn, i, j);
      sa += entry(Fa, i, j);
    }
  printf("  floor -> ceiling through a full partition: without visibility %.5f, auto (rays, "
         "%llu traced) %.5f\n",
         sn / 4, (unsigned long long)ra.rays, sa / 4);
  assert_int_equal(ra.visibility_traced, 1);
  assert_true(sn / 4 > 0.05);
  assert_true(sa == 0);
  cv_ffmatrix_destroy(Fn);
  cv_ffmatrix_destroy(Fa);
  cv_display_destroy(d);

  /* partition covering x in [-3, 0.5]: the left floor column (x < 0.5)
   * sees the ceiling only obliquely, the right one mostly */
  snprintf(buf, sizeof buf, js, "3", "3.5", "0.5", "3.5", "3", "3.5");
  d = parse(buf);
  cv_ffmatrix *Fr = build(d, 0, 0, CV_FF_VIS_RAYS, &ra);
  Fn = build(d, 0, 0, CV_FF_VIS_NONE, &rn);
  /* floor patch u=1 (x in [0.5, 1]) to ceiling patch u=1: fully visible */
  size_t f1 = cv_display_patch_index(d, 0, 1, 0), c1 = cv_display_patch_index(d, 1, 1, 0);
  size_t f0 = cv_display_patch_index(d, 0, 0, 0), c0 = cv_display_patch_index(d, 1, 0, 0);
  printf("  half partition: visible pair %.5f (unoccluded %.5f), blocked pair %.5f (unoccluded "
         "%.5f)\n",
         entry(Fr, c1, f1), entry(Fn, c1, f1), entry(Fr, c0, f0), entry(Fn, c0, f0));
  assert_near(entry(Fr, c1, f1), entry(Fn, c1, f1), 1e-7);
  assert_true(entry(Fr, c0, f0) == 0);
  cv_ffmatrix_destroy(Fr);
  cv_ffmatrix_destroy(Fn);
  cv_display_destroy(d);
}

/* Projector-to-patch factors: cos(alpha) / r^2, relative to the brightest
 * patch of each projector, times intensity_scale. */
static void test_projector_factors(void **state) {
  (void)state;
  const char *js =
      "{\"surfaces\": ["
      " {\"name\": \"wall\", \"corners\": [[-1,0,0],[1,0,0],[-1,2,0]], \"patches\": [2,2], "
      "\"reflectance\": [1,1,1]}],"
      " \"projectors\": [{\"position\": [-0.5, 0.5, 2], \"intensity_scale\": 0.8}]}";
  cv_display *d = parse(js);
  /* patch centres: (-0.5,0.5), (0.5,0.5), (-0.5,1.5), (0.5,1.5) at z = 0 */
  double ref[4];
  const double c[4][2] = {{-0.5, 0.5}, {0.5, 0.5}, {-0.5, 1.5}, {0.5, 1.5}};
  for (int k = 0; k < 4; k++) {
    double dx = c[k][0] + 0.5, dy = c[k][1] - 0.5, r2 = dx * dx + dy * dy + 4;
    ref[k] = (2 / sqrt(r2)) / r2;
  }
  for (int k = 0; k < 4; k++) {
    printf("  projector factor patch %d: %.6f (expected %.6f)\n", k, d->proj[k],
           0.8 * ref[k] / ref[0]);
    assert_near(d->proj[k], 0.8 * ref[k] / ref[0], 1e-6);
  }
  cv_scatter_system sys;
  cv_display_scatter_system(d, NULL, &sys);
  assert_true(sys.proj == d->proj && sys.n == 4);
  cv_display_destroy(d);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_point_polygon_closed_form),
      cmocka_unit_test(test_point_polygon_clipping),
      cmocka_unit_test(test_perpendicular_squares),
      cmocka_unit_test(test_corner_point_to_point),
      cmocka_unit_test(test_parallel_squares),
      cmocka_unit_test(test_closed_cube),
      cmocka_unit_test(test_reciprocity_unequal),
      cmocka_unit_test(test_light_directing),
      cmocka_unit_test(test_sparsification),
      cmocka_unit_test(test_visibility),
      cmocka_unit_test(test_projector_factors),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
