/* Geometry preprocessor tests on small hand-built meshes with known answers:
 * welding, crease preservation, degenerate and duplicate removal (both
 * windings), crack closing at 0.5x the crack width and not at 2x, sliver
 * reporting, unreferenced-vertex removal, determinism. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>
#include "cv_test_near.h"

#include "mesh/clean.h"
#include "mesh_check.h"

static cv_mesh *mk(const float (*v)[3], size_t nv, const uint32_t (*t)[3], size_t nt) {
  cv_mesh *m;
  assert_int_equal(cv_mesh_create(&m), CV_OK);
  float alb[3] = {0.5f, 0.5f, 0.5f};
  assert_int_equal(cv_mesh_add_material(m, "grey", alb, 0, NULL), CV_OK);
  for (size_t i = 0; i < nv; i++)
    assert_int_equal(cv_mesh_add_vertex(m, v[i][0], v[i][1], v[i][2], NULL), CV_OK);
  for (size_t i = 0; i < nt; i++)
    assert_int_equal(cv_mesh_add_tri(m, t[i][0], t[i][1], t[i][2], 0), CV_OK);
  return m;
}

static cv_clean_report clean_ok(cv_mesh *m) {
  cv_clean_report r;
  cv_err err;
  int st = cv_mesh_clean(m, NULL, &r, &err);
  if (st) fprintf(stderr, "clean: %s\n", err.msg);
  assert_int_equal(st, CV_OK);
  return r;
}

/* A unit quad as two triangles whose diagonal vertices are duplicated, one
 * copy 1e-7 away (diag ~1.41, weld tolerance 1.41e-6): 6 -> 4 vertices. */
static void test_weld(void **state) {
  (void)state;
  const float v[6][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 0, 0}, {1, 1 + 1e-7f, 0}, {0, 1, 0}};
  const uint32_t t[2][3] = {{0, 1, 2}, {3, 4, 5}};
  cv_mesh *m = mk(v, 6, t, 2);
  cv_clean_report r = clean_ok(m);
  assert_int_equal(r.welded, 2);
  assert_int_equal(m->nv, 4);
  assert_int_equal(m->nt, 2);
  assert_int_equal(mc_boundary_edges(m), 4);
  assert_int_equal(m->tri[3], 0); /* vertex 3 became vertex 0 */
  assert_int_equal(m->tri[4], 2);
  cv_mesh_destroy(m);
}

/* Two faces of a box meeting at a 90-degree edge, each with its own copies
 * of the edge vertices: nothing is welded, the crease stays split. */
static void test_crease_kept(void **state) {
  (void)state;
  const float v[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1},  /* floor y = 0 */
                         {0, 0, 0}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}}; /* wall z = 0 */
  const uint32_t t[4][3] = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}};
  cv_mesh *m = mk(v, 8, t, 4);
  cv_clean_report r = clean_ok(m);
  assert_int_equal(r.welded, 0);
  assert_int_equal(r.weld_crease_kept, 2);
  assert_int_equal(r.crack_vertex_merges + r.crack_edge_splits, 0);
  assert_int_equal(m->nv, 8);
  assert_int_equal(m->nt, 4);
  cv_mesh_destroy(m);

  /* the same at 30 degrees (below the 60-degree crease angle) is welded */
  const float c30 = 0.8660254f, s30 = 0.5f;
  const float w[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1},
                         {0, 0, 0}, {0, s30, -c30}, {1, s30, -c30}, {1, 0, 0}};
  const uint32_t u[4][3] = {{0, 2, 1}, {0, 3, 2}, {4, 6, 5}, {4, 7, 6}};
  m = mk(w, 8, u, 4);
  r = clean_ok(m);
  assert_int_equal(r.welded, 2);
  assert_int_equal(m->nv, 6);
  cv_mesh_destroy(m);
}

/* Degenerate: a repeated index and a zero-altitude (collinear) triangle. */
static void test_degenerate(void **state) {
  (void)state;
  const float v[7][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0},
                         {2, 0, 0}, {3, 0, 0}, {4, 0, 0}, /* collinear */
                         {2, 1, 0}};
  const uint32_t t[4][3] = {{0, 1, 2}, {0, 0, 1}, {3, 4, 5}, {3, 5, 6}};
  cv_mesh *m = mk(v, 7, t, 4);
  cv_clean_report r = clean_ok(m);
  assert_int_equal(r.degenerate_index, 1);
  assert_int_equal(r.degenerate_area, 1);
  assert_int_equal(m->nt, 2);
  assert_int_equal(r.unreferenced, 1); /* vertex 4 */
  assert_int_equal(m->nv, 6);
  /* order kept: old vertex 5 is now 4 */
  assert_true(m->pos[3 * 4] == 4.0f);
  assert_int_equal(m->tri[3], 3);
  assert_int_equal(m->tri[4], 4);
  assert_int_equal(m->tri[5], 5);
  cv_mesh_destroy(m);
}

/* Duplicates: two same-winding copies (one rotated) and one reversed. */
static void test_duplicates(void **state) {
  (void)state;
  const float v[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
  const uint32_t t[5][3] = {{0, 1, 2}, {1, 3, 2}, {1, 2, 0}, {0, 2, 1}, {0, 1, 2}};
  cv_mesh *m = mk(v, 4, t, 5);
  cv_clean_report r = clean_ok(m);
  assert_int_equal(r.duplicate_same, 2);
  assert_int_equal(r.duplicate_opposite, 1);
  assert_int_equal(r.nt_after_bc, 2);
  assert_int_equal(m->nt, 2);
  assert_int_equal(m->tri[0], 0); /* the first copy is kept as it was */
  assert_int_equal(m->tri[1], 1);
  assert_int_equal(m->tri[2], 2);
  cv_mesh_destroy(m);
}

/* Two coplanar patches: A = [0,1]^2 (2 triangles), B = [1+g,2] x [0,1] (4
 * triangles, left edge split at y = 0.5).  Bounding diagonal ~ sqrt(5), so
 * the crack width is w = 1e-4 * sqrt(5).  At g = w/2 the two corner pairs
 * merge, B's middle vertex splits A's edge (a T-junction fix), and only the
 * outer 7-edge loop stays open; at g = 2w nothing changes. */
static cv_mesh *crack_mesh(double g) {
  float x = (float)(1.0 + g);
  const float v[10][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},          /* A */
                          {x, 0, 0}, {2, 0, 0}, {2, 1, 0}, {x, 1, 0}, {x, 0.5f, 0}, /* B */
                          {2, 0.5f, 0}};
  const uint32_t t[6][3] = {{0, 1, 2}, {0, 2, 3}, {4, 5, 9}, {4, 9, 8}, {8, 9, 6}, {8, 6, 7}};
  return mk(v, 10, t, 6);
}

static void test_crack(void **state) {
  (void)state;
  double w = 1e-4 * sqrt(5.0);
  cv_mesh *m = crack_mesh(0.5 * w);
  assert_int_equal(mc_boundary_edges(m), 10);
  cv_clean_report r = clean_ok(m);
  cv_clean_report_print(stdout, &r);
  assert_int_equal(r.crack_vertex_merges, 2);
  assert_int_equal(r.crack_edge_splits, 1);
  assert_int_equal(r.crack_tris_added, 1);
  assert_int_equal(r.boundary_edges_before, 10);
  assert_int_equal(r.boundary_edges_after, 7);
  assert_int_equal(r.nt_after_bc, 6);
  assert_int_equal(r.nt_after_d, 7);
  assert_int_equal(mc_boundary_edges(m), 7);
  assert_int_equal(m->nt, 7);
  assert_int_equal(m->nv, 8);
  /* area is preserved up to the crack strip (g x 1) */
  double area = 0;
  for (size_t t = 0; t < m->nt; t++) area += mc_tri_area(m, t);
  assert_near(area, 2.0, 2 * w);
  cv_mesh_destroy(m);

  m = crack_mesh(2.0 * w);
  r = clean_ok(m);
  assert_int_equal(r.crack_vertex_merges, 0);
  assert_int_equal(r.crack_edge_splits, 0);
  assert_int_equal(r.boundary_edges_after, 10);
  assert_int_equal(m->nt, 6);
  assert_int_equal(m->nv, 10);
  cv_mesh_destroy(m);
}


/* Corner UVs follow cleaning: with a planar map u = x / 2, v = y on every
 * corner, after crack closing (vertex merges, a T-junction split, which
 * interpolates along the split edge) and compaction every corner's UV still
 * equals its vertex's planar map (to the crack width). */
static void test_crack_uv(void **state) {
  (void)state;
  double w = 1e-4 * sqrt(5.0);
  cv_mesh *m = crack_mesh(0.5 * w);
  assert_int_equal(cv_mesh_enable_uv(m), CV_OK);
  for (size_t t = 0; t < m->nt; t++)
    for (int k = 0; k < 3; k++) {
      const float *p = m->pos + 3 * m->tri[3 * t + k];
      m->tri_uv[6 * t + 2 * k] = p[0] / 2;
      m->tri_uv[6 * t + 2 * k + 1] = p[1];
    }
  cv_clean_report r = clean_ok(m);
  assert_int_equal(r.crack_edge_splits, 1);
  assert_int_equal(m->nt, 7);
  for (size_t t = 0; t < m->nt; t++)
    for (int k = 0; k < 3; k++) {
      const float *p = m->pos + 3 * m->tri[3 * t + k];
      assert_near(m->tri_uv[6 * t + 2 * k], p[0] / 2, w);
      assert_near(m->tri_uv[6 * t + 2 * k + 1], p[1], w);
    }
  cv_mesh *c;
  assert_int_equal(cv_mesh_clone(m, &c), CV_OK);
  assert_memory_equal(c->tri_uv, m->tri_uv, 6 * m->nt * sizeof(float));
  cv_mesh_destroy(c);
  cv_mesh_destroy(m);
}

/* A crack between two touching objects with opposite normals (a box face
 * resting on a floor) is not a crack: nothing is snapped. */
static void test_crack_opposite_normals(void **state) {
  (void)state;
  const float v[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1},   /* floor, up */
                         {0.5f, 1e-5f, 0}, {1, 1e-5f, 0}, {1, 1e-5f, 1}, {0.5f, 1e-5f, 1}};
  const uint32_t t[4][3] = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}}; /* second faces down */
  cv_mesh *m = mk(v, 8, t, 4);
  cv_clean_report r = clean_ok(m);
  assert_int_equal(r.crack_vertex_merges + r.crack_edge_splits, 0);
  assert_int_equal(m->nt, 4);
  cv_mesh_destroy(m);
}

/* Sliver: longest edge 1, altitude 2e-4 -> aspect 5000 > 1e3: reported,
 * kept.  The equilateral-ish neighbour has aspect ~1.15. */
static void test_sliver(void **state) {
  (void)state;
  const float v[6][3] = {{0, 0, 0}, {1, 0, 0}, {0.5f, 2e-4f, 0},
                         {0, 2, 0}, {1, 2, 0}, {0.5f, 2.8660254f, 0}};
  const uint32_t t[2][3] = {{0, 1, 2}, {3, 4, 5}};
  cv_mesh *m = mk(v, 6, t, 2);
  cv_clean_report r = clean_ok(m);
  assert_int_equal(r.slivers, 1);
  assert_int_equal(r.worst_tri, 0);
  assert_near(r.worst_aspect, 5000.0, 5.0);
  assert_int_equal(m->nt, 2);
  cv_mesh_destroy(m);
}

/* Determinism: cleaning two copies gives identical arrays; errors. */
static void test_determinism_errors(void **state) {
  (void)state;
  cv_mesh *a = crack_mesh(0.5e-4), *b;
  assert_int_equal(cv_mesh_clone(a, &b), CV_OK);
  clean_ok(a);
  clean_ok(b);
  assert_int_equal(a->nv, b->nv);
  assert_int_equal(a->nt, b->nt);
  assert_memory_equal(a->pos, b->pos, 3 * a->nv * sizeof(float));
  assert_memory_equal(a->tri, b->tri, 3 * a->nt * sizeof(uint32_t));
  a->pos[4] = NAN;
  cv_err err;
  assert_int_equal(cv_mesh_clean(a, NULL, NULL, &err), CV_ERR_NONFINITE);
  assert_non_null(strstr(err.msg, "clean"));
  cv_clean_params p;
  cv_clean_default_params(&p);
  p.crack_width_rel = -1;
  assert_int_equal(cv_mesh_clean(b, &p, NULL, &err), CV_ERR_INVALID);
  cv_mesh *e;
  assert_int_equal(cv_mesh_create(&e), CV_OK);
  assert_int_equal(cv_mesh_clean(e, NULL, NULL, &err), CV_ERR_EMPTY);
  cv_mesh_destroy(e);
  cv_mesh_destroy(a);
  cv_mesh_destroy(b);
}

/* (g): a 2x1 strip of quads, left quad material A, right quad B (another
 * albedo), and a third quad above the left one in material C with A's albedo.
 * The two vertices on the A|B edge are split (B gets its own copies); A and
 * C share theirs; no vertex is used by two different albedos afterwards;
 * window triangles never split. */
static void test_material_split(void **state) {
  (void)state;
  cv_mesh *m;
  assert_int_equal(cv_mesh_create(&m), CV_OK);
  const float a[3] = {0.5f, 0.5f, 0.5f}, b[3] = {0.03f, 0.03f, 0.03f}, z[3] = {0, 0, 0};
  uint32_t ma, mb, mc, mw;
  assert_int_equal(cv_mesh_add_material(m, "A", a, 0, &ma), CV_OK);
  assert_int_equal(cv_mesh_add_material(m, "B", b, CV_MAT_LCD, &mb), CV_OK);
  assert_int_equal(cv_mesh_add_material(m, "C", a, 0, &mc), CV_OK);
  assert_int_equal(cv_mesh_add_material(m, "glass", z, CV_MAT_WINDOW, &mw), CV_OK);
  /* 3 x 3 grid of vertices in the z = 0 plane: index = 3*row + col. */
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) assert_int_equal(cv_mesh_add_vertex(m, (float)c, (float)r, 0, NULL), CV_OK);
  const uint32_t quad[4][4] = {{0, 1, 4, 3}, {1, 2, 5, 4}, {3, 4, 7, 6}, {4, 5, 8, 7}};
  const uint32_t qm[4] = {ma, mb, mc, mw};
  for (int q = 0; q < 4; q++) {
    assert_int_equal(cv_mesh_add_tri(m, quad[q][0], quad[q][1], quad[q][2], qm[q]), CV_OK);
    assert_int_equal(cv_mesh_add_tri(m, quad[q][0], quad[q][2], quad[q][3], qm[q]), CV_OK);
  }
  cv_clean_report r = clean_ok(m);
  assert_int_equal(r.material_splits, 2); /* vertices 1 and 4 (B's corners on the A|B edge) */
  assert_int_equal(m->nv, 11);
  assert_int_equal(m->nt, 8);
  /* No vertex is used by two different (non-window) albedos. */
  float *va = malloc(3 * m->nv * sizeof *va);
  int *seen = calloc(m->nv, sizeof *seen);
  for (size_t t = 0; t < m->nt; t++) {
    const cv_material *mt = &m->mats[m->tri_mat[t]];
    if (mt->flags & CV_MAT_WINDOW) continue;
    for (int k = 0; k < 3; k++) {
      uint32_t v = m->tri[3 * t + k];
      if (seen[v]) assert_memory_equal(va + 3 * v, mt->albedo, 3 * sizeof(float));
      memcpy(va + 3 * v, mt->albedo, 3 * sizeof(float));
      seen[v] = 1;
    }
  }
  /* A and C (same albedo) still share the edge vertices 3 and 4. */
  int a_has4 = 0, c_has4 = 0;
  for (size_t t = 0; t < m->nt; t++)
    for (int k = 0; k < 3; k++)
      if (m->tri[3 * t + k] == 4) {
        a_has4 |= m->tri_mat[t] == ma;
        c_has4 |= m->tri_mat[t] == mc;
      }
  assert_true(a_has4 && c_has4);
  free(va);
  free(seen);
  cv_mesh_destroy(m);
}

int run_clean_tests(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_weld),       cmocka_unit_test(test_crease_kept),
      cmocka_unit_test(test_degenerate), cmocka_unit_test(test_duplicates),
      cmocka_unit_test(test_crack),      cmocka_unit_test(test_crack_opposite_normals),
      cmocka_unit_test(test_sliver),     cmocka_unit_test(test_determinism_errors),
      cmocka_unit_test(test_material_split), cmocka_unit_test(test_crack_uv),
  };
  return cmocka_run_group_tests_name("clean", tests, NULL, NULL);
}
