/* PRT bake and relighting against closed forms and an independent
 * brute-force Monte Carlo estimate:
 *  - unshadowed plane under constant and linear sky: albedo * L (0.5%);
 *  - closed furnace box: the geometric series a(1 + a + ... + a^N) (1%);
 *  - open box with a window on top, floor centre vs a path tracer written
 *    here on top of Embree (2%);
 *  - overlapping, duplicate and degenerate triangles;
 *  - determinism across thread counts, the file format, sun direct light. */
#include <math.h>
#include <omp.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>
#include "cv_test_near.h"

#include "prt/auto.h"
#include "prt/bake.h"
#include "prt/prt.h"
#include "prt/relight.h"
#include "rt/rt.h"
#include "sh/sh.h"
#include "io/png.h"
#include "io/texture.h"

/* n x n grid of quads over a parallelogram o + s*e1 + t*e2 (s,t in [0,1]);
 * winding makes the normal e1 x e2. */
static void grid(cv_mesh *m, const float o[3], const float e1[3], const float e2[3], int n,
                 uint32_t mat) {
  uint32_t base = (uint32_t)m->nv;
  for (int j = 0; j <= n; j++)
    for (int i = 0; i <= n; i++) {
      float s = (float)i / n, t = (float)j / n;
      cv_mesh_add_vertex(m, o[0] + s * e1[0] + t * e2[0], o[1] + s * e1[1] + t * e2[1],
                         o[2] + s * e1[2] + t * e2[2], NULL);
    }
  for (int j = 0; j < n; j++)
    for (int i = 0; i < n; i++) {
      uint32_t a = base + j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      cv_mesh_add_tri(m, a, b, d, mat);
      cv_mesh_add_tri(m, a, d, c, mat);
    }
}

/* Floor facing +Y: e1 = +Z, e2 = +X gives normal Z x X = +Y. */
static cv_mesh *plane_mesh(int n, const float albedo[3]) {
  cv_mesh *m;
  cv_mesh_create(&m);
  uint32_t mat;
  cv_mesh_add_material(m, "floor", albedo, 0, &mat);
  const float o[3] = {-1, 0, -1}, e1[3] = {0, 0, 2}, e2[3] = {2, 0, 0};
  grid(m, o, e1, e2, n, mat);
  return m;
}

/* Unit cube [0,1]^3 with inward normals; top face tagged as window if asked. */
static cv_mesh *box_mesh(int n, float a, int top_window) {
  cv_mesh *m;
  cv_mesh_create(&m);
  const float alb[3] = {a, a, a}, zero[3] = {0, 0, 0};
  uint32_t wall, win;
  cv_mesh_add_material(m, "wall", alb, 0, &wall);
  cv_mesh_add_material(m, "window_top", zero, CV_MAT_WINDOW, &win);
  const float X[3] = {1, 0, 0}, Y[3] = {0, 1, 0}, Z[3] = {0, 0, 1};
  const float o0[3] = {0, 0, 0}, ox[3] = {1, 0, 0}, oy[3] = {0, 1, 0}, oz[3] = {0, 0, 1};
  grid(m, o0, Z, X, n, wall);                    /* floor y=0, normal +Y */
  grid(m, oy, X, Z, n, top_window ? win : wall); /* top y=1, normal -Y */
  grid(m, o0, X, Y, n, wall);                    /* z=0, normal +Z */
  grid(m, oz, Y, X, n, wall);                    /* z=1, normal -Z */
  grid(m, o0, Y, Z, n, wall);                    /* x=0, normal +X */
  grid(m, ox, Z, Y, n, wall);                    /* x=1, normal -X */
  return m;
}

/* SH coefficients (3 bands) of L(d) = 1 + k*d.y by a fine midpoint quadrature
 * in (cos theta, phi) using only the basis evaluation. */
static void project_linear_sky(double k, cv_lighting *l) {
  memset(l, 0, sizeof *l);
  l->bands = 3;
  const int nt = 400, np = 800;
  double acc[9] = {0};
  for (int a = 0; a < nt; a++)
    for (int b = 0; b < np; b++) {
      double ct = -1 + 2 * (a + 0.5) / nt, st = sqrt(1 - ct * ct), ph = 2 * M_PI * (b + .5) / np;
      double d[3] = {st * cos(ph), ct, st * sin(ph)}, y[9];
      cv_sh_eval_d(3, d, y);
      double L = 1 + k * d[1], w = 4 * M_PI / ((double)nt * np);
      for (int i = 0; i < 9; i++) acc[i] += L * y[i] * w;
    }
  for (int i = 0; i < 9; i++)
    for (int c = 0; c < 3; c++) l->sh[3 * i + c] = acc[i];
}

static void constant_light(double L, int bands, cv_lighting *l) {
  memset(l, 0, sizeof *l);
  l->bands = bands;
  for (int c = 0; c < 3; c++) l->sh[c] = L * sqrt(4 * M_PI);
}


/* A textured quad under constant light L: the receiver's transfer is stored
 * without its own albedo (albedo 1), so the radiance per pixel is
 * texture(uv) x L; the PRT file keeps UVs and the texture reference, and
 * per-vertex outputs fold the material's mean albedo back in. */
static void test_textured_quad(void **state) {
  (void)state;
  char png[1024], path[1024];
  snprintf(png, sizeof png, "%s/quad_tex.png", CV_TEST_TMP_DIR);
  snprintf(path, sizeof path, "%s/quad_tex.prt", CV_TEST_TMP_DIR);
  uint8_t px[4 * 4 * 3];
  for (int i = 0; i < 48; i++) px[i] = (uint8_t)(17 * i % 256); /* every texel different */
  cv_err err;
  assert_int_equal(cv_png_write(png, 4, 4, 3, px, &err), CV_OK);
  cv_image *tex;
  assert_int_equal(cv_texture_load(png, &tex, &err), CV_OK);
  float mean[3] = {0, 0, 0};
  for (int i = 0; i < 16; i++)
    for (int c = 0; c < 3; c++) mean[c] += tex->px[3 * i + c] / 16;
  cv_mesh *m = plane_mesh(4, mean); /* the import gives a textured material its mean */
  assert_int_equal(cv_mesh_set_texture(m, 0, png), CV_OK);
  assert_int_equal(cv_mesh_enable_uv(m), CV_OK);
  for (size_t t = 0; t < m->nt; t++) /* u along e1 (z), v along e2 (x) */
    for (int k = 0; k < 3; k++) {
      const float *q = m->pos + 3 * m->tri[3 * t + k];
      m->tri_uv[6 * t + 2 * k] = (q[2] + 1) / 2;
      m->tri_uv[6 * t + 2 * k + 1] = (q[0] + 1) / 2;
    }
  cv_bake_params p = {.bands = 3, .rays = 256, .bounces = 1, .seed = 7, .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  cv_prt *prt;
  assert_int_equal(cv_prt_bake(m, &p, &prt, NULL, &err), CV_OK);
  assert_true(prt->flags & CV_PRT_TEXTURED);
  assert_int_equal(cv_prt_write(path, prt, &err), CV_OK);
  cv_prt_destroy(prt);
  assert_int_equal(cv_prt_read(path, &prt, &err), CV_OK);
  assert_true(prt->flags & CV_PRT_TEXTURED);
  assert_string_equal(prt->mat_tex[0], png);
  assert_memory_equal(prt->tri_uv, m->tri_uv, 6 * m->nt * sizeof(float));
  for (size_t i = 0; i < 3 * prt->nv; i++) assert_true(prt->albedo[i] == 1.0f);
  const double L = 2.0;
  cv_lighting l;
  constant_light(L, 3, &l);
  float *rad = malloc(3 * prt->nv * sizeof(float));
  assert_int_equal(cv_prt_relight(prt, &l, NULL, 0, rad, NULL), CV_OK);
  /* per pixel: the radiance interpolated at the texel centre (any triangle:
   * it is L everywhere) times the texture there equals texel x L */
  double worst = 0;
  for (int j = 0; j < 4; j++)
    for (int i = 0; i < 4; i++) {
      float a[3];
      cv_texture_sample(tex, (i + 0.5) / 4, 1.0 - (j + 0.5) / 4, a); /* row j from the top */
      for (int c = 0; c < 3; c++) {
        const float texel = tex->px[3 * (4 * j + i) + c];
        for (size_t v = 0; v < prt->nv; v++) {
          double e = fabs(rad[3 * v + c] * a[c] - texel * L) / (texel * L + 1e-3);
          worst = e > worst ? e : worst;
        }
      }
    }
  printf("textured quad: worst relative error of texture x irradiance %.2e\n", worst);
  assert_true(worst < 0.01);
  assert_int_equal(cv_prt_fold_texture_means(prt, rad), CV_OK);
  for (size_t v = 0; v < prt->nv; v++)
    for (int c = 0; c < 3; c++) assert_near(rad[3 * v + c] / (mean[c] * L), 1, 0.01);
  free(rad);
  /* version 1 files (no textures) are still read; version 1 with the texture
   * flag is refused */
  cv_prt_destroy(prt);
  cv_mesh *plain = plane_mesh(2, mean);
  assert_int_equal(cv_prt_bake(plain, &p, &prt, NULL, &err), CV_OK);
  assert_int_equal(cv_prt_write(path, prt, &err), CV_OK);
  cv_prt_destroy(prt);
  FILE *f = fopen(path, "r+b");
  assert_non_null(f);
  const uint32_t v1 = 1;
  assert_int_equal(fseek(f, 8, SEEK_SET), 0);
  assert_int_equal(fwrite(&v1, 4, 1, f), 1);
  fclose(f);
  assert_int_equal(cv_prt_read(path, &prt, &err), CV_OK);
  assert_null(prt->tri_uv);
  cv_prt_destroy(prt);
  f = fopen(path, "r+b");
  uint32_t flags;
  assert_int_equal(fseek(f, 20, SEEK_SET), 0);
  assert_int_equal(fread(&flags, 4, 1, f), 1);
  flags |= CV_PRT_TEXTURED;
  assert_int_equal(fseek(f, 20, SEEK_SET), 0);
  assert_int_equal(fwrite(&flags, 4, 1, f), 1);
  fclose(f);
  assert_int_equal(cv_prt_read(path, &prt, &err), CV_ERR_FORMAT);
  assert_non_null(strstr(err.msg, "version 1 has no textures"));
  cv_mesh_destroy(plain);
  cv_image_destroy(tex);
  cv_mesh_destroy(m);
}

static void test_unshadowed_plane(void **state) {
  (void)state;
  const float alb[3] = {0.5f, 0.3f, 0.8f};
  cv_mesh *m = plane_mesh(8, alb);
  cv_bake_params p = {.bands = 3, .rays = 256, .bounces = 1, .seed = 7, .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  cv_prt *prt;
  cv_err err;
  assert_int_equal(cv_prt_bake(m, &p, &prt, NULL, &err), CV_OK);
  float *rad = malloc(3 * prt->nv * sizeof(float));
  cv_lighting l;
  constant_light(2.0, 3, &l);
  assert_int_equal(cv_prt_relight(prt, &l, NULL, 0, rad, NULL), CV_OK);
  for (size_t v = 0; v < prt->nv; v++)
    for (int c = 0; c < 3; c++)
      assert_near(rad[3 * v + c] / (2.0 * alb[c]), 1, 0.005);
  /* Linear sky: irradiance pi*(1 + k*2/3) on an up-facing plane. */
  project_linear_sky(0.5, &l);
  assert_int_equal(cv_prt_relight(prt, &l, NULL, 0, rad, NULL), CV_OK);
  double worst = 0;
  for (size_t v = 0; v < prt->nv; v++)
    for (int c = 0; c < 3; c++) {
      double e = fabs(rad[3 * v + c] / (alb[c] * (1 + 0.5 * 2.0 / 3.0)) - 1);
      worst = e > worst ? e : worst;
    }
  printf("unshadowed plane, linear sky: worst relative error %.2e\n", worst);
  assert_true(worst < 0.005);
  /* Nothing to bounce off: the interreflected transfer is exactly zero. */
  for (size_t i = 0; i < 3 * prt->nv * 9; i++) assert_true(prt->ti[i] == 0.0f);
  free(rad);
  cv_prt_destroy(prt);
  cv_mesh_destroy(m);
}

static void test_furnace(void **state) {
  (void)state;
  const float a = 0.6f;
  cv_mesh *m = box_mesh(4, a, 0);
  cv_tracer *tr;
  assert_int_equal(cv_tracer_create(m, &tr, NULL), CV_OK);
  const int bands = 2, nc = 4, B = 4;
  float *prev = calloc(3 * m->nv * nc, sizeof(float)), *ti = calloc(3 * m->nv * nc, sizeof(float));
  const double t0 = 1.0 / sqrt(4 * M_PI);
  for (size_t v = 0; v < m->nv; v++)
    for (int c = 0; c < 3; c++) prev[(v * 3 + c) * nc] = (float)(a * t0);
  assert_int_equal(cv_prt_propagate(tr, bands, 128, 3, B, 1, prev, ti, NULL), CV_OK);
  double series = 0, ak = 1;
  for (int b = 1; b <= B; b++) series += (ak *= a);
  double worst = 0;
  for (size_t v = 0; v < m->nv; v++) {
    double got = ti[(v * 3) * nc] / (a * t0);
    double e = fabs(got / series - 1);
    worst = e > worst ? e : worst;
  }
  printf("furnace, %d bounces, a = %.1f: series %.6f, worst vertex error %.2e\n", B, a, series,
         worst);
  assert_true(worst < 0.01);
  free(prev);
  free(ti);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
}

/* The geometric tail of the missing bounces (bake.h, prt.tail).  Closed
 * furnace: successive bounces have the ratio a exactly, so
 * cv_prt_tail_ratio must find a (within the Monte Carlo noise, 1%).  Open
 * box (window on top, a = 0.6): the area-weighted DC of ti with 2 bounces
 * + tail within 1% of an 8-bounce bake (a^9 / (1 - a) ~ 2.5% of the series
 * left beyond 8), and closer than 2 bounces alone; 0 bounces: no effect. */
static void test_tail(void **state) {
  (void)state;
  const float a = 0.6f;
  cv_mesh *m = box_mesh(4, a, 0);
  cv_tracer *tr;
  assert_int_equal(cv_tracer_create(m, &tr, NULL), CV_OK);
  const int nc = 4;
  float *prev = calloc(3 * m->nv * nc, sizeof(float)), *ti = calloc(3 * m->nv * nc, sizeof(float));
  float *b0 = malloc(3 * m->nv * nc * sizeof(float));
  for (size_t v = 0; v < m->nv; v++)
    for (int c = 0; c < 3; c++) prev[(v * 3 + c) * nc] = (float)(a / sqrt(4 * M_PI));
  memcpy(b0, prev, 3 * m->nv * nc * sizeof(float));
  assert_int_equal(cv_prt_propagate(tr, 2, 256, 3, 1, 1, prev, ti, NULL), CV_OK);
  double r[3];
  assert_int_equal(cv_prt_tail_ratio(tr, 2, b0, prev, r), 0);
  printf("tail ratio in the furnace (a = %.1f): %.4f %.4f %.4f\n", a, r[0], r[1], r[2]);
  for (int c = 0; c < 3; c++) assert_near(r[c] / a, 1, 0.01);
  free(prev), free(ti), free(b0);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);

  m = box_mesh(6, a, 1);
  double dc[3];
  const int bounces[3] = {8, 2, 2}, tails[3] = {0, 0, 1};
  for (int k = 0; k < 3; k++) {
    cv_bake_params p = {.bands = 2, .rays = 512, .bounces = bounces[k], .seed = 5,
                        .spread = CV_BAKE_DEFAULT_SPREAD, .tail = tails[k], .quiet = 1};
    cv_prt *prt;
    cv_bake_stats bs;
    assert_int_equal(cv_prt_bake(m, &p, &prt, &bs, NULL), CV_OK);
    dc[k] = 0;
    for (size_t v = 0; v < prt->nv; v++) dc[k] += prt->ti[(v * 3) * 4];
    if (tails[k]) printf("open box: tail ratio %.4f\n", bs.tail_ratio[0]);
    cv_prt_destroy(prt);
  }
  printf("open box, sum of ti DC: 8 bounces %.5f, 2 bounces %.5f (%.2f%%), 2 + tail %.5f (%.2f%%)\n",
         dc[0], dc[1], 100 * (dc[1] / dc[0] - 1), dc[2], 100 * (dc[2] / dc[0] - 1));
  assert_near(dc[2] / dc[0], 1, 0.01);
  assert_near(dc[2] / dc[0], 1, 0.5 * fabs(dc[1] / dc[0] - 1));
  /* bounces = 0: the tail has nothing to extend (no ti). */
  cv_bake_params p0 = {.bands = 2, .rays = 16, .bounces = 0, .seed = 5,
                       .spread = CV_BAKE_DEFAULT_SPREAD, .tail = 1, .quiet = 1};
  cv_prt *prt0;
  assert_int_equal(cv_prt_bake(m, &p0, &prt0, NULL, NULL), CV_OK);
  assert_null(prt0->ti);
  cv_prt_destroy(prt0);
  cv_mesh_destroy(m);
}

/* xorshift64* for the independent reference */
static double rnd(uint64_t *s) {
  *s ^= *s >> 12;
  *s ^= *s << 25;
  *s ^= *s >> 27;
  return (double)((*s * 0x2545F4914F6CDD1DULL) >> 11) * 0x1p-53;
}

static void cos_dir(const double n[3], uint64_t *s, float d[3]) {
  double r1 = rnd(s), r2 = rnd(s), ph = 2 * M_PI * r1, st = sqrt(r2), ct = sqrt(1 - r2);
  double t[3], b[3];
  if (fabs(n[0]) > 0.5) {
    t[0] = n[1]; t[1] = -n[0]; t[2] = 0;
  } else {
    t[0] = 0; t[1] = n[2]; t[2] = -n[1];
  }
  double l = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
  for (int k = 0; k < 3; k++) t[k] /= l;
  b[0] = n[1] * t[2] - n[2] * t[1];
  b[1] = n[2] * t[0] - n[0] * t[2];
  b[2] = n[0] * t[1] - n[1] * t[0];
  for (int k = 0; k < 3; k++) d[k] = (float)(st * cos(ph) * t[k] + st * sin(ph) * b[k] + ct * n[k]);
}

/* Radiance leaving p (normal n) under a constant environment L = 1 with up
 * to `depth` further bounces, albedo a everywhere. */
static double path(const cv_rt *rt, const cv_mesh *m, const float p[3], const double n[3],
                   int depth, double a, uint64_t *s) {
  float d[3], o[3], nf[3] = {(float)n[0], (float)n[1], (float)n[2]};
  cos_dir(n, s, d);
  cv_rt_offset_origin(p, nf, o);
  if (cv_rt_reaches_env(rt, o, d, 0)) return a;
  if (depth == 0) return 0;
  cv_hit h;
  if (!cv_rt_intersect(rt, o, d, 0, INFINITY, &h)) return 0;
  float q[3];
  double nq[3], l = sqrt(h.ng[0] * h.ng[0] + h.ng[1] * h.ng[1] + h.ng[2] * h.ng[2]);
  for (int k = 0; k < 3; k++) {
    q[k] = o[k] + h.t * d[k];
    nq[k] = h.ng[k] / l;
  }
  (void)m;
  return a * path(rt, m, q, nq, depth - 1, a, s);
}

static void test_open_box_vs_brute_force(void **state) {
  (void)state;
  const float a = 0.6f;
  const int n = 16;
  cv_mesh *m = box_mesh(n, a, 1);
  cv_bake_params p = {.bands = 2, .rays = 1024, .bounces = 2, .seed = 11, .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  cv_tracer *tr;
  assert_int_equal(cv_tracer_create(m, &tr, NULL), CV_OK);
  cv_prt *prt;
  assert_int_equal(cv_prt_bake_tracer(tr, &p, &prt, NULL, NULL), CV_OK);
  float *rad = malloc(3 * prt->nv * sizeof(float));
  cv_lighting l;
  constant_light(1.0, 2, &l);
  assert_int_equal(cv_prt_relight(prt, &l, NULL, 0, rad, NULL), CV_OK);
  uint32_t centre = (uint32_t)((n / 2) * (n + 1) + n / 2); /* floor grid comes first */
  assert_near(m->pos[3 * centre], 0.5f, 1e-6f);
  assert_true(m->pos[3 * centre + 1] == 0.0f);
  uint64_t s = 0x9E3779B97F4A7C15ULL;
  const int N = 200000;
  double sum = 0, sum2 = 0;
  const double up[3] = {0, 1, 0};
  const float pc[3] = {0.5f, 0.0f, 0.5f};
  cv_rt_thread_init();
  for (int i = 0; i < N; i++) {
    double x = path(cv_tracer_rt(tr), m, pc, up, 2, a, &s);
    sum += x;
    sum2 += x * x;
  }
  double ref = sum / N, se = sqrt((sum2 / N - ref * ref) / N);
  double got = rad[3 * centre];
  printf("open box floor centre: PRT %.5f, brute force %.5f +- %.5f (%.2f%%)\n", got, ref, se,
         100 * (got / ref - 1));
  assert_near(got / ref, 1, 0.02);
  free(rad);
  cv_prt_destroy(prt);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
}

/* Dmitriev 4.1.1: a vertex just covered by an overlapping plate.  Shooting
 * from the vertex would see the plate right above it and go black; shooting
 * from points in its fan leaves it about half lit. */
static void test_overlap_no_leak(void **state) {
  (void)state;
  const float alb[3] = {0.5f, 0.5f, 0.5f};
  cv_mesh *m = plane_mesh(2, alb); /* vertices on a 3x3 grid, centre vertex 4 at (0,0,0) */
  uint32_t plate = 0;
  const float o[3] = {-3, 1e-4f, -3}, e1[3] = {0, 0, 6}, e2[3] = {3.01f, 0, 0};
  grid(m, o, e1, e2, 1, plate); /* covers x < 0.01 just above the floor */
  cv_bake_params p = {.bands = 2, .rays = 4096, .bounces = 0, .seed = 5, .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  cv_prt *prt;
  assert_int_equal(cv_prt_bake(m, &p, &prt, NULL, NULL), CV_OK);
  assert_true(prt->pos[3 * 4] == 0.0f && prt->pos[3 * 4 + 2] == 0.0f);
  double frac = prt->td[4 * 4] * sqrt(4 * M_PI); /* 1 = unshadowed */
  cv_prt_destroy(prt);
  p.spread = 1.0f; /* the paper's whole hat */
  assert_int_equal(cv_prt_bake(m, &p, &prt, NULL, NULL), CV_OK);
  double frac1 = prt->td[4 * 4] * sqrt(4 * M_PI);
  cv_prt_destroy(prt);
  p.spread = 0.0f; /* rays from the vertex itself: the leak the paper describes */
  assert_int_equal(cv_prt_bake(m, &p, &prt, NULL, NULL), CV_OK);
  double frac0 = prt->td[4 * 4] * sqrt(4 * M_PI);
  printf("slightly covered vertex, lit fraction: spread 0.5 %.3f, 1 %.3f, 0 (vertex) %.3f\n", frac,
         frac1, frac0);
  assert_true(frac > 0.45 && frac < 0.52);
  assert_true(frac1 > 0.46 && frac1 < 0.52);
  assert_true(frac0 < 0.01);
  cv_prt_destroy(prt);
  cv_mesh_destroy(m);
}

static void test_duplicate_and_degenerate(void **state) {
  (void)state;
  const float alb[3] = {0.4f, 0.4f, 0.4f};
  cv_mesh *m = plane_mesh(4, alb);
  size_t nt = m->nt;
  for (size_t t = 0; t < nt; t++) /* every triangle twice */
    cv_mesh_add_tri(m, m->tri[3 * t], m->tri[3 * t + 1], m->tri[3 * t + 2], m->tri_mat[t]);
  cv_mesh_add_tri(m, 0, 0, 1, 0);  /* collapsed */
  cv_mesh_add_tri(m, 0, 1, 2, 0);  /* collinear: zero area */
  cv_bake_params p = {.bands = 2, .rays = 256, .bounces = 1, .seed = 5, .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  cv_prt *prt;
  assert_int_equal(cv_prt_bake(m, &p, &prt, NULL, NULL), CV_OK);
  float *rad = malloc(3 * prt->nv * sizeof(float));
  cv_lighting l;
  constant_light(1.0, 2, &l);
  assert_int_equal(cv_prt_relight(prt, &l, NULL, 0, rad, NULL), CV_OK);
  for (size_t v = 0; v < prt->nv; v++) assert_near(rad[3 * v] / 0.4, 1, 0.005);
  free(rad);
  cv_prt_destroy(prt);
  cv_mesh_destroy(m);
}

static void test_determinism_and_file(void **state) {
  (void)state;
  cv_mesh *m = box_mesh(3, 0.5f, 1);
  cv_bake_params p = {.bands = 4, .rays = 64, .bounces = 2, .seed = 3, .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  cv_prt *a, *b, *c;
  omp_set_num_threads(1);
  assert_int_equal(cv_prt_bake(m, &p, &a, NULL, NULL), CV_OK);
  omp_set_num_threads(3);
  assert_int_equal(cv_prt_bake(m, &p, &b, NULL, NULL), CV_OK);
  size_t nc = 16;
  assert_memory_equal(a->td, b->td, a->nv * nc * sizeof(float));
  assert_memory_equal(a->ti, b->ti, 3 * a->nv * nc * sizeof(float));
  assert_true(a->meta.input_hash == b->meta.input_hash);
  p.seed = 4;
  assert_int_equal(cv_prt_bake(m, &p, &c, NULL, NULL), CV_OK);
  assert_true(memcmp(a->td, c->td, a->nv * nc * sizeof(float)) != 0);
  assert_true(a->meta.input_hash != c->meta.input_hash);

  char path[512];
  snprintf(path, sizeof path, "%s/roundtrip.prt", CV_TEST_TMP_DIR);
  cv_err err;
  assert_int_equal(cv_prt_write(path, a, &err), CV_OK);
  cv_prt *r;
  assert_int_equal(cv_prt_read(path, &r, &err), CV_OK);
  assert_int_equal(r->bands, 4);
  assert_memory_equal(r->td, a->td, a->nv * nc * sizeof(float));
  assert_memory_equal(r->ti, a->ti, 3 * a->nv * nc * sizeof(float));
  assert_memory_equal(r->mats, a->mats, a->nm * sizeof(cv_material));
  uint64_t h;
  assert_int_equal(cv_prt_read_input_hash(path, &h, &err), CV_OK);
  assert_true(h == a->meta.input_hash);
  cv_prt_destroy(r);

  /* Truncated and corrupted files are rejected with the file name. */
  FILE *f = fopen(path, "rb");
  fseek(f, 0, SEEK_END);
  long size = ftell(f);
  fseek(f, 0, SEEK_SET);
  unsigned char *buf = malloc(size);
  assert_int_equal(fread(buf, 1, size, f), (size_t)size);
  fclose(f);
  char bad[512];
  snprintf(bad, sizeof bad, "%s/bad.prt", CV_TEST_TMP_DIR);
  long cuts[3] = {10, 128, size - 7};
  for (int k = 0; k < 3; k++) {
    f = fopen(bad, "wb");
    fwrite(buf, 1, cuts[k], f);
    fclose(f);
    assert_int_equal(cv_prt_read(bad, &r, &err), CV_ERR_FORMAT);
    assert_non_null(strstr(err.msg, "bad.prt"));
  }
  buf[size / 2] ^= 0x40;
  f = fopen(bad, "wb");
  fwrite(buf, 1, size, f);
  fclose(f);
  assert_int_equal(cv_prt_read(bad, &r, &err), CV_ERR_FORMAT);
  assert_non_null(strstr(err.msg, "corrupt"));
  assert_int_equal(cv_prt_read_input_hash("/nonexistent/x.prt", &h, &err), CV_ERR_NOT_FOUND);
  free(buf);
  cv_prt_destroy(a);
  cv_prt_destroy(b);
  cv_prt_destroy(c);
  cv_mesh_destroy(m);
}

static void test_sun_direct(void **state) {
  (void)state;
  const float alb[3] = {0.5f, 0.25f, 1.0f};
  cv_mesh *m = plane_mesh(2, alb);
  cv_tracer *tr;
  assert_int_equal(cv_tracer_create(m, &tr, NULL), CV_OK);
  cv_bake_params p = {.bands = 3, .rays = 64, .bounces = 0, .seed = 1, .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  cv_prt *prt;
  assert_int_equal(cv_prt_bake_tracer(tr, &p, &prt, NULL, NULL), CV_OK);
  cv_lighting l;
  constant_light(0.0, 3, &l);
  l.has_sun = 1;
  double el = 30 * M_PI / 180; /* cos(theta) = sin(30 deg) = 0.5 */
  l.sun_dir[0] = cos(el);
  l.sun_dir[1] = sin(el);
  l.sun_E[0] = l.sun_E[1] = l.sun_E[2] = 1000;
  float *rad = malloc(3 * prt->nv * sizeof(float));
  assert_int_equal(cv_prt_relight(prt, &l, tr, 16, rad, NULL), CV_OK);
  for (size_t v = 0; v < prt->nv; v++)
    for (int c = 0; c < 3; c++)
      assert_near(rad[3 * v + c], alb[c] * 1000 * 0.5 / M_PI, 1e-3 * 1000 * alb[c]);
  /* Sun below the plane: nothing. */
  l.sun_dir[1] = -0.5;
  assert_int_equal(cv_prt_relight(prt, &l, tr, 16, rad, NULL), CV_OK);
  for (size_t i = 0; i < 3 * prt->nv; i++) assert_true(rad[i] == 0.0f);
  free(rad);
  cv_prt_destroy(prt);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
}

static void test_bad_params(void **state) {
  (void)state;
  const float alb[3] = {0.5f, 0.5f, 0.5f};
  cv_mesh *m = plane_mesh(1, alb);
  cv_prt *prt;
  cv_err err;
  cv_bake_params p = {.bands = 9, .rays = 16, .bounces = 0, .seed = 1, .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  assert_int_equal(cv_prt_bake(m, &p, &prt, NULL, &err), CV_ERR_RANGE);
  assert_non_null(strstr(err.msg, "prt.bands"));
  p.bands = 3;
  p.rays = 0;
  assert_int_equal(cv_prt_bake(m, &p, &prt, NULL, &err), CV_ERR_RANGE);
  assert_non_null(strstr(err.msg, "prt.rays"));
  cv_mesh_destroy(m);
}

/* CIE overcast sky (1 + 2 cos t)/3 on an up-facing plane: E = 7 pi / 9,
 * so radiance = albedo * 7/9; 5 bands carry it to well under 1%. */
static void test_cie_overcast(void **state) {
  (void)state;
  const float alb[3] = {0.5f, 0.5f, 0.5f};
  cv_mesh *m = plane_mesh(2, alb);
  cv_bake_params p = {.bands = 5, .rays = 1024, .bounces = 0, .seed = 2, .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  cv_prt *prt;
  assert_int_equal(cv_prt_bake(m, &p, &prt, NULL, NULL), CV_OK);
  cv_lighting l;
  cv_lighting_cie_overcast(5, &l);
  float rad[3 * 9];
  assert_int_equal(cv_prt_relight(prt, &l, NULL, 0, rad, NULL), CV_OK);
  for (int v = 0; v < 9; v++) {
    double e = rad[3 * v] / (0.5 * 7.0 / 9.0) - 1;
    assert_near(e, 0, 0.01);
  }
  cv_prt_destroy(prt);
  cv_mesh_destroy(m);
}

/* auto: a loose budget is met cheaply, a tighter one needs more rays or
 * bands, an impossible one is flagged and answered with the most accurate
 * candidate; the reported error of a pick within budget is within it. */
static void test_auto_select(void **state) {
  (void)state;
  cv_mesh *m = box_mesh(6, 0.5f, 1);
  cv_tracer *tr;
  assert_int_equal(cv_tracer_create(m, &tr, NULL), CV_OK);
  cv_auto_result loose, tight, impossible;
  assert_int_equal(cv_prt_auto_select(tr, NULL, 0.3, 1, 0, 0, &loose), CV_OK);
  assert_int_equal(cv_prt_auto_select(tr, NULL, 0.03, 1, 0, 0, &tight), CV_OK);
  assert_int_equal(cv_prt_auto_select(tr, NULL, 1e-6, 1, 0, 0, &impossible), CV_OK);
  printf("auto: budget 30%% -> %d bands %d rays (%.2f%%); 3%% -> %d bands %d rays (%.2f%%)\n",
         loose.bands, loose.rays, 100 * loose.est_error, tight.bands, tight.rays,
         100 * tight.est_error);
  assert_true(loose.met_budget && loose.est_error <= 0.3);
  assert_true(tight.met_budget && tight.est_error <= 0.03);
  assert_true(tight.rays * (1 + 0.03 * tight.bands * tight.bands) >
              loose.rays * (1 + 0.03 * loose.bands * loose.bands));
  assert_false(impossible.met_budget);
  for (int i = 0; i < impossible.n_cand; i++)
    assert_true(impossible.est_error <= impossible.cand[i].error);
  /* Pinned parameters are respected. */
  cv_auto_result pinned;
  assert_int_equal(cv_prt_auto_select(tr, NULL, 0.05, 1, 4, 0, &pinned), CV_OK);
  assert_int_equal(pinned.bands, 4);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
}

/* Window importance sampling: same expectation as cosine sampling (both
 * against a 32768-ray cosine reference on the floor and walls of a box whose
 * top is a small window), and lower noise at 256 rays. */
static void test_window_mis(void **state) {
  (void)state;
  cv_mesh *m;
  cv_mesh_create(&m);
  const float alb[3] = {0.5f, 0.5f, 0.5f}, zero[3] = {0, 0, 0};
  uint32_t wall, win;
  cv_mesh_add_material(m, "wall", alb, 0, &wall);
  cv_mesh_add_material(m, "window_small", zero, CV_MAT_WINDOW, &win);
  const float X[3] = {1, 0, 0}, Y[3] = {0, 1, 0}, Z[3] = {0, 0, 1};
  const float o0[3] = {0, 0, 0}, ox[3] = {1, 0, 0}, oz[3] = {0, 0, 1};
  grid(m, o0, Z, X, 8, wall); /* floor */
  grid(m, o0, X, Y, 8, wall);
  grid(m, oz, Y, X, 8, wall);
  grid(m, o0, Y, Z, 8, wall);
  grid(m, ox, Z, Y, 8, wall);
  /* top: a 4x4 grid whose 2x2 centre cells are the window (0.25 m^2) */
  const float sx[3] = {0.25f, 0, 0}, sz[3] = {0, 0, 0.25f};
  for (int i = 0; i < 4; i++)
    for (int k = 0; k < 4; k++) {
      float o[3] = {0.25f * i, 1, 0.25f * k};
      grid(m, o, sx, sz, 1, (i == 1 || i == 2) && (k == 1 || k == 2) ? win : wall);
    }
  (void)Y;
  cv_tracer *tr;
  assert_int_equal(cv_tracer_create(m, &tr, NULL), CV_OK);
  const size_t nv = 81 * 5; /* floor and walls */
  uint32_t *verts = malloc(nv * sizeof(uint32_t));
  for (size_t k = 0; k < nv; k++) verts[k] = (uint32_t)k;
  float *ref = malloc(nv * 4 * sizeof(float)), *mis = malloc(nv * 4 * sizeof(float)),
        *cos_ = malloc(nv * 4 * sizeof(float)), *mis_hi = malloc(nv * 4 * sizeof(float));
  cv_tracer_set_window_sampling(tr, 0);
  cv_bake_direct_subset(tr, 2, 32768, 100, verts, nv, ref);
  cv_bake_direct_subset(tr, 2, 256, 1, verts, nv, cos_);
  cv_tracer_set_window_sampling(tr, 1);
  assert_true(cv_tracer_window_sampling(tr));
  cv_bake_direct_subset(tr, 2, 256, 1, verts, nv, mis);
  cv_bake_direct_subset(tr, 2, 32768, 7, verts, nv, mis_hi);
  double e_mis = 0, e_cos = 0, e_hi = 0, r2 = 0, s_ref = 0, s_hi = 0;
  for (size_t k = 0; k < nv * 4; k++) {
    e_mis += (mis[k] - ref[k]) * (mis[k] - ref[k]);
    e_cos += (cos_[k] - ref[k]) * (cos_[k] - ref[k]);
    e_hi += (mis_hi[k] - ref[k]) * (mis_hi[k] - ref[k]);
    r2 += ref[k] * ref[k];
  }
  for (size_t k = 0; k < nv; k++) {
    s_ref += ref[4 * k];
    s_hi += mis_hi[4 * k];
  }
  printf("window MIS, 256 rays: %.2f%% vs cosine %.2f%%; 32768 rays MIS vs cosine: %.2f%% "
         "(mean coefficient 0 differs by %.3f%%)\n",
         100 * sqrt(e_mis / r2), 100 * sqrt(e_cos / r2), 100 * sqrt(e_hi / r2),
         100 * (s_hi / s_ref - 1));
  assert_near(s_hi / s_ref, 1, 0.003); /* same expectation */
  assert_true(sqrt(e_hi / r2) < 0.02);
  assert_true(e_mis < 0.5 * e_cos);            /* at least 2x lower variance */
  free(verts);
  free(ref);
  free(mis);
  free(cos_);
  free(mis_hi);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
}

/* Writes bytes to path (test helper). */
static void write_bytes(const char *path, const void *b, size_t n) {
  FILE *f = fopen(path, "wb");
  assert_non_null(f);
  assert_int_equal(fwrite(b, 1, n, f), n);
  fclose(f);
}

/* Hostile .prt files: header counts far beyond the file's size are refused
 * before any allocation, naming the count; NaN or non-unit normals, negative
 * albedo and NaN transfer are refused naming the vertex and the field. */
/* The bounce passes' half-float records: every value back within 2^-12 of its
 * record's largest |value| (round to nearest), zeros and signs exact, records
 * independent of each other. */
static void test_bounce_records(void **state) {
  (void)state;
  enum { B = 5, REC = 3 * B * B, NV = 4 };
  cv_bounce_records *r;
  assert_int_equal(cv_bounce_records_create(B, NV, &r), CV_OK);
  float val[NV][REC], back[REC];
  uint32_t x = 7u;
  for (int v = 0; v < NV; v++)
    for (int i = 0; i < REC; i++) {
      x ^= x << 13, x ^= x >> 17, x ^= x << 5;
      float u = (float)(x >> 8) / 16777216.0f;
      /* v 0: zero record; 1: values in [0, 3); 2: signed, spanning 1e-9..1;
       * 3: one large value over tiny ones (tiny ones fall in half denormals) */
      val[v][i] = v == 0 ? 0.0f
                  : v == 1 ? 3.0f * u
                  : v == 2 ? (i % 2 ? -1.0f : 1.0f) * powf(10.0f, -9.0f * u)
                           : (i == 7 ? 5.0f : 1e-6f * u);
    }
  for (int v = 0; v < NV; v++) cv_bounce_records_set(r, (size_t)v, val[v]);
  for (int v = 0; v < NV; v++) {
    float mx = 0;
    for (int i = 0; i < REC; i++) mx = fmaxf(mx, fabsf(val[v][i]));
    cv_bounce_records_get(r, (size_t)v, back);
    for (int i = 0; i < REC; i++) {
      assert_near(back[i], val[v][i], mx * 0x1p-12f);
      if (val[v][i] == 0.0f) assert_true(back[i] == 0.0f);
      else assert_true(back[i] == 0.0f || (back[i] > 0) == (val[v][i] > 0));
    }
  }
  cv_bounce_records_destroy(r);
  assert_int_equal(cv_bounce_records_create(0, NV, &r), CV_ERR_RANGE);
}

/* Half denormals (values below 2^-14 of the record's largest): rounded to the
 * nearest multiple of 2^-24 of it, and read back exactly also with the bake
 * threads' flush-to-zero / denormals-are-zero on.  (They once came out 2^9
 * times too small, then read as 0 under DAZ.) */
static void test_bounce_records_denormal(void **state) {
  (void)state;
  enum { B = 3, REC = 3 * B * B };
  cv_bounce_records *r;
  assert_int_equal(cv_bounce_records_create(B, 1, &r), CV_OK);
  float val[REC], back[REC];
  val[0] = 1.0f;
  for (int i = 1; i < REC; i++) /* 2^-14 down to 2^-27, both signs, odd mantissas */
    val[i] = (i % 2 ? 1.0f : -1.0f) * ldexpf(1.0f + 0.37f * (float)(i % 3), -14 - (i % 14));
  for (int daz = 0; daz < 2; daz++) {
    if (daz) cv_rt_thread_init();
    cv_bounce_records_set(r, 0, val);
    cv_bounce_records_get(r, 0, back);
    for (int i = 1; i < REC; i++) {
      const double want = nearbyint((double)val[i] * 0x1p24) * 0x1p-24; /* ties to even */
      if (fabs(val[i]) < 0x1p-14) assert_true(back[i] == (float)want);
      else assert_near(back[i], val[i], 0x1p-25f);
    }
  }
  cv_bounce_records_destroy(r);
}

/* The bounce pass's AVX2 + F16C sums and the portable ones give the same
 * bits (with the bake's FTZ/DAZ on, records with half denormals). */
static void test_bounce_simd_equal(void **state) {
  (void)state;
  enum { B = 5, REC = 3 * B * B };
  cv_mesh *m = box_mesh(4, 0.5f, 1);
  cv_tracer *tr;
  assert_int_equal(cv_tracer_create(m, &tr, NULL), CV_OK);
  const size_t nv = cv_tracer_vertex_count(tr);
  cv_bounce_records *rec;
  assert_int_equal(cv_bounce_records_create(B, nv, &rec), CV_OK);
  float *val = malloc(REC * sizeof(float)), *a = malloc(nv * REC * sizeof(float)),
        *b = malloc(nv * REC * sizeof(float));
  uint32_t *verts = malloc(nv * sizeof(uint32_t)), x = 11u;
  for (size_t v = 0; v < nv; v++) {
    for (int i = 0; i < REC; i++) {
      x ^= x << 13, x ^= x >> 17, x ^= x << 5;
      const float u = (float)(x >> 8) / 16777216.0f;
      val[i] = i % 5 == 0 ? ldexpf(u, -20) : (i % 2 ? u : -0.3f * u);
    }
    cv_bounce_records_set(rec, v, val);
    verts[v] = (uint32_t)v;
  }
  const int simd = cv_tracer_set_simd(tr, 1);
  print_message("bounce sums: %s\n", simd ? "AVX2 + F16C" : "portable only (no AVX2/F16C)");
  for (int rays = 16; rays <= 37; rays += 21) { /* whole packets, then a partial one */
    cv_tracer_set_simd(tr, 1);
    assert_int_equal(cv_bake_bounce_subset(tr, B, rays, 9, rec, verts, nv, a), CV_OK);
    assert_int_equal(cv_tracer_set_simd(tr, 0), 0);
    assert_int_equal(cv_bake_bounce_subset(tr, B, rays, 9, rec, verts, nv, b), CV_OK);
    assert_memory_equal(a, b, nv * REC * sizeof(float));
    double s = 0;
    for (size_t i = 0; i < nv * REC; i++) s += fabs(a[i]);
    assert_true(s > 0);
  }
  free(val);
  free(a);
  free(b);
  free(verts);
  cv_bounce_records_destroy(rec);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
}

static void test_hostile_files(void **state) {
  (void)state;
  const float alb[3] = {0.5f, 0.5f, 0.5f};
  cv_mesh *m = plane_mesh(2, alb);
  cv_bake_params p = {.bands = 3, .rays = 16, .bounces = 1, .seed = 1, .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  cv_prt *a, *r = NULL;
  cv_err err;
  assert_int_equal(cv_prt_bake(m, &p, &a, NULL, &err), CV_OK);
  char path[512];
  snprintf(path, sizeof path, "%s/hostile.prt", CV_TEST_TMP_DIR);
  assert_int_equal(cv_prt_write(path, a, &err), CV_OK);
  FILE *f = fopen(path, "rb");
  unsigned char buf[1 << 16];
  size_t size = fread(buf, 1, sizeof buf, f);
  fclose(f);
  assert_true(size > 128 && size < sizeof buf);

  /* nv at byte 24, nt at 32, nm at 40 (docs/prt-format.md). */
  const struct { size_t off; uint64_t v; const char *want; } lie[] = {
      {24, 1ull << 30, "nv 1073741824 vertices"},
      {32, 1ull << 32, "nt 4294967296 triangles"},
      {40, 1ull << 20, "nm 1048576 materials"},
      {24, 1, "need a"},
  };
  for (size_t k = 0; k < sizeof lie / sizeof lie[0]; k++) {
    unsigned char b[1 << 16];
    memcpy(b, buf, size);
    memcpy(b + lie[k].off, &lie[k].v, 8);
    write_bytes(path, b, size);
    assert_int_equal(cv_prt_read(path, &r, &err), CV_ERR_FORMAT);
    assert_null(r);
    assert_non_null(strstr(err.msg, "hostile.prt"));
    assert_non_null(strstr(err.msg, lie[k].want));
    assert_non_null(strstr(err.msg, "the file has"));
  }

  /* Bad records, written with a valid hash so only the record check can catch them. */
  const struct { float *field; float v; int status; const char *want; } bad[] = {
      {&a->nrm[3 * 1 + 2], NAN, CV_ERR_NONFINITE, "vertex 1 normal.z is nan, expected finite"},
      {&a->nrm[3 * 2 + 0], a->nrm[3 * 2 + 0] + 0.5f, CV_ERR_RANGE, "vertex 2 normal"},
      {&a->albedo[3 * 3 + 1], -0.25f, CV_ERR_RANGE, "vertex 3 albedo.g is -0.25, expected in [0, 1]"},
      {&a->albedo[0], 1.5f, CV_ERR_RANGE, "vertex 0 albedo.r is 1.5"},
      {&a->pos[4], INFINITY, CV_ERR_NONFINITE, "vertex 1 position.y is inf"},
      {&a->td[5], NAN, CV_ERR_NONFINITE, "direct transfer coefficient"},
      {&a->ti[7], NAN, CV_ERR_NONFINITE, "indirect transfer"},
  };
  for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
    float keep = *bad[k].field;
    *bad[k].field = bad[k].v;
    assert_int_equal(cv_prt_write(path, a, &err), CV_OK);
    *bad[k].field = keep;
    assert_int_equal(cv_prt_read(path, &r, &err), bad[k].status);
    assert_null(r);
    if (!strstr(err.msg, bad[k].want)) fail_msg("message '%s' lacks '%s'", err.msg, bad[k].want);
  }
  /* A zero normal (a vertex no triangle faces) is allowed. */
  memset(&a->nrm[0], 0, 3 * sizeof(float));
  assert_int_equal(cv_prt_write(path, a, &err), CV_OK);
  assert_int_equal(cv_prt_read(path, &r, &err), CV_OK);
  cv_prt_destroy(r);
  cv_prt_destroy(a);
  cv_mesh_destroy(m);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_unshadowed_plane),
      cmocka_unit_test(test_furnace), cmocka_unit_test(test_tail),
      cmocka_unit_test(test_open_box_vs_brute_force),
      cmocka_unit_test(test_overlap_no_leak),
      cmocka_unit_test(test_duplicate_and_degenerate),
      cmocka_unit_test(test_determinism_and_file),
      cmocka_unit_test(test_sun_direct),
      cmocka_unit_test(test_bad_params),
      cmocka_unit_test(test_cie_overcast),
      cmocka_unit_test(test_auto_select),
      cmocka_unit_test(test_window_mis),
      cmocka_unit_test(test_hostile_files),
      cmocka_unit_test(test_textured_quad),
      cmocka_unit_test(test_bounce_records),
      cmocka_unit_test(test_bounce_records_denormal),
      cmocka_unit_test(test_bounce_simd_equal),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
