/* The reference path tracer (src/ref) against closed forms:
 *  - furnace: a closed box of albedo a whose walls emit Le has radiance
 *    Le (1 + a + ... + a^N) with N bounces, Le / (1 - a) until roulette (1%);
 *  - a lone plane under a constant sky: albedo * L (1%);
 *  - a lone plane under a map with a hot spot: (a / pi) sum_pixels L cos
 *    dOmega by exact per-row quadrature (1%): checks the alias table's pdf;
 *  - a lone plane under a sun: (a / pi) E cos exactly;
 *  - the open box of tests/prt (window on top, constant sky): floor centre
 *    against the PRT bake of the same box (2%);
 *  - the same seed gives the same image for 1 and 2 threads; bad input;
 *  - window-light splitting (prt/scene_light): the split lights carry the
 *    energy they remove, and on the open box under a map with a bright patch
 *    above the window the split brings the PRT closer to the reference;
 *  - --pixel-lights: the sun per pixel (prt/shade_view) draws a floating
 *    box's shadow as Embree visibility does (>= 99% of the floor pixels),
 *    interpolated per vertex it does not. */
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

#include "io/exr.h"
#include "mesh/clean.h"
#include "prt/bake.h"
#include "prt/relight.h"
#include "prt/scene_light.h"
#include "prt/shade_view.h"
#include "ref/ref.h"

/* n x n grid of quads over o + s e1 + t e2; normal e1 x e2. */
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

static cv_mesh *plane_mesh(const float albedo[3]) {
  cv_mesh *m;
  cv_mesh_create(&m);
  uint32_t mat;
  cv_mesh_add_material(m, "floor", albedo, 0, &mat);
  const float o[3] = {-1, 0, -1}, e1[3] = {0, 0, 2}, e2[3] = {2, 0, 0};
  grid(m, o, e1, e2, 4, mat);
  return m;
}

/* Unit cube [0,1]^3, inward normals; top face a window if asked. */
static cv_mesh *box_mesh(int n, float a, int top_window) {
  cv_mesh *m;
  cv_mesh_create(&m);
  const float alb[3] = {a, a, a}, zero[3] = {0, 0, 0};
  uint32_t wall, win;
  cv_mesh_add_material(m, "wall", alb, 0, &wall);
  cv_mesh_add_material(m, "window_top", zero, CV_MAT_WINDOW, &win);
  const float X[3] = {1, 0, 0}, Y[3] = {0, 1, 0}, Z[3] = {0, 0, 1};
  const float o0[3] = {0, 0, 0}, ox[3] = {1, 0, 0}, oy[3] = {0, 1, 0}, oz[3] = {0, 0, 1};
  grid(m, o0, Z, X, n, wall);
  grid(m, oy, X, Z, n, top_window ? win : wall);
  grid(m, o0, X, Y, n, wall);
  grid(m, oz, Y, X, n, wall);
  grid(m, o0, Y, Z, n, wall);
  grid(m, ox, Z, Y, n, wall);
  return m;
}

static cv_ref_light *constant_light(double r, double g, double b) {
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  spec.kind = CV_LIGHT_CONSTANT;
  spec.constant[0] = r;
  spec.constant[1] = g;
  spec.constant[2] = b;
  cv_ref_light *l = NULL;
  assert_int_equal(cv_ref_light_build(&spec, &l, NULL), CV_OK);
  return l;
}

/* Mean of a rendered image (double). */
static void image_mean(const cv_image *img, double m[3]) {
  m[0] = m[1] = m[2] = 0;
  size_t n = (size_t)img->w * img->h;
  for (size_t i = 0; i < n; i++)
    for (int c = 0; c < 3; c++) m[c] += img->px[3 * i + c];
  for (int c = 0; c < 3; c++) m[c] /= (double)n;
}

static void render_mean(const cv_ref_scene *s, const cv_ref_light *l, const cv_ref_camera *cam,
                        const cv_ref_params *p, double m[3]) {
  cv_image *img;
  assert_int_equal(cv_image_create(cam->w, cam->h, 3, &img), CV_OK);
  cv_ref_stats st;
  assert_int_equal(cv_ref_render(s, l, cam, p, img, NULL, &st, NULL), CV_OK);
  assert_int_equal(st.nonfinite, 0);
  image_mean(img, m);
  cv_image_destroy(img);
}

static void test_furnace(void **state) {
  (void)state;
  const float a = 0.5f;
  cv_mesh *m = box_mesh(2, a, 0);
  cv_ref_scene *s;
  assert_int_equal(cv_ref_scene_create(m, &s, NULL), CV_OK);
  cv_ref_light *l = constant_light(0, 0, 0);
  cv_ref_camera cam = {.eye = {0.5, 0.5, 0.5}, .look = {0.5, 0.5, 0}, .up = {0, 1, 0},
                       .fov_deg = 120, .w = 16, .h = 16};
  cv_ref_params p;
  cv_ref_params_default(&p);
  p.spp = 256;
  p.pass_spp = 256;
  p.quiet = 1;
  p.emission[0] = p.emission[1] = p.emission[2] = 1.0;
  for (int B = -1; B <= 3; B++) {
    p.bounces = B;
    double expect = 0, ak = 1, mean[3];
    if (B < 0) expect = 1 / (1 - a);
    else
      for (int k = 0; k <= B; k++, ak *= a) expect += ak;
    render_mean(s, l, &cam, &p, mean);
    printf("furnace a = %.1f, bounces %d: %.5f, series %.5f (%.3f%%)\n", a, B, mean[0], expect,
           100 * (mean[0] / expect - 1));
    for (int c = 0; c < 3; c++) assert_near(mean[c] / expect, 1, 0.01);
  }
  cv_ref_light_destroy(l);
  cv_ref_scene_destroy(s);
  cv_mesh_destroy(m);
}

static void test_plane_constant_sky(void **state) {
  (void)state;
  const float alb[3] = {0.5f, 0.3f, 0.8f};
  const double L[3] = {1.0, 2.0, 0.5};
  cv_mesh *m = plane_mesh(alb);
  cv_ref_scene *s;
  assert_int_equal(cv_ref_scene_create(m, &s, NULL), CV_OK);
  cv_ref_light *l = constant_light(L[0], L[1], L[2]);
  cv_ref_camera cam = {.eye = {0, 1, 0}, .look = {0, 0, 0}, .up = {0, 0, -1}, .fov_deg = 30,
                       .w = 8, .h = 8};
  cv_ref_params p;
  cv_ref_params_default(&p);
  p.spp = 512;
  p.quiet = 1;
  double mean[3];
  render_mean(s, l, &cam, &p, mean);
  for (int c = 0; c < 3; c++) {
    printf("plane, constant sky, channel %d: %.5f, expected %.5f\n", c, mean[c], alb[c] * L[c]);
    assert_near(mean[c] / (alb[c] * L[c]), 1, 0.01);
  }
  cv_ref_light_destroy(l);
  cv_ref_scene_destroy(s);
  cv_mesh_destroy(m);
}

static void test_plane_hot_map(void **state) {
  (void)state;
  const float alb[3] = {0.6f, 0.6f, 0.6f};
  cv_mesh *m = plane_mesh(alb);
  cv_ref_scene *s;
  assert_int_equal(cv_ref_scene_create(m, &s, NULL), CV_OK);
  const int w = 64, h = 32;
  cv_envmap *env;
  assert_int_equal(cv_envmap_create(w, h, &env), CV_OK);
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      float *px = cv_image_at(env->img, x, y);
      double v = 0.2 + 0.8 * (double)x / w + 0.3 * y / h;
      px[0] = (float)v;
      px[1] = (float)(0.5 * v);
      px[2] = (float)(1.5 - v);
    }
  float *hot = cv_image_at(env->img, 40, 6); /* a small, very bright "sun" */
  hot[0] = hot[1] = hot[2] = 2000.0f;
  /* Expected radiance of the up-facing plane: (a/pi) sum L * integral of
   * cos(theta) over each pixel of the upper half (rows 0..h/2-1). */
  double expect[3] = {0};
  for (int y = 0; y < h / 2; y++) {
    double t0 = M_PI * y / h, t1 = M_PI * (y + 1) / h;
    double wcos = (2 * M_PI / w) * 0.5 * (sin(t1) * sin(t1) - sin(t0) * sin(t0));
    for (int x = 0; x < w; x++)
      for (int c = 0; c < 3; c++) expect[c] += cv_image_at(env->img, x, y)[c] * wcos;
  }
  for (int c = 0; c < 3; c++) expect[c] *= alb[c] / M_PI;
  cv_ref_light *l;
  assert_int_equal(cv_ref_light_from_map(env, NULL, &l, NULL), CV_OK);
  cv_ref_camera cam = {.eye = {0, 1, 0}, .look = {0, 0, 0}, .up = {0, 0, -1}, .fov_deg = 30,
                       .w = 8, .h = 8};
  cv_ref_params p;
  cv_ref_params_default(&p);
  p.spp = 1024;
  p.pass_spp = 1024;
  p.quiet = 1;
  double mean[3];
  render_mean(s, l, &cam, &p, mean);
  for (int c = 0; c < 3; c++) {
    printf("plane, map with a hot pixel, channel %d: %.5f, quadrature %.5f (%.3f%%)\n", c,
           mean[c], expect[c], 100 * (mean[c] / expect[c] - 1));
    assert_near(mean[c] / expect[c], 1, 0.01);
  }
  cv_ref_light_destroy(l);
  cv_envmap_destroy(env);
  cv_ref_scene_destroy(s);
  cv_mesh_destroy(m);
}

static void test_plane_sun(void **state) {
  (void)state;
  const float alb[3] = {0.5f, 0.25f, 0.75f};
  cv_mesh *m = plane_mesh(alb);
  cv_ref_scene *s;
  assert_int_equal(cv_ref_scene_create(m, &s, NULL), CV_OK);
  cv_envmap *black;
  assert_int_equal(cv_envmap_create(16, 8, &black), CV_OK);
  cv_ref_light *l;
  assert_int_equal(cv_ref_light_from_map(black, NULL, &l, NULL), CV_OK);
  const double el = 60 * M_PI / 180, dir[3] = {cos(el), sin(el), 0}, E[3] = {1000, 2000, 500};
  cv_ref_light_set_sun(l, dir, E);
  double mean[3], se[3];
  cv_ref_params p;
  cv_ref_params_default(&p);
  const double org[3] = {0.1, 1, 0.2}, d[3] = {0, -1, 0};
  assert_int_equal(cv_ref_radiance(s, l, &p, org, d, 64, mean, se, NULL), CV_OK);
  for (int c = 0; c < 3; c++) {
    double e = alb[c] / M_PI * E[c] * sin(el);
    printf("plane under a sun, channel %d: %.6f, expected %.6f\n", c, mean[c], e);
    assert_near(mean[c] / e, 1, 1e-5);
  }
  cv_ref_light_destroy(l);
  cv_envmap_destroy(black);
  cv_ref_scene_destroy(s);
  cv_mesh_destroy(m);
}

static void test_open_box_vs_bake(void **state) {
  (void)state;
  const float a = 0.6f;
  const int n = 16;
  cv_mesh *m = box_mesh(n, a, 1);
  /* The bake's value (tests/prt checks it against its own brute force). */
  cv_bake_params bp = {.bands = 2, .rays = 1024, .bounces = 2, .seed = 11,
                       .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  cv_prt *prt;
  assert_int_equal(cv_prt_bake(m, &bp, &prt, NULL, NULL), CV_OK);
  float *rad = malloc(3 * prt->nv * sizeof(float));
  cv_lighting lt;
  memset(&lt, 0, sizeof lt);
  lt.bands = 2;
  for (int c = 0; c < 3; c++) lt.sh[c] = sqrt(4 * M_PI);
  assert_int_equal(cv_prt_relight(prt, &lt, NULL, 0, rad, NULL), CV_OK);
  uint32_t centre = (uint32_t)((n / 2) * (n + 1) + n / 2);
  assert_near(prt->pos[3 * centre], 0.5f, 1e-6f);
  assert_true(prt->pos[3 * centre + 1] == 0.0f);
  double bake = rad[3 * centre];
  /* The reference: a ray straight down onto the floor centre. */
  cv_ref_scene *s;
  assert_int_equal(cv_ref_scene_create(m, &s, NULL), CV_OK);
  cv_ref_light *l = constant_light(1, 1, 1);
  cv_ref_params p;
  cv_ref_params_default(&p);
  p.bounces = 2;
  const double org[3] = {0.5, 0.5, 0.5}, d[3] = {0, -1, 0};
  double mean[3], se[3];
  assert_int_equal(cv_ref_radiance(s, l, &p, org, d, 200000, mean, se, NULL), CV_OK);
  printf("open box floor centre, 2 bounces: reference %.5f +- %.5f, bake %.5f (%.2f%%)\n", mean[0],
         se[0], bake, 100 * (bake / mean[0] - 1));
  assert_true(se[0] < 0.004 * mean[0]);
  assert_near(bake / mean[0], 1, 0.02);
  /* All bounces: strictly more light than two. */
  double all[3];
  p.bounces = -1;
  assert_int_equal(cv_ref_radiance(s, l, &p, org, d, 200000, all, se, NULL), CV_OK);
  printf("open box floor centre, until roulette: %.5f +- %.5f\n", all[0], se[0]);
  assert_true(all[0] > mean[0]);
  /* Without the window the box is closed and dark. */
  cv_mesh *closed = box_mesh(4, a, 0);
  cv_ref_scene *sc;
  assert_int_equal(cv_ref_scene_create(closed, &sc, NULL), CV_OK);
  assert_int_equal(cv_ref_radiance(sc, l, &p, org, d, 1000, all, NULL, NULL), CV_OK);
  assert_true(all[0] == 0.0 && all[1] == 0.0 && all[2] == 0.0);
  cv_ref_scene_destroy(sc);
  cv_mesh_destroy(closed);
  cv_ref_light_destroy(l);
  cv_ref_scene_destroy(s);
  free(rad);
  cv_prt_destroy(prt);
  cv_mesh_destroy(m);
}

static void test_determinism(void **state) {
  (void)state;
  cv_mesh *m = box_mesh(4, 0.5f, 1);
  cv_ref_scene *s;
  assert_int_equal(cv_ref_scene_create(m, &s, NULL), CV_OK);
  cv_ref_light *l = constant_light(1, 0.5, 0.25);
  cv_ref_camera cam = {.eye = {0.5, 0.5, 0.9}, .look = {0.5, 0.3, 0}, .up = {0, 1, 0},
                       .fov_deg = 90, .w = 24, .h = 16};
  cv_ref_params p;
  cv_ref_params_default(&p);
  p.spp = 8;
  p.pass_spp = 3;
  p.quiet = 1;
  cv_image *a, *b;
  assert_int_equal(cv_image_create(24, 16, 3, &a), CV_OK);
  assert_int_equal(cv_image_create(24, 16, 3, &b), CV_OK);
  int nt = omp_get_max_threads();
  omp_set_num_threads(1);
  assert_int_equal(cv_ref_render(s, l, &cam, &p, a, NULL, NULL, NULL), CV_OK);
  omp_set_num_threads(2);
  assert_int_equal(cv_ref_render(s, l, &cam, &p, b, NULL, NULL, NULL), CV_OK);
  omp_set_num_threads(nt);
  assert_memory_equal(a->px, b->px, 24 * 16 * 3 * sizeof(float));
  p.seed = 2;
  assert_int_equal(cv_ref_render(s, l, &cam, &p, b, NULL, NULL, NULL), CV_OK);
  assert_true(memcmp(a->px, b->px, 24 * 16 * 3 * sizeof(float)) != 0);
  cv_image_destroy(a);
  cv_image_destroy(b);
  cv_ref_light_destroy(l);
  cv_ref_scene_destroy(s);
  cv_mesh_destroy(m);
}

static void test_bad_input(void **state) {
  (void)state;
  const float bad[3] = {0.5f, 1.5f, 0.5f};
  cv_mesh *m = plane_mesh(bad);
  cv_ref_scene *s = NULL;
  cv_err err;
  cv_err_clear(&err);
  assert_int_equal(cv_ref_scene_create(m, &s, &err), CV_ERR_RANGE);
  assert_null(s);
  assert_non_null(strstr(err.msg, "floor"));
  cv_mesh_destroy(m);
  const float ok[3] = {0.5f, 0.5f, 0.5f};
  m = plane_mesh(ok);
  assert_int_equal(cv_ref_scene_create(m, &s, NULL), CV_OK);
  cv_ref_light *l = constant_light(1, 1, 1);
  cv_ref_camera cam = {.eye = {0, 1, 0}, .look = {0, 1, 0}, .up = {0, 1, 0}, .fov_deg = 60,
                       .w = 4, .h = 4};
  cv_ref_params p;
  cv_ref_params_default(&p);
  cv_image *img;
  assert_int_equal(cv_image_create(4, 4, 3, &img), CV_OK);
  assert_int_equal(cv_ref_render(s, l, &cam, &p, img, NULL, NULL, &err), CV_ERR_INVALID);
  cam.look[1] = 0; /* looking straight down along up: no frame either */
  assert_int_equal(cv_ref_render(s, l, &cam, &p, img, NULL, NULL, &err), CV_ERR_INVALID);
  cam.up[1] = 0;
  cam.up[2] = -1;
  p.spp = 0;
  assert_int_equal(cv_ref_render(s, l, &cam, &p, img, NULL, NULL, &err), CV_ERR_INVALID);
  assert_non_null(strstr(err.msg, "spp"));
  cv_image_destroy(img);
  cv_ref_light_destroy(l);
  cv_ref_scene_destroy(s);
  cv_mesh_destroy(m);
}

/* Open box (window on top) under a map: dim sky plus a bright 20-degree patch
 * straight above the window.  PRT floor centre at 3 bands with and without
 * --split, against the reference with the same bounce count. */
static void test_split_lights(void **state) {
  (void)state;
  const int w = 256, h = 128;
  cv_image *img;
  assert_int_equal(cv_image_create(w, h, 3, &img), CV_OK);
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      float *p = cv_image_at(img, x, y);
      double th = M_PI * (y + 0.5) / h, ph = 2 * M_PI * (x + 0.5) / w;
      /* bright patch: 10-20 degrees from the zenith on one side */
      int hot = th > 10 * M_PI / 180 && th < 20 * M_PI / 180 && ph < M_PI / 2;
      p[0] = p[1] = p[2] = hot ? 40.0f : 0.5f;
    }
  char path[512];
  snprintf(path, sizeof path, "%s/split_map.exr", CV_TEST_TMP_DIR);
  assert_int_equal(cv_exr_write(path, img, 0, CV_EXR_NONE, NULL), CV_OK);
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  spec.kind = CV_LIGHT_ENV;
  spec.n_env = 1;
  spec.weight[0] = 1;
  spec.extract_sun = 0;
  snprintf(spec.env[0], sizeof spec.env[0], "%s", path);
  const float a = 0.6f;
  const int n = 16;
  cv_mesh *m = box_mesh(n, a, 1);
  cv_bake_params bp = {.bands = 3, .rays = 2048, .bounces = 1, .seed = 3,
                       .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  cv_tracer *tr;
  assert_int_equal(cv_tracer_create(m, &tr, NULL), CV_OK);
  cv_prt *prt;
  assert_int_equal(cv_prt_bake_tracer(tr, &bp, &prt, NULL, NULL), CV_OK);
  cv_scene_light *sl;
  assert_int_equal(cv_scene_light_build(&spec, 3, &sl, NULL), CV_OK);
  float *rad = malloc(3 * prt->nv * sizeof(float));
  uint32_t centre = (uint32_t)((n / 2) * (n + 1) + n / 2);
  cv_lighting l0 = cv_scene_light_sh(sl);
  assert_int_equal(cv_prt_relight(prt, &l0, tr, 64, rad, NULL), CV_OK);
  double plain = rad[3 * centre];
  /* relight_ex without extra lights is relight */
  float *rad2 = malloc(3 * prt->nv * sizeof(float));
  assert_int_equal(cv_prt_relight_ex(prt, &l0, NULL, 0, tr, 64, rad2, NULL), CV_OK);
  assert_memory_equal(rad, rad2, 3 * prt->nv * sizeof(float));
  /* Split: the lights carry what the SH lighting lost (the DC term is the
   * map's mean radiance times sqrt(4 pi)). */
  assert_int_equal(cv_scene_light_split(sl, tr, 32, 64, NULL), CV_OK);
  const cv_dir_light *ex;
  int ne = cv_scene_light_extra(sl, &ex);
  assert_true(ne > 0 && ne <= 32);
  cv_lighting l1 = cv_scene_light_sh(sl);
  double lost = (l0.sh[0] - l1.sh[0]) * sqrt(4 * M_PI), carried = 0;
  for (int k = 0; k < ne; k++) carried += ex[k].E[0];
  printf("split: %d lights carry %.5f, SH lost %.5f\n", ne, carried, lost);
  assert_near(carried / lost, 1, 1e-3);
  assert_int_equal(cv_prt_relight_ex(prt, &l1, ex, ne, tr, 64, rad2, NULL), CV_OK);
  double split = rad2[3 * centre];
  /* The reference at the same point, the same bounce count. */
  cv_ref_light *rl;
  assert_int_equal(cv_ref_light_build(&spec, &rl, NULL), CV_OK);
  cv_ref_scene *rs;
  assert_int_equal(cv_ref_scene_create(m, &rs, NULL), CV_OK);
  cv_ref_params p;
  cv_ref_params_default(&p);
  p.bounces = 1;
  const double org[3] = {0.5, 0.5, 0.5}, d[3] = {0, -1, 0};
  double ref[3], se[3];
  assert_int_equal(cv_ref_radiance(rs, rl, &p, org, d, 100000, ref, se, NULL), CV_OK);
  printf("floor centre: reference %.5f +- %.5f; PRT 3 bands %.5f (%.2f%%), with %d split "
         "lights %.5f (%.2f%%)\n", ref[0], se[0], plain, 100 * (plain / ref[0] - 1), ne, split,
         100 * (split / ref[0] - 1));
  assert_near(split / ref[0], 1, fabs(plain / ref[0] - 1));
  assert_near(split / ref[0], 1, 0.03);
  cv_ref_scene_destroy(rs);
  cv_ref_light_destroy(rl);
  free(rad);
  free(rad2);
  cv_scene_light_destroy(sl);
  cv_prt_destroy(prt);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
  cv_image_destroy(img);
}

/* Material boundaries (clean step (g)): a dashboard-like plate (albedo 0.1)
 * with an LCD-like inset (0.03) sharing its edge vertices.  After cleaning
 * and baking, every vertex's PRT albedo equals the albedo of every triangle
 * that uses it, and the inset's radiance under a constant sky is exactly
 * its own albedo times L (1%), as the reference says. */
static void test_material_boundary_albedo(void **state) {
  (void)state;
  cv_mesh *m;
  assert_int_equal(cv_mesh_create(&m), CV_OK);
  const float dash[3] = {0.1f, 0.1f, 0.1f}, lcd[3] = {0.03f, 0.03f, 0.03f};
  uint32_t md, ml;
  assert_int_equal(cv_mesh_add_material(m, "dashboard", dash, 0, &md), CV_OK);
  assert_int_equal(cv_mesh_add_material(m, "lcd_panel", lcd, CV_MAT_LCD, &ml), CV_OK);
  const float o[3] = {-1, 0, -1}, e1[3] = {0, 0, 2}, e2[3] = {2, 0, 0};
  grid(m, o, e1, e2, 4, md); /* 4 x 4 quads; make the middle 2 x 2 the LCD */
  for (size_t t = 0; t < m->nt; t++) {
    size_t q = t / 2, i = q % 4, j = q / 4;
    if (i >= 1 && i <= 2 && j >= 1 && j <= 2) m->tri_mat[t] = ml;
  }
  cv_clean_report rep;
  assert_int_equal(cv_mesh_clean(m, NULL, &rep, NULL), CV_OK);
  assert_int_equal(rep.material_splits, 8); /* the inset's 8 rim vertices */
  cv_bake_params bp = {.bands = 2, .rays = 64, .bounces = 0, .seed = 1,
                       .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  cv_prt *prt;
  assert_int_equal(cv_prt_bake(m, &bp, &prt, NULL, NULL), CV_OK);
  for (size_t t = 0; t < prt->nt; t++)
    for (int k = 0; k < 3; k++)
      assert_memory_equal(prt->albedo + 3 * prt->tri[3 * t + k], prt->mats[prt->tri_mat[t]].albedo,
                          3 * sizeof(float));
  cv_lighting lt;
  memset(&lt, 0, sizeof lt);
  lt.bands = 2;
  for (int c = 0; c < 3; c++) lt.sh[c] = 2.0 * sqrt(4 * M_PI);
  float *rad = malloc(3 * prt->nv * sizeof(float));
  assert_int_equal(cv_prt_relight(prt, &lt, NULL, 0, rad, NULL), CV_OK);
  for (size_t t = 0; t < prt->nt; t++) {
    if (prt->tri_mat[t] != ml) continue;
    for (int k = 0; k < 3; k++)
      assert_near(rad[3 * prt->tri[3 * t + k]] / (2.0 * 0.03), 1, 0.01);
  }
  free(rad);
  cv_prt_destroy(prt);
  cv_mesh_destroy(m);
}

/* --pixel-lights (prt/shade_view): a 2 x 2 m floor of 4 x 4 quads under a
 * sun, a 0.4 m cube floating above it, seen from above.  Per floor pixel the
 * truth is one Embree shadow ray from the pixel's surface point; a pixel
 * counts as lit when its radiance is above half the unshadowed a E cos / pi.
 * With the sun per pixel >= 99% of the pixels agree; with the sun
 * interpolated from the vertices (0.5 m apart) the shadow is smeared and
 * fewer agree. */
static double pixel_light_agreement(const cv_prt *prt, const cv_tracer *tr, int per_pixel,
                                    double a, double E, double cosine) {
  cv_lighting l = {.bands = (int)prt->bands, .has_sun = 1};
  const double s[3] = {0.3, 1.0, 0.2}, sl = sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
  for (int k = 0; k < 3; k++) {
    l.sun_dir[k] = s[k] / sl;
    l.sun_E[k] = E;
  }
  cv_relight_opts ro;
  cv_relight_opts_default(&ro);
  ro.sun_direct = !per_pixel;
  ro.clamp = !per_pixel;
  float *rad = malloc(3 * prt->nv * sizeof(float));
  assert_int_equal(cv_prt_relight_opt(prt, &l, NULL, 0, tr, &ro, rad, NULL), CV_OK);
  cv_dir_light sun;
  memcpy(sun.dir, l.sun_dir, sizeof sun.dir);
  memcpy(sun.E, l.sun_E, sizeof sun.E);
  cv_shade_view_params vp = {.rad = rad, .lights = &sun, .n_lights = per_pixel};
  const double eye[3] = {0, 3, 0}, look[3] = {0, 0, 0}, up[3] = {0, 0, -1};
  cv_pinhole_init(&vp.cam, eye, look, up, 28, 96, 96);
  cv_image *img;
  assert_int_equal(cv_image_create(96, 96, 3, &img), CV_OK);
  const cv_rt *rt = cv_tracer_rt(tr);
  cv_shade_view_stats st;
  cv_shade_view(prt, rt, &vp, img, &st);
  assert_int_equal(st.nonfinite, 0);
  const float sf[3] = {(float)l.sun_dir[0], (float)l.sun_dir[1], (float)l.sun_dir[2]};
  const double lit_value = a * E * cosine / M_PI;
  size_t floor_px = 0, agree = 0, lit = 0;
  cv_rt_thread_init();
  for (int y = 0; y < 96; y++)
    for (int x = 0; x < 96; x++) {
      float o[3], d[3], p[3], org[3];
      cv_pinhole_ray(&vp.cam, x, y, o, d);
      cv_hit h;
      if (!cv_rt_intersect(rt, o, d, 0, INFINITY, &h) || prt->tri_mat[h.tri] != 0) continue;
      for (int k = 0; k < 3; k++) p[k] = o[k] + h.t * d[k];
      const float n[3] = {0, 1, 0};
      cv_rt_offset_origin(p, n, org);
      const int truth = cv_rt_reaches_env(rt, org, sf, 0.0f);
      const int shown = cv_image_at(img, x, y)[0] > 0.5 * lit_value;
      floor_px++;
      agree += truth == shown;
      lit += truth;
    }
  printf("pixel lights %s: %zu floor pixels (%zu lit), %.2f%% agree with Embree visibility\n",
         per_pixel ? "sun" : "none", floor_px, lit, 100.0 * agree / floor_px);
  assert_true(floor_px > 4000 && lit > floor_px / 2 && lit < floor_px);
  cv_image_destroy(img);
  free(rad);
  return (double)agree / floor_px;
}

static void test_pixel_lights(void **state) {
  (void)state;
  const float a = 0.5f, alb[3] = {a, a, a};
  cv_mesh *m = plane_mesh(alb); /* material 0: the floor, normal +y */
  uint32_t boxm;
  cv_mesh_add_material(m, "box", alb, 0, &boxm);
  const float X[3] = {0.4f, 0, 0}, Y[3] = {0, 0.4f, 0}, Z[3] = {0, 0, 0.4f};
  const float o0[3] = {-0.2f, 0.3f, -0.2f}, ox[3] = {0.2f, 0.3f, -0.2f},
              oy[3] = {-0.2f, 0.7f, -0.2f}, oz[3] = {-0.2f, 0.3f, 0.2f};
  grid(m, o0, X, Z, 1, boxm);
  grid(m, oy, Z, X, 1, boxm);
  grid(m, o0, Y, X, 1, boxm);
  grid(m, oz, X, Y, 1, boxm);
  grid(m, o0, Z, Y, 1, boxm);
  grid(m, ox, Y, Z, 1, boxm);
  cv_bake_params bp = {.bands = 2, .rays = 64, .bounces = 0, .seed = 5,
                       .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  cv_tracer *tr;
  assert_int_equal(cv_tracer_create(m, &tr, NULL), CV_OK);
  cv_prt *prt;
  assert_int_equal(cv_prt_bake_tracer(tr, &bp, &prt, NULL, NULL), CV_OK);
  const double E = 3.0, cosine = 1.0 / sqrt(0.09 + 1.0 + 0.04);
  const double sun = pixel_light_agreement(prt, tr, 1, a, E, cosine);
  const double none = pixel_light_agreement(prt, tr, 0, a, E, cosine);
  assert_true(sun >= 0.99);
  assert_true(none < sun - 0.02);
  cv_prt_destroy(prt);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_furnace),          cmocka_unit_test(test_plane_constant_sky),
      cmocka_unit_test(test_plane_hot_map),    cmocka_unit_test(test_plane_sun),
      cmocka_unit_test(test_open_box_vs_bake), cmocka_unit_test(test_determinism),
      cmocka_unit_test(test_bad_input),        cmocka_unit_test(test_split_lights),
      cmocka_unit_test(test_material_boundary_albedo), cmocka_unit_test(test_pixel_lights),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
