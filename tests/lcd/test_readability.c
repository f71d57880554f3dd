/* Readability figures (src/lcd/readability.h) against closed forms:
 *  - the CIE 146:2002 glare equation at hand-computed points, 0 outside
 *    its validity range; the Ferwerda TVI at hand-computed points;
 *  - a lone matte panel (Lambertian table, reflectance rho) under a constant
 *    environment L, gathered for real: L_r = rho L and
 *    CR = (L_on + rho L + L_v) / (L_off + rho L + L_v) within 1%;
 *  - the veil of a constant surround equals an independent quadrature of
 *    L g(theta) cos(theta) over the cap (0.5%);
 *  - a small uniform disc source of illuminance E at angle theta (sampled
 *    through the luminance callback) gives L_v = g(theta) E within 2%, and
 *    within 4 standard errors; a point source exactly g(theta) E cos(theta);
 *  - what the eye sees (the panel flagged, the environment elsewhere) and
 *    whether it sees the sun;
 *  - the fraction of area meeting the requirement, the heat map's contour,
 *    and bad parameters naming their key. */
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
#include "lcd/gather.h"
#include "lcd/readability.h"
#include "io/png.h"
#include "rt/rt.h"

/* --- formulas ---------------------------------------------------------------- */

static void test_glare_equation(void **state) {
  (void)state;
  /* hand-computed: 10/th^3 + (5/th^2 + 0.1 p/th)(1 + (A/62.5)^4) + 0.0025 p */
  assert_near(cv_cie_glare(10, 25, 0.5), 0.067658, 1e-9);
  assert_near(cv_cie_glare(1, 70, 1.0), 23.127448736, 1e-8);
  assert_near(cv_cie_glare(30, 40, 0), 0.006857993481, 1e-11);
  assert_true(cv_cie_glare(0.05, 40, 0.5) == 0);
  assert_true(cv_cie_glare(120, 40, 0.5) == 0);
  /* age raises the veil; older eyes scatter more */
  assert_true(cv_cie_glare(5, 70, 0.5) > cv_cie_glare(5, 25, 0.5));
}

static void test_tvi(void **state) {
  (void)state;
  /* photopic: log dL = log La - 1.255 */
  assert_near(cv_tvi_ferwerda(100), 5.559042572704, 1e-9);
  /* scotopic: the rods, (0.405 log La + 1.6)^2.18 - 2.86 at La = 1e-3 */
  assert_near(cv_tvi_ferwerda(1e-3) / 0.00184003383618, 1, 1e-9);
  /* monotone over 12 decades, no jump above 2% at the branch ends */
  double prev = cv_tvi_ferwerda(1e-6);
  for (double x = -6; x <= 6; x += 0.01) {
    double t = cv_tvi_ferwerda(pow(10, x));
    assert_true(t >= prev * 0.98);
    assert_true(t <= prev * 1.1);
    prev = t;
  }
}

/* --- a lone matte panel under a constant environment --------------------------- */

static cv_mesh *panel_mesh(void) {
  cv_mesh *m;
  cv_mesh_create(&m);
  uint32_t mat;
  const float alb[3] = {0.05f, 0.05f, 0.05f};
  cv_mesh_add_material(m, "lcd", alb, CV_MAT_LCD, &mat);
  const float hw = 0.1f, hh = 0.06f;
  cv_mesh_add_vertex(m, -hw, -hh, 0, NULL);
  cv_mesh_add_vertex(m, hw, -hh, 0, NULL);
  cv_mesh_add_vertex(m, hw, hh, 0, NULL);
  cv_mesh_add_vertex(m, -hw, hh, 0, NULL);
  cv_mesh_add_tri(m, 0, 1, 2, mat);
  cv_mesh_add_tri(m, 0, 2, 3, mat);
  return m;
}

static cv_brdf *lambert_table(double rho) {
  cv_brdf *b;
  assert_int_equal(cv_brdf_alloc(91, 181, &b), CV_OK);
  size_t n = (size_t)91 * 91 * 181;
  for (size_t i = 0; i < 3 * n; i++) b->f[i] = (float)(rho / M_PI);
  cv_brdf_rehash(b);
  return b;
}

static double const_lum(void *ctx, const double d[3]) {
  (void)d;
  return *(const double *)ctx;
}

/* independent: L * integral over [0.1, 100] deg of g cos 2 pi sin dtheta,
 * midpoint rule on 200000 steps of log theta */
static double veil_const_quadrature(double L, double age, double p) {
  const int n = 200000;
  const double a = log(0.1), b = log(100.0), h = (b - a) / n;
  double s = 0;
  for (int i = 0; i < n; i++) {
    const double thd = exp(a + (i + 0.5) * h), th = thd * M_PI / 180;
    s += cv_cie_glare(thd, age, p) * cos(th) * 2 * M_PI * sin(th) * th * h;
  }
  return L * s;
}

static void test_matte_panel(void **state) {
  (void)state;
  const double rho = 0.3, L = 80; /* grey environment: Y = L */
  cv_brdf *b = lambert_table(rho);
  cv_mesh *m = panel_mesh();
  cv_err err;
  cv_rt *rt;
  cv_lcd_panel panel;
  cv_lcd_gather *g;
  assert_int_equal(cv_rt_create(m, &rt, &err), CV_OK);
  assert_int_equal(cv_lcd_panel_from_mesh(m, &panel, &err), CV_OK);
  assert_int_equal(cv_lcd_gather_create(rt, m, &panel, b, &g, &err), CV_OK);
  cv_envmap *env;
  assert_int_equal(cv_envmap_create(64, 32, &env), CV_OK);
  for (size_t i = 0; i < 3 * (size_t)64 * 32; i++) env->img->px[i] = (float)L;
  cv_lcd_light *l;
  const double sd[3] = {0, 1, 0}, E[3] = {0, 0, 0};
  assert_int_equal(cv_lcd_light_create(env, NULL, m->nv, 0, sd, E, &l), CV_OK);
  cv_lcd_params p;
  cv_lcd_params_default(&p);
  p.w = 20, p.h = 12, p.spp = 32;
  p.eye[0] = 0.05f, p.eye[1] = 0.1f, p.eye[2] = 0.6f; /* BRDF sampling + cosine (MIS) */
  cv_lcd_accum *acc;
  assert_int_equal(cv_lcd_accum_create(p.w, p.h, cv_lcd_default_clamp(l, b), &acc), CV_OK);
  for (uint32_t r = 0; r < 4; r++) assert_int_equal(cv_lcd_render_round(g, l, &p, r, acc), CV_OK);

  /* what the eye sees: the panel (the task: flagged, black) or the environment */
  float rgb[3];
  const float to_panel[3] = {-0.05f / 0.6103f, -0.1f / 0.6103f, -0.6f / 0.6103f};
  assert_int_equal(cv_lcd_eye_radiance(g, l, p.eye, to_panel, rgb), 1);
  assert_true(rgb[0] == 0 && rgb[1] == 0 && rgb[2] == 0);
  const float up[3] = {0, 1, 0};
  assert_int_equal(cv_lcd_eye_radiance(g, l, p.eye, up, rgb), 0);
  assert_near(rgb[1], L, 1e-3 * L);
  assert_int_equal(cv_lcd_sun_visible(g, l, p.eye), 0); /* this light has no sun */
  {
    cv_lcd_light *ls;
    const double sun_up[3] = {0, 1, 0}, sun_E[3] = {1e4, 1e4, 1e4};
    assert_int_equal(cv_lcd_light_create(env, NULL, m->nv, 1, sun_up, sun_E, &ls), CV_OK);
    assert_int_equal(cv_lcd_sun_visible(g, ls, p.eye), 1);
    cv_lcd_light_destroy(ls);
    /* a sun straight behind the panel as seen from the eye: hidden by it */
    const double sun_back[3] = {to_panel[0], to_panel[1], to_panel[2]};
    assert_int_equal(cv_lcd_light_create(env, NULL, m->nv, 1, sun_back, sun_E, &ls), CV_OK);
    assert_int_equal(cv_lcd_sun_visible(g, ls, p.eye), 0);
    cv_lcd_light_destroy(ls);
  }

  /* the veil of the same constant surround seen from the eye */
  cv_lcd_veil_params vp;
  cv_lcd_veil_params_default(&vp);
  const double gaze[3] = {0, 0, -1};
  double Lc = L;
  cv_lcd_figure lv;
  assert_int_equal(cv_lcd_veil(gaze, &vp, const_lum, &Lc, NULL, 0, &lv), CV_OK);
  const double lv_ref = veil_const_quadrature(L, vp.age, vp.pigment);
  print_message("constant surround L=%g: L_v %.4f +- %.4f, quadrature %.4f\n", L, lv.value, lv.se,
                lv_ref);
  assert_near(lv.value / lv_ref, 1, 0.005);

  cv_lcd_read_params rp;
  cv_lcd_read_params_default(&rp);
  cv_lcd_readability rd;
  assert_int_equal(cv_lcd_readability_compute(acc, &rp, &lv, &rd, &err), CV_OK);
  const double lr = rho * L, cr = (rp.white + lr + lv_ref) / (rp.black + lr + lv_ref);
  print_message("matte rho=%g: L_r %.4f +- %.4f (want %.4f), CR %.4f +- %.4f (want %.4f), "
                "VL %.2f, frac %.3f\n",
                rho, rd.L_r.value, rd.L_r.se, lr, rd.cr_mean.value, rd.cr_mean.se, cr,
                rd.vl.value, rd.frac_ok.value);
  assert_near(rd.L_r.value / lr, 1, 0.01);
  assert_near(rd.cr_mean.value / cr, 1, 0.01);
  assert_true(rd.L_r.se >= 0 && rd.L_r.se < 0.01 * lr);
  assert_true(rd.spp == 128);
  /* every texel above 3:1 here (CR about 8) */
  assert_true(rd.frac_ok.value == 1.0);
  assert_true(rd.cr_worst > 3);
  /* VL: (L_on - L_off) / dL_t at the background L_off + L_r + L_v */
  const double vl = (rp.white - rp.black) / cv_tvi_ferwerda(rp.black + rd.L_r.value + lv.value);
  assert_near(rd.vl.value / vl, 1, 1e-9);
  cv_lcd_readability_free(&rd);

  /* a requirement above the panel's CR: no texel meets it */
  rp.cr_min = 2 * cr;
  assert_int_equal(cv_lcd_readability_compute(acc, &rp, &lv, &rd, &err), CV_OK);
  assert_true(rd.frac_ok.value == 0.0);
  cv_lcd_readability_free(&rd);

  cv_lcd_accum_destroy(acc);
  cv_lcd_light_destroy(l);
  cv_envmap_destroy(env);
  cv_lcd_gather_destroy(g);
  cv_rt_destroy(rt);
  cv_mesh_destroy(m);
  cv_brdf_destroy(b);
}

/* --- a small source ---------------------------------------------------------------- */

typedef struct {
  double c[3];  /* disc centre direction */
  double cos_a; /* cos of its angular radius */
  double L;     /* its luminance */
} disc;

static double disc_lum(void *ctx, const double d[3]) {
  const disc *s = ctx;
  return d[0] * s->c[0] + d[1] * s->c[1] + d[2] * s->c[2] >= s->cos_a ? s->L : 0;
}

static void test_small_source(void **state) {
  (void)state;
  const double gaze[3] = {0, 0, -1};
  const double th = 15, alpha = 1.0, E_gl = 20; /* lx at the eye normal to the line of sight */
  const double t = th * M_PI / 180, a = alpha * M_PI / 180;
  disc s = {{sin(t) * 0.6, sin(t) * 0.8, -cos(t)}, cos(a), 0};
  /* a uniform disc of luminance L: illuminance pi L sin^2(a) normal to its axis */
  s.L = E_gl / cos(t) / (M_PI * sin(a) * sin(a));
  cv_lcd_veil_params vp;
  cv_lcd_veil_params_default(&vp);
  vp.rows = 192, vp.cols = 512, vp.spc = 16;
  cv_lcd_figure lv;
  const double want = cv_cie_glare(th, vp.age, vp.pigment) * E_gl;
  for (uint32_t seed = 1; seed <= 5; seed++) { /* five independent estimates */
    vp.seed = seed;
    assert_int_equal(cv_lcd_veil(gaze, &vp, disc_lum, &s, NULL, 0, &lv), CV_OK);
    print_message("disc at %g deg, E %g lx, seed %u: L_v %.5f +- %.5f, equation %.5f (%+.2f%%)\n",
                  th, E_gl, seed, lv.value, lv.se, want, 100 * (lv.value / want - 1));
    assert_near(lv.value / want, 1, 0.02);
    assert_true(lv.se > 0);
    assert_near(lv.value, want, 4 * lv.se + 0.01 * want);
  }

  /* the same illuminance from a point source: exact */
  cv_lcd_point_source ps = {{s.c[0], s.c[1], s.c[2]}, E_gl / cos(t)};
  assert_int_equal(cv_lcd_veil(gaze, &vp, NULL, NULL, &ps, 1, &lv), CV_OK);
  assert_near(lv.value / want, 1, 1e-9);
  assert_true(lv.se == 0);
  /* behind the driver (beyond 100 degrees): no veil */
  cv_lcd_point_source back = {{0, 0, 1}, 1e5};
  assert_int_equal(cv_lcd_veil(gaze, &vp, NULL, NULL, &back, 1, &lv), CV_OK);
  assert_true(lv.value == 0);
  /* bad input */
  vp.age = -1;
  assert_int_equal(cv_lcd_veil(gaze, &vp, NULL, NULL, &ps, 1, &lv), CV_ERR_INVALID);
  vp.age = 40, vp.pigment = 1.5;
  assert_int_equal(cv_lcd_veil(gaze, &vp, NULL, NULL, &ps, 1, &lv), CV_ERR_INVALID);
  vp.pigment = 0.5, vp.spc = 1;
  assert_int_equal(cv_lcd_veil(gaze, &vp, disc_lum, &s, NULL, 0, &lv), CV_ERR_INVALID);
}

/* --- parameters and the heat map --------------------------------------------------- */

static void test_params_and_heatmap(void **state) {
  (void)state;
  cv_lcd_read_params rp;
  cv_lcd_read_params_default(&rp);
  cv_err err;
  rp.white = 1, rp.black = 2;
  assert_int_equal(cv_lcd_read_params_check(&rp, &err), CV_ERR_INVALID);
  assert_non_null(strstr(err.msg, "white_luminance"));
  cv_lcd_read_params_default(&rp);
  rp.cr_min = 0.5;
  assert_int_equal(cv_lcd_read_params_check(&rp, &err), CV_ERR_INVALID);
  assert_non_null(strstr(err.msg, "cr_min"));

  /* a hand-made CR map: left half 1:1, right half 5:1, requirement 3:1 */
  cv_lcd_readability r;
  memset(&r, 0, sizeof r);
  r.w = 10, r.h = 4, r.cr_min = 3;
  float cr[40];
  for (int i = 0; i < 40; i++) cr[i] = i % 10 < 5 ? 1.0f : 5.0f;
  r.cr = cr;
  const int bar = 6;
  uint8_t px[10 * (4 + 6) * 3];
  assert_int_equal(cv_lcd_heatmap_rgb(&r, bar, px), CV_OK);
  for (int y = 0; y < 4; y++)
    for (int x = 0; x < 10; x++) {
      const uint8_t *o = px + 3 * (y * 10 + x);
      const int white = o[0] == 255 && o[1] == 255 && o[2] == 255;
      assert_int_equal(white, x == 4 || x == 5); /* the contour on both sides of the edge */
    }
  /* left (low CR) darker than right (viridis is brighter upwards) */
  assert_true(px[3 * 0 + 1] < px[3 * 9 + 1]);
  /* the contour follows cr_smooth when given: a lone texel that only the
   * raw map has above the requirement makes none */
  float sm[40];
  memcpy(sm, cr, sizeof sm);
  cr[12] = 5.0f;
  r.cr_smooth = sm;
  assert_int_equal(cv_lcd_heatmap_rgb(&r, bar, px), CV_OK);
  assert_false(px[3 * 12] == 255 && px[3 * 12 + 1] == 255 && px[3 * 12 + 2] == 255);
  assert_true(px[3 * 12 + 1] > px[3 * 11 + 1]); /* but its colour is its own */
  /* the bar's threshold marker: CR 3 at log10(3) * 9 = 4.3 -> column 4 (+-1) */
  const uint8_t *m = px + 3 * ((4 + bar - 1) * 10 + 4);
  assert_true(m[0] == 255 && m[1] == 255 && m[2] == 255);
}

/* --- content on the panel: its own aspect, never stretched ------------------------ */

static void test_content_aspect(void **state) {
  (void)state;
  /* a white 4:3 image on a 5:3 panel of 50 x 30 texels: 40 x 30 in the
   * middle, black (the panel's black luminance) 5 texels on each side */
  uint8_t px[4 * 3];
  memset(px, 255, sizeof px);
  cv_err err;
  const char *path = CV_TEST_TMP_DIR "/white43.png";
  assert_int_equal(cv_png_write(path, 4, 3, 1, px, &err), CV_OK);
  cv_image *img;
  assert_int_equal(cv_lcd_content_load(path, 50, 30, 5.0 / 3.0, 400, 1, &img, &err), CV_OK);
  for (int y = 0; y < 30; y++)
    for (int x = 0; x < 50; x++) {
      const float *q = cv_image_at(img, x, y);
      const double want = x < 5 || x >= 45 ? 1 : 400;
      assert_near(q[1], want, 1e-3 * want);
    }
  cv_image_destroy(img);
  /* a 5:3 image fills it; a taller one gets bars at the top and bottom */
  assert_int_equal(cv_png_write(path, 3, 4, 1, px, &err), CV_OK);
  assert_int_equal(cv_lcd_content_load(path, 50, 30, 5.0 / 3.0, 400, 1, &img, &err), CV_OK);
  assert_near(cv_image_at(img, 25, 0)[0], 400, 0.4); /* full height */
  assert_near(cv_image_at(img, 2, 15)[0], 1, 1e-3);  /* 3:4 -> 22.5 texels wide */
  cv_image_destroy(img);
  /* white below black, missing file: errors */
  assert_int_equal(cv_lcd_content_load(path, 50, 30, 5.0 / 3.0, 1, 2, &img, &err), CV_ERR_INVALID);
  assert_int_not_equal(cv_lcd_content_load(CV_TEST_TMP_DIR "/nosuch.png", 50, 30, 1, 400, 1, &img, &err), CV_OK);
  assert_non_null(strstr(err.msg, "nosuch.png"));
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_glare_equation), cmocka_unit_test(test_tvi),
      cmocka_unit_test(test_matte_panel),    cmocka_unit_test(test_small_source),
      cmocka_unit_test(test_params_and_heatmap), cmocka_unit_test(test_content_aspect),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
