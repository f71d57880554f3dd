/* Packet and stream queries (cv_rt_intersect_packet, cv_rt_window_hit_packet,
 * cv_rt_intersect_stream) against the single-ray queries on the same rays:
 * a closed box of tessellated walls with a window in its lid and an
 * occluder inside, rays from points inside in all directions and in narrow
 * coherent bundles, every packet size 1..16, random active masks, coherent
 * and incoherent contexts.  Each ray must find the same triangle (or none)
 * with t, u, v equal to 1e-5 and the same geometric normal; inactive rays
 * and unused lanes report nothing; bad sizes are refused. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>
#include "cv_test_near.h"

#include "rt/rt.h"

static uint64_t rng = 99;
static double rnd(void) {
  uint64_t z = (rng += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  z ^= z >> 31;
  return (double)(z >> 11) * 0x1p-53;
}

/* An n x n grid quad: corner c, edges e1, e2 (normal e1 x e2). */
static void grid(cv_mesh *m, const float c[3], const float e1[3], const float e2[3], int n,
                 uint32_t mat) {
  uint32_t base = (uint32_t)m->nv;
  for (int j = 0; j <= n; j++)
    for (int i = 0; i <= n; i++) {
      float s = (float)i / n, t = (float)j / n;
      cv_mesh_add_vertex(m, c[0] + s * e1[0] + t * e2[0], c[1] + s * e1[1] + t * e2[1],
                         c[2] + s * e1[2] + t * e2[2], NULL);
    }
  for (int j = 0; j < n; j++)
    for (int i = 0; i < n; i++) {
      uint32_t a = base + (uint32_t)(j * (n + 1) + i), b = a + 1, d = a + (uint32_t)(n + 1), e = d + 1;
      cv_mesh_add_tri(m, a, b, e, mat);
      cv_mesh_add_tri(m, a, e, d, mat);
    }
}

/* Box [-1,1]^3 with walls of 8 x 8 quads, the lid's middle a window, and a
 * small tilted occluder plate inside. */
static cv_mesh *box_scene(void) {
  cv_mesh *m;
  cv_mesh_create(&m);
  const float grey[3] = {.5f, .5f, .5f}, zero[3] = {0, 0, 0};
  uint32_t op, win;
  cv_mesh_add_material(m, "wall", grey, 0, &op);
  cv_mesh_add_material(m, "window_lid", zero, CV_MAT_WINDOW, &win);
  const float c0[3] = {-1, -1, -1};
  const float X[3] = {2, 0, 0}, Y[3] = {0, 2, 0}, Z[3] = {0, 0, 2};
  grid(m, c0, Y, X, 8, op); /* z = -1 */
  grid(m, c0, X, Z, 8, op); /* y = -1 */
  grid(m, c0, Z, Y, 8, op); /* x = -1 */
  const float cx[3] = {1, -1, -1}, cz[3] = {-1, -1, 1};
  grid(m, cx, Y, Z, 8, op);
  grid(m, cz, X, Y, 8, op);
  /* lid y = 1: a ring of wall around a 1 x 1 window */
  const float l0[3] = {-1, 1, -1}, lx[3] = {2, 0, 0}, lz1[3] = {0, 0, 0.5f};
  grid(m, l0, lz1, lx, 4, op);
  const float l1[3] = {-1, 1, 0.5f};
  grid(m, l1, lz1, lx, 4, op);
  const float l2[3] = {-1, 1, -0.5f}, sx[3] = {0.5f, 0, 0}, sz[3] = {0, 0, 1};
  grid(m, l2, sz, sx, 2, op);
  const float l3[3] = {0.5f, 1, -0.5f};
  grid(m, l3, sz, sx, 2, op);
  const float w0[3] = {-0.5f, 1, -0.5f}, wx[3] = {1, 0, 0}, wz[3] = {0, 0, 1};
  grid(m, w0, wz, wx, 4, win);
  const float o0[3] = {-0.3f, 0.2f, -0.3f}, ox[3] = {0.6f, 0.1f, 0}, oz[3] = {0, 0.05f, 0.6f};
  grid(m, o0, ox, oz, 3, op);
  return m;
}

static void check_same(const cv_hit *a, int fa, const cv_hit *b, int fb, int *bad) {
  if (fa != fb) {
    (*bad)++;
    return;
  }
  if (!fa) return;
  if (a->tri != b->tri || fabsf(a->t - b->t) > 1e-5f * fmaxf(1, a->t) ||
      fabsf(a->u - b->u) > 1e-5f || fabsf(a->v - b->v) > 1e-5f)
    (*bad)++;
  for (int k = 0; k < 3; k++)
    if (fabsf(a->ng[k] - b->ng[k]) > 1e-5f * (fabsf(a->ng[k]) + 1e-3f)) (*bad)++;
}

static void make_rays(int n, int coherent, float *org, float *dir) {
  float c[3] = {(float)(rnd() * 1.6 - 0.8), (float)(rnd() * 1.6 - 0.8), (float)(rnd() * 1.6 - 0.8)};
  float axis[3];
  double z = 2 * rnd() - 1, ph = 2 * M_PI * rnd(), r = sqrt(1 - z * z);
  axis[0] = (float)(r * cos(ph)), axis[1] = (float)z, axis[2] = (float)(r * sin(ph));
  for (int i = 0; i < n; i++) {
    float d[3];
    if (coherent) { /* a 5-degree bundle from a 1 cm spot */
      for (int k = 0; k < 3; k++) {
        org[3 * i + k] = c[k] + (float)(0.01 * (rnd() - 0.5));
        d[k] = axis[k] + (float)(0.09 * (rnd() - 0.5));
      }
    } else {
      for (int k = 0; k < 3; k++) org[3 * i + k] = (float)(rnd() * 1.6 - 0.8);
      double zz = 2 * rnd() - 1, pp = 2 * M_PI * rnd(), rr = sqrt(1 - zz * zz);
      d[0] = (float)(rr * cos(pp)), d[1] = (float)zz, d[2] = (float)(rr * sin(pp));
    }
    float l = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int k = 0; k < 3; k++) dir[3 * i + k] = d[k] / l;
  }
}

static void test_packets_match_single(void **state) {
  (void)state;
  cv_mesh *m = box_scene();
  cv_rt *rt;
  cv_err err;
  assert_int_equal(cv_rt_create(m, &rt, &err), CV_OK);
  assert_true(cv_rt_has_windows(rt));
  cv_rt_thread_init();
  int bad = 0, traced = 0, hits = 0, wins = 0, inactive_found = 0;
  for (int rep = 0; rep < 400; rep++) {
    const int n = 1 + rep % CV_RT_PACKET_MAX, coherent = (rep / CV_RT_PACKET_MAX) % 2;
    float org[3 * CV_RT_PACKET_MAX], dir[3 * CV_RT_PACKET_MAX];
    uint8_t active[CV_RT_PACKET_MAX], found[CV_RT_PACKET_MAX], wfound[CV_RT_PACKET_MAX];
    cv_hit hit[CV_RT_PACKET_MAX], whit[CV_RT_PACKET_MAX];
    make_rays(n, coherent, org, dir);
    const int masked = rep % 3 == 0;
    for (int i = 0; i < n; i++) active[i] = masked ? rnd() < 0.6 : 1;
    int c = cv_rt_intersect_packet(rt, n, org, dir, masked ? active : NULL, 0, INFINITY, coherent,
                                   hit, found);
    int cw = cv_rt_window_hit_packet(rt, n, org, dir, masked ? active : NULL, 0, coherent, whit,
                                     wfound);
    int count = 0, wcount = 0;
    for (int i = 0; i < n; i++) {
      count += found[i], wcount += wfound[i];
      if (!active[i]) {
        inactive_found += found[i] + wfound[i];
        continue;
      }
      cv_hit h1, w1;
      int f1 = cv_rt_intersect(rt, org + 3 * i, dir + 3 * i, 0, INFINITY, &h1);
      int g1 = cv_rt_window_hit(rt, org + 3 * i, dir + 3 * i, 0, &w1);
      check_same(&h1, f1, &hit[i], found[i], &bad);
      check_same(&w1, g1, &whit[i], wfound[i], &bad);
      traced++, hits += f1, wins += g1;
    }
    assert_int_equal(c, count);
    assert_int_equal(cw, wcount);
  }
  print_message("packets: %d rays, %d opaque hits, %d window crossings, %d mismatches\n", traced,
                hits, wins, bad);
  assert_int_equal(bad, 0);
  assert_int_equal(inactive_found, 0);
  assert_true(hits > traced / 2 && wins > 0);
  /* finite tfar: hits beyond it are not reported */
  float o[3] = {0, 0, 0}, d[3] = {0, 0, -1};
  cv_hit h;
  uint8_t f;
  assert_int_equal(cv_rt_intersect_packet(rt, 1, o, d, NULL, 0, 0.5f, 1, &h, &f), 0);
  assert_int_equal(cv_rt_intersect_packet(rt, 1, o, d, NULL, 0, 1.5f, 1, &h, &f), 1);
  assert_near(h.t, 1, 1e-5f);
  /* bad sizes */
  assert_int_equal(cv_rt_intersect_packet(rt, 0, o, d, NULL, 0, INFINITY, 0, &h, &f), -1);
  assert_int_equal(cv_rt_intersect_packet(rt, CV_RT_PACKET_MAX + 1, o, d, NULL, 0, INFINITY, 0, &h, &f), -1);
  assert_int_equal(cv_rt_window_hit_packet(rt, 0, o, d, NULL, 0, 0, &h, &f), -1);
  cv_rt_destroy(rt);
  cv_mesh_destroy(m);
}

/* SoA packets give the very hits of cv_rt_intersect_packet (incoherent,
 * every lane active): the same primitive's triangle, u and v to the bit; a
 * primitive's entry in cv_rt_opaque_vertices is its triangle's vertices. */
static void test_packet_soa(void **state) {
  (void)state;
  cv_mesh *m = box_scene();
  cv_rt *rt;
  cv_err err;
  assert_int_equal(cv_rt_create(m, &rt, &err), CV_OK);
  cv_rt_thread_init();
  const uint32_t *ov = cv_rt_opaque_vertices(rt);
  assert_non_null(ov);
  int bad = 0, hits = 0;
  for (int rep = 0; rep < 200; rep++) {
    const int n = 1 + rep % CV_RT_PACKET_MAX;
    float org[3 * CV_RT_PACKET_MAX], dir[3 * CV_RT_PACKET_MAX], u[CV_RT_PACKET_MAX],
        v[CV_RT_PACKET_MAX];
    uint32_t prim[CV_RT_PACKET_MAX];
    uint8_t found[CV_RT_PACKET_MAX];
    cv_hit hit[CV_RT_PACKET_MAX];
    cv_ray_soa r;
    make_rays(n, (rep / 7) % 2, org, dir);
    for (int i = 0; i < n; i++)
      for (int k = 0; k < 3; k++) {
        r.org[k][i] = org[3 * i + k];
        r.dir[k][i] = dir[3 * i + k];
      }
    int c = cv_rt_intersect_packet(rt, n, org, dir, NULL, 0, INFINITY, 0, hit, found);
    int cs = cv_rt_intersect_packet_soa(rt, n, &r, 0, INFINITY, prim, u, v);
    assert_int_equal(c, cs);
    for (int i = 0; i < n; i++) {
      if (found[i] != (prim[i] != CV_RT_NO_HIT)) {
        bad++;
        continue;
      }
      if (!found[i]) continue;
      hits++;
      const uint32_t t = cv_rt_opaque_triangle(rt, prim[i]);
      if (t != hit[i].tri || memcmp(&u[i], &hit[i].u, 4) || memcmp(&v[i], &hit[i].v, 4)) bad++;
      for (int k = 0; k < 3; k++)
        if (ov[3 * (size_t)prim[i] + k] != m->tri[3 * (size_t)t + k]) bad++;
    }
  }
  assert_int_equal(bad, 0);
  assert_true(hits > 1000);
  cv_ray_soa r;
  uint32_t prim[1];
  float u[1], v[1];
  assert_int_equal(cv_rt_intersect_packet_soa(rt, 0, &r, 0, INFINITY, prim, u, v), -1);
  assert_int_equal(cv_rt_intersect_packet_soa(rt, CV_RT_PACKET_MAX + 1, &r, 0, INFINITY, prim, u, v), -1);
  cv_rt_destroy(rt);
  cv_mesh_destroy(m);
}

static void test_stream_and_no_windows(void **state) {
  (void)state;
  cv_mesh *m = box_scene();
  cv_rt *rt;
  assert_int_equal(cv_rt_create(m, &rt, NULL), CV_OK);
  cv_rt_thread_init();
  enum { N = 3000 };
  static float org[3 * N], dir[3 * N];
  static cv_hit hit[N];
  static uint8_t found[N], active[N];
  for (int b = 0; b < N; b += 100) make_rays(100, (b / 100) % 2, org + 3 * b, dir + 3 * b);
  for (int i = 0; i < N; i++) active[i] = i % 7 != 3;
  int bad = 0;
  for (int co = 0; co < 2; co++) {
    size_t c = cv_rt_intersect_stream(rt, N, org, dir, active, 0, INFINITY, co, hit, found);
    size_t count = 0;
    for (int i = 0; i < N; i++) {
      count += found[i];
      if (!active[i]) {
        assert_int_equal(found[i], 0);
        continue;
      }
      cv_hit h1;
      int f1 = cv_rt_intersect(rt, org + 3 * i, dir + 3 * i, 0, INFINITY, &h1);
      check_same(&h1, f1, &hit[i], found[i], &bad);
    }
    assert_int_equal(c, count);
  }
  print_message("stream: %d rays twice, %d mismatches\n", N, bad);
  assert_int_equal(bad, 0);
  cv_rt_destroy(rt);
  cv_mesh_destroy(m);
  /* without windows the window packet query finds nothing */
  cv_mesh *w;
  cv_mesh_create(&w);
  const float grey[3] = {.5f, .5f, .5f};
  uint32_t op;
  cv_mesh_add_material(w, "floor", grey, 0, &op);
  const float c0[3] = {-1, 0, -1}, X[3] = {2, 0, 0}, Z[3] = {0, 0, 2};
  grid(w, c0, Z, X, 2, op);
  assert_int_equal(cv_rt_create(w, &rt, NULL), CV_OK);
  float o[3] = {0, 1, 0}, d[3] = {0, -1, 0};
  cv_hit h;
  uint8_t f = 7;
  assert_int_equal(cv_rt_window_hit_packet(rt, 1, o, d, NULL, 0, 1, &h, &f), 0);
  assert_int_equal(f, 0);
  assert_int_equal(cv_rt_intersect_packet(rt, 1, o, d, NULL, 0, INFINITY, 1, &h, &f), 1);
  cv_rt_destroy(rt);
  cv_mesh_destroy(w);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_packets_match_single),
      cmocka_unit_test(test_stream_and_no_windows),
      cmocka_unit_test(test_packet_soa),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
