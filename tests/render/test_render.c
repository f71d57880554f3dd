/* Tests of the wall-eye renderer (src/render) on whatever EGL gives: Mesa's
 * llvmpipe in CI.  If no EGL context can be made these tests FAIL (the
 * group setup asserts), they never skip.
 *
 *  - GL frame vs an independent CPU reference: Embree primary rays through
 *    the wall's pixel centres from the eye (corners taken directly from the
 *    wall, not from cv_offaxis), radiance from cv_prt_relight interpolated at
 *    the hit, the background through the windows: the reference of
 *    `cave shade --view`, generalised to an off-axis screen.  Two poses (an
 *    on-axis wall, an oblique side wall with an off-centre eye and a scene
 *    offset), float and half-float transfer.
 *  - the same with a sun: the GPU's shadow map per pixel against the CPU's
 *    ray-traced, vertex-interpolated sun (statistical bounds).
 *  - depth EQUAL shades every visible pixel: sentinel-cleared targets show
 *    no hole, and the image equals a single-pass depth-LESS render.
 *  - the shader's Drago (+ Rec.709) equals cv_drago_map / cv_drago_image
 *    within 1e-5 on a log ramp of flat quads.
 *  - the luminance pass equals Rec.709 Y of the HDR output at the same size,
 *    and the log-average of a 4x downsampled full-size frame.
 *  - 2x supersampling equals a 2x render box-filtered on the CPU.
 *  - the CPU relight against transform feedback, the simplified shadow
 *    casters against the mesh in the map.
 *  - argument errors. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>
#include "cv_test_near.h"

#include "mesh/cabin.h"
#include "prt/bake.h"
#include "prt/relight.h"
#include "prt/scene_light.h"
#include "render/renderer.h"
#include "render/renderer_internal.h"
#include "tonemap/drago.h"
#include "tonemap/foveal.h"
#include "view/offaxis.h"

typedef struct fixture {
  cv_prt *prt;
  cv_tracer *tr;
  cv_cabin_info info;
  cv_renderer *r;
} fixture;

static fixture F;

/* assert_int_equal on a status, printing the error line first. */
#define OK(call)                                              \
  do {                                                        \
    int st_ = (call);                                         \
    if (st_) printf("%s -> %d: %s\n", #call, st_, err.msg);   \
    assert_int_equal(st_, CV_OK);                             \
  } while (0)

static int setup(void **state) {
  (void)state;
  cv_cabin_params cp;
  cv_cabin_default_params(&cp);
  cp.tess = 1;
  cv_mesh *m = NULL;
  cv_err err;
  if (cv_cabin_generate_ex(&cp, &m, &F.info, &err)) return -1;
  cv_bake_params bp = {.bands = 5, .rays = 16, .bounces = 1, .seed = 3,
                       .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  if (cv_prt_bake(m, &bp, &F.prt, NULL, &err)) return -1;
  cv_mesh *pm = NULL;
  if (cv_prt_to_mesh(F.prt, &pm) || cv_tracer_create(pm, &F.tr, &err)) return -1;
  cv_mesh_destroy(pm);
  cv_mesh_destroy(m);
  /* EGL must work: a failure here fails every test (no skip). */
  cv_render_opts o;
  cv_render_default_opts(&o);
  o.display_float = 1; /* exact display values for the comparisons */
  o.half_transfer = 0;  /* float transfer: the CPU references' precision (the half-float
                           storage, the default with a software GL, has tests of its own) */
  if (cv_renderer_create(F.prt, &o, &F.r, &err)) {
    fprintf(stderr, "cannot start the renderer: %s\n", err.msg);
    return -1;
  }
  printf("GL: %s\n", cv_renderer_gl_name(F.r));
  return 0;
}

static int teardown(void **state) {
  (void)state;
  cv_renderer_destroy(F.r);
  cv_tracer_destroy(F.tr);
  cv_prt_destroy(F.prt);
  return 0;
}

/* A smooth coloured SH lighting without a sun. */
static void test_lighting(cv_lighting *l) {
  memset(l, 0, sizeof *l);
  l->bands = 5;
  const double base[3] = {1.0, 0.9, 0.8};
  for (int c = 0; c < 3; c++) {
    l->sh[c] = base[c] * sqrt(4 * M_PI);
    l->sh[3 * 1 + c] = 0.6 + 0.1 * c; /* y: brighter above */
    l->sh[3 * 2 + c] = -0.3;          /* z */
    l->sh[3 * 3 + c] = 0.2 * c;       /* x */
    l->sh[3 * 6 + c] = 0.15;
  }
}

/* A Preetham sky (turbidity 3) with its sun 35 degrees up, 30 degrees right
 * of ahead: through the windscreen onto the dashboard. */
static cv_scene_light *sky_35_30(void) {
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  spec.kind = CV_LIGHT_SKY;
  spec.turbidity = 3, spec.sun_elevation_deg = 35, spec.sun_azimuth_deg = 30;
  cv_scene_light *sl = NULL;
  cv_err err;
  assert_int_equal(cv_scene_light_build(&spec, 5, &sl, &err), CV_OK);
  return sl;
}

static const float BG[3] = {0.5f, 0.7f, 1.2f};

static cv_image *const_bg(void) {
  cv_image *bg;
  assert_int_equal(cv_image_create(8, 4, 3, &bg), CV_OK);
  for (int i = 0; i < 32; i++)
    for (int c = 0; c < 3; c++) bg->px[3 * i + c] = BG[c];
  return bg;
}

typedef struct pose {
  double pa[3], pb[3], pc[3], eye[3], offset[3];
  int w, h;
} pose;

/* Pose 0: a 1.6 x 1.2 m wall 1 m ahead of the driver's eye (scene frame).
 * Pose 1: the left wall of a 3 m CAVE, the eye off-centre, the CAVE mapped
 * into the car by an offset. */
static pose make_pose(int k) {
  pose p;
  memset(&p, 0, sizeof p);
  const float *e = F.info.eye;
  if (k == 0) {
    double d[3][3] = {{-0.8, -0.6, -1}, {0.8, -0.6, -1}, {-0.8, 0.6, -1}};
    for (int j = 0; j < 3; j++) {
      p.pa[j] = e[j] + d[0][j];
      p.pb[j] = e[j] + d[1][j];
      p.pc[j] = e[j] + d[2][j];
      p.eye[j] = e[j];
    }
    p.w = 240, p.h = 180;
  } else {
    double pa[3] = {-1.5, 0, 1.5}, pb[3] = {-1.5, 0, -1.5}, pc[3] = {-1.5, 3, 1.5};
    double head[3] = {0.25, 1.3, -0.2};
    memcpy(p.pa, pa, sizeof pa);
    memcpy(p.pb, pb, sizeof pb);
    memcpy(p.pc, pc, sizeof pc);
    memcpy(p.eye, head, sizeof head);
    for (int j = 0; j < 3; j++) p.offset[j] = e[j] - (j == 1 ? 1.25 : 0.0);
    p.w = p.h = 200;
  }
  return p;
}

static cv_render_view make_view(const pose *p, int ss) {
  cv_render_view v;
  memset(&v, 0, sizeof v);
  assert_int_equal(cv_offaxis_compute(p->pa, p->pb, p->pc, p->eye, 0.02, 20, &v.proj), CV_OK);
  memcpy(v.scene_offset, p->offset, sizeof p->offset);
  v.w = p->w, v.h = p->h, v.supersample = ss;
  return v;
}

/* CPU reference: rays from the eye through the pixel centres of the wall
 * (scene frame = CAVE + offset), radiance interpolated from the vertices. */
static void cpu_view(const pose *p, const float *rad, cv_image *img, const cv_scene_light *sl,
                     unsigned char *geom) {
  const cv_rt *rt = cv_tracer_rt(F.tr);
  for (int y = 0; y < p->h; y++) {
    cv_rt_thread_init();
    for (int x = 0; x < p->w; x++) {
      double fx = (x + 0.5) / p->w, fy = 1 - (y + 0.5) / p->h;
      float o[3], d[3];
      double dl = 0;
      for (int j = 0; j < 3; j++) {
        double q = p->pa[j] + fx * (p->pb[j] - p->pa[j]) + fy * (p->pc[j] - p->pa[j]);
        d[j] = (float)(q - p->eye[j]);
        dl += (double)d[j] * d[j];
        o[j] = (float)(p->eye[j] + p->offset[j]);
      }
      for (int j = 0; j < 3; j++) d[j] = (float)(d[j] / sqrt(dl));
      float *px = cv_image_at(img, x, y);
      cv_hit h;
      if (cv_rt_intersect(rt, o, d, 0, INFINITY, &h)) {
        const uint32_t *t = F.prt->tri + 3 * h.tri;
        float w0 = 1 - h.u - h.v;
        for (int c = 0; c < 3; c++)
          px[c] = w0 * rad[3 * t[0] + c] + h.u * rad[3 * t[1] + c] + h.v * rad[3 * t[2] + c];
        if (geom) geom[y * p->w + x] = 1;
      } else if (sl) {
        cv_scene_light_background(sl, d, px);
      } else {
        for (int c = 0; c < 3; c++) px[c] = BG[c];
      }
    }
  }
}

static double lum(const float *px) { return 0.2126 * px[0] + 0.7152 * px[1] + 0.0722 * px[2]; }

typedef struct cmp_stats {
  double frac_bad, max_rel_good, mean_rel, median_rel;
} cmp_stats;

static int cmp_dbl(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

/* Per pixel: relative difference of luminance-weighted RGB,
 * max_c |g - c| / (max_c c + floor). */
static cmp_stats compare(const cv_image *gpu, const cv_image *cpu, double tol, double floor) {
  cmp_stats s = {0, 0, 0, 0};
  size_t n = (size_t)gpu->w * gpu->h, bad = 0;
  double *rel = malloc(n * sizeof *rel);
  for (size_t i = 0; i < n; i++) {
    double dmax = 0, ref = 0;
    for (int c = 0; c < 3; c++) {
      double g = gpu->px[3 * i + c], r = cpu->px[3 * i + c];
      dmax = fmax(dmax, fabs(g - r));
      ref = fmax(ref, fabs(r));
    }
    rel[i] = dmax / (ref + floor);
    s.mean_rel += rel[i] / n;
    if (rel[i] > tol) bad++;
    else s.max_rel_good = fmax(s.max_rel_good, rel[i]);
  }
  qsort(rel, n, sizeof *rel, cmp_dbl);
  s.median_rel = rel[n / 2];
  s.frac_bad = (double)bad / n;
  free(rel);
  return s;
}

/* GL frame vs CPU: per-pixel tolerance 1e-3 relative (float transfer; 4e-3
 * with half floats), at most 2% of pixels beyond it (silhouettes and
 * triangle edges where the two rasterisers pick different triangles). */
static void gl_vs_cpu(int half, int cull) {
  cv_renderer *r;
  cv_err err;
  cv_render_opts o;
  cv_render_default_opts(&o);
  o.half_transfer = half; /* not the default's choice (half with a software GL) */
  o.cull_back = cull;
  OK(cv_renderer_create(F.prt, &o, &r, &err));
  assert_int_equal(cv_renderer_half_transfer(r), half);
  cv_lighting l;
  test_lighting(&l);
  cv_render_light_stats ls;
  OK(cv_renderer_set_lighting(r, &l, &ls, NULL, &err));
  cv_image *bg = const_bg();
  OK(cv_renderer_set_background(r, bg, &err));
  float *rad = malloc(3 * F.prt->nv * sizeof *rad);
  cv_relight_stats rs;
  assert_int_equal(cv_prt_relight(F.prt, &l, NULL, 0, rad, &rs), CV_OK);
  /* The GPU counts clamped and non-finite channels together. */
  printf("clamped channels: GPU %llu, CPU %llu\n", (unsigned long long)ls.clamped,
         (unsigned long long)(rs.clamped_negative + rs.nonfinite));
  if (!half) assert_true(ls.clamped <= rs.clamped_negative + rs.nonfinite + 3);
  const double tol = half ? 4e-3 : 1e-3;
  for (int k = 0; k < 2; k++) {
    pose p = make_pose(k);
    cv_render_view v = make_view(&p, 1);
    cv_image *g, *c;
    assert_int_equal(cv_image_create(p.w, p.h, 3, &g), CV_OK);
    assert_int_equal(cv_image_create(p.w, p.h, 3, &c), CV_OK);
    int st = cv_renderer_shade(r, &v, NULL, 0, NULL, g, NULL, &err);
    if (st) printf("%s\n", err.msg);
    assert_int_equal(st, CV_OK);
    cpu_view(&p, rad, c, NULL, NULL);
    cmp_stats s = compare(g, c, tol, 1e-3);
    printf("pose %d (%s transfer%s): %.3f%% pixels beyond %.0e, max %.2e among the rest, median "
           "%.2e, mean %.2e\n",
           k, half ? "half" : "float", cull ? ", back faces culled" : "", 100 * s.frac_bad, tol, s.max_rel_good, s.median_rel,
           s.mean_rel);
    assert_true(s.frac_bad < 0.02);
    assert_true(s.median_rel < tol / 10);
    cv_image_destroy(g);
    cv_image_destroy(c);
  }
  free(rad);
  cv_image_destroy(bg);
  cv_renderer_destroy(r);
}

static void test_gl_matches_cpu(void **state) {
  (void)state;
  gl_vs_cpu(0, 0);
}

/* The cabin is closed and consistently wound: culling back faces (the
 * benchmark's setting) changes nothing visible. */
static void test_gl_matches_cpu_culled(void **state) {
  (void)state;
  gl_vs_cpu(0, 1);
}

static void test_gl_matches_cpu_half(void **state) {
  (void)state;
  gl_vs_cpu(1, 0);
}

/* With a sun: per-pixel shadow map (GPU) vs per-vertex ray-traced sun
 * interpolated (CPU, 64 fan samples per vertex) differ at shadow edges by
 * construction, so the bounds are statistical, over the pixels that see
 * geometry: mean luminance within 5% overall and over the sunlit pixels
 * (CPU sun term > 10% of the pixel), median pixel within 2%.  The sun comes
 * from ahead-right, 35 degrees up, through the windscreen. */
static void test_gl_sun(void **state) {
  (void)state;
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  spec.kind = CV_LIGHT_SKY;
  spec.turbidity = 3;
  spec.sun_elevation_deg = 35;
  spec.sun_azimuth_deg = 30;
  cv_scene_light *sl;
  cv_err err;
  assert_int_equal(cv_scene_light_build(&spec, 5, &sl, &err), CV_OK);
  cv_lighting l = cv_scene_light_sh(sl);
  assert_true(l.has_sun);
  OK(cv_renderer_set_lighting(F.r, &l, NULL, NULL, &err));
  cv_image *bg;
  assert_int_equal(cv_render_background_image(sl, 512, &bg), CV_OK);
  OK(cv_renderer_set_background(F.r, bg, &err));
  float *rad = malloc(3 * F.prt->nv * sizeof *rad), *rad0 = malloc(3 * F.prt->nv * sizeof *rad);
  assert_int_equal(cv_prt_relight(F.prt, &l, F.tr, 64, rad, NULL), CV_OK);
  assert_int_equal(cv_prt_relight(F.prt, &l, NULL, 0, rad0, NULL), CV_OK); /* without direct sun */
  pose p = make_pose(0);
  cv_render_view v = make_view(&p, 1);
  const int n = p.w * p.h;
  cv_image *g, *c, *c0;
  unsigned char *geom = calloc(n, 1);
  assert_int_equal(cv_image_create(p.w, p.h, 3, &g), CV_OK);
  assert_int_equal(cv_image_create(p.w, p.h, 3, &c), CV_OK);
  assert_int_equal(cv_image_create(p.w, p.h, 3, &c0), CV_OK);
  OK(cv_renderer_shade(F.r, &v, NULL, 0, NULL, g, NULL, &err));
  cpu_view(&p, rad, c, sl, geom);
  cpu_view(&p, rad0, c0, sl, NULL);
  double yg = 0, yc = 0, sg = 0, sc = 0, *rel = malloc(n * sizeof *rel);
  int ngeom = 0, nsun = 0;
  for (int i = 0; i < n; i++) {
    if (!geom[i]) continue;
    double a = lum(g->px + 3 * i), b = lum(c->px + 3 * i), b0 = lum(c0->px + 3 * i);
    yg += a, yc += b;
    rel[ngeom++] = fabs(a - b) / (b + 1e-6);
    if (b - b0 > 0.1 * b) sg += a, sc += b, nsun++;
  }
  qsort(rel, ngeom, sizeof *rel, cmp_dbl);
  printf("sun: %d geometry pixels, %d sunlit; mean luminance GPU/CPU - 1: %.2f%% overall, %.2f%% "
         "sunlit; median pixel %.2e, 90th percentile %.2e\n",
         ngeom, nsun, 100 * (yg / yc - 1), 100 * (sg / sc - 1), rel[ngeom / 2],
         rel[(int)(0.9 * ngeom)]);
  assert_true(ngeom > n / 4 && nsun > n / 50);
  assert_near(yg / yc, 1, 0.05);
  assert_near(sg / sc, 1, 0.05);
  assert_true(rel[ngeom / 2] < 0.02);
  /* The sun split (triangles facing away from the sun drawn without the
   * sun's code) changes no pixel: the same frame from a renderer without
   * it, both poses, within float noise (1e-6 relative). */
  cv_render_opts o;
  cv_render_default_opts(&o);
  o.sun_split = 0;
  o.half_transfer = 0; /* as the fixture's */
  cv_renderer *whole;
  OK(cv_renderer_create(F.prt, &o, &whole, &err));
  OK(cv_renderer_set_lighting(whole, &l, NULL, NULL, &err));
  OK(cv_renderer_set_background(whole, bg, &err));
  for (int k = 0; k < 2; k++) {
    pose pk = make_pose(k);
    cv_render_view vk = make_view(&pk, 1);
    cv_image *a, *b;
    assert_int_equal(cv_image_create(pk.w, pk.h, 3, &a), CV_OK);
    assert_int_equal(cv_image_create(pk.w, pk.h, 3, &b), CV_OK);
    OK(cv_renderer_shade(F.r, &vk, NULL, 0, NULL, a, NULL, &err));
    OK(cv_renderer_shade(whole, &vk, NULL, 0, NULL, b, NULL, &err));
    size_t differ = 0, np = (size_t)pk.w * pk.h;
    double worst = 0;
    for (size_t i = 0; i < 3 * np; i++) {
      double d = fabs(a->px[i] - b->px[i]) / (fabs(b->px[i]) + 1e-3);
      worst = fmax(worst, d);
      differ += d > 1e-6;
    }
    printf("sun split, pose %d: %zu of %zu channel values differ beyond 1e-6 from the unsplit "
           "frame, max relative difference %.2e\n", k, differ, 3 * np, worst);
    assert_int_equal(differ, 0);
    cv_image_destroy(a);
    cv_image_destroy(b);
  }
  cv_renderer_destroy(whole);
  free(rel);
  free(geom);
  cv_image_destroy(g);
  cv_image_destroy(c);
  cv_image_destroy(c0);
  cv_image_destroy(bg);
  free(rad);
  free(rad0);
  cv_scene_light_destroy(sl);
}

/* Lighting changes.  (a) The culled shadow map (opts.shadow_cull: only the
 * triangles facing away from the sun) shades like the full one on the
 * closed cabin: at most 0.5% of the pixels differ beyond 1e-3, both poses
 * (sub-texel differences at shadow edges; tests/bench/bench_shadow measures
 * both against Embree).  (b) A sun moved by far less than a texel keeps the
 * map (opts.shadow_reuse) and the image; one moved by 3 degrees redraws it;
 * the same sun is reused even with shadow_reuse 0. */
static void test_gl_sun_cull_reuse(void **state) {
  (void)state;
  cv_err err;
  cv_scene_light *sl = sky_35_30();
  cv_lighting l = cv_scene_light_sh(sl);
  cv_render_opts o;
  cv_render_default_opts(&o);
  o.display_float = 1;
  o.shadow_cull = 1;
  cv_renderer *rc, *full;
  OK(cv_renderer_create(F.prt, &o, &rc, &err));
  o.shadow_cull = 0;
  OK(cv_renderer_create(F.prt, &o, &full, &err));
  printf("cabin closed and consistently wound: %d\n", cv_renderer_mesh_closed(rc));
  assert_int_equal(cv_renderer_mesh_closed(rc), 1); /* so the default (-1) culls */
  cv_frame_timing t = {0};
  OK(cv_renderer_set_lighting(rc, &l, NULL, &t, &err));
  assert_int_equal(t.shadow_reused, 0);
  OK(cv_renderer_set_lighting(full, &l, NULL, NULL, &err));
  cv_image *bg = const_bg();
  OK(cv_renderer_set_background(rc, bg, &err));
  OK(cv_renderer_set_background(full, bg, &err));
  cv_image *a[2], *b[2];
  for (int k = 0; k < 2; k++) {
    pose pk = make_pose(k);
    cv_render_view vk = make_view(&pk, 1);
    assert_int_equal(cv_image_create(pk.w, pk.h, 3, &a[k]), CV_OK);
    assert_int_equal(cv_image_create(pk.w, pk.h, 3, &b[k]), CV_OK);
    OK(cv_renderer_shade(rc, &vk, NULL, 0, NULL, a[k], NULL, &err));
    OK(cv_renderer_shade(full, &vk, NULL, 0, NULL, b[k], NULL, &err));
    size_t differ = 0, np = (size_t)pk.w * pk.h;
    for (size_t i = 0; i < np; i++) {
      double d = 0;
      for (int c = 0; c < 3; c++)
        d = fmax(d, fabs(a[k]->px[3 * i + c] - b[k]->px[3 * i + c]) / (fabs(b[k]->px[3 * i + c]) + 1e-3));
      differ += d > 1e-3;
    }
    printf("culled shadow map, pose %d: %zu of %zu pixels differ beyond 1e-3 from the full map\n", k,
           differ, np);
    assert_true(differ <= np / 200);
  }
  /* (b) turn the sun by 1e-6 rad about the vertical: kept, same image */
  cv_lighting l2 = l;
  const double ang[2] = {1e-6, 0.05};
  for (int step = 0; step < 2; step++) {
    const double c = cos(ang[step]), s = sin(ang[step]);
    l2.sun_dir[0] = c * l.sun_dir[0] + s * l.sun_dir[2];
    l2.sun_dir[2] = -s * l.sun_dir[0] + c * l.sun_dir[2];
    OK(cv_renderer_set_lighting(rc, &l2, NULL, &t, &err));
    printf("sun turned by %g rad: shadow map %s\n", ang[step], t.shadow_reused ? "kept" : "redrawn");
    assert_int_equal(t.shadow_reused, step == 0);
    if (step == 0) {
      pose p0 = make_pose(0);
      cv_render_view v0 = make_view(&p0, 1);
      cv_image *c0;
      assert_int_equal(cv_image_create(p0.w, p0.h, 3, &c0), CV_OK);
      OK(cv_renderer_shade(rc, &v0, NULL, 0, NULL, c0, NULL, &err));
      double worst = 0;
      for (size_t i = 0; i < 3 * (size_t)p0.w * p0.h; i++)
        worst = fmax(worst, fabs(c0->px[i] - a[0]->px[i]) / (fabs(a[0]->px[i]) + 1e-3));
      printf("kept map: max relative difference %.2e\n", worst);
      assert_true(worst < 1e-4);
      cv_image_destroy(c0);
    }
  }
  cv_renderer_destroy(rc);
  cv_renderer_destroy(full);
  o.shadow_cull = 1;
  o.shadow_reuse = 0;
  OK(cv_renderer_create(F.prt, &o, &rc, &err));
  OK(cv_renderer_set_lighting(rc, &l, NULL, &t, &err));
  OK(cv_renderer_set_lighting(rc, &l, NULL, &t, &err));
  assert_int_equal(t.shadow_reused, 1);
  cv_renderer_destroy(rc);
  for (int k = 0; k < 2; k++) cv_image_destroy(a[k]), cv_image_destroy(b[k]);
  cv_image_destroy(bg);
  cv_scene_light_destroy(sl);
}

/* Max over a view's channels of |a - b| / (|b| + floor), and the number of
 * pixels beyond tol. */
static double max_rel(const cv_image *a, const cv_image *b, double tol, double floor, size_t *beyond) {
  double worst = 0;
  size_t n = (size_t)a->w * a->h;
  *beyond = 0;
  for (size_t i = 0; i < n; i++) {
    double d = 0;
    for (int c = 0; c < 3; c++)
      d = fmax(d, fabs(a->px[3 * i + c] - b->px[3 * i + c]) / (fabs(b->px[3 * i + c]) + floor));
    worst = fmax(worst, d);
    *beyond += d > tol;
  }
  return worst;
}

/* The lighting change's two cheap paths (opts.relight_cpu, opts.shadow_casters)
 * against the reference paths (transform feedback, the mesh in the map):
 *  - the CPU relight equals the feedback relight within 1e-4 relative per
 *    channel (the same float sums in another order: a sky's SH sums cancel,
 *    so float rounding of terms ~10x the result shows at 1e-5) with the
 *    same clamp count, also under a lighting that rings below zero;
 *  - the casters: fewer triangles, within their tolerance, culled on the
 *    closed cabin; the image differs from the mesh's map only at shadow
 *    edges (at most 0.5% of the pixels beyond 1e-3);
 *  - shadow_casters 0 builds none. */
static void test_cpu_relight_and_casters(void **state) {
  (void)state;
  cv_err err;
  cv_scene_light *sl = sky_35_30();
  cv_lighting lsun = cv_scene_light_sh(sl), lring;
  test_lighting(&lring);
  lring.sh[3 * 12] = lring.sh[3 * 12 + 1] = lring.sh[3 * 12 + 2] = -2.5; /* rings below 0 */
  cv_render_opts o;
  cv_render_default_opts(&o);
  o.display_float = 1;
  o.half_transfer = 0; /* float everywhere here: test_cpu_relight_half has the halves */
  cv_renderer *ref, *cpu, *dflt; /* feedback + mesh map; CPU + mesh map; the defaults */
  o.relight_cpu = 0, o.shadow_casters = 0;
  OK(cv_renderer_create(F.prt, &o, &ref, &err));
  o.relight_cpu = 1;
  OK(cv_renderer_create(F.prt, &o, &cpu, &err));
  cv_render_default_opts(&o);
  o.display_float = 1;
  o.half_transfer = 0;
  OK(cv_renderer_create(F.prt, &o, &dflt, &err));
  printf("GL: %s (software %d): default relight on the CPU: %s\n", cv_renderer_gl_name(dflt),
         cv_renderer_is_software(dflt), o.relight_cpu < 0 ? "when software" : "set");
  cv_image *bg = const_bg();
  cv_renderer *R[3] = {ref, cpu, dflt};
  for (int i = 0; i < 3; i++) OK(cv_renderer_set_background(R[i], bg, &err));
  for (int li = 0; li < 2; li++) {
    const cv_lighting *l = li ? &lring : &lsun;
    cv_render_light_stats st[3];
    for (int i = 0; i < 3; i++) OK(cv_renderer_set_lighting(R[i], l, &st[i], NULL, &err));
    printf("%s: clamped channels feedback %llu, CPU %llu, default %llu\n", li ? "ringing SH" : "sky",
           (unsigned long long)st[0].clamped, (unsigned long long)st[1].clamped,
           (unsigned long long)st[2].clamped);
    assert_true(st[0].clamped == st[1].clamped && st[1].clamped == st[2].clamped);
    if (li) assert_true(st[0].clamped > 0); /* the case is one */
    for (int k = 0; k < 2; k++) {
      pose p = make_pose(k);
      cv_render_view v = make_view(&p, 1);
      cv_image *img[3];
      for (int i = 0; i < 3; i++) {
        assert_int_equal(cv_image_create(p.w, p.h, 3, &img[i]), CV_OK);
        OK(cv_renderer_shade(R[i], &v, NULL, 0, NULL, img[i], NULL, &err));
      }
      size_t b1, b2, np = (size_t)p.w * p.h;
      /* ringing: pixels near 0 by cancellation of terms ~1: an absolute floor of 1e-2 */
      const double w1 = max_rel(img[1], img[0], 1e-4, li ? 1e-2 : 1e-3, &b1),
                   w2 = max_rel(img[2], img[0], 1e-3, 1e-3, &b2);
      printf("  pose %d: CPU relight vs feedback max %.2e; casters vs mesh map: %zu of %zu pixels "
             "beyond 1e-3\n", k, w1, b2, np);
      assert_true(w1 < 1e-4);
      assert_true(b2 <= np / 200);
      (void)w2;
      for (int i = 0; i < 3; i++) cv_image_destroy(img[i]);
    }
  }
  cv_shadow_casters sc;
  assert_int_equal(cv_renderer_shadow_casters(dflt, &sc), CV_OK);
  printf("casters within %.1f mm: %zu of %zu triangles, error %.3f mm, defects %zu, culled %d, "
         "%zu in the last map, built in %.0f ms\n", 1e3 * sc.tolerance_m, sc.triangles,
         sc.mesh_triangles, 1e3 * sc.error_m, sc.defects, sc.culled, sc.drawn, sc.build_ms);
  assert_int_equal(sc.built, 1);
  assert_true(sc.triangles > 0 && sc.triangles < sc.mesh_triangles / 2);
  assert_true(sc.error_m <= sc.tolerance_m * (1 + 1e-6));
  assert_int_equal(sc.culled, 1);
  assert_true(sc.drawn < sc.triangles);
  assert_int_equal(cv_renderer_shadow_casters(ref, &sc), CV_OK);
  assert_int_equal(sc.built, 0);
  assert_int_equal(cv_renderer_shadow_casters(NULL, &sc), CV_ERR_INVALID);
  for (int i = 0; i < 3; i++) cv_renderer_destroy(R[i]);
  cv_image_destroy(bg);
  cv_scene_light_destroy(sl);
}

/* The CPU relight of a half-float transfer (opts.half_transfer) against the
 * transform feedback of the same halves, with its vector path (F16C + FMA,
 * when the CPU has them) and with the portable one: within 1e-4 relative
 * (the float test's bound), the same clamp counts, under the sky and under
 * a lighting that rings below zero. */
static void test_cpu_relight_half(void **state) {
  (void)state;
  cv_err err;
  cv_scene_light *sl = sky_35_30();
  cv_lighting lsun = cv_scene_light_sh(sl), lring;
  test_lighting(&lring);
  lring.sh[3 * 12] = lring.sh[3 * 12 + 1] = lring.sh[3 * 12 + 2] = -2.5;
  cv_render_opts o;
  cv_render_default_opts(&o);
  o.display_float = 1, o.half_transfer = 1, o.shadow_casters = 0;
  cv_renderer *ref, *cpu;
  o.relight_cpu = 0;
  OK(cv_renderer_create(F.prt, &o, &ref, &err));
  o.relight_cpu = 1;
  OK(cv_renderer_create(F.prt, &o, &cpu, &err));
  cv_image *bg = const_bg();
  OK(cv_renderer_set_background(ref, bg, &err));
  OK(cv_renderer_set_background(cpu, bg, &err));
  pose p = make_pose(0);
  cv_render_view v = make_view(&p, 1);
  cv_image *a, *b, *c;
  assert_int_equal(cv_image_create(p.w, p.h, 3, &a), CV_OK);
  assert_int_equal(cv_image_create(p.w, p.h, 3, &b), CV_OK);
  assert_int_equal(cv_image_create(p.w, p.h, 3, &c), CV_OK);
  for (int li = 0; li < 2; li++) {
    const cv_lighting *l = li ? &lring : &lsun;
    cv_render_light_stats s0, s1, s2;
    OK(cv_renderer_set_lighting(ref, l, &s0, NULL, &err));
    const int simd = cvr_relight_simd(1);
    OK(cv_renderer_set_lighting(cpu, l, &s1, NULL, &err));
    OK(cv_renderer_shade(ref, &v, NULL, 0, NULL, a, NULL, &err));
    OK(cv_renderer_shade(cpu, &v, NULL, 0, NULL, b, NULL, &err));
    cvr_relight_simd(0);
    OK(cv_renderer_set_lighting(cpu, l, &s2, NULL, &err));
    OK(cv_renderer_shade(cpu, &v, NULL, 0, NULL, c, NULL, &err));
    cvr_relight_simd(1);
    size_t n1, n2;
    const double w1 = max_rel(b, a, 1e-4, li ? 1e-2 : 1e-3, &n1), w2 = max_rel(c, a, 1e-4, li ? 1e-2 : 1e-3, &n2);
    printf("%s, half transfer: CPU relight (%s) vs feedback max %.2e, portable path %.2e; clamped "
           "%llu / %llu / %llu\n", li ? "ringing SH" : "sky", simd ? "F16C + FMA" : "portable, no F16C",
           w1, w2, (unsigned long long)s0.clamped, (unsigned long long)s1.clamped,
           (unsigned long long)s2.clamped);
    assert_true(w1 < 1e-4 && w2 < 1e-4);
    assert_true(s0.clamped == s1.clamped && s1.clamped == s2.clamped);
    if (li) assert_true(s0.clamped > 0);
  }
  cv_image_destroy(a), cv_image_destroy(b), cv_image_destroy(c);
  cv_renderer_destroy(ref), cv_renderer_destroy(cpu);
  /* The default (-1): half floats exactly when the relight runs on the CPU. */
  cv_render_default_opts(&o);
  assert_int_equal(o.half_transfer, -1);
  cv_renderer *dflt, *fb;
  OK(cv_renderer_create(F.prt, &o, &dflt, &err));
  o.relight_cpu = 0;
  OK(cv_renderer_create(F.prt, &o, &fb, &err));
  printf("default transfer: %s (relight on the CPU: %d); with transform feedback: %s\n",
         cv_renderer_half_transfer(dflt) ? "half" : "float", cv_renderer_relight_on_cpu(dflt),
         cv_renderer_half_transfer(fb) ? "half" : "float");
  assert_int_equal(cv_renderer_half_transfer(dflt), cv_renderer_relight_on_cpu(dflt));
  assert_int_equal(cv_renderer_half_transfer(fb), 0);
  cv_renderer_destroy(dflt), cv_renderer_destroy(fb);
  /* --transfer's words */
  int h = 7;
  assert_int_equal(cv_render_transfer_parse("auto", &h), 0);
  assert_int_equal(h, -1);
  assert_int_equal(cv_render_transfer_parse("float", &h), 0);
  assert_int_equal(h, 0);
  assert_int_equal(cv_render_transfer_parse("half", &h), 0);
  assert_int_equal(h, 1);
  assert_int_equal(cv_render_transfer_parse("Half", &h), -1);
  assert_int_equal(cv_render_transfer_parse("", &h), -1);
  assert_int_equal(cv_render_transfer_parse(NULL, &h), -1);
  assert_int_equal(h, 1);
  cv_image_destroy(bg);
  cv_scene_light_destroy(sl);
}

/* The sun's shadow map fitted to the beam (cvr_sun_matrices): for suns from
 * straight above (the frame's up axis switches), from the horizon, from
 * below and oblique ones, every opaque vertex of the scene lies inside the
 * map in texel space (brute force over all vertices against the extent the
 * renderer finds from the chunks' boxes), the texels are square, the longer
 * side has opts.shadow_res texels and the vertices span it up to its 1%
 * pads, the shorter side no more texels than its span needs. */
static void test_sun_matrices_fit(void **state) {
  (void)state;
  cv_err err;
  cv_renderer *r;
  OK(cv_renderer_create(F.prt, NULL, &r, &err));
  const double suns[6][3] = {{0, 1, 0}, {0.41, 0.57, -0.71}, {1, 0, 0}, {0, -1, 0}, {0.02, 0.999, 0.03},
                             {-0.6, 0.2, 0.77}};
  for (int k = 0; k < 6; k++) {
    double s[3], l = 0;
    for (int j = 0; j < 3; j++) l += suns[k][j] * suns[k][j];
    for (int j = 0; j < 3; j++) s[j] = suns[k][j] / sqrt(l);
    float clip[16], texel;
    int size[2];
    cvr_sun_matrices(&r->ctx, &r->light.shadow, &r->scene, s, clip, &texel, size);
    const float *q = r->light.shadow.q;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < r->scene.nv_used; v++) {
      const float *p = r->scene.pos_cpu + 3 * v;
      for (int a = 0; a < 3; a++) {
        const double x = (double)q[a] * p[0] + (double)q[4 + a] * p[1] + (double)q[8 + a] * p[2] + q[12 + a];
        lo[a] = fmin(lo[a], x), hi[a] = fmax(hi[a], x);
      }
    }
    const int res = r->o.shadow_res, lng = size[0] >= size[1] ? 0 : 1;
    printf("sun (%.2f, %.2f, %.2f): map %d x %d texels of %.2f mm; vertices in x [%.1f, %.1f], "
           "y [%.1f, %.1f], depth [%.4f, %.4f]\n", s[0], s[1], s[2], size[0], size[1], 1e3 * texel,
           lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]);
    assert_int_equal(size[lng], res);
    assert_true(size[1 - lng] >= 2 && size[1 - lng] <= res);
    assert_near(r->light.shadow.k[0] / r->light.shadow.k[1], 1, 1e-5); /* square texels */
    for (int a = 0; a < 2; a++) /* inside: texel centres at integers, edges at -0.5, n - 0.5 */
      assert_true(lo[a] >= -0.5 && hi[a] <= size[a] - 0.5);
    assert_true(lo[2] >= 0 && hi[2] <= 1);
    /* tight: the pads are 1% of the span and 1 mm on each side */
    assert_true(hi[lng] - lo[lng] >= 0.97 * size[lng]);
    assert_true(hi[1 - lng] - lo[1 - lng] >= 0.97 * (size[1 - lng] - 1) - 2.0 / 1e3 / texel);
  }
  cv_renderer_destroy(r);
}

/* The CPU relight's half-float conversions (opts.half_transfer): F16C and
 * the portable one give the same float for each of the 65,536 halves (NaN
 * for NaN). */
static void test_half_conversions(void **state) {
  (void)state;
  uint16_t *h = malloc(65536 * sizeof *h);
  float *a = malloc(65536 * sizeof *a), *b = malloc(65536 * sizeof *b);
  assert_non_null(h), assert_non_null(a), assert_non_null(b);
  for (uint32_t i = 0; i < 65536; i++) h[i] = (uint16_t)i;
  cvr_halves_soft(h, a, 65536);
  const int hw = cvr_halves_f16c(h, b, 65535); /* an odd count: the tail too */
  b[65535] = a[65535];
  size_t differ = 0;
  for (uint32_t i = 0; i < 65536; i++)
    differ += isnan(a[i]) ? !isnan(b[i]) : memcmp(&a[i], &b[i], sizeof a[i]) != 0;
  printf("half -> float: F16C %s, %zu of 65536 differ from the portable conversion\n",
         hw ? "used" : "not on this CPU (portable both times)", differ);
  assert_int_equal(differ, 0);
  assert_true(a[0x3c00] == 1.0f && a[0xc000] == -2.0f && a[0x0001] == ldexpf(1, -24));
  free(h), free(a), free(b);
}

/* cv_renderer_mesh_closed: a unit box wound outwards is closed; without one
 * face, or with one face wound the other way, it is not; each gets its shadow
 * casters (nothing to simplify on 12 triangles), culled only when closed. */
static void test_mesh_closed(void **state) {
  (void)state;
  static const float P[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  static const uint32_t Q[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4},
                                   {2, 3, 7, 6}, {1, 2, 6, 5}, {0, 4, 7, 3}};
  for (int k = 0; k < 3; k++) { /* 0: closed, 1: a face missing, 2: a face flipped */
    cv_mesh *m;
    cv_err err;
    uint32_t mat;
    assert_int_equal(cv_mesh_create(&m), CV_OK);
    assert_int_equal(cv_mesh_add_material(m, "grey", (const float[3]){0.5f, 0.5f, 0.5f}, 0, &mat), CV_OK);
    for (int i = 0; i < 8; i++) assert_int_equal(cv_mesh_add_vertex(m, P[i][0], P[i][1], P[i][2], NULL), CV_OK);
    for (int f = 0; f < 6; f++) {
      if (k == 1 && f == 5) continue;
      const uint32_t *q = Q[f];
      if (k == 2 && f == 5) {
        assert_int_equal(cv_mesh_add_tri(m, q[0], q[2], q[1], mat), CV_OK);
        assert_int_equal(cv_mesh_add_tri(m, q[0], q[3], q[2], mat), CV_OK);
      } else {
        assert_int_equal(cv_mesh_add_tri(m, q[0], q[1], q[2], mat), CV_OK);
        assert_int_equal(cv_mesh_add_tri(m, q[0], q[2], q[3], mat), CV_OK);
      }
    }
    cv_bake_params bp = {.bands = 2, .rays = 4, .bounces = 0, .seed = 1,
                         .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
    cv_prt *p;
    OK(cv_prt_bake(m, &bp, &p, NULL, &err));
    cv_renderer *r;
    OK(cv_renderer_create(p, NULL, &r, &err));
    printf("box %d: closed %d\n", k, cv_renderer_mesh_closed(r));
    assert_int_equal(cv_renderer_mesh_closed(r), k == 0);
    /* its shadow casters under a sun: nothing to simplify on 12 triangles;
     * culled only on the closed box */
    cv_scene_light *sl = sky_35_30();
    const cv_lighting l = cv_scene_light_sh(sl);
    OK(cv_renderer_set_lighting(r, &l, NULL, NULL, &err));
    cv_shadow_casters sc;
    assert_int_equal(cv_renderer_shadow_casters(r, &sc), CV_OK);
    printf("  casters: %zu of %zu triangles, defects %zu, culled %d, %zu in the map\n", sc.triangles,
           sc.mesh_triangles, sc.defects, sc.culled, sc.drawn);
    assert_int_equal(sc.built, 1);
    assert_int_equal(sc.triangles, sc.mesh_triangles);
    assert_int_equal(sc.culled, k == 0);
    assert_true(k == 0 ? sc.drawn < sc.triangles : sc.drawn == sc.triangles);
    if (k == 0) assert_int_equal(sc.defects, 0);
    cv_scene_light_destroy(sl);
    cv_renderer_destroy(r);
    cv_prt_destroy(p);
    cv_mesh_destroy(m);
  }
}

/* Split window lights (cv_renderer_set_split, as `cave shade --split`): the
 * Preetham sky's residual split into 16 directional lights, the sun left out
 * so that only the split lights carry direct light.  GL (per-vertex direct
 * light from cv_split_direct, SH term through ti) against cv_prt_relight_ex
 * interpolated on the CPU: the tolerances of the plain comparison (1e-3 per
 * pixel, <= 2% of pixels beyond, median < 1e-4); the split lights must
 * change the frame (mean luminance of the geometry by > 5%: the test can
 * fail), and n = 0 gives back the frame without them. */
static void test_gl_split(void **state) {
  (void)state;
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  spec.kind = CV_LIGHT_SKY;
  spec.turbidity = 3;
  spec.sun_elevation_deg = 35;
  spec.sun_azimuth_deg = 30;
  cv_scene_light *sl;
  cv_err err;
  assert_int_equal(cv_scene_light_build(&spec, 5, &sl, &err), CV_OK);
  OK(cv_scene_light_split(sl, F.tr, 16, 32, &err));
  const cv_dir_light *ex;
  const int n = cv_scene_light_extra(sl, &ex);
  assert_true(n > 0);
  cv_lighting l = cv_scene_light_sh(sl);
  l.has_sun = 0;
  const size_t nv = F.prt->nv;
  float *rad = malloc(3 * nv * sizeof *rad), *direct = calloc(3 * nv, sizeof *direct);
  float *rad0 = malloc(3 * nv * sizeof *rad0);
  assert_int_equal(cv_prt_relight_ex(F.prt, &l, ex, n, F.tr, 16, rad, NULL), CV_OK);
  assert_int_equal(cv_prt_relight(F.prt, &l, NULL, 0, rad0, NULL), CV_OK);
  assert_int_equal(cv_split_direct(F.prt, F.tr, ex, n, 16, direct), CV_OK);
  OK(cv_renderer_set_split(F.r, ex, n, direct, &err));
  OK(cv_renderer_set_lighting(F.r, &l, NULL, NULL, &err));
  cv_image *bg;
  assert_int_equal(cv_render_background_image(sl, 256, &bg), CV_OK);
  OK(cv_renderer_set_background(F.r, bg, &err));
  for (int k = 0; k < 2; k++) {
    pose p = make_pose(k);
    cv_render_view v = make_view(&p, 1);
    const int np = p.w * p.h;
    cv_image *g, *c, *c0;
    unsigned char *geom = calloc(np, 1);
    assert_int_equal(cv_image_create(p.w, p.h, 3, &g), CV_OK);
    assert_int_equal(cv_image_create(p.w, p.h, 3, &c), CV_OK);
    assert_int_equal(cv_image_create(p.w, p.h, 3, &c0), CV_OK);
    OK(cv_renderer_shade(F.r, &v, NULL, 0, NULL, g, NULL, &err));
    cpu_view(&p, rad, c, sl, geom);
    cpu_view(&p, rad0, c0, sl, NULL);
    /* Over the pixels that see geometry (the background is a resampled image). */
    cv_image *gg, *cg;
    assert_int_equal(cv_image_create(np, 1, 3, &gg), CV_OK);
    assert_int_equal(cv_image_create(np, 1, 3, &cg), CV_OK);
    int ng = 0;
    double y = 0, y0 = 0;
    for (int i = 0; i < np; i++)
      if (geom[i]) {
        y += lum(c->px + 3 * i), y0 += lum(c0->px + 3 * i);
        memcpy(gg->px + 3 * ng, g->px + 3 * i, 3 * sizeof(float));
        memcpy(cg->px + 3 * ng, c->px + 3 * i, 3 * sizeof(float));
        ng++;
      }
    gg->w = cg->w = ng;
    cmp_stats st = compare(gg, cg, 1e-3, 1e-3);
    cv_image_destroy(gg);
    cv_image_destroy(cg);
    printf("split %d lights, pose %d: %d geometry pixels, %.3f%% beyond 1e-3, median %.2e; the "
           "lights add %.1f%% to their mean luminance\n",
           n, k, ng, 100 * st.frac_bad, st.median_rel, 100 * (y / y0 - 1));
    assert_true(ng > np / 4);
    assert_true(st.frac_bad < 0.02);
    assert_true(st.median_rel < 1e-4);
    assert_true(y > 1.05 * y0);
    if (k == 0) { /* removing them gives the frame without them */
      OK(cv_renderer_set_split(F.r, NULL, 0, NULL, &err));
      OK(cv_renderer_set_lighting(F.r, &l, NULL, NULL, &err));
      OK(cv_renderer_shade(F.r, &v, NULL, 0, NULL, g, NULL, &err));
      for (int i = 0; i < np; i++) /* background pixels out of the comparison */
        if (!geom[i]) memcpy(g->px + 3 * i, c0->px + 3 * i, 3 * sizeof(float));
      cmp_stats s0 = compare(g, c0, 1e-3, 1e-3);
      printf("split removed: %.3f%% pixels beyond 1e-3 of the frame without split lights\n",
             100 * s0.frac_bad);
      assert_true(s0.frac_bad < 0.02);
      OK(cv_renderer_set_split(F.r, ex, n, direct, &err));
      OK(cv_renderer_set_lighting(F.r, &l, NULL, NULL, &err));
    }
    free(geom);
    cv_image_destroy(g);
    cv_image_destroy(c);
    cv_image_destroy(c0);
  }
  assert_int_equal(cv_renderer_set_split(F.r, ex, -1, direct, &err), CV_ERR_INVALID);
  OK(cv_renderer_set_split(F.r, NULL, 0, NULL, &err));
  cv_image_destroy(bg);
  free(rad);
  free(rad0);
  free(direct);
  cv_scene_light_destroy(sl);
}

/* Depth EQUAL after the z pre-pass leaves no hole: with the targets cleared
 * to -1 first, no pixel keeps -1, and the image equals a single-pass
 * depth-LESS render except where coplanar triangles tie (<= 0.1%). */
static void test_no_holes(void **state) {
  (void)state;
  cv_render_opts o;
  cv_render_default_opts(&o);
  o.debug_clear = 1;
  cv_renderer *eq, *less;
  cv_err err;
  OK(cv_renderer_create(F.prt, &o, &eq, &err));
  o.depth_less = 1;
  OK(cv_renderer_create(F.prt, &o, &less, &err));
  cv_image *bg = const_bg();
  cv_renderer *rs[2] = {eq, less};
  /* the SH lighting, then a sky with a sun (the shading pass then draws
   * the sun-facing and the other triangles separately) */
  cv_scene_light *sl = sky_35_30();
  for (int li = 0; li < 2; li++)
  for (int k = 0; k < 2; k++) {
    cv_lighting l;
    if (li == 0) test_lighting(&l);
    else l = cv_scene_light_sh(sl);
    for (int i = 0; i < 2; i++) {
      OK(cv_renderer_set_lighting(rs[i], &l, NULL, NULL, &err));
      OK(cv_renderer_set_background(rs[i], bg, &err));
    }
    pose p = make_pose(k);
    p.w *= 2, p.h *= 2;
    cv_render_view v = make_view(&p, 1);
    cv_image *a, *b;
    assert_int_equal(cv_image_create(p.w, p.h, 3, &a), CV_OK);
    assert_int_equal(cv_image_create(p.w, p.h, 3, &b), CV_OK);
    OK(cv_renderer_shade(eq, &v, NULL, 0, NULL, a, NULL, &err));
    OK(cv_renderer_shade(less, &v, NULL, 0, NULL, b, NULL, &err));
    size_t holes = 0, differ = 0, n = (size_t)p.w * p.h;
    for (size_t i = 0; i < n; i++) {
      if (a->px[3 * i] == -1.0f || b->px[3 * i] == -1.0f) holes++;
      if (memcmp(a->px + 3 * i, b->px + 3 * i, 3 * sizeof(float))) differ++;
    }
    printf("%s, pose %d %dx%d: %zu holes, %zu pixels (%.4f%%) differ from depth LESS\n",
           li ? "sky + sun" : "SH lighting", k, p.w, p.h, holes, differ, 100.0 * differ / n);
    assert_int_equal(holes, 0);
    assert_true(differ <= n / 1000);
    cv_image_destroy(a);
    cv_image_destroy(b);
  }
  cv_image_destroy(bg);
  cv_scene_light_destroy(sl);
  cv_renderer_destroy(eq);
  cv_renderer_destroy(less);
}

/* A ramp of flat quads, each with its own 4 vertices and one radiance value
 * (bands 2, lighting l_0 = tint, td_0 = value, albedo 1, no interreflection,
 * so the relit radiance is value * tint exactly). */
#define RAMP_N 16
static cv_prt *ramp_prt(double *values) {
  cv_prt *p;
  const size_t nq = RAMP_N * RAMP_N;
  assert_int_equal(cv_prt_alloc(2, 4 * nq, 2 * nq, 1, 0, &p), CV_OK);
  snprintf(p->mats[0].name, sizeof p->mats[0].name, "ramp");
  for (int c = 0; c < 3; c++) p->mats[0].albedo[c] = 1;
  for (size_t q = 0; q < nq; q++) {
    int qx = (int)(q % RAMP_N), qy = (int)(q / RAMP_N);
    /* 0 first, then log-spaced 1e-4 .. 1e5 cd/m2 */
    values[q] = q == 0 ? 0.0 : pow(10.0, -4 + 9.0 * (double)(q - 1) / (nq - 2));
    for (int k = 0; k < 4; k++) {
      size_t v = 4 * q + k;
      p->pos[3 * v] = (float)(-1 + 2.0 * (qx + (k & 1)) / RAMP_N);
      p->pos[3 * v + 1] = (float)(-1 + 2.0 * (qy + (k >> 1)) / RAMP_N);
      p->pos[3 * v + 2] = -1;
      p->nrm[3 * v + 2] = 1;
      for (int c = 0; c < 3; c++) p->albedo[3 * v + c] = 1;
      p->td[4 * v] = (float)values[q];
    }
    uint32_t b = (uint32_t)(4 * q);
    uint32_t t[6] = {b, b + 1, b + 3, b, b + 3, b + 2};
    memcpy(p->tri + 6 * q, t, sizeof t);
  }
  return p;
}

/* exact: the shader's own log/pow (opts.tone_exact) instead of the tables. */
static void drago_ramp(int exact) {
  double values[RAMP_N * RAMP_N];
  cv_prt *p = ramp_prt(values);
  cv_renderer *r, *r8;
  cv_err err;
  cv_render_opts o;
  cv_render_default_opts(&o);
  o.tone_exact = exact;
  o.half_transfer = 0; /* the ramp's values exactly (halves would round them) */
  OK(cv_renderer_create(p, &o, &r8, &err)); /* default 8-bit display target */
  o.display_float = 1;
  OK(cv_renderer_create(p, &o, &r, &err));
  const int res = RAMP_N * 8;
  pose ps = {.pa = {-1, -1, -1}, .pb = {1, -1, -1}, .pc = {-1, 1, -1}, .eye = {0.1, -0.2, 0.5},
             .w = res, .h = res};
  cv_render_view v;
  memset(&v, 0, sizeof v);
  assert_int_equal(cv_offaxis_compute(ps.pa, ps.pb, ps.pc, ps.eye, 0.1, 10, &v.proj), CV_OK);
  v.w = v.h = res, v.supersample = 1;
  const double tints[2][3] = {{1, 1, 1}, {1.0, 0.45, 0.2}};
  /* (lwa, lwmax, bias): Lwmax/Lwa 100, 1.4e4, 4e7 (the clamp below Lwmax at
   * bias 0.85), 1e3 at bias 0.7 */
  const double lw[4][3] = {{1, 100, 0.85}, {0.37, 5e3, 0.85}, {2e-3, 8e4, 0.85}, {5, 5e3, 0.7}};
  double worst[2] = {0, 0}, worst8 = 0, tab_err = 0;
  cv_image *disp, *hdr, *cpu_in, *cpu_out, *disp8;
  assert_int_equal(cv_image_create(res, res, 3, &disp8), CV_OK);
  assert_int_equal(cv_image_create(res, res, 3, &disp), CV_OK);
  assert_int_equal(cv_image_create(res, res, 3, &hdr), CV_OK);
  assert_int_equal(cv_image_create(RAMP_N * RAMP_N, 1, 3, &cpu_in), CV_OK);
  assert_int_equal(cv_image_create(RAMP_N * RAMP_N, 1, 3, &cpu_out), CV_OK);
  for (int ti = 0; ti < 2; ti++) {
    cv_lighting l;
    memset(&l, 0, sizeof l);
    l.bands = 2;
    for (int c = 0; c < 3; c++) l.sh[c] = tints[ti][c];
    OK(cv_renderer_set_lighting(r, &l, NULL, NULL, &err));
    OK(cv_renderer_set_lighting(r8, &l, NULL, NULL, &err));
    for (int li = 0; li < 4; li++) {
      cv_drago d;
      cv_drago_default(&d);
      d.lwa = lw[li][0];
      d.lwmax = lw[li][1];
      d.bias = lw[li][2];
      cv_drago_consts dc;
      cv_drago_prepare(&d, &dc);
      for (int tr = 0; tr < 2; tr++) {
        OK(cv_renderer_shade(r, &v, &dc, tr, disp, hdr, NULL, &err));
        OK(cv_renderer_shade(r8, &v, &dc, tr, disp8, NULL, NULL, &err));
        double te;
        assert_int_equal(cv_renderer_tone_table(r, &te), !exact);
        tab_err = fmax(tab_err, te);
        for (int q = 0; q < RAMP_N * RAMP_N; q++)
          for (int c = 0; c < 3; c++) cpu_in->px[3 * q + c] = (float)(values[q] * tints[ti][c]);
        assert_int_equal(cv_drago_image(cpu_in, &d, tr, cpu_out, NULL), CV_OK);
        for (int q = 0; q < RAMP_N * RAMP_N; q++) {
          /* pixel at the quad's centre; rows flip (row 0 = top = +y) */
          int x = (q % RAMP_N) * 8 + 4, y = res - 1 - ((q / RAMP_N) * 8 + 4);
          const float *g = cv_image_at(disp, x, y), *h = cv_image_at(hdr, x, y),
                      *g8 = cv_image_at(disp8, x, y);
          for (int c = 0; c < 3; c++) {
            double want = cpu_out->px[3 * q + c], e = fabs(g[c] - want);
            if (ti == 0 && !tr)
              assert_near(cv_drago_map(&dc, values[q]), want, 1e-6); /* map = image, grey */
            worst[tr] = fmax(worst[tr], e);
            if (e > 1e-5)
              printf("value %g tint %d lwa %g ch %d transfer %d: GPU %.8f CPU %.8f\n", values[q], ti,
                     d.lwa, c, tr, g[c], want);
            assert_true(e <= 1e-5);
            /* 8-bit target: llvmpipe rounds to the nearest k/255 (1e-5 slack for
             * ties); the GL spec lets a GL take either of the two closest codes
             * ("rounding to nearest is preferred"), and NVIDIA's does */
            double e8 = fabs(g8[c] - want) * 255;
            worst8 = fmax(worst8, e8);
            assert_true(e8 <= (cv_renderer_is_software(r8) ? 0.5 + 255e-5 : 1.0));
            double hv = values[q] * tints[ti][c];
            assert_near(h[c], hv, 1e-6 * hv + 1e-30);
          }
        }
      }
    }
  }
  printf("Drago ramp, %s (%d values 0, 1e-4..1e5, 2 tints, 4 adaptations): max |GPU - CPU| "
         "%.2e display-linear, %.2e with Rec.709 transfer\n",
         exact ? "shader log/pow" : "Drago table + transfer polynomial", RAMP_N * RAMP_N,
         worst[0], worst[1]);
  if (!exact) printf("Drago table as built: max relative error %.2e (floor 1e-4)\n", tab_err);
  printf("8-bit display target: max |GPU - CPU| %.3f / 255\n", worst8);
  cv_image_destroy(disp8);
  cv_renderer_destroy(r8);
  cv_image_destroy(disp);
  cv_image_destroy(hdr);
  cv_image_destroy(cpu_in);
  cv_image_destroy(cpu_out);
  cv_renderer_destroy(r);
  cv_prt_destroy(p);
}

static void test_drago_ramp(void **state) {
  (void)state;
  drago_ramp(0);
}

static void test_drago_ramp_exact(void **state) {
  (void)state;
  drago_ramp(1);
}

/* The dashboard LCD (cv_renderer_set_panel, the shaders' PANEL variant):
 * a panel over the middle of the ramp's plane shows its image's radiance
 * in the HDR, luminance and display outputs, the ramp stays outside it, and
 * NaN texels are counted. */
static void test_panel(void **state) {
  (void)state;
  double values[RAMP_N * RAMP_N];
  cv_prt *p = ramp_prt(values);
  cv_renderer *r;
  cv_err err;
  cv_render_opts o;
  cv_render_default_opts(&o);
  o.display_float = 1;
  OK(cv_renderer_create(p, &o, &r, &err));
  cv_lighting l;
  memset(&l, 0, sizeof l);
  l.bands = 2;
  for (int c = 0; c < 3; c++) l.sh[c] = 1;
  OK(cv_renderer_set_lighting(r, &l, NULL, NULL, &err));
  const int res = 128;
  cv_render_view v;
  memset(&v, 0, sizeof v);
  const double pa[3] = {-1, -1, -1}, pb[3] = {1, -1, -1}, pc[3] = {-1, 1, -1}, eye[3] = {0.1, -0.2, 0.5};
  assert_int_equal(cv_offaxis_compute(pa, pb, pc, eye, 0.1, 10, &v.proj), CV_OK);
  v.w = v.h = res, v.supersample = 1;
  cv_image *img;
  assert_int_equal(cv_image_create(4, 4, 3, &img), CV_OK);
  const float rgb[3] = {7, 8, 9};
  for (int i = 0; i < 16; i++)
    for (int c = 0; c < 3; c++) img->px[3 * i + c] = rgb[c];
  img->px[0] = NAN;
  const float ctr[3] = {0, 0, -1}, u[3] = {1, 0, 0}, vv[3] = {0, 1, 0}, size[2] = {1, 1};
  OK(cv_renderer_set_panel(r, ctr, u, vv, size, img, &err));
  assert_int_equal(cv_renderer_panel_invalid(r), 1);
  img->px[0] = rgb[0];
  OK(cv_renderer_set_panel(r, ctr, u, vv, size, img, &err));
  assert_int_equal(cv_renderer_panel_invalid(r), 0);
  cv_image *hdr, *disp, *lm;
  assert_int_equal(cv_image_create(res, res, 3, &hdr), CV_OK);
  assert_int_equal(cv_image_create(res, res, 3, &disp), CV_OK);
  assert_int_equal(cv_image_create(res, res, 1, &lm), CV_OK);
  cv_drago d;
  cv_drago_default(&d);
  d.lwa = 2, d.lwmax = 50;
  cv_drago_consts dc;
  cv_drago_prepare(&d, &dc);
  OK(cv_renderer_luminance(r, &v, lm, NULL, &err));
  OK(cv_renderer_shade(r, &v, &dc, 1, disp, hdr, NULL, &err));
  const double y = lum(rgb), ld = cv_drago_map(&dc, y);
  int inside = 0, outside = 0, ramp = 0;
  double worst = 0;
  for (int py = 0; py < res; py++)
    for (int px = 0; px < res; px++) {
      double sx = -1 + 2.0 * (px + 0.5) / res, sy = 1 - 2.0 * (py + 0.5) / res;
      const float *h = cv_image_at(hdr, px, py), *g = cv_image_at(disp, px, py);
      if (fabs(sx) < 0.45 && fabs(sy) < 0.45) {
        inside++;
        for (int c = 0; c < 3; c++) {
          worst = fmax(worst, fabs(h[c] - rgb[c]) / rgb[c]);
          double want = cv_rec709_transfer(fmin(rgb[c] * ld / y, 1.0));
          worst = fmax(worst, fabs(g[c] - want));
        }
        worst = fmax(worst, fabs(lm->px[py * res + px] - y) / y);
      } else if (fabs(sx) > 0.55 || fabs(sy) > 0.55) {
        outside++;
        ramp += fabs(h[0] - rgb[0]) > 1e-3; /* the ramp's values are never 7 */
      }
    }
  printf("panel: %d pixels inside, max difference from the image (HDR, luminance relative; "
         "display absolute) %.2e; %d of %d pixels outside show the ramp\n", inside, worst, ramp,
         outside);
  assert_true(inside > 2500);
  assert_int_equal(ramp, outside);
  /* with a sun too (the SUN + PANEL variants): the panel still wins */
  l.has_sun = 1;
  l.sun_dir[0] = 0.3, l.sun_dir[1] = 0.2, l.sun_dir[2] = 1;
  l.sun_E[0] = l.sun_E[1] = l.sun_E[2] = 3;
  OK(cv_renderer_set_lighting(r, &l, NULL, NULL, &err));
  OK(cv_renderer_luminance(r, &v, lm, NULL, &err));
  OK(cv_renderer_shade(r, &v, &dc, 1, disp, hdr, NULL, &err));
  const float *mid = cv_image_at(hdr, res / 2, res / 2);
  for (int c = 0; c < 3; c++) assert_near(mid[c], rgb[c], 1e-5 * rgb[c]);
  assert_true(worst < 1e-5);
  cv_image_destroy(hdr);
  cv_image_destroy(disp);
  cv_image_destroy(lm);
  cv_image_destroy(img);
  cv_renderer_destroy(r);
  cv_prt_destroy(p);
}

/* The fixture's renderer lit by test_lighting in front of const_bg();
 * returns the background (the caller destroys it). */
static cv_image *lit_with_background(void) {
  cv_lighting l;
  test_lighting(&l);
  cv_err err;
  OK(cv_renderer_set_lighting(F.r, &l, NULL, NULL, &err));
  cv_image *bg = const_bg();
  OK(cv_renderer_set_background(F.r, bg, &err));
  return bg;
}

/* The luminance pass: (1) at the HDR frame's size it equals Y of the HDR
 * output within 1e-6 relative per pixel; (2) at 128x128 its log-average
 * (eps 1e-4) and mean are within 1% of a 512x512 HDR frame box-filtered
 * 4x4, and its maximum does not exceed the full frame's; (3) the HDR frame
 * downsampled by cv_lum_downsample (`cave run`'s luminance image) is that
 * box filter, close to the pass, with the frame's maximum. */
static void test_luminance_pass(void **state) {
  (void)state;
  cv_err err;
  cv_image *bg = lit_with_background();
  pose p = make_pose(1);
  p.w = p.h = 128;
  cv_render_view v = make_view(&p, 1);
  cv_image *lm, *hdr, *big;
  assert_int_equal(cv_image_create(128, 128, 1, &lm), CV_OK);
  assert_int_equal(cv_image_create(128, 128, 3, &hdr), CV_OK);
  assert_int_equal(cv_image_create(512, 512, 3, &big), CV_OK);
  OK(cv_renderer_luminance(F.r, &v, lm, NULL, &err));
  OK(cv_renderer_shade(F.r, &v, NULL, 0, NULL, hdr, NULL, &err));
  double worst = 0;
  for (int i = 0; i < 128 * 128; i++) {
    double y = lum(hdr->px + 3 * i);
    worst = fmax(worst, fabs(lm->px[i] - y) / (y + 1e-6));
  }
  printf("luminance pass vs Y(HDR) at 128x128: max relative difference %.2e\n", worst);
  assert_true(worst < 1e-6);
  v.w = v.h = 512;
  OK(cv_renderer_shade(F.r, &v, NULL, 0, NULL, big, NULL, &err));
  double la = 0, lb = 0, ma = 0, mb = 0, maxa = 0, maxb = 0;
  for (int y = 0; y < 128; y++)
    for (int x = 0; x < 128; x++) {
      double s = 0;
      for (int j = 0; j < 4; j++)
        for (int i = 0; i < 4; i++) {
          double yy = lum(cv_image_at(big, 4 * x + i, 4 * y + j));
          s += yy / 16;
          maxb = fmax(maxb, yy);
        }
      double a = lm->px[y * 128 + x];
      la += log(a + 1e-4), lb += log(s + 1e-4), ma += a, mb += s;
      maxa = fmax(maxa, a);
    }
  double n = 128.0 * 128.0;
  double ga = exp(la / n), gb = exp(lb / n);
  printf("128x128 luminance pass vs 512x512 HDR box-filtered: log-average %.5g vs %.5g (%.3f%%), "
         "mean %.5g vs %.5g (%.3f%%), max %.5g vs %.5g\n",
         ga, gb, 100 * (ga / gb - 1), ma / n, mb / n, 100 * (ma / mb - 1), maxa, maxb);
  assert_near(ga / gb, 1, 0.01);
  assert_near(ma / mb, 1, 0.01);
  assert_true(maxa <= maxb * (1 + 1e-6));
  /* (3) what `cave run` uses instead of the pass: cv_lum_downsample of the
   * HDR frame is that 4x4 box filter (1e-5 relative per pixel), its log-
   * average within 1% of the pass's, its max the frame's largest Y */
  cv_image *dl;
  assert_int_equal(cv_image_create(128, 128, 1, &dl), CV_OK);
  double my = -1, worst_box = 0, ld = 0;
  uint64_t nbad = 99;
  assert_int_equal(cv_lum_downsample(big, dl, &my, &nbad), CV_OK);
  for (int y = 0; y < 128; y++)
    for (int x = 0; x < 128; x++) {
      double s = 0;
      for (int j = 0; j < 4; j++)
        for (int i = 0; i < 4; i++) s += lum(cv_image_at(big, 4 * x + i, 4 * y + j)) / 16;
      const double d = dl->px[y * 128 + x];
      worst_box = fmax(worst_box, fabs(d - s) / (s + 1e-6));
      ld += log(d + 1e-4);
    }
  const double gd = exp(ld / n);
  printf("cv_lum_downsample of the 512x512 frame: box filter max relative difference %.2e, "
         "log-average %.5g vs the pass's %.5g (%.3f%%), max %.5g (frame %.5g), %llu invalid\n",
         worst_box, gd, ga, 100 * (gd / ga - 1), my, maxb, (unsigned long long)nbad);
  assert_true(worst_box < 1e-5);
  assert_near(gd / ga, 1, 0.01);
  assert_near(my, maxb, 1e-6 * maxb);
  assert_int_equal(nbad, 0);
  cv_image_destroy(dl);
  cv_image_destroy(lm);
  cv_image_destroy(hdr);
  cv_image_destroy(big);
  cv_image_destroy(bg);
}

/* cv_renderer_shade_stats: the luminance image, max and invalid count
 * reduced on the GPU (opts.lum_stats_gpu = 1) equal cv_lum_downsample of
 * the HDR frame (1e-5 relative; exactly for the count), at non-integer
 * ratios, with 2x supersampling, and on an HDR target holding NaN, Inf,
 * negative and -0 pixels; the display image is unchanged by the reduction
 * (bit-equal); on the CPU (lum_stats_gpu = 0, llvmpipe's default) they are
 * cv_lum_downsample's, bit for bit. */
static void lum_stats_compare(const cv_image *hdr, const cv_image *gpu, double gmax, uint64_t gbad,
                              const char *what) {
  cv_image *cpu;
  assert_int_equal(cv_image_create(gpu->w, gpu->h, 1, &cpu), CV_OK);
  double cmax = -1, worst = 0;
  uint64_t cbad = 99;
  assert_int_equal(cv_lum_downsample(hdr, cpu, &cmax, &cbad), CV_OK);
  size_t nan_both = 0;
  for (int i = 0; i < gpu->w * gpu->h; i++) {
    const double a = gpu->px[i], b = cpu->px[i];
    if (isnan(a) || isnan(b)) {
      assert_true(isnan(a) && isnan(b));
      nan_both++;
      continue;
    }
    worst = fmax(worst, fabs(a - b) / (fabs(b) + 1e-30));
  }
  printf("%s: GPU luminance statistics %dx%d of %dx%d vs cv_lum_downsample: max relative difference "
         "%.2e, max %.6g vs %.6g, invalid %llu vs %llu, NaN pixels %zu\n",
         what, gpu->w, gpu->h, hdr->w, hdr->h, worst, gmax, cmax, (unsigned long long)gbad,
         (unsigned long long)cbad, nan_both);
  assert_true(worst < 1e-5);
  assert_near(gmax, cmax, 1e-6 * cmax);
  assert_int_equal(gbad, cbad);
  cv_image_destroy(cpu);
}

static void test_lum_stats_gpu(void **state) {
  (void)state;
  cv_err err;
  cv_image *bg = lit_with_background();
  cv_drago d;
  cv_drago_default(&d);
  cv_drago_consts dc;
  cv_drago_prepare(&d, &dc);
  F.r->o.lum_stats_gpu = 1;
  assert_true(cv_renderer_lum_stats_on_gpu(F.r));
  /* (1) 250 x 190 into 64 x 48, 37 x 29 and 300 x 201 (non-integer ratios) */
  pose p = make_pose(1);
  p.w = 250, p.h = 190;
  cv_render_view v = make_view(&p, 1);
  cv_image *hdr, *disp, *disp2, *lum;
  assert_int_equal(cv_image_create(250, 190, 3, &hdr), CV_OK);
  assert_int_equal(cv_image_create(250, 190, 3, &disp), CV_OK);
  assert_int_equal(cv_image_create(250, 190, 3, &disp2), CV_OK);
  const int sizes[3][2] = {{64, 48}, {37, 29}, {300, 201}}; /* the last larger than the frame */
  for (int k = 0; k < 3; k++) {
    assert_int_equal(cv_image_create(sizes[k][0], sizes[k][1], 1, &lum), CV_OK);
    double mx = -1;
    uint64_t bad = 99;
    cv_frame_timing t = {0};
    OK(cv_renderer_shade_stats(F.r, &v, &dc, 0, disp, hdr, lum, &mx, &bad, &t, &err));
    lum_stats_compare(hdr, lum, mx, bad, "250x190");
    OK(cv_renderer_shade(F.r, &v, &dc, 0, disp2, NULL, NULL, &err));
    assert_memory_equal(disp->px, disp2->px, 3 * 250 * 190 * sizeof(float));
    /* without the HDR read-back: the same statistics */
    cv_image *lum2;
    assert_int_equal(cv_image_create(sizes[k][0], sizes[k][1], 1, &lum2), CV_OK);
    double mx2 = -1;
    uint64_t bad2 = 99;
    OK(cv_renderer_shade_stats(F.r, &v, &dc, 0, disp2, NULL, lum2, &mx2, &bad2, NULL, &err));
    assert_memory_equal(lum->px, lum2->px, (size_t)lum->w * lum->h * sizeof(float));
    assert_true(mx == mx2 && bad == bad2);
    assert_memory_equal(disp->px, disp2->px, 3 * 250 * 190 * sizeof(float));
    cv_image_destroy(lum2);
    cv_image_destroy(lum);
  }
  /* (2) 2x supersampling: the statistics of the resolved HDR image */
  p.w = 96, p.h = 72;
  v = make_view(&p, 2);
  cv_image *h2;
  assert_int_equal(cv_image_create(96, 72, 3, &h2), CV_OK);
  assert_int_equal(cv_image_create(40, 30, 1, &lum), CV_OK);
  double mx = -1;
  uint64_t bad = 99;
  OK(cv_renderer_shade_stats(F.r, &v, NULL, 0, NULL, h2, lum, &mx, &bad, NULL, &err));
  lum_stats_compare(h2, lum, mx, bad, "96x72, 2x supersampled");
  cv_image_destroy(lum);
  /* (3) invalid pixels, written into the HDR target: NaN, +Inf, -1, -0 and
   * a footprint of invalid pixels only */
  p.w = 50, p.h = 40;
  v = make_view(&p, 1);
  cv_image *h3;
  assert_int_equal(cv_image_create(50, 40, 3, &h3), CV_OK);
  assert_int_equal(cv_image_create(7, 6, 1, &lum), CV_OK);
  OK(cv_renderer_shade_stats(F.r, &v, NULL, 0, NULL, h3, lum, NULL, NULL, NULL, &err));
  for (int y = 0; y < 40; y++)
    for (int x = 0; x < 50; x++) {
      float *q = h3->px + 3 * (size_t)(y * 50 + x);
      if ((x * 7 + y * 3) % 11 == 0) q[1] = NAN;
      if ((x + 5 * y) % 13 == 0) q[0] = INFINITY;
      if ((3 * x + y) % 17 == 0) q[2] = -1.0f;
      if ((x + y) % 19 == 0) q[0] = -0.0f;
      if (x < 7 && y < 6) q[2] = NAN; /* the first footprint (x 0..7.1, y 0..6.7): all invalid */
      if (x == 7 && y < 7) q[2] = NAN;
      if (y == 6 && x < 8) q[2] = NAN;
    }
  float *rgba = malloc(4 * 50 * 40 * sizeof *rgba);
  for (int y = 0; y < 40; y++)
    for (int x = 0; x < 50; x++)
      for (int c = 0; c < 4; c++)
        rgba[4 * ((39 - y) * 50 + x) + c] = c < 3 ? h3->px[3 * (y * 50 + x) + c] : 1.0f;
  glBindTexture(GL_TEXTURE_2D, F.r->passes.targets.tex_hdr);
  glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, 50, 40, GL_RGBA, GL_FLOAT, rgba);
  glBindTexture(GL_TEXTURE_2D, 0);
  free(rgba);
  mx = -1, bad = 0;
  OK(cvr_reduce_luminance(&F.r->ctx, &F.r->passes, 50, 40, 1, lum, &mx, &bad, &err));
  assert_true(isnan(lum->px[0]));
  assert_true(bad > 100);
  lum_stats_compare(h3, lum, mx, bad, "50x40 with invalid pixels");
  /* (4) on the CPU: cv_lum_downsample of the read-back HDR image */
  F.r->o.lum_stats_gpu = 0;
  assert_false(cv_renderer_lum_stats_on_gpu(F.r));
  p.w = 250, p.h = 190;
  v = make_view(&p, 1);
  cv_image *lc, *lw;
  assert_int_equal(cv_image_create(64, 48, 1, &lc), CV_OK);
  assert_int_equal(cv_image_create(64, 48, 1, &lw), CV_OK);
  double mc = -1, mw = -2;
  uint64_t bc = 99, bw = 98;
  OK(cv_renderer_shade_stats(F.r, &v, &dc, 0, disp2, NULL, lc, &mc, &bc, NULL, &err));
  OK(cv_renderer_shade(F.r, &v, &dc, 0, NULL, hdr, NULL, &err));
  assert_int_equal(cv_lum_downsample(hdr, lw, &mw, &bw), CV_OK);
  assert_memory_equal(lc->px, lw->px, 64 * 48 * sizeof(float));
  assert_true(mc == mw && bc == bw);
  cv_image_destroy(lc);
  cv_image_destroy(lw);
  F.r->o.lum_stats_gpu = -1;
  assert_int_equal(cv_renderer_lum_stats_on_gpu(F.r), !cv_renderer_is_software(F.r));
  /* bad shapes */
  cv_image *three;
  assert_int_equal(cv_image_create(7, 6, 3, &three), CV_OK);
  assert_int_equal(cv_renderer_shade_stats(F.r, &v, NULL, 0, NULL, NULL, three, NULL, NULL, NULL, &err),
                   CV_ERR_INVALID);
  cv_image_destroy(three);
  cv_image_destroy(lum);
  cv_image_destroy(h3);
  cv_image_destroy(h2);
  cv_image_destroy(hdr);
  cv_image_destroy(disp);
  cv_image_destroy(disp2);
  cv_image_destroy(bg);
}

/* 2x supersampling equals a 2x-size render box-filtered on the CPU (1e-6),
 * for the HDR and the tone-mapped outputs. */
static void test_supersample(void **state) {
  (void)state;
  cv_lighting l;
  test_lighting(&l);
  cv_err err;
  OK(cv_renderer_set_lighting(F.r, &l, NULL, NULL, &err));
  pose p = make_pose(0);
  p.w = 96, p.h = 72;
  cv_render_view v = make_view(&p, 2);
  cv_drago d;
  cv_drago_default(&d);
  cv_drago_consts dc;
  cv_drago_prepare(&d, &dc);
  cv_image *ss_d, *ss_h, *big_d, *big_h;
  assert_int_equal(cv_image_create(96, 72, 3, &ss_d), CV_OK);
  assert_int_equal(cv_image_create(96, 72, 3, &ss_h), CV_OK);
  assert_int_equal(cv_image_create(192, 144, 3, &big_d), CV_OK);
  assert_int_equal(cv_image_create(192, 144, 3, &big_h), CV_OK);
  OK(cv_renderer_shade(F.r, &v, &dc, 1, ss_d, ss_h, NULL, &err));
  v.w = 192, v.h = 144, v.supersample = 1;
  OK(cv_renderer_shade(F.r, &v, &dc, 1, big_d, big_h, NULL, &err));
  double worst = 0;
  for (int y = 0; y < 72; y++)
    for (int x = 0; x < 96; x++)
      for (int c = 0; c < 3; c++) {
        const cv_image *pairs[2][2] = {{ss_d, big_d}, {ss_h, big_h}};
        for (int k = 0; k < 2; k++) {
          double s = 0;
          for (int j = 0; j < 2; j++)
            for (int i = 0; i < 2; i++) s += cv_image_at(pairs[k][1], 2 * x + i, 2 * y + j)[c];
          double want = s / 4, got = cv_image_at(pairs[k][0], x, y)[c];
          worst = fmax(worst, fabs(got - want) / (fabs(want) + 1e-3));
        }
      }
  printf("2x supersampling vs CPU box filter of a 2x render: max relative difference %.2e\n", worst);
  assert_true(worst < 1e-6);
  cv_image_destroy(ss_d);
  cv_image_destroy(ss_h);
  cv_image_destroy(big_d);
  cv_image_destroy(big_h);
}

static void test_errors(void **state) {
  (void)state;
  cv_err err;
  cv_lighting l;
  test_lighting(&l);
  l.bands = 3; /* the scene has 5 */
  assert_int_equal(cv_renderer_set_lighting(F.r, &l, NULL, NULL, &err), CV_ERR_RANGE);
  assert_non_null(strstr(err.msg, "bands"));
  test_lighting(&l);
  l.sh[4] = NAN;
  assert_int_equal(cv_renderer_set_lighting(F.r, &l, NULL, NULL, &err), CV_ERR_NONFINITE);
  test_lighting(&l);
  OK(cv_renderer_set_lighting(F.r, &l, NULL, NULL, &err));
  pose p = make_pose(0);
  cv_render_view v = make_view(&p, 3);
  cv_image *img;
  assert_int_equal(cv_image_create(p.w, p.h, 3, &img), CV_OK);
  assert_int_equal(cv_renderer_shade(F.r, &v, NULL, 0, NULL, img, NULL, &err), CV_ERR_INVALID);
  assert_non_null(strstr(err.msg, "supersample"));
  v.supersample = 1;
  assert_int_equal(cv_renderer_shade(F.r, &v, NULL, 0, img, NULL, NULL, &err), CV_ERR_INVALID);
  v.w += 1;
  assert_int_equal(cv_renderer_shade(F.r, &v, NULL, 0, NULL, img, NULL, &err), CV_ERR_INVALID);
  cv_image_destroy(img);
  cv_renderer *r;
  OK(cv_renderer_create(F.prt, NULL, &r, &err));
  cv_image *lm;
  assert_int_equal(cv_image_create(16, 16, 1, &lm), CV_OK);
  assert_int_equal(cv_renderer_luminance(r, &v, lm, NULL, &err), CV_ERR_INVALID); /* no lighting */
  assert_non_null(strstr(err.msg, "lighting"));
  cv_image_destroy(lm);
  cv_renderer_destroy(r);
  cv_renderer_destroy(NULL);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_gl_matches_cpu),  cmocka_unit_test(test_gl_matches_cpu_half),
      cmocka_unit_test(test_gl_matches_cpu_culled), cmocka_unit_test(test_gl_sun), cmocka_unit_test(test_gl_split), cmocka_unit_test(test_gl_sun_cull_reuse), cmocka_unit_test(test_cpu_relight_and_casters), cmocka_unit_test(test_cpu_relight_half), cmocka_unit_test(test_sun_matrices_fit), cmocka_unit_test(test_half_conversions), cmocka_unit_test(test_mesh_closed),          cmocka_unit_test(test_no_holes),
      cmocka_unit_test(test_drago_ramp),      cmocka_unit_test(test_drago_ramp_exact),
      cmocka_unit_test(test_panel),           cmocka_unit_test(test_luminance_pass), cmocka_unit_test(test_lum_stats_gpu),
      cmocka_unit_test(test_supersample),     cmocka_unit_test(test_errors),
  };
  return cmocka_run_group_tests(tests, setup, teardown);
}
