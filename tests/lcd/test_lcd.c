/* LCD panel final gather (src/lcd) against closed forms and independent
 * references:
 *  - Lambertian table of albedo a under a constant environment L and a sun:
 *    a*L + a/pi*E*cos (cosine sampling exactly, BRDF sampling and MIS 0.5%);
 *  - a mirror-like table reflects a four-level environment pattern to the
 *    right quadrants of the panel (4% at 256 samples, against the table's
 *    albedo at each texel's view angle);
 *  - the sampling pdf integrates to 1 (fine quadrature, 1e-3), matches the
 *    density the samples report, is continuous across cell edges, is within
 *    10% of f cos / albedo, and chi-square tests of 200000 samples against
 *    the pdf's own mass (independent quadrature) pass at p = 0.001, on
 *    5 x 10 degree bins and on 0.25 degree bins at the mirror peak;
 *  - window sampling and its MIS: in the cabin with interior and
 *    environment at the same radiance L a Lambertian table reads a*L (0.2%
 *    mean over texels, 10% per texel at 256 samples) for four strategy mixes;
 *  - fixed-point sums are bit-identical under permutation and split of the
 *    rounds, tiles and thread counts (and differ for other rounds);
 *  - keys and progressive restart; accumulation file round trip;
 *  - a MERL file written here reads back (Lambertian R, theta_half-indexed G,
 *    missing B samples counted);
 *  - bad BRDF files give one clear error naming the file and the entry;
 *  - the built-in anti-glare table conserves energy; the panel frame read
 *    from the cabin's LCD triangles equals the generator's. */
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

#include "lcd/accum.h"
#include "lcd/brdf.h"
#include "lcd/brdf_sample.h"
#include "lcd/gather.h"
#include "mesh/cabin.h"
#include "rt/rt.h"

#define TMP(name) CV_TEST_TMP_DIR "/" name

/* splitmix64: an independent PRNG for the statistical tests */
static uint64_t rng_state = 12345;
static double rnd(void) {
  uint64_t z = (rng_state += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  z ^= z >> 31;
  return (double)(z >> 11) * 0x1p-53;
}

/* A lone LCD quad (the only geometry: every ray that misses it reaches the
 * environment), centred at the origin with the given unit normal. */
static cv_mesh *panel_mesh(const float n[3]) {
  cv_mesh *m;
  cv_mesh_create(&m);
  uint32_t mat;
  const float alb[3] = {0.05f, 0.05f, 0.05f};
  cv_mesh_add_material(m, "lcd", alb, CV_MAT_LCD, &mat);
  float u[3] = {n[2], 0, -n[0]}; /* +Y x n */
  float ul = sqrtf(u[0] * u[0] + u[2] * u[2]);
  u[0] /= ul, u[2] /= ul;
  float v[3] = {n[1] * u[2] - n[2] * u[1], n[2] * u[0] - n[0] * u[2], n[0] * u[1] - n[1] * u[0]};
  const float hw = 0.1f, hh = 0.06f;
  const float c[4][2] = {{-hw, -hh}, {hw, -hh}, {hw, hh}, {-hw, hh}};
  for (int k = 0; k < 4; k++)
    cv_mesh_add_vertex(m, c[k][0] * u[0] + c[k][1] * v[0], c[k][0] * u[1] + c[k][1] * v[1],
                       c[k][0] * u[2] + c[k][1] * v[2], NULL);
  cv_mesh_add_tri(m, 0, 1, 2, mat);
  cv_mesh_add_tri(m, 0, 2, 3, mat);
  return m;
}

typedef struct {
  cv_mesh *m;
  cv_rt *rt;
  cv_lcd_panel panel;
  cv_lcd_gather *g;
} scene;

static void scene_make(scene *s, cv_mesh *m, const cv_brdf *b) {
  cv_err err;
  s->m = m;
  assert_int_equal(cv_rt_create(m, &s->rt, &err), CV_OK);
  assert_int_equal(cv_lcd_panel_from_mesh(m, &s->panel, &err), CV_OK);
  assert_int_equal(cv_lcd_gather_create(s->rt, m, &s->panel, b, &s->g, &err), CV_OK);
}

static void scene_free(scene *s) {
  cv_lcd_gather_destroy(s->g);
  cv_rt_destroy(s->rt);
  cv_mesh_destroy(s->m);
}

static cv_brdf *lambert_table(const float a[3]) {
  cv_brdf *b;
  assert_int_equal(cv_brdf_alloc(91, 181, &b), CV_OK);
  size_t n = (size_t)91 * 91 * 181;
  for (size_t i = 0; i < n; i++)
    for (int c = 0; c < 3; c++) b->f[3 * i + c] = (float)(a[c] / M_PI);
  cv_brdf_rehash(b);
  return b;
}

/* Envmap from a function of the direction (pixel centres, latlong layout). */
static cv_envmap *env_from(int w, void (*fn)(const double d[3], float rgb[3])) {
  cv_envmap *e;
  assert_int_equal(cv_envmap_create(w, w / 2, &e), CV_OK);
  for (int y = 0; y < w / 2; y++)
    for (int x = 0; x < w; x++) {
      double th = M_PI * (y + 0.5) / (w / 2), ph = 2 * M_PI * ((x + 0.5) / w - 0.5);
      double d[3] = {sin(th) * sin(ph), cos(th), -sin(th) * cos(ph)};
      fn(d, cv_image_at(e->img, x, y));
    }
  return e;
}

static void env_const(const double d[3], float rgb[3]) {
  (void)d;
  rgb[0] = 1, rgb[1] = 2, rgb[2] = 3;
}

/* --- 1. Lambertian under a constant environment and a sun ---------------- */

static void test_lambert_constant(void **state) {
  (void)state;
  const float a[3] = {0.6f, 0.5f, 0.4f}, n[3] = {0, 0.2060f, 0.9786f};
  cv_brdf *b = lambert_table(a);
  scene s;
  scene_make(&s, panel_mesh(n), b);
  cv_envmap *env = env_from(64, env_const);
  const double sd[3] = {0.3, 0.5, 0.8124}, E[3] = {50, 40, 30};
  double sl = sqrt(sd[0] * sd[0] + sd[1] * sd[1] + sd[2] * sd[2]);
  double nl = sqrt((double)n[1] * n[1] + (double)n[2] * n[2]);
  double cs = (sd[1] * n[1] + sd[2] * n[2]) / sl / nl;
  cv_lcd_light *l;
  assert_int_equal(cv_lcd_light_create(env, NULL, s.m->nv, 1, sd, E, &l), CV_OK);
  const double strat[3] = {0.0, 1.0, 0.5}, tol[3] = {1e-5, 5e-3, 5e-3};
  for (int k = 0; k < 3; k++) {
    cv_lcd_params p;
    cv_lcd_params_default(&p);
    p.w = 16, p.h = 12, p.spp = 64;
    p.eye[0] = -0.2f, p.eye[1] = 0.3f, p.eye[2] = 0.6f;
    p.brdf_fraction = strat[k];
    p.env_fraction = 0; /* BRDF and cosine alone: cosine sampling is then exact per sample */
    cv_lcd_accum *acc;
    assert_int_equal(cv_lcd_accum_create(p.w, p.h, cv_lcd_default_clamp(l, b), &acc), CV_OK);
    assert_int_equal(cv_lcd_render_round(s.g, l, &p, 0, acc), CV_OK);
    cv_image *img;
    assert_int_equal(cv_lcd_accum_to_image(acc, NULL, &img), CV_OK);
    double worst = 0, mean[3] = {0, 0, 0};
    for (int i = 0; i < p.w * p.h; i++)
      for (int c = 0; c < 3; c++) {
        double want = a[c] * (c + 1) + a[c] / M_PI * E[c] * cs;
        double got = img->px[3 * i + c];
        mean[c] += got / (p.w * p.h);
        worst = fmax(worst, fabs(got / want - 1));
      }
    print_message("lambert c=%.1f: worst texel rel. error %.2e, mean R %.6f (want %.6f)\n",
                  strat[k], worst, mean[0], a[0] * 1 + a[0] / M_PI * E[0] * cs);
    for (int c = 0; c < 3; c++) {
      double want = a[c] * (c + 1) + a[c] / M_PI * E[c] * cs;
      assert_near(mean[c] / want, 1, tol[k]);
    }
    /* cosine sampling is exact per sample but for the sun's term: its one
     * direction per round, drawn in the solar disc (half angle alpha), has
     * a cosine within sin(theta_s) sin(alpha) + 1 - cos(alpha) of the
     * disc centre's */
    const double al = CV_LCD_SUN_HALF_ANGLE_DEG * M_PI / 180;
    const double dcos = sqrt(1 - cs * cs) * sin(al) + 1 - cos(al);
    double bound = 0;
    for (int c = 0; c < 3; c++) {
      const double sun = a[c] / M_PI * E[c], all = a[c] * (c + 1) + sun * cs;
      bound = fmax(bound, sun * (dcos + 2e-5 * cs) / all); /* 2e-5: the disc's E factor */
    }
    if (k == 0) assert_true(worst < 1e-5 + bound);
    else assert_true(worst < 0.03);
    assert_int_equal(acc->data[CV_LCD_ACC_SHADOW], p.w * p.h);
    assert_int_equal(acc->data[CV_LCD_ACC_SUNLIT], p.w * p.h);
    assert_int_equal(acc->data[CV_LCD_ACC_HITS], 0);
    assert_int_equal(acc->data[CV_LCD_ACC_CLAMPED] + acc->data[CV_LCD_ACC_NONFINITE], 0);
    cv_image_destroy(img);
    cv_lcd_accum_destroy(acc);
  }
  cv_lcd_light_destroy(l);
  cv_envmap_destroy(env);
  scene_free(&s);
  cv_brdf_destroy(b);
}

/* --- 2. mirror-like table, known pattern ---------------------------------- */

static void env_quadrants(const double d[3], float rgb[3]) {
  float v = (d[0] > 0 ? 1.0f : 0.25f) * (d[1] > 0 ? 1.0f : 0.5f);
  rgb[0] = rgb[1] = rgb[2] = v;
}

static void test_mirror_pattern(void **state) {
  (void)state;
  cv_antiglare_params ap = {.rd = 0, .rs = 0.9, .sigma_s_deg = 1.0, .rh = 0, .sigma_h_deg = 1};
  cv_brdf *b;
  assert_int_equal(cv_brdf_antiglare(&ap, 91, 181, &b), CV_OK);
  double alb[3 * 91];
  cv_brdf_report rep;
  assert_int_equal(cv_brdf_validate(b, &rep, alb, NULL), CV_OK);
  const float n[3] = {0, 0, 1};
  scene s;
  scene_make(&s, panel_mesh(n), b);
  cv_envmap *env = env_from(512, env_quadrants);
  cv_lcd_light *l;
  assert_int_equal(cv_lcd_light_create(env, NULL, s.m->nv, 0, NULL, NULL, &l), CV_OK);
  cv_lcd_params p;
  cv_lcd_params_default(&p);
  p.w = 40, p.h = 24, p.spp = 256, p.brdf_fraction = 1;
  p.eye[0] = 0, p.eye[1] = 0, p.eye[2] = 0.3f;
  cv_lcd_accum *acc;
  assert_int_equal(cv_lcd_accum_create(p.w, p.h, cv_lcd_default_clamp(l, b), &acc), CV_OK);
  assert_int_equal(cv_lcd_render_round(s.g, l, &p, 0, acc), CV_OK);
  cv_image *img;
  assert_int_equal(cv_lcd_accum_to_image(acc, NULL, &img), CV_OK);
  int checked = 0;
  double worst = 0;
  for (int y = 0; y < p.h; y++)
    for (int x = 0; x < p.w; x++) {
      /* texel centre on the panel (u = +X, v = +Y, row 0 at the top) */
      double px = ((x + 0.5) / p.w - 0.5) * 0.2, py = (0.5 - (y + 0.5) / p.h) * 0.12;
      /* the mirror direction is (px, py, 0.3)/r: skip texels within 6 degrees of an edge */
      if (fabs(px) < 0.3 * tan(6 * M_PI / 180) || fabs(py) < 0.3 * tan(6 * M_PI / 180)) continue;
      double want_l = (px > 0 ? 1.0 : 0.25) * (py > 0 ? 1.0 : 0.5);
      double r = sqrt(px * px + py * py + 0.09), to = acos(0.3 / r) * 180 / M_PI;
      int k = (int)to;
      double t = to - k, rho = (1 - t) * alb[3 * k] + t * alb[3 * (k + 1)];
      double got = cv_image_at(img, x, y)[1];
      worst = fmax(worst, fabs(got / (rho * want_l) - 1));
      checked++;
    }
  print_message("mirror: %d texels checked, worst rel. error %.3f (table albedo %.3f at normal)\n",
                checked, worst, alb[0]);
  assert_true(checked >= 200);
  assert_true(worst < 0.04);
  assert_true(alb[0] > 0.8 && alb[0] <= 1);
  cv_image_destroy(img);
  cv_lcd_accum_destroy(acc);
  cv_lcd_light_destroy(l);
  cv_envmap_destroy(env);
  scene_free(&s);
  cv_brdf_destroy(b);
}

/* --- 3. sampling: pdf normalisation, consistency, chi-square -------------- */

/* Chi-square statistic of observed counts against expected ones (bins
 * expecting fewer than 5 pooled), and the critical value at p = 0.001
 * (Wilson-Hilferty). */
static void chi2_stat(const double *obs, const double *expct, int nb, double n, double *chi2,
                      double *crit, int *dof_out) {
  double c = 0, rest_e = 0, rest_o = 0;
  int bins = 0;
  for (int i = 0; i < nb; i++) {
    double e = expct[i] * n;
    if (e < 5) {
      rest_e += e;
      rest_o += obs[i];
      continue;
    }
    c += (obs[i] - e) * (obs[i] - e) / e;
    bins++;
  }
  if (rest_e > 0) {
    c += (rest_o - rest_e) * (rest_o - rest_e) / fmax(rest_e, 1);
    bins++;
  }
  double dof = bins - 1, z = 3.09;
  *chi2 = c;
  *crit = dof * pow(1 - 2 / (9 * dof) + z * sqrt(2 / (9 * dof)), 3);
  *dof_out = bins - 1;
}

/* Integral of the sampler's pdf over theta in [t0, t1], phi_d in [p0, p1]
 * (radians, both azimuth sides), by a q x q midpoint rule: an independent
 * quadrature of the density the sampler claims. */
static double pdf_mass(const cv_brdf_sampler *s, int k, float t, double t0, double t1, double p0,
                       double p1, int q) {
  double acc = 0, dt = (t1 - t0) / q, dp = (p1 - p0) / q;
  for (int i = 0; i < q; i++) {
    double th = t0 + (i + 0.5) * dt;
    for (int j = 0; j < q; j++)
      acc += cv_brdf_pdf(s, k, t, (float)th, (float)(p0 + (j + 0.5) * dp)) * sin(th);
  }
  return 2 * acc * dt * dp;
}

static void test_sampling_pdf_chi2(void **state) {
  (void)state;
  cv_brdf *b;
  cv_brdf_report rep;
  cv_err err;
  assert_int_equal(cv_brdf_load(CV_BRDF_BUILTIN_ANTIGLARE, &b, &rep, &err), CV_OK);
  cv_brdf_sampler *s;
  assert_int_equal(cv_brdf_sampler_create(b, &s), CV_OK);
  double alb[3 * 91];
  assert_int_equal(cv_brdf_validate(b, NULL, alb, &err), CV_OK);
  const double views[4] = {0.3, 20.5, 45.0, 75.2};
  const double D = M_PI / 180;
  for (int v = 0; v < 4; v++) {
    float to = (float)(views[v] * D);
    int k;
    float t;
    cv_brdf_view_bins(s, to, &k, &t);
    /* (a) integral of the pdf over the hemisphere: midpoint rule on a grid
     * of 0.05 degrees, aligned with the 1-degree cells */
    const int nth = 1800, nph = 3600;
    double integ = 0;
    for (int i = 0; i < nth; i++) {
      double th = (i + 0.5) * (M_PI / 2) / nth;
      double dom = sin(th) * (M_PI / 2 / nth) * (M_PI / nph) * 2; /* both azimuth sides */
      for (int j = 0; j < nph; j++) {
        double ph = (j + 0.5) * M_PI / nph;
        integ += cv_brdf_pdf(s, k, t, (float)th, (float)ph) * dom;
      }
    }
    /* (b) chi-square of samples against the pdf's own mass (independent
     * quadrature) over 5 x 10 degree bins of (theta_i, phi_d), and (c) over
     * 0.25 x 0.5 degree bins within 3 degrees of the mirror direction, where
     * the continuous sampling inside the 1-degree cells shows */
    enum { BT = 18, BP = 18, FT = 24, FP = 12, N = 200000 };
    double expct[BT * BP], obs[BT * BP], fexp[FT * FP], fobs[FT * FP];
    memset(obs, 0, sizeof obs);
    memset(fobs, 0, sizeof fobs);
    for (int bt = 0; bt < BT; bt++)
      for (int bp = 0; bp < BP; bp++)
        expct[bt * BP + bp] = pdf_mass(s, k, t, bt * 5 * D, (bt + 1) * 5 * D, bp * 10 * D,
                                       (bp + 1) * 10 * D, 40);
    const double ft0 = fmax(0, views[v] - 3), fp0 = 177; /* degrees */
    double fin = 0;
    for (int bt = 0; bt < FT; bt++)
      for (int bp = 0; bp < FP; bp++) {
        double m = pdf_mass(s, k, t, (ft0 + 0.25 * bt) * D, (ft0 + 0.25 * (bt + 1)) * D,
                            (fp0 + 0.25 * bp) * D, (fp0 + 0.25 * (bp + 1)) * D, 8);
        fexp[bt * FP + bp] = m;
        fin += m;
      }
    /* (d) the pdf matches f cos / albedo (what it approximates) to a few
     * percent where f is not tiny: the x = sin^2 interpolation differs from
     * the theta one only inside cells */
    double worst_ratio = 0;
    const double rho = (1 - (views[v] - (int)views[v])) * alb[3 * (int)views[v] + 1] +
                       (views[v] - (int)views[v]) * alb[3 * ((int)views[v] + 1) + 1];
    for (int i = 0; i < 400; i++) {
      double th = (1 + 87.5 * rnd()) * D, ph = M_PI * rnd();
      float f[3];
      cv_brdf_eval(b, th, to, ph, f);
      double want = f[1] * cos(th) / rho, got = cv_brdf_pdf(s, k, t, (float)th, (float)ph);
      worst_ratio = fmax(worst_ratio, fabs(got / want - 1));
    }
    int mismatch = 0;
    for (int i = 0; i < N; i++) {
      float u[2] = {(float)rnd(), (float)rnd()}, wi[3], th, ph, pdf, f[3];
      assert_true(cv_brdf_sample(s, k, t, u, wi, &th, &ph, &pdf, f));
      assert_true(wi[2] >= 0);
      assert_near(wi[0] * wi[0] + wi[1] * wi[1] + wi[2] * wi[2], 1, 1e-5f);
      float p2 = cv_brdf_pdf(s, k, t, th, ph);
      if (fabsf(p2 / pdf - 1) > 1e-4f) mismatch++;
      float fe[3];
      cv_brdf_eval(b, th, to, ph, fe);
      assert_near(f[1], fe[1], 1e-4f * fe[1] + 1e-9f); /* f returned = the table's */
      int bt = (int)(th / D / 5), bp = (int)(ph / D / 10);
      if (bt > BT - 1) bt = BT - 1;
      if (bp > BP - 1) bp = BP - 1;
      obs[bt * BP + bp]++;
      double ft = (th / D - ft0) / 0.25, fp = (ph / D - fp0) / 0.25;
      if (ft >= 0 && ft < FT && fp >= 0 && fp < FP) fobs[(int)ft * FP + (int)fp]++;
    }
    double chi2, crit, fchi2, fcrit;
    int dof, fdof;
    chi2_stat(obs, expct, BT * BP, N, &chi2, &crit, &dof);
    /* the fine bins, conditioned on landing in the window */
    double nin = 0;
    for (int i = 0; i < FT * FP; i++) nin += fobs[i];
    for (int i = 0; i < FT * FP; i++) fexp[i] /= fin;
    chi2_stat(fobs, fexp, FT * FP, nin, &fchi2, &fcrit, &fdof);
    print_message("theta_o %5.1f: integral of pdf %.6f; chi2 %.1f on %d dof (critical %.1f); "
                  "near the mirror %.0f samples, chi2 %.1f on %d dof (critical %.1f); "
                  "%d pdf mismatches; pdf vs f cos/albedo within %.1f%%\n",
                  views[v], integ, chi2, dof, crit, nin, fchi2, fdof, fcrit, mismatch,
                  100 * worst_ratio);
    assert_near(integ, 1, 1e-3);
    assert_true(chi2 < crit);
    assert_true(nin > 1000 && fchi2 < fcrit);
    assert_true(mismatch < N / 1000);
    assert_true(worst_ratio < 0.1);
  }
  /* (e) the density is continuous: no jump across cell edges (1e-4 degree
   * either side of theta and phi grid lines) */
  int k;
  float t;
  cv_brdf_view_bins(s, (float)(30.4 * D), &k, &t);
  double worst_jump = 0;
  for (int i = 0; i < 2000; i++) {
    double th = (1 + (int)(88 * rnd())) * D, ph = (0.5 + 179 * rnd()) * D, e = 1e-4 * D;
    if (i % 2) th = (1 + 88 * rnd()) * D, ph = (1 + (int)(178 * rnd())) * D;
    float a0 = cv_brdf_pdf(s, k, t, (float)(th - (i % 2 ? 0 : e)), (float)(ph - (i % 2 ? e : 0)));
    float a1 = cv_brdf_pdf(s, k, t, (float)(th + (i % 2 ? 0 : e)), (float)(ph + (i % 2 ? e : 0)));
    if (a0 > 1e-3f) worst_jump = fmax(worst_jump, fabs(a1 / a0 - 1));
  }
  print_message("largest relative pdf change across a cell edge (+-0.0001 deg): %.2e\n", worst_jump);
  assert_true(worst_jump < 1e-3);
  cv_brdf_sampler_destroy(s);
  cv_brdf_destroy(b);
}

/* Window sampling and the split MIS (interior over BRDF + cosine, the
 * environment over all three): a Lambertian table in the closed cabin, with
 * the interior and the environment both at radiance L, reflects a*L at
 * every texel, whatever the strategy mix; a wrong window density or weight
 * would show as a bias where the windows are seen. */
static void test_window_mis(void **state) {
  (void)state;
  cv_cabin_params cp;
  cv_cabin_default_params(&cp);
  cv_mesh *m;
  cv_cabin_info info;
  cv_err err;
  assert_int_equal(cv_cabin_generate_ex(&cp, &m, &info, &err), CV_OK);
  const float a[3] = {0.5f, 0.5f, 0.5f};
  cv_brdf *b = lambert_table(a);
  scene s;
  scene_make(&s, m, b);
  float *vrad = malloc(3 * m->nv * sizeof(float));
  for (size_t i = 0; i < 3 * m->nv; i++) vrad[i] = 2.0f;
  cv_envmap *env;
  assert_int_equal(cv_envmap_create(64, 32, &env), CV_OK);
  for (size_t i = 0; i < (size_t)64 * 32 * 3; i++) env->img->px[i] = 2.0f;
  cv_lcd_light *l;
  assert_int_equal(cv_lcd_light_create(env, vrad, m->nv, 0, NULL, NULL, &l), CV_OK);
  /* brdf, window, environment fractions */
  const double mix[7][3] = {{1, 0.5, 0},   {0, 0.5, 0},    {0.5, 0.25, 0}, {1, 0, 0},
                            {1, 0.3, 0.3}, {0.5, 0, 0.5}, {0, 0.25, 0.25}};
  for (int c = 0; c < 7; c++) {
    cv_lcd_params p;
    cv_lcd_params_default(&p);
    p.w = 24, p.h = 16, p.spp = 64;
    p.brdf_fraction = mix[c][0];
    p.window_fraction = mix[c][1];
    p.env_fraction = mix[c][2];
    memcpy(p.eye, info.eye, sizeof p.eye);
    cv_lcd_accum *acc;
    assert_int_equal(cv_lcd_accum_create(p.w, p.h, cv_lcd_default_clamp(l, b), &acc), CV_OK);
    for (uint32_t r = 0; r < 4; r++) assert_int_equal(cv_lcd_render_round(s.g, l, &p, r, acc), CV_OK);
    cv_image *img;
    assert_int_equal(cv_lcd_accum_to_image(acc, NULL, &img), CV_OK);
    double mean = 0, worst = 0;
    for (int i = 0; i < p.w * p.h; i++) {
      mean += img->px[3 * i + 1] / (p.w * p.h);
      worst = fmax(worst, fabs(img->px[3 * i + 1] / 1.0 - 1));
    }
    print_message("window MIS c=%.2f w=%.2f e=%.2f: mean %.5f (want 1), worst texel %.2f%%, env "
                  "rays %.1f%%, lost %lld\n",
                  mix[c][0], mix[c][1], mix[c][2], mean, 100 * worst,
                  100.0 * acc->data[CV_LCD_ACC_ENV] / (double)(acc->data[CV_LCD_ACC_ENV] + acc->data[CV_LCD_ACC_HITS]),
                  (long long)acc->data[CV_LCD_ACC_LOST]);
    assert_true(acc->data[CV_LCD_ACC_ENV] > 0 && acc->data[CV_LCD_ACC_LOST] == 0);
    assert_near(mean, 1, 2e-3);
    assert_true(worst < 0.1);
    cv_image_destroy(img);
    cv_lcd_accum_destroy(acc);
  }
  cv_lcd_light_destroy(l);
  cv_envmap_destroy(env);
  free(vrad);
  scene_free(&s);
  cv_brdf_destroy(b);
}

/* A sky with a bright disc (a sun left in the map, 5 degrees, 300x the sky)
 * behind the car and to the left, where the panel sees it through the rear
 * and side windows. */
static void env_disc(const double d[3], float rgb[3]) {
  const double c[3] = {-0.45, 0.55, 0.70}, n = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
  const double cosg = (d[0] * c[0] + d[1] * c[1] + d[2] * c[2]) / n;
  const double sky = d[1] > 0 ? 0.5 + d[1] : 0.2;
  const double L = cosg > cos(5 * M_PI / 180) ? 300 * sky : sky;
  rgb[0] = (float)(0.9 * L), rgb[1] = (float)L, rgb[2] = (float)(1.2 * L);
}

/* Environment light sampling with MIS is unbiased: on the default cabin
 * with the anti-glare BRDF under a sky holding a bright disc, the panel's
 * mean reflected luminance from mixes with environment samples equals the
 * window mix's (BRDF + cosine + window, no environment samples) within 4
 * standard errors of the difference (each estimate with its own seed; the
 * i.i.d. error of cv_lcd_accum_error, an upper bound for the scrambled
 * Sobol points). */
static void test_env_mis_unbiased(void **state) {
  (void)state;
  cv_cabin_params cp;
  cv_cabin_default_params(&cp);
  cv_mesh *m;
  cv_cabin_info info;
  cv_err err;
  assert_int_equal(cv_cabin_generate_ex(&cp, &m, &info, &err), CV_OK);
  cv_brdf *b;
  assert_int_equal(cv_brdf_load(CV_BRDF_BUILTIN_ANTIGLARE, &b, NULL, &err), CV_OK);
  scene s;
  scene_make(&s, m, b);
  float *vrad = malloc(3 * m->nv * sizeof(float));
  for (size_t i = 0; i < 3 * m->nv; i++) vrad[i] = 0.3f;
  cv_envmap *env = env_from(256, env_disc);
  cv_lcd_light *l;
  assert_int_equal(cv_lcd_light_create(env, vrad, m->nv, 0, NULL, NULL, &l), CV_OK);
  /* brdf, window, environment fractions: the first (windows, no
   * environment samples) is the reference, the last the default */
  enum { NMIX = 5 };
  const double mix[NMIX][3] = {{0.9, 0.5, 0}, {0.9, 0.3, 0.3}, {1, 0, 0.5}, {0.9, 0, 0.25},
                               {0.9, CV_LCD_WINDOW_FRACTION, CV_LCD_ENV_FRACTION}};
  double mean[NMIX], se[NMIX];
  for (int c = 0; c < NMIX; c++) {
    cv_lcd_params p;
    cv_lcd_params_default(&p);
    p.w = 16, p.h = 12, p.spp = 256;
    p.brdf_fraction = mix[c][0];
    p.window_fraction = mix[c][1];
    p.env_fraction = mix[c][2];
    p.seed = 11 + (uint32_t)c;
    memcpy(p.eye, info.eye, sizeof p.eye);
    cv_lcd_accum *acc;
    assert_int_equal(cv_lcd_accum_create(p.w, p.h, cv_lcd_default_clamp(l, b), &acc), CV_OK);
    for (uint32_t r = 0; r < 8; r++) assert_int_equal(cv_lcd_render_round(s.g, l, &p, r, acc), CV_OK);
    cv_lcd_error e;
    assert_int_equal(cv_lcd_accum_error(acc, &e), CV_OK);
    mean[c] = e.mean_luminance;
    se[c] = e.rms_se / sqrt((double)(p.w * p.h));
    assert_true(acc->data[CV_LCD_ACC_ENV] > 0);
    assert_true(acc->data[CV_LCD_ACC_CLAMPED] == 0 && acc->data[CV_LCD_ACC_NONFINITE] == 0);
    print_message("env MIS c=%.2f w=%.2f e=%.2f: panel mean Y %.5f +- %.5f (texel rel. error "
                  "%.2f%% at %d spp)\n",
                  mix[c][0], mix[c][1], mix[c][2], mean[c], se[c], 100 * e.rel_rms, 8 * p.spp);
    cv_lcd_accum_destroy(acc);
  }
  { /* bad fractions: refused, nothing added */
    cv_lcd_params p;
    cv_lcd_params_default(&p);
    p.w = 16, p.h = 12, p.spp = 8;
    memcpy(p.eye, info.eye, sizeof p.eye);
    cv_lcd_accum *acc;
    assert_int_equal(cv_lcd_accum_create(p.w, p.h, cv_lcd_default_clamp(l, b), &acc), CV_OK);
    const double bad[4][2] = {{0.5, 0.5}, {0.2, 1.0}, {0.0, -0.1}, {0.6, 0.6}};
    for (int i = 0; i < 4; i++) {
      p.window_fraction = bad[i][0];
      p.env_fraction = bad[i][1];
      assert_int_equal(cv_lcd_render_round(s.g, l, &p, 0, acc), CV_ERR_INVALID);
    }
    assert_true(acc->data[CV_LCD_ACC_SPP] == 0);
    cv_lcd_accum_destroy(acc);
  }
  for (int c = 1; c < NMIX; c++) {
    const double z = fabs(mean[c] - mean[0]) / sqrt(se[c] * se[c] + se[0] * se[0]);
    print_message("mix %d vs the window mix: %.2f standard errors\n", c, z);
    assert_true(z < 4);
  }
  cv_lcd_light_destroy(l);
  cv_envmap_destroy(env);
  free(vrad);
  scene_free(&s);
  cv_brdf_destroy(b);
}

/* The environment strategy's visibility tables, softened
 * (cv_lcd_soften_visibility): a lone visible cell keeps its value and
 * gives half of it to its 8 neighbours, across the azimuth seam but not
 * across the poles; a uniform table is unchanged; each table on its own;
 * bad arguments refused. */
static void test_soften_visibility(void **state) {
  (void)state;
  enum { W = 6, H = 4, NC = W * H };
  float v[3 * NC];
  memset(v, 0, sizeof v);
  v[1 * W + 2] = 1.0f;  /* table 0: a lone cell inside */
  v[NC + 0 * W + 0] = 0.8f; /* table 1: a cell on the seam, in the top row */
  for (int i = 0; i < NC; i++) v[2 * NC + i] = 0.25f; /* table 2: uniform */
  assert_int_equal(cv_lcd_soften_visibility(v, W, H, 3), CV_OK);
  for (int Y = 0; Y < H; Y++)
    for (int X = 0; X < W; X++) {
      const int near = abs(X - 2) <= 1 && abs(Y - 1) <= 1;
      const float want = X == 2 && Y == 1 ? 1.0f : near ? 0.5f : 0.0f;
      assert_float_equal(v[Y * W + X], want, 0);
      /* table 1: the cell's neighbours are X in {W-1, 0, 1} and rows 0-1 only */
      const int dx = X == W - 1 ? 1 : X; /* distance across the seam */
      const float want1 = X == 0 && Y == 0 ? 0.8f : (dx <= 1 && Y <= 1) ? 0.4f : 0.0f;
      assert_float_equal(v[NC + Y * W + X], want1, 0);
      assert_float_equal(v[2 * NC + Y * W + X], 0.25f, 0);
    }
  assert_int_equal(cv_lcd_soften_visibility(NULL, W, H, 1), CV_ERR_INVALID);
  assert_int_equal(cv_lcd_soften_visibility(v, 0, H, 1), CV_ERR_INVALID);
  assert_int_equal(cv_lcd_soften_visibility(v, W, H, -1), CV_ERR_INVALID);
  assert_int_equal(cv_lcd_soften_visibility(v, W, H, 0), CV_OK); /* no table: nothing to do */
}

/* Interior light sampling with MIS is unbiased: on the default cabin with
 * the anti-glare BRDF, an interior radiance with a bright patch (a sunlit
 * spot: 40x the rest on the vertices in a 30 cm ball) and the disc sky, the
 * panel's mean from mixes with interior samples equals the existing
 * estimator's within 4 standard errors of the difference; bad fractions are
 * refused; the interior samples aim at the patch. */
static void test_interior_mis_unbiased(void **state) {
  (void)state;
  cv_cabin_params cp;
  cv_cabin_default_params(&cp);
  cv_mesh *m;
  cv_cabin_info info;
  cv_err err;
  assert_int_equal(cv_cabin_generate_ex(&cp, &m, &info, &err), CV_OK);
  cv_brdf *b;
  assert_int_equal(cv_brdf_load(CV_BRDF_BUILTIN_ANTIGLARE, &b, NULL, &err), CV_OK);
  scene s;
  scene_make(&s, m, b);
  /* the patch: around the point 0.5 m behind the eye, at seat height */
  const float pc[3] = {info.eye[0], info.eye[1] - 0.3f, info.eye[2] + 0.5f};
  float *vrad = malloc(3 * m->nv * sizeof(float));
  size_t bright = 0;
  for (size_t i = 0; i < m->nv; i++) {
    const float *q = m->pos + 3 * i;
    const float d2 = (q[0] - pc[0]) * (q[0] - pc[0]) + (q[1] - pc[1]) * (q[1] - pc[1]) +
                     (q[2] - pc[2]) * (q[2] - pc[2]);
    const float v = d2 < 0.09f ? 12.0f : 0.3f;
    bright += d2 < 0.09f;
    for (int c = 0; c < 3; c++) vrad[3 * i + c] = v * (0.9f + 0.1f * (float)c);
  }
  assert_true(bright > 0);
  cv_envmap *env = env_from(256, env_disc);
  cv_lcd_light *l;
  assert_int_equal(cv_lcd_light_create(env, vrad, m->nv, 0, NULL, NULL, &l), CV_OK);
  /* brdf, window, environment, interior fractions; the first is the existing default */
  const double mix[4][4] = {{0.9, 0.5, 0, 0}, {0.9, 0.25, 0, 0.5}, {1, 0, 0.2, 0.4}, {0, 0.2, 0.2, 0.4}};
  double mean[4], se[4];
  for (int c = 0; c < 4; c++) {
    cv_lcd_params p;
    cv_lcd_params_default(&p);
    p.w = 16, p.h = 12, p.spp = 256;
    p.brdf_fraction = mix[c][0];
    p.window_fraction = mix[c][1];
    p.env_fraction = mix[c][2];
    p.interior_fraction = mix[c][3];
    p.seed = 21 + (uint32_t)c;
    memcpy(p.eye, info.eye, sizeof p.eye);
    cv_lcd_accum *acc;
    assert_int_equal(cv_lcd_accum_create(p.w, p.h, cv_lcd_default_clamp(l, b), &acc), CV_OK);
    for (uint32_t r = 0; r < 8; r++) assert_int_equal(cv_lcd_render_round(s.g, l, &p, r, acc), CV_OK);
    cv_lcd_error e;
    assert_int_equal(cv_lcd_accum_error(acc, &e), CV_OK);
    mean[c] = e.mean_luminance;
    se[c] = e.rms_se / sqrt((double)(p.w * p.h));
    assert_true(acc->data[CV_LCD_ACC_CLAMPED] == 0 && acc->data[CV_LCD_ACC_NONFINITE] == 0);
    print_message("interior MIS c=%.2f w=%.2f e=%.2f i=%.2f: panel mean Y %.5f +- %.5f (texel "
                  "rel. error %.2f%% at %d spp)\n",
                  mix[c][0], mix[c][1], mix[c][2], mix[c][3], mean[c], se[c], 100 * e.rel_rms,
                  8 * p.spp);
    cv_lcd_accum_destroy(acc);
  }
  { /* bad fractions: refused, nothing added */
    cv_lcd_params p;
    cv_lcd_params_default(&p);
    p.w = 16, p.h = 12, p.spp = 8;
    memcpy(p.eye, info.eye, sizeof p.eye);
    cv_lcd_accum *acc;
    assert_int_equal(cv_lcd_accum_create(p.w, p.h, cv_lcd_default_clamp(l, b), &acc), CV_OK);
    const double bad[3][2] = {{0.5, 0.5}, {0.0, 1.0}, {0.0, -0.1}};
    for (int i = 0; i < 3; i++) {
      p.window_fraction = bad[i][0];
      p.interior_fraction = bad[i][1];
      assert_int_equal(cv_lcd_render_round(s.g, l, &p, 0, acc), CV_ERR_INVALID);
    }
    assert_true(acc->data[CV_LCD_ACC_SPP] == 0);
    cv_lcd_accum_destroy(acc);
  }
  for (int c = 1; c < 4; c++) {
    const double z = fabs(mean[c] - mean[0]) / sqrt(se[c] * se[c] + se[0] * se[0]);
    print_message("interior mix %d vs existing: %.2f standard errors\n", c, z);
    assert_true(z < 4);
  }
  cv_lcd_light_destroy(l);
  cv_envmap_destroy(env);
  free(vrad);
  scene_free(&s);
  cv_brdf_destroy(b);
}

/* --- 4. determinism of the fixed-point sums -------------------------------- */

static void env_sky(const double d[3], float rgb[3]) {
  rgb[0] = (float)(1 + d[1] + 0.5 * d[0]);
  rgb[1] = (float)(1.5 + d[1]);
  rgb[2] = (float)(2 + d[1] - 0.3 * d[2]);
}

static void test_determinism(void **state) {
  (void)state;
  cv_cabin_params cp;
  cv_cabin_default_params(&cp);
  cv_mesh *m;
  cv_cabin_info info;
  cv_err err;
  assert_int_equal(cv_cabin_generate_ex(&cp, &m, &info, &err), CV_OK);
  cv_brdf *b;
  assert_int_equal(cv_brdf_load(CV_BRDF_BUILTIN_ANTIGLARE, &b, NULL, &err), CV_OK);
  scene s;
  scene_make(&s, m, b);
  /* the frame read from the LCD triangles is the generator's */
  for (int k = 0; k < 3; k++) {
    assert_near(s.panel.center[k], info.lcd.center[k], 1e-4f);
    assert_near(s.panel.normal[k], info.lcd.normal[k], 1e-4f);
    assert_near(s.panel.u[k], info.lcd.u[k], 1e-4f);
  }
  assert_near(s.panel.size[0], info.lcd.size[0], 1e-4f);
  assert_near(s.panel.size[1], info.lcd.size[1], 1e-4f);
  float *vrad = malloc(3 * m->nv * sizeof(float));
  for (size_t i = 0; i < 3 * m->nv; i++) vrad[i] = (float)(0.05 + 0.1 * rnd());
  cv_envmap *env = env_from(128, env_sky);
  const double sd[3] = {-0.69, 0.35, 0.63}, E[3] = {30, 30, 25}; /* through the left window */
  cv_lcd_light *l;
  assert_int_equal(cv_lcd_light_create(env, vrad, m->nv, 1, sd, E, &l), CV_OK);
  cv_lcd_params p;
  cv_lcd_params_default(&p);
  p.w = 40, p.h = 30, p.spp = 8, p.brdf_fraction = 0.9;
  memcpy(p.eye, info.eye, sizeof p.eye);
  double clamp = cv_lcd_default_clamp(l, b);
  cv_lcd_accum *A, *B[3], *T;
  assert_int_equal(cv_lcd_accum_create(p.w, p.h, clamp, &A), CV_OK);
  p.threads = 1;
  for (uint32_t r = 0; r < 6; r++) assert_int_equal(cv_lcd_render_round(s.g, l, &p, r, A), CV_OK);
  /* three contributors, rounds permuted, two threads, summed in another order */
  const uint32_t parts[3][3] = {{5, 0, 99}, {3, 99, 99}, {1, 4, 2}};
  p.threads = 2;
  for (int c = 0; c < 3; c++) {
    assert_int_equal(cv_lcd_accum_create(p.w, p.h, clamp, &B[c]), CV_OK);
    for (int j = 0; j < 3; j++)
      if (parts[c][j] != 99) assert_int_equal(cv_lcd_render_round(s.g, l, &p, parts[c][j], B[c]), CV_OK);
  }
  assert_int_equal(cv_lcd_accum_add(B[2], B[0]), CV_OK);
  assert_int_equal(cv_lcd_accum_add(B[2], B[1]), CV_OK);
  assert_int_equal(B[2]->data[CV_LCD_ACC_SPP], 48);
  assert_memory_equal(A->data, B[2]->data, A->n * sizeof(int64_t));
  /* tiles: the left and right halves rendered apart equal the whole */
  cv_lcd_accum *half;
  assert_int_equal(cv_lcd_accum_create(p.w / 2, p.h, clamp, &half), CV_OK);
  cv_lcd_params q = p;
  q.x0 = p.w / 2;
  for (uint32_t r = 0; r < 6; r++) assert_int_equal(cv_lcd_render_round(s.g, l, &q, r, half), CV_OK);
  for (int y = 0; y < p.h; y++)
    for (int x = 0; x < p.w / 2; x++)
      assert_memory_equal(half->data + cv_lcd_acc_rgb(half, x, y),
                          A->data + cv_lcd_acc_rgb(A, x + p.w / 2, y), 3 * sizeof(int64_t));
  { /* the same with every strategy on: window, environment (per-region
     * tables) and interior samples */
    cv_lcd_params p2 = p;
    p2.window_fraction = 0.2, p2.env_fraction = 0.2, p2.interior_fraction = 0.2;
    cv_lcd_accum *A2, *B2, *H2;
    assert_int_equal(cv_lcd_accum_create(p.w, p.h, clamp, &A2), CV_OK);
    assert_int_equal(cv_lcd_accum_create(p.w, p.h, clamp, &B2), CV_OK);
    assert_int_equal(cv_lcd_accum_create(p.w / 2, p.h, clamp, &H2), CV_OK);
    p2.threads = 1;
    for (uint32_t r = 0; r < 3; r++) assert_int_equal(cv_lcd_render_round(s.g, l, &p2, r, A2), CV_OK);
    p2.threads = 2;
    for (uint32_t r = 3; r-- > 0;) assert_int_equal(cv_lcd_render_round(s.g, l, &p2, r, B2), CV_OK);
    assert_memory_equal(A2->data, B2->data, A2->n * sizeof(int64_t));
    { /* the phase_seconds hook times the phases and changes no value */
      double ph[CV_LCD_PHASES];
      for (int k = 0; k < CV_LCD_PHASES; k++) ph[k] = 0;
      cv_lcd_params pt = p2;
      pt.phase_seconds = ph;
      cv_lcd_accum *P2;
      assert_int_equal(cv_lcd_accum_create(p.w, p.h, clamp, &P2), CV_OK);
      for (uint32_t r = 0; r < 3; r++) assert_int_equal(cv_lcd_render_round(s.g, l, &pt, r, P2), CV_OK);
      assert_memory_equal(A2->data, P2->data, A2->n * sizeof(int64_t));
      print_message("phases of 3 rounds (s): setup %.4f generate %.4f order %.4f closest %.4f "
                    "windows %.4f shade %.4f\n", ph[0], ph[1], ph[2], ph[3], ph[4], ph[5]);
      for (int k = 0; k < CV_LCD_PHASES; k++) assert_true(isfinite(ph[k]) && ph[k] >= 0);
      /* rays were generated, traced (some escaped through a window) and shaded */
      assert_true(ph[CV_LCD_PHASE_GENERATE] > 0 && ph[CV_LCD_PHASE_CLOSEST] > 0);
      assert_true(ph[CV_LCD_PHASE_WINDOWS] > 0 && ph[CV_LCD_PHASE_SHADE] > 0);
      cv_lcd_accum_destroy(P2);
    }
    cv_lcd_params q2 = p2;
    q2.x0 = p.w / 2;
    for (uint32_t r = 0; r < 3; r++) assert_int_equal(cv_lcd_render_round(s.g, l, &q2, r, H2), CV_OK);
    for (int y = 0; y < p.h; y++)
      for (int x = 0; x < p.w / 2; x++)
        assert_memory_equal(H2->data + cv_lcd_acc_rgb(H2, x, y),
                            A2->data + cv_lcd_acc_rgb(A2, x + p.w / 2, y), 3 * sizeof(int64_t));
    /* the environment tables kept across calls (gather.c, env_tables): a
     * call from another eye in between, which replaces them, changes
     * nothing */
    {
      cv_lcd_params pe = p2;
      pe.eye[0] += 0.05f;
      cv_lcd_accum *E2, *C3;
      assert_int_equal(cv_lcd_accum_create(p.w, p.h, clamp, &E2), CV_OK);
      assert_int_equal(cv_lcd_accum_create(p.w, p.h, clamp, &C3), CV_OK);
      for (uint32_t r = 0; r < 3; r++) {
        assert_int_equal(cv_lcd_render_round(s.g, l, &pe, r, E2), CV_OK);
        assert_int_equal(cv_lcd_render_round(s.g, l, &p2, r, C3), CV_OK);
      }
      assert_memory_equal(A2->data, C3->data, A2->n * sizeof(int64_t));
      assert_true(memcmp(A2->data + CV_LCD_ACC_HEADER, E2->data + CV_LCD_ACC_HEADER,
                         (size_t)(A2->n - CV_LCD_ACC_HEADER) * sizeof(int64_t)) != 0);
      cv_lcd_accum_destroy(E2);
      cv_lcd_accum_destroy(C3);
    }
    /* and they differ from the default mix's */
    assert_true(memcmp(A2->data + CV_LCD_ACC_HEADER, A->data + CV_LCD_ACC_HEADER,
                       (size_t)(A->n - CV_LCD_ACC_HEADER) * sizeof(int64_t)) != 0);
    cv_lcd_accum_destroy(A2);
    cv_lcd_accum_destroy(B2);
    cv_lcd_accum_destroy(H2);
  }
  /* the check can fail: other rounds give other sums */
  assert_int_equal(cv_lcd_accum_create(p.w, p.h, clamp, &T), CV_OK);
  for (uint32_t r = 0; r < 6; r++) assert_int_equal(cv_lcd_render_round(s.g, l, &p, r == 5 ? 6 : r, T), CV_OK);
  assert_true(memcmp(A->data, T->data, A->n * sizeof(int64_t)) != 0);
  /* mixing buffers of another size or clamp is refused */
  assert_int_equal(cv_lcd_accum_add(A, half), CV_ERR_INVALID);
  cv_lcd_accum *C2;
  assert_int_equal(cv_lcd_accum_create(p.w, p.h, clamp * 4, &C2), CV_OK);
  assert_int_equal(cv_lcd_accum_add(A, C2), CV_ERR_INVALID);
  /* something was seen: interior hits, windows, sun shadow rays */
  print_message("cabin 40x30 x 48 spp: hits %lld, env %lld, lost %lld, shadow %lld (lit %lld), "
                "clamped %lld\n",
                (long long)A->data[CV_LCD_ACC_HITS], (long long)A->data[CV_LCD_ACC_ENV],
                (long long)A->data[CV_LCD_ACC_LOST], (long long)A->data[CV_LCD_ACC_SHADOW],
                (long long)A->data[CV_LCD_ACC_SUNLIT], (long long)A->data[CV_LCD_ACC_CLAMPED]);
  assert_true(A->data[CV_LCD_ACC_HITS] > 0 && A->data[CV_LCD_ACC_ENV] > 0);
  assert_int_equal(A->data[CV_LCD_ACC_SHADOW], 6 * p.w * p.h);
  /* the sun through the left window lights part of the panel, not all of it */
  assert_true(A->data[CV_LCD_ACC_SUNLIT] > 0 && A->data[CV_LCD_ACC_SUNLIT] < 6 * p.w * p.h);
  /* the error estimate falls with more samples */
  cv_lcd_error e1, e2;
  assert_int_equal(cv_lcd_accum_error(B[0], &e1), CV_OK);
  assert_int_equal(cv_lcd_accum_error(A, &e2), CV_OK);
  print_message("estimated rel. RMS error: %.4f at %llu spp, %.4f at %llu spp\n", e1.rel_rms,
                (unsigned long long)e1.spp, e2.rel_rms, (unsigned long long)e2.spp);
  assert_true(e1.rel_rms > 0 && e2.rel_rms < e1.rel_rms);
  /* file round trip */
  cv_lcd_accum *R;
  assert_int_equal(cv_lcd_accum_write(TMP("acc.bin"), A, &err), CV_OK);
  assert_int_equal(cv_lcd_accum_read(TMP("acc.bin"), &R, &err), CV_OK);
  assert_int_equal(R->n, A->n);
  assert_true(R->unit == A->unit);
  assert_memory_equal(R->data, A->data, A->n * sizeof(int64_t));
  cv_lcd_accum_destroy(R);
  for (int c = 0; c < 3; c++) cv_lcd_accum_destroy(B[c]);
  cv_lcd_accum_destroy(A);
  cv_lcd_accum_destroy(T);
  cv_lcd_accum_destroy(C2);
  cv_lcd_accum_destroy(half);
  cv_lcd_light_destroy(l);
  cv_envmap_destroy(env);
  free(vrad);
  scene_free(&s);
  cv_brdf_destroy(b);
}

static void test_keys_progress(void **state) {
  (void)state;
  const float e1[3] = {-0.370f, 1.020f, 0.000f}, e2[3] = {-0.3715f, 1.0208f, 0.0012f},
              e3[3] = {-0.380f, 1.020f, 0.000f};
  cv_lcd_key a, b, c, d;
  assert_int_equal(cv_lcd_key_make(e1, 0.005, 7, 9, &a), CV_OK);
  assert_int_equal(cv_lcd_key_make(e2, 0.005, 7, 9, &b), CV_OK); /* within the tolerance cell */
  assert_int_equal(cv_lcd_key_make(e3, 0.005, 7, 9, &c), CV_OK); /* 1 cm away */
  assert_int_equal(cv_lcd_key_make(e1, 0.005, 8, 9, &d), CV_OK); /* other lighting */
  assert_true(cv_lcd_key_equal(&a, &b));
  assert_false(cv_lcd_key_equal(&a, &c));
  assert_false(cv_lcd_key_equal(&a, &d));
  assert_true(cv_lcd_key_compare(&a, &c) == -cv_lcd_key_compare(&c, &a));
  float q[3];
  cv_lcd_key_eye(&a, 0.005, q);
  assert_near(q[0], -0.370f, 1e-6f);
  assert_near(q[1], 1.020f, 1e-6f);
  const float bad[3] = {NAN, 0, 0};
  assert_int_equal(cv_lcd_key_make(bad, 0.005, 1, 1, &d), CV_ERR_INVALID);
  assert_int_equal(cv_lcd_key_make(e1, 0, 1, 1, &d), CV_ERR_INVALID);
  assert_int_equal(cv_lcd_key_make(e1, 1e-12, 1, 1, &d), CV_ERR_RANGE);
  /* progressive: same key accumulates, a new key starts over */
  cv_lcd_accum *x;
  assert_int_equal(cv_lcd_accum_create(2, 2, 1.0, &x), CV_OK);
  x->data[CV_LCD_ACC_SPP] = 10;
  x->data[cv_lcd_acc_rgb(x, 1, 1)] = 5;
  cv_lcd_progress pr;
  memset(&pr, 0, sizeof pr);
  int restarted;
  assert_int_equal(cv_lcd_progress_submit(&pr, &a, x, &restarted), CV_OK);
  assert_true(restarted);
  assert_int_equal(cv_lcd_progress_submit(&pr, &b, x, &restarted), CV_OK);
  assert_false(restarted);
  assert_int_equal(pr.acc->data[CV_LCD_ACC_SPP], 20);
  assert_int_equal(pr.acc->data[cv_lcd_acc_rgb(x, 1, 1)], 10);
  assert_int_equal(cv_lcd_progress_submit(&pr, &c, x, &restarted), CV_OK);
  assert_true(restarted);
  assert_int_equal(pr.acc->data[CV_LCD_ACC_SPP], 10);
  assert_int_equal(pr.restarts, 1);
  /* overflow guard */
  x->data[CV_LCD_ACC_SPP] = CV_LCD_MAX_SPP;
  assert_int_equal(cv_lcd_progress_submit(&pr, &c, x, &restarted), CV_ERR_RANGE);
  cv_lcd_progress_free(&pr);
  cv_lcd_accum_destroy(x);
}

/* --- 5. MERL ---------------------------------------------------------------- */

static void put32(FILE *f, int32_t v) { fwrite(&v, 4, 1, f); }

static void test_merl_roundtrip(void **state) {
  (void)state;
  const size_t N = (size_t)90 * 90 * 180;
  double *plane = malloc(N * sizeof(double));
  FILE *f = fopen(TMP("test.binary"), "wb");
  assert_non_null(f);
  put32(f, 90), put32(f, 90), put32(f, 180);
  /* R: Lambertian, albedo 0.3 */
  for (size_t i = 0; i < N; i++) plane[i] = 1500.0 * 0.3 / M_PI;
  fwrite(plane, sizeof(double), N, f);
  /* G: a function of the theta_half index only */
  for (size_t i = 0; i < N; i++) plane[i] = 1500.0 / 1.15 * (0.01 + 0.002 * (double)(i / (90 * 180)));
  fwrite(plane, sizeof(double), N, f);
  /* B: constant, with the last theta_half row missing (negative) */
  for (size_t i = 0; i < N; i++) plane[i] = i / (90 * 180) == 89 ? -1.0 : 1500.0 / 1.66 * 0.05;
  fwrite(plane, sizeof(double), N, f);
  fclose(f);
  free(plane);
  cv_brdf *b;
  cv_brdf_report rep;
  cv_err err;
  assert_int_equal(cv_brdf_load(TMP("test.binary"), &b, &rep, &err), CV_OK);
  assert_int_equal(b->n_theta, 91);
  assert_int_equal(b->n_phi, 181);
  assert_int_equal(rep.merl_missing, 90 * 180);
  print_message("MERL: %llu missing samples, %llu grid points on them; albedo max %.4f\n",
                (unsigned long long)rep.merl_missing, (unsigned long long)rep.merl_missing_used,
                rep.albedo_max);
  int checked = 0;
  for (int io = 0; io < 91; io += 7)
    for (int ii = 0; ii < 91; ii += 5)
      for (int ip = 0; ip < 181; ip += 11) {
        const float *e = cv_brdf_at(b, io, ii, ip);
        assert_near(e[0], (float)(0.3 / M_PI), 1e-6f);
        /* independent theta_half index: the half vector of w_i and w_o */
        double ti = ii * M_PI / 180, to = io * M_PI / 180, ph = ip * M_PI / 180;
        double h[3] = {sin(ti) * cos(ph) + sin(to), sin(ti) * sin(ph), cos(ti) + cos(to)};
        double hl = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
        if (hl < 1e-6) continue;
        double th = acos(fmin(1, h[2] / hl));
        double x = sqrt(th / (M_PI / 2) * 8100);
        if (fabs(x - floor(x + 0.5)) < 1e-6) continue; /* on an index boundary */
        int ih = (int)x;
        if (ih > 89) ih = 89;
        assert_near(e[1], (float)(0.01 + 0.002 * ih), 1e-6f);
        if (ih == 89) assert_true(e[2] == 0.0f);
        else assert_near(e[2], 0.05f, 1e-6f);
        checked++;
      }
  assert_true(checked > 1000);
  /* MERL's own index agrees for a mirror pair at 30 degrees: theta_half = 0 */
  assert_int_equal(cv_brdf_merl_index(M_PI / 6, 0, M_PI / 6, M_PI) / (90 * 180), 0);
  cv_brdf_destroy(b);
}

/* --- 6. bad files ----------------------------------------------------------- */

static void write_table(const char *path, int nt, int np, int ch, const float *vals, size_t nvals,
                        uint32_t version) {
  FILE *f = fopen(path, "wb");
  assert_non_null(f);
  fwrite(CV_BRDF_MAGIC, 1, 8, f);
  uint32_t h[4] = {version, (uint32_t)nt, (uint32_t)np, (uint32_t)ch};
  fwrite(h, 4, 4, f);
  fwrite(vals, 4, nvals, f);
  fclose(f);
}

static void expect_fail(const char *path, int status, const char *a, const char *b) {
  cv_brdf *br = (cv_brdf *)1;
  cv_err err;
  cv_err_clear(&err);
  int st = cv_brdf_load(path, &br, NULL, &err);
  print_message("  %s -> %s\n", path, err.msg);
  assert_int_equal(st, status);
  assert_null(br);
  assert_non_null(strstr(err.msg, path));
  if (a) assert_non_null(strstr(err.msg, a));
  if (b) assert_non_null(strstr(err.msg, b));
  assert_null(strchr(err.msg, '\n'));
}

static void test_bad_files(void **state) {
  (void)state;
  /* 10 x 10 x 19 grid (10-degree steps), 3 channels */
  const int nt = 10, np = 19;
  size_t n = (size_t)nt * nt * np * 3;
  float *v = malloc(n * sizeof(float));
  for (size_t i = 0; i < n; i++) v[i] = 0.1f;
  write_table(TMP("good.brdf"), nt, np, 3, v, n, 1);
  cv_brdf *b;
  cv_brdf_report rep;
  cv_err err;
  assert_int_equal(cv_brdf_load(TMP("good.brdf"), &b, &rep, &err), CV_OK);
  assert_int_equal(b->n_theta, 10);
  assert_near(rep.albedo_max, 0.1 * M_PI, 1e-4); /* a constant f has albedo pi f */
  assert_int_equal(rep.albedo_violations, 0);
  cv_brdf_destroy(b);
  /* entry (theta_o 20, theta_i 30, phi_d 40 degrees), channel G */
  size_t e = (((size_t)2 * nt + 3) * np + 4) * 3 + 1;
  v[e] = NAN;
  write_table(TMP("nan.brdf"), nt, np, 3, v, n, 1);
  expect_fail(TMP("nan.brdf"), CV_ERR_NONFINITE, "theta_o=20 theta_i=30 phi_d=40", "channel G is NaN");
  v[e] = -0.5f;
  write_table(TMP("neg.brdf"), nt, np, 3, v, n, 1);
  expect_fail(TMP("neg.brdf"), CV_ERR_RANGE, "theta_o=20 theta_i=30 phi_d=40", "negative");
  v[e] = 0.1f;
  write_table(TMP("trunc.brdf"), nt, np, 3, v, n - 7, 1);
  expect_fail(TMP("trunc.brdf"), CV_ERR_FORMAT, "truncated", NULL);
  write_table(TMP("long.brdf"), nt, np, 3, v, n, 1);
  FILE *f = fopen(TMP("long.brdf"), "ab");
  fputs("xx", f);
  fclose(f);
  expect_fail(TMP("long.brdf"), CV_ERR_FORMAT, "trailing", NULL);
  write_table(TMP("ver.brdf"), nt, np, 3, v, n, 7);
  expect_fail(TMP("ver.brdf"), CV_ERR_FORMAT, "version 7", NULL);
  write_table(TMP("ch.brdf"), nt, np, 2, v, (size_t)nt * nt * np * 2, 1);
  expect_fail(TMP("ch.brdf"), CV_ERR_FORMAT, "channels", NULL);
  write_table(TMP("grid.brdf"), 1, np, 3, v, (size_t)np * 3, 1);
  expect_fail(TMP("grid.brdf"), CV_ERR_FORMAT, "grid", NULL);
  /* the largest grid the header allows, in a 100-byte file: refused from the
   * header and the file size, before allocating its 140 GB */
  write_table(TMP("huge.brdf"), 1801, 3601, 3, v, 19, 1);
  expect_fail(TMP("huge.brdf"), CV_ERR_FORMAT, "1801x1801x3601 grid", "the file has 100");
  f = fopen(TMP("junk.brdf"), "wb");
  fputs("hello, this is not a BRDF\n", f);
  fclose(f);
  expect_fail(TMP("junk.brdf"), CV_ERR_FORMAT, "neither", NULL);
  expect_fail(TMP("missing.brdf"), CV_ERR_IO, "cannot open", NULL);
  f = fopen(TMP("dims.binary"), "wb");
  put32(f, 90), put32(f, 90), put32(f, 90);
  fclose(f);
  expect_fail(TMP("dims.binary"), CV_ERR_FORMAT, "MERL dimensions 90 x 90 x 90", NULL);
  f = fopen(TMP("short.binary"), "wb");
  put32(f, 90), put32(f, 90), put32(f, 180);
  double d = 1;
  fwrite(&d, 8, 1, f);
  fclose(f);
  expect_fail(TMP("short.binary"), CV_ERR_FORMAT, "truncated", NULL);
  /* an albedo above 1 is reported, not fatal */
  for (size_t i = 0; i < n; i++) v[i] = 0.5f;
  write_table(TMP("bright.brdf"), nt, np, 3, v, n, 1);
  assert_int_equal(cv_brdf_load(TMP("bright.brdf"), &b, &rep, &err), CV_OK);
  assert_int_equal(rep.albedo_violations, nt);
  assert_near(rep.albedo_max, 0.5 * M_PI, 1e-3);
  assert_true(rep.first_violation_deg == 0);
  cv_brdf_destroy(b);
  free(v);
}

/* --- 7. the built-in anti-glare model ---------------------------------------- */

static void test_antiglare(void **state) {
  (void)state;
  cv_brdf *b;
  cv_brdf_report rep;
  cv_err err;
  assert_int_equal(cv_brdf_load(CV_BRDF_BUILTIN_ANTIGLARE, &b, &rep, &err), CV_OK);
  double alb[3 * 91];
  assert_int_equal(cv_brdf_validate(b, &rep, alb, &err), CV_OK);
  cv_antiglare_params p;
  cv_antiglare_default(&p);
  print_message("anti-glare albedo: %.4f at 0 deg, %.4f at 45, %.4f at 80; max %.4f at %.0f deg\n",
                alb[0], alb[3 * 45], alb[3 * 80], rep.albedo_max, rep.albedo_max_deg);
  assert_int_equal(rep.albedo_violations, 0);
  /* at normal incidence the lobes are whole: rd + rs + rh (1-degree
   * quadrature of a 1-degree Gaussian: 2%) */
  assert_near(alb[0] / (p.rd + p.rs + p.rh), 1, 0.02);
  /* a round trip through the table file keeps every value */
  assert_int_equal(cv_brdf_write(TMP("ag.brdf"), b, &err), CV_OK);
  cv_brdf *c;
  assert_int_equal(cv_brdf_load(TMP("ag.brdf"), &c, NULL, &err), CV_OK);
  assert_true(c->hash == b->hash);
  /* the peak sits at the mirror direction */
  float fm[3], fo[3];
  cv_brdf_eval(b, 30 * M_PI / 180, 30 * M_PI / 180, M_PI, fm);
  cv_brdf_eval(b, 30 * M_PI / 180, 30 * M_PI / 180, 0, fo);
  assert_true(fm[0] > 100 * fo[0]);
  cv_brdf_destroy(c);
  cv_brdf_destroy(b);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_lambert_constant), cmocka_unit_test(test_mirror_pattern),
      cmocka_unit_test(test_sampling_pdf_chi2), cmocka_unit_test(test_window_mis),
      cmocka_unit_test(test_env_mis_unbiased), cmocka_unit_test(test_soften_visibility),
      cmocka_unit_test(test_interior_mis_unbiased),
      cmocka_unit_test(test_determinism),
      cmocka_unit_test(test_keys_progress),     cmocka_unit_test(test_merl_roundtrip),
      cmocka_unit_test(test_bad_files),         cmocka_unit_test(test_antiglare),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
