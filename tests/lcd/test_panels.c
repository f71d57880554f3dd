/* Several LCD panels (src/lcd/panels.c, lcd_config.c's lcd.panels) and the
 * veil words of the accumulator:
 *  - veils stored per round sum to the same value, bit for bit;
 *  - the panels list: inheritance from the block, errors naming the key
 *    (duplicate names, two panels on the mesh, not a rectangle, a corner
 *    outside the scene, black above white);
 *  - a panel's rows of the stacked buffer equal that panel rendered alone
 *    (the same samples: `cave lcd` and the service agree whatever the panel
 *    count). */
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
#include "lcd/lcd_config.h"
#include "lcd/panels.h"
#include "mesh/cabin.h"
#include "prt/bake.h"
#include "rt/rt.h"

#define TMP(name) CV_TEST_TMP_DIR "/" name

/* The instrument cluster of configs/scenes/default.json. */
#define CLUSTER "[[-0.46, 0.6813, -0.9772], [-0.28, 0.6813, -0.9772], [-0.46, 0.7596, -0.9937]]"

static void write_file(const char *path, const char *text) {
  FILE *f = fopen(path, "w");
  assert_non_null(f);
  fputs(text, f);
  fclose(f);
}

static void test_veil_words(void **state) {
  (void)state;
  cv_lcd_accum *a, *sum;
  assert_int_equal(cv_lcd_accum_create(4, 3, 2.0, &a), CV_OK);
  assert_int_equal(cv_lcd_accum_create(4, 3, 2.0, &sum), CV_OK);
  /* a buffer that holds no round takes no veil */
  assert_int_equal(cv_lcd_accum_set_veil(a, 0, 1, 0.1), CV_ERR_INVALID);
  a->data[CV_LCD_ACC_SPP] = 4;
  a->data[CV_LCD_ACC_ROUNDS] = 1;
  assert_int_equal(cv_lcd_accum_set_veil(a, 0, 33.6312, 0.2), CV_OK);
  assert_int_equal(cv_lcd_accum_set_veil(a, 1, 511.25, 0.05), CV_OK);
  assert_int_equal(cv_lcd_accum_set_veil(a, CV_LCD_ACC_VEIL_SLOTS, 1, 0), CV_ERR_INVALID);
  assert_int_equal(cv_lcd_accum_set_veil(a, 0, NAN, 0), CV_ERR_INVALID);
  assert_int_equal(cv_lcd_accum_set_veil(a, 0, -1, 0), CV_ERR_INVALID);
  double v, se;
  assert_int_equal(cv_lcd_accum_veil(sum, 0, &v, &se), 0); /* none yet */
  for (int r = 0; r < 7; r++) assert_int_equal(cv_lcd_accum_add(sum, a), CV_OK);
  double v1, se1;
  assert_int_equal(cv_lcd_accum_veil(a, 0, &v1, &se1), 1);
  assert_int_equal(cv_lcd_accum_veil(sum, 0, &v, &se), 1);
  assert_true(v == v1 && se == se1); /* the mean of equal words is the word */
  assert_near(v, 33.6312, 1e-7);
  assert_int_equal(cv_lcd_accum_veil(sum, 1, &v, &se), 1);
  assert_near(v, 511.25, 1e-7);
  assert_near(se, 0.05, 1e-7);
  cv_lcd_accum_destroy(a);
  cv_lcd_accum_destroy(sum);
}

static int load_text(const char *text, cv_lcd_config *c, cv_err *err) {
  write_file(TMP("panels.json"), text);
  cv_lcd_config_default(c);
  int st = cv_lcd_config_load_scene(TMP("panels.json"), c, err);
  if (!st) st = cv_lcd_config_panels(c, err);
  return st;
}

static void test_config(void **state) {
  (void)state;
  cv_lcd_config c;
  cv_err err;
  /* the single-panel form: one panel "lcd" with the block's settings */
  assert_int_equal(load_text("{\"lcd\": {\"content_luminance\": 300, \"resolution\": [40, 24]}}", &c, &err), CV_OK);
  assert_int_equal(c.n_panels, 1);
  assert_string_equal(c.panels[0].name, "lcd");
  assert_true(c.panels[0].content_luminance == 300 && c.panels[0].black_luminance == 0.6);
  assert_int_equal(c.panels[0].width, 40);
  /* a list: unset fields from the block */
  assert_int_equal(load_text("{\"lcd\": {\"content_luminance\": 400, \"panels\": [{\"name\": \"centre\"},"
                             " {\"name\": \"cluster\", \"black_luminance\": 2, \"corners\": " CLUSTER "}]}}",
                             &c, &err), CV_OK);
  assert_int_equal(c.n_panels, 2);
  assert_true(c.panels[0].content_luminance == 400);
  assert_near(c.panels[0].black_luminance, 0.8, 1e-12);
  assert_true(c.panels[1].content_luminance == 400 && c.panels[1].black_luminance == 2);
  assert_true(c.panels[1].has_corners && !c.panels[0].has_corners);
  /* errors name the key */
  static const struct {
    const char *text, *want;
  } bad[] = {
      {"{\"lcd\": {\"panels\": [{\"name\": \"a\"}, {\"name\": \"a\", \"corners\": " CLUSTER "}]}}",
       "lcd.panels[1].name: 'a' is also"},
      {"{\"lcd\": {\"panels\": [{\"name\": \"a\"}, {\"name\": \"b\"}]}}", "lcd.panels[1].corners: required"},
      {"{\"lcd\": {\"panels\": [{\"name\": \"a\", \"corners\": [[0,0,0], [1,0,0], [1,1,0]]}]}}",
       "lcd.panels[0].corners: not a rectangle"},
      {"{\"lcd\": {\"panels\": [{\"name\": \"a\", \"content_luminance\": 10, \"black_luminance\": 20}]}}",
       "lcd.panels[0].black_luminance"},
      {"{\"lcd\": {\"panels\": [{\"name\": \"a\", \"content\": \"nosuch.png\"}]}}",
       "lcd.panels[0].content: "},
      {"{\"lcd\": {\"panels\": [{\"name\": \"a b\"}]}}", "lcd.panels[0].name"},
      {"{\"lcd\": {\"panels\": []}}", "lcd.panels: expected a list"},
      {"{\"lcd\": {\"age\": -1}}", "lcd.age"},
  };
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    cv_err_clear(&err);
    assert_int_equal(load_text(bad[i].text, &c, &err), CV_ERR_CONFIG);
    if (!strstr(err.msg, bad[i].want)) fail_msg("case %zu: '%s' lacks '%s'", i, err.msg, bad[i].want);
  }
}

static void test_stacked_equals_alone(void **state) {
  (void)state;
  cv_cabin_params cp;
  cv_cabin_default_params(&cp);
  cp.tess = 1;
  cv_mesh *m;
  cv_cabin_info info;
  cv_err err;
  assert_int_equal(cv_cabin_generate_ex(&cp, &m, &info, &err), CV_OK);
  cv_tracer *tr;
  assert_int_equal(cv_tracer_create(m, &tr, &err), CV_OK);
  cv_lcd_config one, two;
  assert_int_equal(load_text("{\"lcd\": {\"resolution\": [24, 16]}}", &one, &err), CV_OK);
  assert_int_equal(load_text("{\"lcd\": {\"resolution\": [24, 16], \"panels\": [{\"name\": \"centre\"},"
                             " {\"name\": \"cluster\", \"resolution\": [20, 8], \"corners\": " CLUSTER "}]}}",
                             &two, &err), CV_OK);
  cv_lcd_layout L1, L2;
  assert_int_equal(cv_lcd_layout_make(&one, m, &L1, &err), CV_OK);
  assert_int_equal(cv_lcd_layout_make(&two, m, &L2, &err), CV_OK);
  assert_true(L2.W == 24 && L2.H == 24 && L2.y0[1] == 16 && L2.w[1] == 20);
  /* a corner outside the scene */
  cv_lcd_config far = two;
  far.panels[1].corners[0][2] = -3.5;
  assert_int_equal(cv_lcd_layout_make(&far, m, &L1, &err), CV_ERR_CONFIG);
  assert_non_null(strstr(err.msg, "lcd.panels[1].corners[0]"));
  assert_int_equal(cv_lcd_layout_make(&one, m, &L1, &err), CV_OK);
  cv_lcd_panels *p1, *p2;
  assert_int_equal(cv_lcd_panels_create(&one, &L1, cv_tracer_rt(tr), m, &p1, &err), CV_OK);
  assert_int_equal(cv_lcd_panels_create(&two, &L2, cv_tracer_rt(tr), m, &p2, &err), CV_OK);
  cv_envmap *env;
  assert_int_equal(cv_envmap_create(32, 16, &env), CV_OK);
  for (size_t i = 0; i < (size_t)32 * 16 * 3; i++) env->img->px[i] = 1.0f;
  float *vrad = malloc(3 * m->nv * sizeof(float));
  for (size_t i = 0; i < 3 * m->nv; i++) vrad[i] = 0.5f;
  cv_lcd_light *l;
  assert_int_equal(cv_lcd_light_create(env, vrad, m->nv, 0, NULL, NULL, &l), CV_OK);
  cv_lcd_params p;
  cv_lcd_params_default(&p);
  p.spp = 4;
  p.eye[0] = -0.37f, p.eye[1] = 1.02f, p.eye[2] = 0;
  const double clamp = cv_lcd_panels_clamp(p2, l, 0);
  assert_true(clamp == cv_lcd_panels_clamp(p1, l, 0)); /* the same BRDF */
  cv_lcd_accum *a1, *a2, *crop;
  assert_int_equal(cv_lcd_accum_create(L1.W, L1.H, clamp, &a1), CV_OK);
  assert_int_equal(cv_lcd_accum_create(L2.W, L2.H, clamp, &a2), CV_OK);
  for (uint32_t r = 0; r < 2; r++) {
    assert_int_equal(cv_lcd_panels_round(p1, l, &p, r, a1), CV_OK);
    assert_int_equal(cv_lcd_panels_round(p2, l, &p, r, a2), CV_OK);
  }
  assert_int_equal(a2->data[CV_LCD_ACC_SPP], 8);
  assert_int_equal(a2->data[CV_LCD_ACC_ROUNDS], 2);
  assert_int_equal(cv_lcd_layout_crop(&L2, a2, 0, &crop), CV_OK);
  const size_t tex = 5 * (size_t)L1.W * L1.H;
  assert_memory_equal(crop->data + CV_LCD_ACC_HEADER, a1->data + CV_LCD_ACC_HEADER, tex * sizeof(int64_t));
  cv_lcd_accum_destroy(crop);
  /* the cluster's rows hold light; the texels right of it stay 0 */
  assert_int_equal(cv_lcd_layout_crop(&L2, a2, 1, &crop), CV_OK);
  int64_t s = 0;
  for (size_t i = CV_LCD_ACC_HEADER; i < crop->n; i++) s += crop->data[i];
  assert_true(s > 0);
  cv_lcd_accum_destroy(crop);
  for (int y = L2.y0[1]; y < L2.H; y++)
    for (int x = L2.w[1]; x < L2.W; x++) assert_true(a2->data[cv_lcd_acc_rgb(a2, x, y)] == 0);
  /* the veils of both panels, from the eye */
  cv_lcd_veil_params vp;
  cv_lcd_veil_params_default(&vp);
  cv_lcd_figure lv[CV_LCD_MAX_PANELS];
  double sun[CV_LCD_MAX_PANELS];
  assert_int_equal(cv_lcd_panels_veils(p2, l, p.eye, &vp, lv, sun), CV_OK);
  assert_true(lv[0].value > 0 && lv[1].value > 0 && sun[0] == -1);
  cv_lcd_accum_destroy(a1);
  cv_lcd_accum_destroy(a2);
  cv_lcd_light_destroy(l);
  free(vrad);
  cv_envmap_destroy(env);
  cv_lcd_panels_destroy(p1);
  cv_lcd_panels_destroy(p2);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_veil_words),
      cmocka_unit_test(test_config),
      cmocka_unit_test(test_stacked_equals_alone),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
