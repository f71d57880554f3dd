/* Unit tests of the view module (src/view): the shipped CAVE configs load
 * with their screens facing the head; bad configs give errors naming the
 * field (all of them when there are several); Kooima's off-axis projection
 * maps the screen corners to the NDC square for any eye in front, is
 * symmetric for an eye on the screen's centre normal, and agrees along the
 * edge two walls share; eye placement for stereo. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include "cv_test_near.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/status.h"
#include "view/cave.h"
#include "view/offaxis.h"

#define CAVES CV_SOURCE_DIR "/configs/caves"

static double urand(double lo, double hi) { return lo + (hi - lo) * rand() / (double)RAND_MAX; }

static void must_contain(const char *msg, const char *part) {
  if (!strstr(msg, part)) {
    fprintf(stderr, "error message lacks '%s': %s\n", part, msg);
    fail();
  }
}

/* --- configs ----------------------------------------------------------------- */

static void test_load_shipped(void **state) {
  (void)state;
  cv_cave c;
  cv_err err = {0};
  int st = cv_cave_load(CAVES "/cave5.json", &c, &err);
  if (st) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(st, CV_OK);
  assert_int_equal(c.n_walls, 5);
  const char *names[5] = {"front", "left", "right", "floor", "ceiling"};
  for (int i = 0; i < 5; i++) {
    assert_string_equal(c.walls[i].name, names[i]);
    assert_int_equal(c.walls[i].res[0], 720);
    assert_int_equal(c.walls[i].res[1], 720);
    /* (pb-pa) x (pc-pa) points into the cube: towards its centre */
    const cv_wall *w = &c.walls[i];
    double e1[3], e2[3], n[3], to[3];
    for (int k = 0; k < 3; k++) {
      e1[k] = w->pb[k] - w->pa[k];
      e2[k] = w->pc[k] - w->pa[k];
    }
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    const double centre[3] = {0, 1.5, 0};
    double pcen[3];
    for (int k = 0; k < 3; k++) pcen[k] = w->pa[k] + 0.5 * (e1[k] + e2[k]);
    for (int k = 0; k < 3; k++) to[k] = centre[k] - pcen[k];
    double nl = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    assert_near(nl, 9.0, 1e-12);
    assert_near((n[0] * to[0] + n[1] * to[1] + n[2] * to[2]) / nl, 1.5, 1e-12);
  }
  assert_near(c.eye_separation, 0.064, 1e-15);
  assert_int_equal(c.supersample, 1);
  assert_int_equal(c.lum_res, 128);
  assert_near(c.head[1], 1.2, 1e-15);
  assert_near(c.gaze[2], -1, 1e-15);
  /* the head lands on the default cabin's driver eye */
  const double driver[3] = {-0.37, 1.02, 0};
  for (int k = 0; k < 3; k++) assert_near(c.head[k] + c.scene_offset[k], driver[k], 1e-12);
  assert_int_equal(cv_cave_check_eye(&c, c.head, &err), CV_OK);

  st = cv_cave_load(CAVES "/two-sided-wall.json", &c, &err);
  if (st) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(st, CV_OK);
  assert_int_equal(c.n_walls, 2);
  assert_string_equal(c.walls[0].name, "front");
  assert_string_equal(c.walls[1].name, "left");
  /* defaults */
  assert_near(c.near, 0.05, 1e-15);
  assert_near(c.far, 50, 1e-15);
  assert_near(c.drago_bias, 0.85, 1e-15);
  assert_near(c.drago_ldmax, 100, 1e-15);
  assert_near(c.t0_cone, 0.08, 1e-15);
  assert_near(c.tau_rod, 400, 1e-15);
  assert_near(c.foveal_deg, 10, 1e-15);
}

#define FRONT "{\"name\": \"front\", \"pa\": [-1.5, 0, -1.5], \"pb\": [1.5, 0, -1.5], \"pc\": [-1.5, 3, -1.5], \"res\": [64, 64]}"
#define LEFT "{\"name\": \"left\", \"pa\": [-1.5, 0, 1.5], \"pb\": [-1.5, 0, -1.5], \"pc\": [-1.5, 3, 1.5], \"res\": [64, 64]}"

/* Parses text, expects failure and every part in the message. */
static void expect_bad(const char *text, const char *const *parts, int n_parts) {
  cv_cave c;
  cv_err err = {0};
  int st = cv_cave_parse(text, "bad.json", &c, &err);
  printf("  %s\n", err.msg);
  assert_true(st < 0);
  assert_int_equal(err.status, st);
  must_contain(err.msg, "bad.json: ");
  for (int i = 0; i < n_parts; i++) must_contain(err.msg, parts[i]);
}

static void test_bad_configs(void **state) {
  (void)state;
  cv_cave c;
  cv_err err = {0};
  assert_int_equal(cv_cave_parse("{\"walls\": [" FRONT ", " LEFT "]}", "ok.json", &c, &err), CV_OK);

  const char *skew[] = {"walls[1].pc", "rectangle"};
  expect_bad("{\"walls\": [" FRONT ", {\"name\": \"s\", \"pa\": [-1.5, 0, 1.5], \"pb\": [-1.5, 0, -1.5], "
             "\"pc\": [-1.5, 3, 1.4], \"res\": [8, 8]}]}",
             skew, 2);
  const char *behind[] = {"head", "\"front\""};
  expect_bad("{\"walls\": [" FRONT "], \"head\": [0, 1.2, -2]}", behind, 2);
  const char *dup[] = {"walls[1].name", "duplicate"};
  expect_bad("{\"walls\": [" FRONT ", " FRONT "]}", dup, 2);
  const char *missing[] = {"walls: missing"};
  expect_bad("{\"head\": [0, 1, 0]}", missing, 1);
  const char *res0[] = {"walls[0].res[0]"};
  expect_bad("{\"walls\": [{\"name\": \"front\", \"pa\": [-1.5, 0, -1.5], \"pb\": [1.5, 0, -1.5], "
             "\"pc\": [-1.5, 3, -1.5], \"res\": [0, 64]}]}",
             res0, 1);
  const char *zero[] = {"walls[0].pb", "zero area"};
  expect_bad("{\"walls\": [{\"name\": \"z\", \"pa\": [0, 0, -1], \"pb\": [0, 0, -1], "
             "\"pc\": [0, 1, -1], \"res\": [4, 4]}]}",
             zero, 2);
  const char *unknown[] = {"walls[0].resolution", "unknown field", "eye_sep: unknown field"};
  expect_bad("{\"walls\": [{\"name\": \"front\", \"pa\": [-1.5, 0, -1.5], \"pb\": [1.5, 0, -1.5], "
             "\"pc\": [-1.5, 3, -1.5], \"resolution\": [4, 4]}], \"eye_sep\": 0.06}",
             unknown, 3);
  const char *syntax[] = {"line 1, column 12: JSON syntax error at the end of the text"};
  expect_bad("{\"walls\": [", syntax, 1);
  const char *misc[] = {"supersample", "far: expected far > near", "gaze", "lum_res"};
  expect_bad("{\"walls\": [" FRONT "], \"supersample\": 3, \"near\": 1, \"far\": 0.5, "
             "\"gaze\": [0, 0, 0], \"lum_res\": 1.5}",
             misc, 4);
  const char *nearneg[] = {"near: -1 is outside"};
  expect_bad("{\"walls\": [" FRONT "], \"near\": -1}", nearneg, 1);

  /* three problems at once, all listed */
  const char *three[] = {"walls[0].pc", "walls[1].res[1]", "walls[2].name", "[3 problems]"};
  expect_bad("{\"walls\": [{\"name\": \"front\", \"pa\": [-1.5, 0, -1.5], \"pb\": [1.5, 0, -1.5], "
             "\"pc\": [-1.4, 3, -1.5], \"res\": [8, 8]}, "
             "{\"name\": \"b\", \"pa\": [-1.5, 0, 1.5], \"pb\": [-1.5, 0, -1.5], \"pc\": [-1.5, 3, 1.5], "
             "\"res\": [8, 20000]}, " FRONT "]}",
             three, 4);
  /* many problems: the line stays one line, ends with the count */
  char big[8192] = "{\"walls\": [";
  for (int i = 0; i < 8; i++)
    strcat(big, i ? ", {\"name\": \"\", \"res\": [0, 0]}" : "{\"name\": \"\", \"res\": [0, 0]}");
  strcat(big, "]}");
  int st = cv_cave_parse(big, "big.json", &c, &err);
  assert_true(st < 0);
  assert_null(strchr(err.msg, '\n'));
  must_contain(err.msg, "problems]");
  printf("  (%zu chars) ...%s\n", strlen(err.msg), err.msg + strlen(err.msg) - 40);

  /* a missing file names it */
  st = cv_cave_load(CAVES "/nosuch.json", &c, &err);
  assert_int_equal(st, CV_ERR_IO);
  must_contain(err.msg, "nosuch.json");

  /* an eye behind a screen, checked at run time */
  assert_int_equal(cv_cave_load(CAVES "/cave5.json", &c, &err), CV_OK);
  const double out_front[3] = {0, 1.5, -1.6}, on_floor[3] = {0, 0, 0}, inside[3] = {1.4, 2.9, 1.4};
  assert_int_equal(cv_cave_check_eye(&c, out_front, &err), CV_ERR_RANGE);
  must_contain(err.msg, "\"front\"");
  assert_int_equal(cv_cave_check_eye(&c, on_floor, &err), CV_ERR_RANGE);
  must_contain(err.msg, "\"floor\"");
  assert_int_equal(cv_cave_check_eye(&c, inside, &err), CV_OK);
}

/* --- outputs ------------------------------------------------------------------ */

#define TWO_WALLS                                                                                   \
  "\"walls\": [{\"name\": \"front\", \"pa\": [-1.5,0,-1.5], \"pb\": [1.5,0,-1.5], \"pc\": [-1.5,3,-1.5], " \
  "\"res\": [64,64]}, {\"name\": \"left\", \"pa\": [-1.5,0,1.5], \"pb\": [-1.5,0,-1.5], "                 \
  "\"pc\": [-1.5,3,1.5], \"res\": [64,64]}]"

static void test_outputs_default_and_layout(void **state) {
  (void)state;
  cv_cave c;
  cv_err err = {0};
  assert_int_equal(cv_cave_load(CAVES "/cave5.json", &c, &err), CV_OK);
  /* no "outputs": one passive output per wall-eye, rank 1 + 2w + e */
  assert_int_equal(c.n_outputs, 10);
  assert_int_equal(c.outputs_given, 0);
  for (int w = 0; w < 5; w++)
    for (int e = 0; e < 2; e++) {
      assert_int_equal(cv_cave_walleye_rank(&c, w, e), 1 + 2 * w + e);
      const cv_rank_role r = cv_cave_rank_role(&c, 1 + 2 * w + e);
      assert_int_equal(r.role, CV_ROLE_RENDER);
      assert_int_equal(c.outputs[r.output].gpu, CV_GPU_AUTO);
    }
  assert_int_equal(cv_cave_rank_role(&c, 0).role, CV_ROLE_MASTER);
  assert_int_equal(cv_cave_rank_role(&c, 11).role, CV_ROLE_GATHER);
  assert_true(c.rate == 60);
  assert_true(c.screen_patches == 24);
  assert_near(c.screen_reflectance, 0.8, 1e-12);
  /* packed stereo: one rank, both eyes */
  const char *ok = "{" TWO_WALLS ", \"outputs\": ["
                   "{\"wall\": \"left\", \"eye\": \"both\", \"stereo\": \"side-by-side\", \"gpu\": 1, \"host\": \"n2\", \"display\": \":0.1\", \"fullscreen\": true},"
                   "{\"wall\": \"front\", \"eye\": \"right\", \"gpu\": \"software\", \"geometry\": [100, 0, 640, 480]},"
                   "{\"wall\": \"front\", \"eye\": \"left\", \"gpu\": \"auto\", \"geometry\": [740, 0, 640, 480]}],"
                   "\"rate\": 120, \"screens\": {\"reflectance\": 0.5, \"patches\": 16}}";
  int st = cv_cave_parse(ok, "ok.json", &c, &err);
  if (st) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(st, CV_OK);
  assert_int_equal(c.n_outputs, 3);
  assert_int_equal(cv_cave_walleye_rank(&c, 1, 0), 1);
  assert_int_equal(cv_cave_walleye_rank(&c, 1, 1), 1);
  assert_int_equal(cv_cave_walleye_rank(&c, 0, 1), 2);
  assert_int_equal(cv_cave_walleye_rank(&c, 0, 0), 3);
  assert_int_equal(c.outputs[0].eyes, 3);
  assert_int_equal(c.outputs[0].stereo, CV_STEREO_SIDE_BY_SIDE);
  assert_int_equal(c.outputs[0].gpu, 1);
  assert_int_equal(c.outputs[1].gpu, CV_GPU_SOFTWARE);
  assert_int_equal(c.outputs[2].geometry[0], 740);
  assert_true(c.rate == 120 && c.screen_patches == 16 && c.screen_reflectance == 0.5);
}

static void test_outputs_problems(void **state) {
  (void)state;
  cv_cave c;
  cv_err err = {0};
  char buf[4096];
  int n = 0;
  /* overlapping windows on one display, a display used by two hosts, a
   * missing GPU, a display of another host, a passive output without an
   * eye: every problem listed, counted */
  const char *bad = "{" TWO_WALLS ", \"outputs\": ["
                    "{\"wall\": \"front\", \"eye\": \"left\", \"gpu\": 0, \"host\": \"a\", \"display\": \"a:0\", \"geometry\": [0, 0, 100, 100]},"
                    "{\"wall\": \"front\", \"eye\": \"right\", \"host\": \"a\", \"display\": \"a:0\", \"geometry\": [50, 50, 100, 100]},"
                    "{\"wall\": \"left\", \"eye\": \"left\", \"gpu\": 0, \"host\": \"b\", \"display\": \"a:0\"},"
                    "{\"wall\": \"left\", \"stereo\": \"passive\", \"gpu\": 0}]}";
  FILE *f = fopen(CV_TEST_TMP_DIR "/bad_outputs.json", "w");
  assert_non_null(f);
  fputs(bad, f);
  fclose(f);
  int st = cv_cave_load_all(CV_TEST_TMP_DIR "/bad_outputs.json", &c, buf, sizeof buf, &n, &err);
  assert_int_not_equal(st, CV_OK);
  fprintf(stderr, "%s", buf);
  must_contain(buf, "outputs[1].gpu: missing");
  must_contain(buf, "outputs[1]: window overlaps outputs[0] on host \"a\" display \"a:0\"");
  must_contain(buf, "outputs[2].display: \"a:0\" is a display of host \"a\", but the output runs on \"b\"");
  must_contain(buf, "outputs[2]: display \"a:0\" is used by hosts");
  must_contain(buf, "outputs[3].eye: missing");
  must_contain(err.msg, "problems]");
  int lines = 0;
  for (const char *p = buf; *p; p++) lines += *p == '\n';
  assert_int_equal(lines, n);
  assert_true(n >= 5);
  /* a wall-eye shown twice, one not at all; fullscreen overlaps everything */
  const char *twice = "{" TWO_WALLS ", \"outputs\": ["
                      "{\"wall\": \"front\", \"eye\": \"both\", \"stereo\": \"top-bottom\", \"gpu\": 0, \"fullscreen\": true},"
                      "{\"wall\": \"front\", \"eye\": \"left\", \"gpu\": 0},"
                      "{\"wall\": \"left\", \"eye\": \"left\", \"gpu\": \"fast\"}]}";
  assert_int_not_equal(cv_cave_parse(twice, "twice.json", &c, &err), CV_OK);
  must_contain(err.msg, "wall \"front\" left eye is already shown by outputs[0]");
  must_contain(err.msg, "outputs[1]: window overlaps outputs[0]");
  must_contain(err.msg, "outputs[2].gpu: expected a hardware EGL device index");
  const char *uncovered = "{" TWO_WALLS ", \"outputs\": [{\"wall\": \"front\", \"eye\": \"both\", "
                          "\"stereo\": \"side-by-side\", \"gpu\": 0}, {\"wall\": \"left\", \"eye\": \"left\", \"gpu\": 0}]}";
  assert_int_not_equal(cv_cave_parse(uncovered, "u.json", &c, &err), CV_OK);
  must_contain(err.msg, "no output shows wall \"left\" right eye");
  const char *quad_eye = "{" TWO_WALLS ", \"outputs\": [{\"wall\": \"front\", \"eye\": \"left\", \"stereo\": \"quad\", \"gpu\": 0},"
                         "{\"wall\": \"nowhere\", \"eye\": \"left\", \"gpu\": 0}, {\"wall\": \"left\", \"stereo\": \"3d\", \"gpu\": 0}]}";
  assert_int_not_equal(cv_cave_parse(quad_eye, "q.json", &c, &err), CV_OK);
  must_contain(err.msg, "outputs[0].eye: a quad output shows both eyes");
  must_contain(err.msg, "outputs[1].wall: no wall named \"nowhere\"");
  must_contain(err.msg, "outputs[2].stereo: expected \"passive\", \"quad\"");
  const char *screens = "{" TWO_WALLS ", \"screens\": {\"reflectance\": 1.5, \"patch\": 3}, \"rate\": 0}";
  assert_int_not_equal(cv_cave_parse(screens, "s.json", &c, &err), CV_OK);
  must_contain(err.msg, "screens.reflectance: 1.5 is outside");
  must_contain(err.msg, "screens.patch: unknown field");
  must_contain(err.msg, "rate: 0 is outside");
}

/* --- Kooima ------------------------------------------------------------------ */

static const double PA[3] = {-1.5, 0, -1.5}, PB[3] = {1.5, 0, -1.5}, PC[3] = {-1.5, 3, -1.5};

static void test_corners_to_ndc(void **state) {
  (void)state;
  srand(5);
  double worst = 0, worst_f = 0;
  for (int i = 0; i < 100; i++) {
    double pe[3] = {urand(-1.45, 1.45), urand(0.05, 2.95), urand(-1.45, 1.45)};
    cv_offaxis o;
    assert_int_equal(cv_offaxis_compute(PA, PB, PC, pe, 0.05, 50, &o), CV_OK);
    double pd[3];
    for (int k = 0; k < 3; k++) pd[k] = PB[k] + PC[k] - PA[k];
    const double *corner[4] = {PA, PB, PC, pd};
    const double want[4][2] = {{-1, -1}, {1, -1}, {-1, 1}, {1, 1}};
    double mf[16];
    for (int k = 0; k < 16; k++) mf[k] = o.viewproj[k];
    for (int j = 0; j < 4; j++) {
      double ndc[3], ndcf[3];
      assert_true(cv_offaxis_project(o.viewproj_d, corner[j], ndc) > 0);
      cv_offaxis_project(mf, corner[j], ndcf);
      for (int a = 0; a < 2; a++) {
        worst = fmax(worst, fabs(ndc[a] - want[j][a]));
        worst_f = fmax(worst_f, fabs(ndcf[a] - want[j][a]));
      }
      assert_true(ndc[2] > -1 && ndc[2] < 1);
    }
  }
  printf("corners -> NDC, 100 random eyes: max error %.2g (double), %.2g (float matrices)\n", worst,
         worst_f);
  assert_true(worst < 1e-6);
  assert_true(worst_f < 1e-4);
}

static void test_symmetric_and_errors(void **state) {
  (void)state;
  const double pe[3] = {0, 1.5, 0.7};
  cv_offaxis o;
  assert_int_equal(cv_offaxis_compute(PA, PB, PC, pe, 0.1, 20, &o), CV_OK);
  assert_near(o.l, -o.r, 1e-12);
  assert_near(o.b, -o.t, 1e-12);
  assert_true(o.r > 0 && o.t > 0);
  /* l = -1.5 n / d with d = 2.2 */
  assert_near(o.r, 1.5 * 0.1 / 2.2, 1e-12);
  assert_near(o.vn[2], 1, 1e-15);
  assert_near(o.vr[0], 1, 1e-15);
  assert_near(o.vu[1], 1, 1e-15);
  /* on the normal, the view is the plain look-at: view matrix = translation */
  assert_near(o.view[14], -0.7, 1e-7);
  assert_near(o.view[13], -1.5, 1e-7);
  /* errors */
  const double on[3] = {0.3, 1.0, -1.5}, behind[3] = {0, 1.5, -2};
  assert_int_equal(cv_offaxis_compute(PA, PB, PC, on, 0.1, 20, &o), CV_ERR_INVALID);
  assert_int_equal(cv_offaxis_compute(PA, PB, PC, behind, 0.1, 20, &o), CV_ERR_INVALID);
  const double skew[3] = {-1.4, 3, -1.5};
  assert_int_equal(cv_offaxis_compute(PA, PB, skew, pe, 0.1, 20, &o), CV_ERR_INVALID);
  assert_int_equal(cv_offaxis_compute(PA, PA, PC, pe, 0.1, 20, &o), CV_ERR_INVALID);
  assert_int_equal(cv_offaxis_compute(PA, PB, PC, pe, 0.0, 20, &o), CV_ERR_INVALID);
  assert_int_equal(cv_offaxis_compute(PA, PB, PC, pe, 1.0, 0.5, &o), CV_ERR_INVALID);
  const double nan3[3] = {NAN, 0, 0};
  assert_int_equal(cv_offaxis_compute(PA, PB, PC, nan3, 0.1, 20, &o), CV_ERR_INVALID);
}

static void test_shared_edge(void **state) {
  (void)state;
  /* front and left walls of cave5 share the edge x = -1.5, z = -1.5: the
   * front wall's left border and the left wall's right border */
  const double LA[3] = {-1.5, 0, 1.5}, LB[3] = {-1.5, 0, -1.5}, LC[3] = {-1.5, 3, 1.5};
  srand(9);
  double worst = 0;
  for (int i = 0; i < 100; i++) {
    double pe[3] = {urand(-1.4, 1.4), urand(0.1, 2.9), urand(-1.4, 1.4)};
    cv_offaxis f, l;
    assert_int_equal(cv_offaxis_compute(PA, PB, PC, pe, 0.05, 50, &f), CV_OK);
    assert_int_equal(cv_offaxis_compute(LA, LB, LC, pe, 0.05, 50, &l), CV_OK);
    double p[3] = {-1.5, urand(0, 3), -1.5}, nf[3], nl[3];
    assert_true(cv_offaxis_project(f.viewproj_d, p, nf) > 0);
    assert_true(cv_offaxis_project(l.viewproj_d, p, nl) > 0);
    worst = fmax(worst, fmax(fabs(nf[0] + 1), fabs(nl[0] - 1)));
    /* same height fraction on both walls: y = (p.y / 3) * 2 - 1 */
    worst = fmax(worst, fmax(fabs(nf[1] - (p[1] / 1.5 - 1)), fabs(nl[1] - (p[1] / 1.5 - 1))));
  }
  printf("shared front/left edge: max NDC error %.2g\n", worst);
  assert_true(worst < 1e-6);
}

static void test_head_eyes(void **state) {
  (void)state;
  const double head[3] = {0, 1.2, 0}, g[3] = {0, 0, -1};
  double l[3], r[3];
  cv_head_eyes(head, g, 0.064, l, r);
  assert_near(l[0], -0.032, 1e-15);
  assert_near(r[0], 0.032, 1e-15);
  assert_near(l[1], 1.2, 1e-15);
  assert_near(r[2], 0, 1e-15);
  /* looking left (-X): the right eye is towards -Z... (gaze x up = (0,0,-1)) */
  const double gl[3] = {-2, 0, 0};
  cv_head_eyes(head, gl, 0.064, l, r);
  assert_near(r[2], -0.032, 1e-15);
  assert_near(l[2], 0.032, 1e-15);
  /* tilted gaze: still unit separation, horizontal */
  const double gt[3] = {0.3, -0.8, -1};
  cv_head_eyes(head, gt, 0.064, l, r);
  double d = sqrt(pow(r[0] - l[0], 2) + pow(r[1] - l[1], 2) + pow(r[2] - l[2], 2));
  assert_near(d, 0.064, 1e-12);
  assert_near(r[1], l[1], 1e-15);
  /* vertical gaze falls back to +X */
  const double gv[3] = {0, -1, 0};
  cv_head_eyes(head, gv, 0.064, l, r);
  assert_near(r[0], 0.032, 1e-15);
  assert_true(isfinite(l[0]));
}

/* --size N (cave render and cave run): the longer side N, the aspect kept. */
static void test_fit_res(void **state) {
  (void)state;
  cv_cave c;
  cv_cave_defaults(&c);
  c.n_walls = 3;
  c.walls[0].res[0] = 1920, c.walls[0].res[1] = 1080;
  c.walls[1].res[0] = 1050, c.walls[1].res[1] = 1400;
  c.walls[2].res[0] = 720, c.walls[2].res[1] = 720;
  cv_cave_fit_res(&c, 0); /* no --size: unchanged */
  assert_int_equal(c.walls[0].res[0], 1920);
  cv_cave_fit_res(&c, 480);
  assert_int_equal(c.walls[0].res[0], 480);
  assert_int_equal(c.walls[0].res[1], 270);
  assert_int_equal(c.walls[1].res[0], 360);
  assert_int_equal(c.walls[1].res[1], 480);
  assert_int_equal(c.walls[2].res[0], 480);
  assert_int_equal(c.walls[2].res[1], 480);
  cv_cave_fit_res(&c, 1); /* never 0 pixels */
  assert_int_equal(c.walls[0].res[1], 1);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_fit_res),
      cmocka_unit_test(test_load_shipped),     cmocka_unit_test(test_bad_configs),
      cmocka_unit_test(test_corners_to_ndc),   cmocka_unit_test(test_symmetric_and_errors),
      cmocka_unit_test(test_shared_edge),      cmocka_unit_test(test_head_eyes),
      cmocka_unit_test(test_outputs_default_and_layout), cmocka_unit_test(test_outputs_problems),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
