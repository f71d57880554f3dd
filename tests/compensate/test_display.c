/* Unit tests of the display description (src/compensate/display.h): the
 * shipped configs load and face their viewer, patch numbering and geometry
 * of planes, cylinders and domes, the lobe normalisation, and every kind of
 * bad input gives an error naming the file and the field. */
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

#include "compensate/display.h"
#include "core/status.h"
#include "view/cave.h"

#define PI 3.14159265358979323846

/* configs/displays of the source tree (CV_SOURCE_DIR comes from CMake). */
#define CONFIG_DIR CV_SOURCE_DIR "/configs/displays"

static cv_display *load(const char *name) {
  char path[2048];
  snprintf(path, sizeof path, "%s/%s", CONFIG_DIR, name);
  cv_display *d = NULL;
  cv_err err = {0};
  int st = cv_display_load(path, &d, &err);
  if (st) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(st, CV_OK);
  return d;
}

static double dot3(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* cos of the angle between the patch normal and the direction to t */
static double facing(const cv_patch *p, const double t[3]) {
  double w[3] = {t[0] - p->c[0], t[1] - p->c[1], t[2] - p->c[2]};
  return dot3(p->n, w) / sqrt(dot3(w, w));
}

/* The 5-wall CAVE's display comes from its CAVE config (one description of
 * the CAVE for rendering and compensation): the walls with the config's
 * screen reflectance, 32 patches per side asked for here. */
static void test_cave5(void **state) {
  (void)state;
  cv_cave cave;
  cv_err err = {0};
  int st = cv_cave_load(CV_SOURCE_DIR "/configs/caves/cave5.json", &cave, &err);
  if (st) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(st, CV_OK);
  cv_display *d = NULL;
  st = cv_display_from_cave(&cave, 32, -1, &d, &err);
  if (st) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(st, CV_OK);
  assert_int_equal(cv_display_surface_count(d), 5);
  assert_int_equal(cv_display_patch_count(d), 5 * 32 * 32);
  const double centre[3] = {0, 1.5, 0};
  double area[5] = {0};
  for (size_t i = 0; i < d->n_patches; i++) {
    const cv_patch *p = cv_display_patch(d, i);
    /* every normal points into the cube, along a wall axis */
    assert_true(facing(p, centre) > 0);
    double m = fmax(fabs(p->n[0]), fmax(fabs(p->n[1]), fabs(p->n[2])));
    assert_near(m, 1, 1e-12);
    area[p->surface] += p->area;
    assert_near(d->refl[3 * i], 0.8f, 1e-7);
    assert_true(d->proj[i] == 1.0f);
    assert_true(d->env[3 * i] == 0);
  }
  for (int k = 0; k < 5; k++) assert_near(area[k], 9.0, 1e-9);
  /* numbering: index = offset + v * nu + u, v = 0 at the bottom */
  int front = cv_display_find_surface(d, "front");
  assert_int_equal(front, 0);
  assert_int_equal(cv_display_find_surface(d, "nope"), -1);
  const cv_display_surface *s = cv_display_surface_at(d, 1);
  size_t i = cv_display_patch_index(d, 1, 5, 7);
  assert_int_equal(i, s->offset + 7 * 32 + 5);
  assert_int_equal(d->patches[i].u, 5);
  assert_int_equal(d->patches[i].v, 7);
  const cv_patch *p00 = cv_display_patch(d, cv_display_patch_index(d, 0, 0, 0));
  assert_true(p00->q[0][0] == -1.5 && p00->q[0][1] == 0 && p00->q[0][2] == -1.5);
  assert_true(cv_display_patch(d, cv_display_patch_index(d, 0, 0, 31))->c[1] > 2.9);
  /* u runs to the right as seen from inside: front patch u = 31 at +X */
  assert_true(cv_display_patch(d, cv_display_patch_index(d, 0, 31, 0))->c[0] > 1.4);
  cv_display_destroy(d);
}

static void test_two_sided_wall(void **state) {
  (void)state;
  cv_display *d = load("two-sided-wall.json");
  assert_int_equal(d->n_patches, 2 * 64 * 64);
  const cv_patch *a = &d->patches[0], *b = &d->patches[d->n_patches - 1];
  printf("  two-sided wall: normals (%.3f %.3f %.3f) and (%.3f %.3f %.3f), reflectance %.3f\n",
         a->n[0], a->n[1], a->n[2], b->n[0], b->n[1], b->n[2], d->surfaces[0].reflectance[0]);
  assert_near(dot3(a->n, b->n), 0, 1e-12); /* 90 degrees */
  assert_true(d->has_viewer);
  for (size_t i = 0; i < d->n_patches; i++) assert_true(facing(&d->patches[i], d->viewer) > 0);
  /* the two walls meet: left's lower-right corner = right's lower-left */
  for (int k = 0; k < 3; k++) assert_true(d->surfaces[0].pb[k] == d->surfaces[1].pa[k]);
  /* the walls face each other: inside the L */
  double area = 0;
  for (size_t i = 0; i < d->n_patches; i++) area += d->patches[i].area;
  assert_near(area, 12.0, 1e-9);
  cv_display_destroy(d);
}

static void test_cylinder(void **state) {
  (void)state;
  cv_display *d = load("cylinder.json");
  const cv_display_surface *s = &d->surfaces[0];
  assert_int_equal(s->kind, CV_SURFACE_CYLINDER);
  double area = 0;
  for (size_t i = 0; i < d->n_patches; i++) {
    const cv_patch *p = &d->patches[i];
    const double axis[3] = {s->center[0], p->c[1], s->center[2]};
    assert_true(facing(p, axis) > 1 - 1e-12); /* horizontal, towards the axis */
    area += p->area;
  }
  /* chords: slightly less than the true area pi r h (2 pi r h / 2) */
  double exact = PI * s->radius * (s->range_v[1] - s->range_v[0]);
  printf("  cylinder: %zu patches, chord area %.5f m^2 of %.5f\n", d->n_patches, area, exact);
  assert_true(area < exact && area > exact * (1 - 1e-3));
  /* angle 0 is straight ahead (-Z), +90 deg is +X */
  const cv_patch *mid = &d->patches[cv_display_patch_index(d, 0, s->nu / 2, 0)];
  assert_true(mid->q[0][2] < -1.99);
  assert_near(mid->q[0][0], 0, 1e-9);
  assert_true(d->patches[cv_display_patch_index(d, 0, s->nu - 1, 0)].c[0] > 1.9);
  assert_true(d->patches[cv_display_patch_index(d, 0, 0, s->nv - 1)].c[1] > 2.3);
  cv_display_destroy(d);
}

static void test_dome(void **state) {
  (void)state;
  cv_display *d = load("dome.json");
  const cv_display_surface *s = &d->surfaces[0];
  assert_int_equal(s->kind, CV_SURFACE_DOME);
  double area = 0, fmin_ = INFINITY, fmax_ = 0;
  for (size_t i = 0; i < d->n_patches; i++) {
    const cv_patch *p = &d->patches[i];
    assert_true(facing(p, s->center) > 0.99);
    /* the four corners are coplanar (isosceles trapezoid) */
    for (int k = 0; k < 4; k++) {
      double w[3] = {p->q[k][0] - p->c[0], p->q[k][1] - p->c[1], p->q[k][2] - p->c[2]};
      assert_near(dot3(w, p->n), 0, 1e-12);
    }
    area += p->area;
    fmin_ = fmin(fmin_, d->proj[i]);
    fmax_ = fmax(fmax_, d->proj[i]);
  }
  double exact = s->radius * s->radius * (sin(s->range_v[1]) - sin(s->range_v[0])) *
                 (s->range_u[1] - s->range_u[0]);
  printf("  dome: %zu patches, area %.4f m^2 of %.4f; projector factors in [%.3f, %.3f]\n",
         d->n_patches, area, exact, fmin_, fmax_);
  assert_true(area < exact && area > 0.99 * exact);
  assert_near(fmax_, 1, 1e-6);
  assert_true(fmin_ > 0);
  cv_display_destroy(d);
}

static void test_lobe_norm(void **state) {
  (void)state;
  const char *fmt =
      "{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], "
      "\"patches\": [2,2], \"reflectance\": [1,1,1], \"cosine_exponent\": %g, "
      "\"normal_tilt_deg\": %g}]}";
  const double cases[][2] = {{1, 0}, {3, 0}, {1, 30}, {1, 60}, {2, 40}};
  for (size_t k = 0; k < 5; k++) {
    char js[512];
    snprintf(js, sizeof js, fmt, cases[k][0], cases[k][1]);
    cv_display *d = NULL;
    cv_err err;
    assert_int_equal(cv_display_parse(js, "lobe.json", &d, &err), CV_OK);
    double c = cases[k][0], t = cases[k][1] * PI / 180, got = d->surfaces[0].lobe_norm;
    double ref;
    if (t == 0)
      ref = (c + 1) / (2 * PI);
    else if (c == 1)
      ref = 2 / (PI * (1 + cos(t))); /* the cosine lobe cut by the surface plane */
    else
      ref = -1;
    printf("  lobe_norm c=%g tilt=%g: %.8f (reference %.8f)\n", c, cases[k][1], got, ref);
    if (ref > 0) assert_near(got / ref, 1, 1e-5);
    /* tilt rotates the emission axis towards +v (up here) */
    const cv_patch *p = &d->patches[0];
    assert_near(p->nt[1], sin(t), 1e-12);
    assert_near(p->nt[2], cos(t), 1e-12);
    cv_display_destroy(d);
  }
}

/* --- bad input ----------------------------------------------------------------- */

static const char *GOOD_WALL =
    "{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": [4,4], "
    "\"reflectance\": [0.5,0.5,0.5]}";

typedef struct bad_case {
  const char *json;
  const char *expect; /* substring of the error */
} bad_case;

static void check_bad(const char *json, const char *expect) {
  cv_display *d = (cv_display *)1;
  cv_err err = {0};
  int st = cv_display_parse(json, "cave.json", &d, &err);
  printf("  -> %s\n", err.msg);
  assert_true(st < 0);
  assert_null(d);
  if (!strstr(err.msg, expect)) {
    fprintf(stderr, "expected \"%s\" in \"%s\"\n", expect, err.msg);
    fail();
  }
  assert_true(strncmp(err.msg, "cave.json:", 10) == 0);
}

static void test_bad_input(void **state) {
  (void)state;
  char js[2048];
  const bad_case cases[] = {
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,0.5,0.5], \"colour\": 3}]}",
       "surfaces[0].colour: unknown field"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], "
       "\"reflectance\": [0.5,0.5,0.5]}]}",
       "surfaces[0].patches: missing"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,4], \"reflectance\": \"white\"}]}",
       "surfaces[0].reflectance: expected [r, g, b] in [0, 1]"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[0,4], \"reflectance\": [0.5,0.5,0.5]}]}",
       "surfaces[0].patches[0]: expected a positive integer"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,-2], \"reflectance\": [0.5,0.5,0.5]}]}",
       "surfaces[0].patches[1]: expected a positive integer"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,2.5], \"reflectance\": [0.5,0.5,0.5]}]}",
       "surfaces[0].patches[1]: expected a positive integer"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,4], \"reflectance\": [1.2,0.5,0.5]}]}",
       "surfaces[0].reflectance[0]: 1.2 is outside [0, 1]"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,-0.1,0.5]}]}",
       "surfaces[0].reflectance[1]: -0.1 is outside [0, 1]"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,1e999,0.5]}]}",
       "surfaces[0].reflectance[1]: expected a finite number"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,4],\n \"reflectance\": [0.5,NaN,0.5]}]}",
       "line 2, column 22: JSON syntax error near 'NaN,0.5]}]}' (NaN and Inf are not JSON numbers)"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,NaN,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,0.5,0.5]}]}",
       "line 1, column 60: JSON syntax error near 'NaN,0]], \"patch'"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,0.5,0.5]}, {\"name\": \"a\", \"corners\": "
       "[[0,0,0],[0,0,1],[0,1,0]], \"patches\": [4,4], \"reflectance\": [0.5,0.5,0.5]}]}",
       "surfaces[1].name: duplicate surface name 'a' (also surfaces[0])"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,0.5,0.5], \"cosine_exponent\": 0}]}",
       "surfaces[0].cosine_exponent: 0 is outside (0, 1000]"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,0.5,0.5], \"normal_tilt_deg\": 95}]}",
       "surfaces[0].normal_tilt_deg: 95 is outside (-90, 90)"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,0.5,0.5], \"cosine_exponent\": \"high\"}]}",
       "surfaces[0].cosine_exponent: expected a number"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,0.5,0.5]}]}",
       "surfaces[0].corners: expected [pa, pb, pc]"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[1,0,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,0.5,0.5]}]}",
       "not perpendicular (angle 0 deg)"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[0,0,0],[0,1,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,0.5,0.5]}]}",
       "surfaces[0].corners: pa->pb has zero length"},
      {"{\"surfaces\": [{\"name\": \"w\", \"type\": \"cylinder\", \"center\": [0,0,0], "
       "\"angle_deg\": [-90, 90], \"height\": [0, 2], \"patches\": [8,8], \"reflectance\": "
       "[0.5,0.5,0.5]}]}",
       "surfaces[0].radius: missing"},
      {"{\"surfaces\": [{\"name\": \"w\", \"type\": \"cylinder\", \"center\": [0,0,0], "
       "\"radius\": 2, \"angle_deg\": [90, -90], \"height\": [0, 2], \"patches\": [8,8], "
       "\"reflectance\": [0.5,0.5,0.5]}]}",
       "surfaces[0].angle_deg: expected the first value below the second"},
      {"{\"surfaces\": [{\"name\": \"w\", \"type\": \"cylinder\", \"center\": [0,0,0], "
       "\"radius\": 2, \"angle_deg\": [-90, 90], \"height\": [0, 2], \"patches\": [8,8], "
       "\"reflectance\": [0.5,0.5,0.5], \"corners\": []}]}",
       "surfaces[0].corners: unknown field"},
      {"{\"surfaces\": [{\"name\": \"d\", \"type\": \"dome\", \"center\": [0,0,0], "
       "\"radius\": 3, \"elevation_deg\": [0, 95], \"azimuth_deg\": [-90, 90], \"patches\": "
       "[8,8], \"reflectance\": [0.5,0.5,0.5]}]}",
       "surfaces[0].elevation_deg[1]: 95 is outside [-90, 90]"},
      {"{\"surfaces\": [{\"name\": \"d\", \"type\": \"torus\", \"patches\": [8,8], "
       "\"reflectance\": [0.5,0.5,0.5]}]}",
       "surfaces[0].type: expected \"plane\", \"cylinder\" or \"dome\""},
      {"{\"surfaces\": []}", "surfaces: expected a non-empty array"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,0.5,0.5]}], \"environment\": [-1, 0, 0]}",
       "environment[0]: -1 is outside [0, 1e+06]"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,0.5,0.5]}], \"projectors\": \"real\"}",
       "projectors: expected \"ideal\""},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,0.5,0.5]}], \"projectors\": [{\"position\": [0,0,2], "
       "\"surfaces\": [\"b\"]}]}",
       "projectors[0].surfaces[0]: no surface is named 'b'"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,0.5,0.5]}, {\"name\": \"b\", \"corners\": "
       "[[0,0,1],[0,0,0],[0,1,1]], \"patches\": [2,2], \"reflectance\": [0.5,0.5,0.5]}], "
       "\"projectors\": [{\"position\": [0.5,0.5,2], \"surfaces\": [\"a\"]}]}",
       "projectors: 4 of 4 patches of surface 'b' (surfaces[1]) receive no projector light"},
      {"{\"surfaces\": [{\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0,1,0]], \"patches\": "
       "[4,4], \"reflectance\": [0.5,0.5,0.5]}], \"viewer\": [0.5, 0.5, -2]}",
       "surfaces[0].corners: 16 of 16 patches face away from the viewer"},
      {"[1, 2]", "expected a JSON object at the top level"},
      {"{\"surface\": []}", "surface: unknown field"},
  };
  for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) check_bad(cases[k].json, cases[k].expect);

  /* the example: a skewed wall as the third surface */
  double a = 87.3 * PI / 180;
  snprintf(js, sizeof js,
           "{\"surfaces\": [%s, {\"name\": \"b\", \"corners\": [[0,0,0],[0,0,1],[0,1,0]], "
           "\"patches\": [2,2], \"reflectance\": [0.5,0.5,0.5]}, {\"name\": \"c\", \"corners\": "
           "[[0,0,0],[1,0,0],[%.17g,%.17g,0]], \"patches\": [2,2], \"reflectance\": "
           "[0.5,0.5,0.5]}]}",
           GOOD_WALL, cos(a), sin(a));
  check_bad(js, "cave.json: surfaces[2].corners: pa->pb and pa->pc are not perpendicular "
                "(angle 87.3 deg)");
}

/* Every problem is collected: the load reports the first and the count,
 * validate_all lists all of them. */
static void test_validate_all(void **state) {
  (void)state;
  const char *js =
      "{\"surfaces\": [\n"
      " {\"name\": \"a\", \"corners\": [[0,0,0],[1,0,0],[0.2,1,0]], \"patches\": [0,4], "
      "\"reflectance\": [1.5,0.5,0.5]},\n"
      " {\"name\": \"a\", \"corners\": [[0,0,0],[0,0,1],[0,1,0]], \"patches\": [2,2], "
      "\"reflectance\": [0.5,0.5,0.5], \"gloss\": 1}],\n"
      " \"environment\": [0, 0, -3]\n}";
  char path[2048];
  snprintf(path, sizeof path, "%s/bad_display.json", CV_TEST_TMP_DIR);
  FILE *f = fopen(path, "w");
  assert_non_null(f);
  fputs(js, f);
  fclose(f);
  char buf[4096];
  int count = 0;
  int st = cv_display_validate_all(path, buf, sizeof buf, &count);
  printf("%s", buf);
  assert_int_equal(st < 0, 1);
  assert_int_equal(count, 6);
  const char *want[] = {"surfaces[0].patches[0]", "surfaces[0].reflectance[0]",
                        "surfaces[0].corners: pa->pb and pa->pc are not perpendicular",
                        "surfaces[1].gloss: unknown field", "surfaces[1].name: duplicate",
                        "environment[2]"};
  for (int k = 0; k < 6; k++) assert_non_null(strstr(buf, want[k]));
  int lines = 0;
  for (const char *p = buf; *p; p++) lines += *p == '\n';
  assert_int_equal(lines, 6);
  assert_non_null(strstr(buf, path));

  cv_display *d = NULL;
  cv_err err;
  st = cv_display_load(path, &d, &err);
  printf("  load: %s\n", err.msg);
  assert_int_equal(st, CV_ERR_RANGE);
  assert_null(d);
  assert_non_null(strstr(err.msg, "[+5 more problems]"));

  /* small buffer: truncated, still terminated */
  char small[40];
  cv_display_validate_all(path, small, sizeof small, &count);
  assert_true(strlen(small) < sizeof small);

  /* a valid file: no problems */
  snprintf(path, sizeof path, "%s/two-sided-wall.json", CONFIG_DIR);
  assert_int_equal(cv_display_validate_all(path, buf, sizeof buf, &count), CV_OK);
  assert_int_equal(count, 0);
  assert_string_equal(buf, "");

  /* missing file */
  st = cv_display_load("/nonexistent/display.json", &d, &err);
  assert_int_equal(st, CV_ERR_IO);
  assert_non_null(strstr(err.msg, "/nonexistent/display.json: cannot open"));
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_cave5),       cmocka_unit_test(test_two_sided_wall),
      cmocka_unit_test(test_cylinder),    cmocka_unit_test(test_dome),
      cmocka_unit_test(test_lobe_norm),   cmocka_unit_test(test_bad_input),
      cmocka_unit_test(test_validate_all),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
