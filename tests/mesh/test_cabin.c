/* Cabin generator tests: triangle counts against tess, determinism, window
 * and LCD tags (areas against closed forms), watertight inward-facing shell
 * (edge check and signed volume against the profile's closed-form volume),
 * outward closed objects, no degenerate triangles. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <cmocka.h>
#include "cv_test_near.h"

#include "mesh/cabin.h"
#include "mesh/clean.h"
#include "mesh_check.h"

static double now_s(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static cv_mesh *gen(int tess, cv_cabin_info *info) {
  cv_cabin_params p;
  cv_cabin_default_params(&p);
  p.tess = tess;
  cv_mesh *m = NULL;
  cv_err err;
  int st = cv_cabin_generate_ex(&p, &m, info, &err);
  if (st) fprintf(stderr, "generate: %s\n", err.msg);
  assert_int_equal(st, CV_OK);
  assert_non_null(m);
  return m;
}

/* Counts grow monotonically, ~10K at tess 1, >= 500K at the reported tess;
 * cv_cabin_count agrees with the generated mesh. */
static void test_counts(void **state) {
  (void)state;
  cv_cabin_params p;
  cv_cabin_default_params(&p);
  size_t prev = 0;
  for (int t = 1; t <= 8; t++) {
    size_t nv, nt;
    p.tess = t;
    assert_int_equal(cv_cabin_count(&p, &nv, &nt, NULL), CV_OK);
    printf("  tess %d: %zu vertices, %zu triangles\n", t, nv, nt);
    assert_true(nt > prev);
    prev = nt;
    if (t == 1) {
      assert_true(nt >= 8000 && nt <= 12000);
      cv_mesh *m = gen(1, NULL);
      assert_int_equal(m->nt, nt);
      assert_int_equal(m->nv, nv);
      cv_mesh_destroy(m);
    }
  }
  int T = cv_cabin_tess_for_triangles(500000);
  p.tess = T;
  size_t nt, nt_prev;
  assert_int_equal(cv_cabin_count(&p, NULL, &nt, NULL), CV_OK);
  p.tess = T - 1;
  assert_int_equal(cv_cabin_count(&p, NULL, &nt_prev, NULL), CV_OK);
  assert_true(nt >= 500000);
  assert_true(nt_prev < 500000);
  double t0 = now_s();
  cv_mesh *m = gen(T, NULL);
  double dt = now_s() - t0;
  printf("  tess_for_triangles(500000) = %d: %zu triangles generated in %.1f ms\n", T, m->nt,
         1e3 * dt);
  assert_int_equal(m->nt, nt);
  assert_true(dt < 2.0);
  cv_mesh_destroy(m);
  assert_int_equal(cv_cabin_tess_for_triangles(1), 1);
}

static void test_params_errors(void **state) {
  (void)state;
  cv_cabin_params p;
  cv_cabin_default_params(&p);
  cv_mesh *m = (cv_mesh *)1;
  cv_err err;
  p.tess = 0;
  assert_int_equal(cv_cabin_generate(&p, &m, &err), CV_ERR_RANGE);
  assert_null(m);
  assert_non_null(strstr(err.msg, "tess"));
  cv_cabin_default_params(&p);
  p.width = NAN;
  assert_int_equal(cv_cabin_generate(&p, &m, &err), CV_ERR_RANGE);
  assert_non_null(strstr(err.msg, "width"));
}

static void test_determinism(void **state) {
  (void)state;
  cv_mesh *a = gen(3, NULL), *b = gen(3, NULL);
  assert_int_equal(a->nv, b->nv);
  assert_int_equal(a->nt, b->nt);
  assert_int_equal(a->nm, b->nm);
  assert_memory_equal(a->pos, b->pos, 3 * a->nv * sizeof(float));
  assert_memory_equal(a->tri, b->tri, 3 * a->nt * sizeof(uint32_t));
  assert_memory_equal(a->tri_mat, b->tri_mat, a->nt * sizeof(uint32_t));
  assert_memory_equal(a->mats, b->mats, a->nm * sizeof(cv_material));
  cv_mesh_destroy(a);
  cv_mesh_destroy(b);
}

/* Shell + windows: closed, consistently oriented, inward (signed volume =
 * -(profile area x width)); the profile (z, y) hexagon (-1.3,0) (1.3,0)
 * (1.3,0.8) (0.85,1.2) (-0.55,1.2) (-1.3,0.8) has area 2.08 + 0.8 = 2.88. */
static void check_shell(int tess) {
  cv_cabin_info info;
  cv_mesh *m = gen(tess, &info);
  assert_int_equal(cv_mesh_validate(m, NULL), CV_OK);
  assert_true(info.shell_tri_end > 0 && info.shell_tri_end < m->nt);
  size_t bu, bd;
  mc_edge_check(m, info.shell_tri_begin, info.shell_tri_end, &bu, &bd);
  assert_int_equal(bu, 0);
  assert_int_equal(bd, 0);
  double vol = mc_signed_volume(m, info.shell_tri_begin, info.shell_tri_end);
  double expect = -2.88 * 1.45;
  printf("  tess %d shell signed volume %.6f (closed form %.6f)\n", tess, vol, expect);
  assert_near(vol, expect, 1e-5 * fabs(expect));
  /* the shell part without the window triangles is open */
  for (size_t t = info.shell_tri_begin; t < info.shell_tri_end; t++)
    if (m->mats[m->tri_mat[t]].flags & CV_MAT_WINDOW) {
      size_t bu2, bd2;
      mc_edge_check(m, info.shell_tri_begin, t, &bu2, &bd2);
      assert_true(bu2 > 0);
      break;
    }
  /* window tags only on the shell */
  for (size_t t = info.shell_tri_end; t < m->nt; t++)
    assert_false(m->mats[m->tri_mat[t]].flags & CV_MAT_WINDOW);
  cv_mesh_destroy(m);
}

static void test_shell_closed_inward(void **state) {
  (void)state;
  check_shell(1);
  check_shell(4);
  /* non-default dimensions: the layout scales per axis, the LCD does not */
  cv_cabin_params p = {3.0, 1.6, 1.3, 2};
  cv_cabin_info info;
  cv_mesh *m = NULL;
  assert_int_equal(cv_cabin_generate_ex(&p, &m, &info, NULL), CV_OK);
  size_t bu, bd;
  mc_edge_check(m, info.shell_tri_begin, info.shell_tri_end, &bu, &bd);
  assert_int_equal(bu + bd, 0);
  double vol = mc_signed_volume(m, info.shell_tri_begin, info.shell_tri_end);
  double expect = -2.88 * (3.0 / 2.6) * (1.3 / 1.2) * 1.6;
  assert_near(vol, expect, 1e-5 * fabs(expect));
  assert_near(mc_area_flags(m, CV_MAT_LCD), 0.024, 1e-6);
  float lo[3], hi[3];
  cv_mesh_bounds(m, lo, hi);
  assert_near(hi[0], 0.8f, 1e-6f);
  assert_near(hi[1], 1.3f, 1e-6f);
  assert_near(hi[2], 1.5f, 1e-6f);
  cv_mesh_destroy(m);
}

/* Objects: every position-connected component of the non-shell triangles
 * encloses a positive signed volume (closed and wound outward). */
static uint32_t find(uint32_t *par, uint32_t x) {
  while (par[x] != x) x = par[x] = par[par[x]];
  return x;
}
static void test_objects_outward(void **state) {
  (void)state;
  cv_cabin_info info;
  cv_mesh *m = gen(2, &info);
  uint32_t *id = mc_position_ids(m);
  uint32_t *par = malloc(m->nv * sizeof *par);
  for (size_t v = 0; v < m->nv; v++) par[v] = (uint32_t)v;
  for (size_t t = info.shell_tri_end; t < m->nt; t++)
    for (int j = 1; j < 3; j++) {
      uint32_t a = find(par, id[m->tri[3 * t]]), b = find(par, id[m->tri[3 * t + j]]);
      if (a != b) par[a < b ? b : a] = a < b ? a : b;
    }
  double *vol = calloc(m->nv, sizeof *vol);
  for (size_t t = info.shell_tri_end; t < m->nt; t++)
    vol[find(par, id[m->tri[3 * t]])] += mc_signed_volume(m, t, t + 1);
  size_t ncomp = 0;
  for (size_t v = 0; v < m->nv; v++)
    if (vol[v] != 0) {
      ncomp++;
      assert_true(vol[v] > 0);
    }
  printf("  %zu object components, all with positive volume\n", ncomp);
  assert_true(ncomp >= 8);
  free(vol);
  free(par);
  free(id);
  cv_mesh_destroy(m);
}

static void test_no_degenerate(void **state) {
  (void)state;
  cv_mesh *m = gen(8, NULL);
  double amin = INFINITY;
  for (size_t t = 0; t < m->nt; t++) {
    double h = mc_tri_min_altitude(m, t);
    if (h < amin) amin = h;
  }
  printf("  tess 8: smallest altitude %.3g m\n", amin);
  assert_true(amin > 1e-4);
  cv_mesh_destroy(m);
}

/* Window areas: windshield glass = (1.45 - 2*0.07) * (0.90 - 0.08) * |F1F2|
 * with |F1F2| = sqrt(0.75^2 + 0.4^2); LCD = 0.20 x 0.12, one rectangle in
 * the plane and frame reported by info, facing the driver's eye. */
static void test_tags(void **state) {
  (void)state;
  cv_cabin_info info;
  cv_mesh *m = gen(2, &info);
  const char *wins[] = {"window_windshield", "window_front_left", "window_rear_left",
                        "window_front_right", "window_rear_right", "window_rear"};
  for (int i = 0; i < 6; i++) {
    int k = cv_mesh_find_material(m, wins[i]);
    assert_true(k >= 0);
    assert_true(m->mats[k].flags & CV_MAT_WINDOW);
    assert_true(mc_area_named(m, wins[i]) > 0.1);
  }
  double ws = mc_area_named(m, "window_windshield");
  double ws_expect = (1.45 - 0.14) * 0.82 * sqrt(0.75 * 0.75 + 0.4 * 0.4);
  printf("  windshield glass %.6f m^2 (closed form %.6f), all windows %.4f m^2\n", ws, ws_expect,
         mc_area_flags(m, CV_MAT_WINDOW));
  assert_near(ws, ws_expect, 1e-5);
  /* left/right symmetry */
  assert_near(mc_area_named(m, "window_front_left"), mc_area_named(m, "window_front_right"), 1e-6);

  int nlcd = 0;
  for (size_t i = 0; i < m->nm; i++) nlcd += (m->mats[i].flags & CV_MAT_LCD) != 0;
  assert_int_equal(nlcd, 1);
  double a = mc_area_flags(m, CV_MAT_LCD);
  printf("  lcd area %.8f m^2 (0.024 expected)\n", a);
  assert_near(a, 0.20 * 0.12, 1e-6);
  const cv_cabin_lcd *L = &info.lcd;
  assert_near(L->size[0], 0.20f, 1e-7);
  assert_near(L->size[1], 0.12f, 1e-7);
  double ext[2][2] = {{1, -1}, {1, -1}};
  for (size_t t = 0; t < m->nt; t++) {
    if (!(m->mats[m->tri_mat[t]].flags & CV_MAT_LCD)) continue;
    float n[3];
    cv_mesh_tri_normal(m, t, n);
    double ln = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    assert_true((n[0] * L->normal[0] + n[1] * L->normal[1] + n[2] * L->normal[2]) / ln > 0.99999);
    for (int j = 0; j < 3; j++) {
      const float *p = m->pos + 3 * (size_t)m->tri[3 * t + j];
      double d[3] = {p[0] - L->center[0], p[1] - L->center[1], p[2] - L->center[2]};
      double du = d[0] * L->u[0] + d[1] * L->u[1] + d[2] * L->u[2];
      double dv = d[0] * L->v[0] + d[1] * L->v[1] + d[2] * L->v[2];
      double dn = d[0] * L->normal[0] + d[1] * L->normal[1] + d[2] * L->normal[2];
      assert_near(dn, 0, 1e-5);
      if (du < ext[0][0]) ext[0][0] = du;
      if (du > ext[0][1]) ext[0][1] = du;
      if (dv < ext[1][0]) ext[1][0] = dv;
      if (dv > ext[1][1]) ext[1][1] = dv;
    }
  }
  assert_near(ext[0][0], -0.10, 1e-5);
  assert_near(ext[0][1], 0.10, 1e-5);
  assert_near(ext[1][0], -0.06, 1e-5);
  assert_near(ext[1][1], 0.06, 1e-5);
  /* frame is orthonormal, faces the eye */
  double uv = L->u[0] * L->v[0] + L->u[1] * L->v[1] + L->u[2] * L->v[2];
  assert_near(uv, 0, 1e-6);
  double e[3] = {info.eye[0] - L->center[0], info.eye[1] - L->center[1], info.eye[2] - L->center[2]};
  assert_true(e[0] * L->normal[0] + e[1] * L->normal[1] + e[2] * L->normal[2] > 0);
  /* eye inside the cabin, driver on the left */
  assert_true(info.eye[0] < 0 && info.eye[1] > 0.5f && info.eye[1] < 1.2f);
  /* materials are plausible diffuse albedos */
  int roof = cv_mesh_find_material(m, "roof_liner"), seat = cv_mesh_find_material(m, "seat_fabric");
  assert_true(roof >= 0 && m->mats[roof].albedo[0] > 0.6f);
  assert_true(seat >= 0 && m->mats[seat].albedo[0] >= 0.35f && m->mats[seat].albedo[0] <= 0.5f);
  cv_mesh_destroy(m);
}

/* Every vertex lies inside (or on) the shell's bounding box, and within the
 * hexagonal profile: the objects do not poke through the shell. */
static void test_inside_shell(void **state) {
  (void)state;
  cv_cabin_info info;
  cv_mesh *m = gen(1, &info);
  const double eps = 1e-6;
  /* profile half-planes in (z, y): windshield line through (-1.3,0.8) and
   * (-0.55,1.2); rear-window line through (1.3,0.8) and (0.85,1.2). */
  for (size_t v = 0; v < m->nv; v++) {
    const float *p = m->pos + 3 * v;
    assert_near(p[0], 0, 0.725 + eps);
    assert_true(p[1] >= -eps && p[1] <= 1.2 + eps);
    assert_near(p[2], 0, 1.3 + eps);
    double ws = (p[1] - 0.8) * 0.75 - (p[2] + 1.3) * 0.4;  /* <= 0 behind windshield */
    double rw = (p[1] - 0.8) * 0.45 - (1.3 - p[2]) * 0.4;  /* <= 0 in front of rear window */
    assert_true(ws <= eps);
    assert_true(rw <= eps);
  }
  cv_mesh_destroy(m);
}

/* The preprocessor finds nothing to remove in the generated cabin. */
static void test_cabin_clean(void **state) {
  (void)state;
  cv_mesh *m = gen(1, NULL);
  size_t nt = m->nt;
  cv_clean_report r;
  assert_int_equal(cv_mesh_clean(m, NULL, &r, NULL), CV_OK);
  cv_clean_report_print(stdout, &r);
  assert_int_equal(m->nt, nt);
  assert_int_equal(r.degenerate_index + r.degenerate_area, 0);
  assert_int_equal(r.duplicate_same + r.duplicate_opposite, 0);
  assert_int_equal(r.crack_vertex_merges + r.crack_edge_splits, 0);
  assert_int_equal(r.slivers, 0);
  cv_mesh_destroy(m);
}

int run_cabin_tests(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_counts),         cmocka_unit_test(test_params_errors),
      cmocka_unit_test(test_determinism),    cmocka_unit_test(test_shell_closed_inward),
      cmocka_unit_test(test_objects_outward), cmocka_unit_test(test_no_degenerate),
      cmocka_unit_test(test_tags),           cmocka_unit_test(test_inside_shell),
      cmocka_unit_test(test_cabin_clean),
  };
  return cmocka_run_group_tests_name("cabin", tests, NULL, NULL);
}
