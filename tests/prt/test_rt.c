/* Ray queries: hits, the window rule (Dmitriev 4.1.1), and self-intersection
 * avoidance on triangles lying in axis planes far from the origin. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>
#include "cv_test_near.h"

#include "rt/rt.h"

/* Unit quad in the plane y = h spanning [x0,x0+s] x [z0,z0+s], normal +Y. */
static void quad_y(cv_mesh *m, float x0, float z0, float s, float h, uint32_t mat) {
  uint32_t a, b, c, d;
  cv_mesh_add_vertex(m, x0, h, z0, &a);
  cv_mesh_add_vertex(m, x0 + s, h, z0, &b);
  cv_mesh_add_vertex(m, x0 + s, h, z0 + s, &c);
  cv_mesh_add_vertex(m, x0, h, z0 + s, &d);
  cv_mesh_add_tri(m, a, c, b, mat);
  cv_mesh_add_tri(m, a, d, c, mat);
}

static void test_hits_and_windows(void **state) {
  (void)state;
  cv_mesh *m;
  cv_mesh_create(&m);
  const float grey[3] = {.5f, .5f, .5f}, zero[3] = {0, 0, 0};
  uint32_t op, win;
  cv_mesh_add_material(m, "floor", grey, 0, &op);
  cv_mesh_add_material(m, "window_top", zero, CV_MAT_WINDOW, &win);
  quad_y(m, -1, -1, 2, 0, op);     /* floor */
  quad_y(m, -1, -1, 2, 2, win);    /* window above it */
  quad_y(m, 5, 5, 1, 1, op);       /* unrelated occluder */
  cv_rt *rt;
  cv_err err;
  assert_int_equal(cv_rt_create(m, &rt, &err), CV_OK);
  assert_int_equal(cv_rt_status(rt, &err), CV_OK); /* Embree's error callback saw nothing */
  assert_true(cv_rt_has_windows(rt));
  float o[3] = {0, 1, 0}, down[3] = {0, -1, 0}, up[3] = {0, 1, 0};
  cv_hit h;
  assert_int_equal(cv_rt_intersect(rt, o, down, 0, INFINITY, &h), 1);
  assert_near(h.t, 1.0f, 1e-5f);
  assert_true(m->tri_mat[h.tri] == op);
  /* The window does not block ... */
  assert_int_equal(cv_rt_intersect(rt, o, up, 0, INFINITY, &h), 0);
  /* ... but it is the only way out. */
  assert_int_equal(cv_rt_reaches_env(rt, o, up, 0), 1);
  float side[3] = {1, 0, 0};
  assert_int_equal(cv_rt_reaches_env(rt, o, side, 0), 0); /* escapes, no window */
  assert_int_equal(cv_rt_reaches_env(rt, o, down, 0), 0); /* blocked */
  cv_rt_destroy(rt);

  /* A mesh of windows only has nothing to trace. */
  cv_mesh *w;
  cv_mesh_create(&w);
  cv_mesh_add_material(w, "window", zero, CV_MAT_WINDOW, &win);
  quad_y(w, 0, 0, 1, 0, win);
  assert_int_equal(cv_rt_create(w, &rt, &err), CV_ERR_EMPTY);
  cv_mesh_destroy(w);
  cv_mesh_destroy(m);
}

/* Points on a large axis-aligned plane far from the origin, rays leaving at
 * grazing angles: with the offset no ray hits its own surface. */
static void test_offset_no_self_hit(void **state) {
  (void)state;
  const float offsets[3] = {0.0f, 1000.0f, -40000.0f};
  for (int k = 0; k < 3; k++) {
    cv_mesh *m;
    cv_mesh_create(&m);
    const float grey[3] = {.5f, .5f, .5f};
    uint32_t op;
    cv_mesh_add_material(m, "plane", grey, 0, &op);
    float c = offsets[k];
    quad_y(m, c - 10, c - 10, 20, c, op);
    cv_rt *rt;
    assert_int_equal(cv_rt_create(m, &rt, NULL), CV_OK);
    cv_rt_thread_init();
    int self = 0;
    for (int i = 0; i < 2000; i++) {
      float p[3] = {c - 9 + 18 * (float)((i * 37) % 101) / 101.0f, c,
                    c - 9 + 18 * (float)((i * 53) % 103) / 103.0f};
      float ng[3] = {0, 1, 0}, o[3];
      cv_rt_offset_origin(p, ng, o);
      float phi = 0.1f * i, el = 1e-3f + 0.05f * (float)(i % 7);
      float d[3] = {cosf(phi) * cosf(el), sinf(el), sinf(phi) * cosf(el)};
      self += cv_rt_occluded(rt, o, d, 0, INFINITY);
    }
    assert_int_equal(self, 0);
    cv_rt_destroy(rt);
    cv_mesh_destroy(m);
  }
}

static void test_invalid_mesh(void **state) {
  (void)state;
  cv_mesh *m;
  cv_mesh_create(&m);
  cv_rt *rt;
  cv_err err;
  assert_int_equal(cv_rt_create(m, &rt, &err), CV_ERR_EMPTY);
  const float grey[3] = {.5f, .5f, .5f};
  uint32_t op;
  cv_mesh_add_material(m, "p", grey, 0, &op);
  quad_y(m, 0, 0, 1, 0, op);
  m->pos[4] = NAN;
  assert_int_equal(cv_rt_create(m, &rt, &err), CV_ERR_NONFINITE);
  assert_non_null(strstr(err.msg, "vertex 1"));
  cv_mesh_destroy(m);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_hits_and_windows),
      cmocka_unit_test(test_offset_no_self_hit),
      cmocka_unit_test(test_invalid_mesh),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
