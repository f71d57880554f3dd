/* Absolute light or no verdict, and the illuminance sweep (issue 34):
 *  - the calibration of a lighting: relative maps are uncalibrated,
 *    --illuminance, a declared scale, the sky and a constant are absolute,
 *    illuminance auto is an assumption;
 *  - the verdict: none without absolute light, whatever the figures; with
 *    it, READABLE only when CR, the area share and VL all pass;
 *  - the illuminance at the eye under a constant environment L and a sun:
 *    pi L + E_sun cos (1%), outdoors and at the eye;
 *  - the sweep's 3:1 crossing against the closed form of a matte panel
 *    (Lambertian albedo rho, horizontal, constant environment: L_r =
 *    rho E / pi, the veil E G / pi with G the glare kernel's integral,
 *    computed here by an independent quadrature) within 1%, and the
 *    figures at that level have CR 3 within 1%;
 *  - bad sweeps (LO > HI, N = 0 or 1, negative, junk) are refused with a
 *    one-line reason;
 *  - the heat map figure: title text, the panel magnified to >= 480 pixels
 *    inside a black outline, the colour bar with the requirement white. */
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
#include "lcd/heatmap.h"
#include "lcd/light_level.h"
#include "lcd/readability.h"
#include "lcd/sweep.h"
#include "rt/rt.h"

/* A lone horizontal LCD quad at the origin, normal +Y. */
static cv_mesh *flat_panel(void) {
  cv_mesh *m;
  cv_mesh_create(&m);
  uint32_t mat;
  const float alb[3] = {0.05f, 0.05f, 0.05f};
  cv_mesh_add_material(m, "lcd", alb, CV_MAT_LCD, &mat);
  const float hw = 0.1f, hd = 0.06f;
  cv_mesh_add_vertex(m, -hw, 0, hd, NULL);
  cv_mesh_add_vertex(m, hw, 0, hd, NULL);
  cv_mesh_add_vertex(m, hw, 0, -hd, NULL);
  cv_mesh_add_vertex(m, -hw, 0, -hd, NULL);
  cv_mesh_add_tri(m, 0, 1, 2, mat);
  cv_mesh_add_tri(m, 0, 2, 3, mat);
  return m;
}

static cv_brdf *lambert(float a) {
  cv_brdf *b;
  assert_int_equal(cv_brdf_alloc(91, 181, &b), CV_OK);
  const size_t n = (size_t)91 * 91 * 181 * 3;
  for (size_t i = 0; i < n; i++) b->f[i] = (float)(a / M_PI);
  cv_brdf_rehash(b);
  return b;
}

static cv_envmap *constant_env(int w, float L) {
  cv_envmap *e;
  assert_int_equal(cv_envmap_create(w, w / 2, &e), CV_OK);
  for (size_t i = 0; i < (size_t)w * (w / 2) * 3; i++) e->img->px[i] = L;
  return e;
}

static void test_calibration(void **state) {
  (void)state;
  cv_light_spec s;
  cv_lcd_calib c;
  cv_light_spec_default(&s);
  s.kind = CV_LIGHT_ENV;
  s.n_env = 1;
  snprintf(s.env[0], sizeof s.env[0], "/maps/sunrise.exr");
  s.scale = 10000;
  cv_lcd_calibration(&s, "drive d.json", &c);
  assert_int_equal(c.absolute, 0);
  assert_non_null(strstr(c.source, "uncalibrated"));
  assert_non_null(strstr(c.source, "drive d.json"));
  s.absolute = 1;
  cv_lcd_calibration(&s, "drive d.json", &c);
  assert_int_equal(c.absolute, 1);
  assert_int_equal(c.assumed, 0);
  s.absolute = 0;
  s.scale = 1;
  s.illuminance = 17500;
  cv_lcd_calibration(&s, "command line", &c);
  assert_int_equal(c.absolute, 1);
  assert_non_null(strstr(c.source, "17500 lx"));
  s.illuminance = CV_ILLUMINANCE_AUTO;
  cv_lcd_calibration(&s, "command line", &c);
  assert_int_equal(c.absolute, 1);
  assert_int_equal(c.assumed, 1);
  assert_non_null(strstr(c.source, "ASSUMED"));
  s.kind = CV_LIGHT_SKY;
  cv_lcd_calibration(&s, "x", &c);
  assert_int_equal(c.absolute, 1);
  s.kind = CV_LIGHT_CONSTANT;
  cv_lcd_calibration(&s, "x", &c);
  assert_int_equal(c.absolute, 1);
  s.kind = CV_LIGHT_NONE;
  cv_lcd_calibration(&s, "x", &c);
  assert_int_equal(c.absolute, 0);
}

static void test_verdict(void **state) {
  (void)state;
  cv_lcd_read_params p;
  cv_lcd_read_params_default(&p);
  cv_lcd_readability rd;
  memset(&rd, 0, sizeof rd);
  rd.cr_mean.value = 8.7, rd.frac_ok.value = 1.0, rd.vl.value = 90;
  char why[160];
  /* uncalibrated: no verdict, however good (CR 489 on a relative map) */
  rd.cr_mean.value = 489;
  assert_int_equal(cv_lcd_verdict(&rd, &p, 0, why, sizeof why), CV_LCD_UNCALIBRATED);
  assert_string_equal(cv_lcd_verdict_name(CV_LCD_UNCALIBRATED), "uncalibrated");
  rd.cr_mean.value = 1.9;
  assert_int_equal(cv_lcd_verdict(&rd, &p, 0, why, sizeof why), CV_LCD_UNCALIBRATED);
  /* absolute: all three must pass */
  rd.cr_mean.value = 8.7;
  assert_int_equal(cv_lcd_verdict(&rd, &p, 1, why, sizeof why), CV_LCD_READABLE);
  rd.cr_mean.value = 2.9;
  assert_int_equal(cv_lcd_verdict(&rd, &p, 1, why, sizeof why), CV_LCD_UNREADABLE);
  assert_non_null(strstr(why, "CR"));
  rd.cr_mean.value = 4.2, rd.frac_ok.value = 0.9; /* the mean passes, the area does not */
  assert_int_equal(cv_lcd_verdict(&rd, &p, 1, why, sizeof why), CV_LCD_UNREADABLE);
  assert_non_null(strstr(why, "area"));
  rd.frac_ok.value = 0.99, rd.vl.value = 3;
  assert_int_equal(cv_lcd_verdict(&rd, &p, 1, why, sizeof why), CV_LCD_UNREADABLE);
  assert_non_null(strstr(why, "VL"));
  assert_int_equal(cv_lcd_verdict(&rd, &p, 1, NULL, 0), CV_LCD_UNREADABLE);
}

static void test_sweep_parse(void **state) {
  (void)state;
  double lo, hi;
  int n;
  char why[200];
  assert_int_equal(cv_lcd_sweep_parse("1000:100000", &lo, &hi, &n, why, sizeof why), CV_OK);
  assert_true(lo == 1000 && hi == 100000 && n == 21);
  assert_int_equal(cv_lcd_sweep_parse("10:20:5", &lo, &hi, &n, why, sizeof why), CV_OK);
  assert_int_equal(n, 5);
  assert_near(cv_lcd_sweep_level(10, 20, 5, 2), sqrt(200), 1e-9);
  static const char *const bad[] = {"5:1",  "10:20:0", "10:20:1", "-5:10",   "0:10", "10:-20",
                                    "abc",  "10",      "10:",     ":10",     "10:20:x",
                                    "10:20:2.5", "10:20:1001", "10:2e7", "nan:10", ""};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    why[0] = '\0';
    assert_int_equal(cv_lcd_sweep_parse(bad[i], &lo, &hi, &n, why, sizeof why), CV_ERR_INVALID);
    assert_true(why[0] != '\0' && !strchr(why, '\n')); /* one line saying why */
  }
}

/* G = integral over the cap 0.1..100 deg of g(theta) cos(theta) dw: the veil
 * of a uniform field of unit luminance (Simpson in log theta, 20000 steps). */
static double glare_integral(double age, double p) {
  const int n = 20000;
  const double a = log(0.1 * M_PI / 180), b = log(100 * M_PI / 180), h = (b - a) / n;
  double s = 0;
  for (int i = 0; i <= n; i++) {
    const double th = exp(a + i * h), w = (i == 0 || i == n) ? 1 : (i % 2 ? 4 : 2);
    s += w * cv_cie_glare(th * 180 / M_PI, age, p) * cos(th) * sin(th) * th; /* dth = th du */
  }
  return 2 * M_PI * s * h / 3;
}

static void test_sweep_closed_form(void **state) {
  (void)state;
  const float rho = 0.04f, L = 2.0f; /* constant environment, relative units */
  cv_brdf *b = lambert(rho);
  cv_mesh *m = flat_panel();
  cv_err err;
  cv_rt *rt;
  cv_lcd_panel panel;
  cv_lcd_gather *g;
  assert_int_equal(cv_rt_create(m, &rt, &err), CV_OK);
  assert_int_equal(cv_lcd_panel_from_mesh(m, &panel, &err), CV_OK);
  assert_int_equal(cv_lcd_gather_create(rt, m, &panel, b, &g, &err), CV_OK);
  cv_envmap *env = constant_env(256, L);
  cv_lcd_light *l;
  const double sd[3] = {0, 1, 0}, sE[3] = {0, 0, 0};
  assert_int_equal(cv_lcd_light_create(env, NULL, m->nv, 0, sd, sE, &l), CV_OK);
  /* the reference level: the lighting's horizontal illuminance, pi L */
  const double E_ref = cv_lcd_outdoor_illuminance(l);
  print_message("outdoor illuminance %.6f (pi L = %.6f)\n", E_ref, M_PI * L);
  assert_near(E_ref / (M_PI * L), 1, 1e-3);
  cv_lcd_params par;
  cv_lcd_params_default(&par);
  par.w = 16, par.h = 10, par.spp = 16;
  par.eye[0] = -0.2f, par.eye[1] = 0.5f, par.eye[2] = 0.4f;
  par.brdf_fraction = 0; /* cosine sampling: exact per sample for a Lambertian panel */
  par.env_fraction = par.window_fraction = 0;
  cv_lcd_accum *acc;
  assert_int_equal(cv_lcd_accum_create(par.w, par.h, cv_lcd_default_clamp(l, b), &acc), CV_OK);
  assert_int_equal(cv_lcd_render_round(g, l, &par, 0, acc), CV_OK);
  cv_lcd_read_params rp;
  cv_lcd_read_params_default(&rp);
  rp.white = 500, rp.black = 1, rp.cr_min = 3;
  const double G = glare_integral(40, 0.5);
  const cv_lcd_figure lv = {L * G, 0}; /* a uniform field of luminance L */
  cv_lcd_readability ref;
  assert_int_equal(cv_lcd_readability_compute(acc, &rp, &lv, &ref, &err), CV_OK);
  print_message("L_r %.6f (rho L = %.6f), L_v %.6f\n", ref.L_r.value, rho * L, lv.value);
  assert_near(ref.L_r.value / (rho * L), 1, 1e-3);
  /* closed form: (W + (rho + G) E / pi) = c (B + (rho + G) E / pi) */
  const double want = M_PI * (rp.white - rp.cr_min * rp.black) / ((rp.cr_min - 1) * (rho + G));
  double E_star, se;
  assert_int_equal(cv_lcd_sweep_crossing(&ref, &rp, E_ref, &E_star, &se), 1);
  print_message("3:1 crossing %.2f lx +- %.2g, closed form %.2f lx (G = %.5f)\n", E_star, se,
                want, G);
  assert_near(E_star / want, 1, 0.01);
  /* the figures at that level: CR 3, and the grid crossing of a sweep */
  cv_lcd_readability at;
  assert_int_equal(cv_lcd_sweep_figures(acc, &rp, &lv, E_ref, E_star, &at, &err), CV_OK);
  assert_near(at.cr_mean.value / 3, 1, 0.01);
  assert_near(at.L_r.value / (rho * E_star / M_PI), 1, 0.01);
  cv_lcd_readability_free(&at);
  enum { N = 41 };
  double E[N], cr[N], Ex;
  for (int k = 0; k < N; k++) {
    E[k] = cv_lcd_sweep_level(100, 1e6, N, k);
    assert_int_equal(cv_lcd_sweep_figures(acc, &rp, &lv, E_ref, E[k], &at, &err), CV_OK);
    cr[k] = at.cr_mean.value;
    if (k) assert_true(cr[k] < cr[k - 1]); /* falls with the light */
    cv_lcd_readability_free(&at);
  }
  assert_int_equal(cv_lcd_sweep_grid_crossing(E, cr, 3, N, &Ex), 1);
  print_message("grid crossing %.2f lx\n", Ex);
  assert_near(Ex / want, 1, 0.01);
  /* a bad level is refused, never NaN */
  assert_int_equal(cv_lcd_sweep_figures(acc, &rp, &lv, E_ref, -1, &at, &err), CV_ERR_INVALID);
  assert_int_equal(cv_lcd_sweep_figures(acc, &rp, &lv, 0, 10, &at, &err), CV_ERR_INVALID);
  cv_lcd_readability_free(&ref);
  cv_lcd_accum_destroy(acc);
  cv_lcd_light_destroy(l);
  cv_envmap_destroy(env);
  cv_lcd_gather_destroy(g);
  cv_rt_destroy(rt);
  cv_mesh_destroy(m);
  cv_brdf_destroy(b);
}

/* Illuminance at the eye above the panel, looking ahead away from it: the
 * whole constant environment, pi L on both planes, plus the sun. */
static void test_eye_illuminance(void **state) {
  (void)state;
  cv_brdf *b = lambert(0.04f);
  cv_mesh *m = flat_panel();
  cv_err err;
  cv_rt *rt;
  cv_lcd_panel panel;
  cv_lcd_gather *g;
  assert_int_equal(cv_rt_create(m, &rt, &err), CV_OK);
  assert_int_equal(cv_lcd_panel_from_mesh(m, &panel, &err), CV_OK);
  assert_int_equal(cv_lcd_gather_create(rt, m, &panel, b, &g, &err), CV_OK);
  const float L = 3.0f;
  cv_envmap *env = constant_env(128, L);
  const double el = 30 * M_PI / 180;
  const double sd[3] = {0, sin(el), -cos(el)}, sE[3] = {100, 100, 100}; /* ahead, 30 deg up */
  cv_lcd_light *l;
  assert_int_equal(cv_lcd_light_create(env, NULL, m->nv, 1, sd, sE, &l), CV_OK);
  const float eye[3] = {0, 0.5f, 0.3f}; /* the panel, below, hides 0.1% of the vertical's view */
  cv_lcd_illum il;
  cv_lcd_illuminance(g, l, eye, &il);
  const double Eh = M_PI * L + 100 * sin(el), Ev = M_PI * L + 100 * cos(el);
  print_message("outdoor %.4f, eye h %.4f +- %.2g (want %.4f), v %.4f +- %.2g (want %.4f)\n",
                il.outdoor_h, il.eye_h, il.eye_h_se, Eh, il.eye_v, il.eye_v_se, Ev);
  assert_near(il.outdoor_h / Eh, 1, 0.01);
  assert_near(il.eye_h / Eh, 1, 0.01);
  assert_near(il.eye_v / Ev, 1, 0.01);
  assert_true(isfinite(il.eye_h_se) && isfinite(il.eye_v_se));
  /* the light words of a round carry it; their mean over rounds is it again */
  cv_lcd_accum *a, *b2;
  assert_int_equal(cv_lcd_accum_create(4, 4, 1.0, &a), CV_OK);
  assert_int_equal(cv_lcd_accum_create(4, 4, 1.0, &b2), CV_OK);
  a->data[CV_LCD_ACC_ROUNDS] = b2->data[CV_LCD_ACC_ROUNDS] = 1;
  const double E3[3] = {il.outdoor_h, il.eye_h, il.eye_v};
  double got[3];
  assert_int_equal(cv_lcd_accum_light(a, got), 0);
  assert_int_equal(cv_lcd_accum_set_light(a, E3), CV_OK);
  assert_int_equal(cv_lcd_accum_set_light(b2, E3), CV_OK);
  assert_int_equal(cv_lcd_accum_add(a, b2), CV_OK);
  assert_int_equal(cv_lcd_accum_light(a, got), 1);
  for (int k = 0; k < 3; k++) assert_near(got[k], E3[k], 1e-6);
  const double badE[3] = {-1, 0, 0};
  assert_int_equal(cv_lcd_accum_set_light(b2, badE), CV_ERR_INVALID);
  cv_lcd_accum_destroy(a);
  cv_lcd_accum_destroy(b2);
  cv_lcd_light_destroy(l);
  cv_envmap_destroy(env);
  cv_lcd_gather_destroy(g);
  cv_rt_destroy(rt);
  cv_mesh_destroy(m);
  cv_brdf_destroy(b);
}

static void test_heatmap_figure(void **state) {
  (void)state;
  cv_lcd_readability r;
  memset(&r, 0, sizeof r);
  r.w = 40, r.h = 24, r.cr_min = 3, r.white = 500, r.black = 1;
  const size_t n = (size_t)r.w * r.h;
  r.lr = calloc(n, sizeof(float));
  r.cr = calloc(n, sizeof(float));
  r.cr_smooth = calloc(n, sizeof(float));
  for (int y = 0; y < r.h; y++)
    for (int x = 0; x < r.w; x++) { /* CR from 1.5 (left) to 8 (right) */
      const size_t i = (size_t)y * r.w + x;
      r.cr[i] = r.cr_smooth[i] = (float)(1.5 + 6.5 * x / (r.w - 1));
      r.lr[i] = (float)((r.white - r.cr[i] * r.black) / (r.cr[i] - 1));
    }
  const char *lines[2] = {"panel centre: CR 3.2", "light 20000 lx"};
  uint8_t *px = NULL;
  int W = 0, H = 0;
  assert_int_equal(cv_lcd_heatmap_figure(&r, lines, 2, &px, &W, &H), CV_OK);
  print_message("heat map figure %d x %d\n", W, H);
  assert_true(W >= 480 + 4 && H > 24 * 12);
  /* the title is drawn (black pixels in its first text row), the rest of the
   * margin white */
  int black = 0;
  for (int y = 12; y < 12 + 14; y++)
    for (int x = 0; x < W; x++) black += px[3 * ((size_t)y * W + x)] == 0;
  assert_true(black > 50);
  assert_int_equal(px[0], 255);
  /* the panel, magnified 12 x, centred, inside the outline */
  const int pw = 40 * 12, x0 = (W - pw) / 2, y0 = 12 + 2 * (14 + 6) + 6 + 2;
  assert_int_equal(px[3 * ((size_t)(y0 - 1) * W + x0 + 10)], 0);      /* the outline */
  const uint8_t *left = px + 3 * ((size_t)(y0 + 200) * W + x0 + 2);    /* CR 1.5: violet-blue */
  const uint8_t *right = px + 3 * ((size_t)(y0 + 200) * W + x0 + pw - 3); /* CR 8: yellow-green */
  assert_true(left[2] > left[1] && right[1] > right[2]);
  cv_lcd_readability_free(&r);
  free(px);
  /* one line of text is 6 pixels per character and scale */
  uint8_t img[3 * 100 * 20];
  memset(img, 255, sizeof img);
  const uint8_t k[3] = {0, 0, 0};
  assert_int_equal(cv_lcd_draw_text(img, 100, 20, 1, 1, 1, "CR 3:1", k), 36);
  assert_int_equal(cv_lcd_heatmap_figure(&r, lines, 2, &px, &W, &H), CV_ERR_INVALID); /* freed */
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_calibration),       cmocka_unit_test(test_verdict),
      cmocka_unit_test(test_sweep_parse),       cmocka_unit_test(test_sweep_closed_form),
      cmocka_unit_test(test_eye_illuminance),   cmocka_unit_test(test_heatmap_figure),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
