/* Model placement (mesh/place: units, up axis, transform) and the units and
 * up axis files declare (io/mesh_import), on assimp's own test models from
 * Debian's assimp-testmodels (installed by cluster/setup.sh): regr01.obj is
 * a house in centimetres with Z up, box.fbx carries UnitScaleFactor 100, a
 * glTF is metres and Y up by specification.  Also the scene config keys
 * mesh.units / mesh.up / mesh.transform and their errors, and material
 * overrides by glob pattern on the IFC house with nine materials "Glas". */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "io/mesh_import.h"
#include "io/scene_config.h"
#include "mesh/place.h"

#define MODELS "/usr/share/assimp/models"

static const char *need_model(const char *rel) {
  static char p[512];
  snprintf(p, sizeof p, "%s/%s", MODELS, rel);
  /* assimp-testmodels is part of the test set-up (cluster/setup.sh): a
   * missing model is a broken set-up, not a skip */
  if (access(p, R_OK) != 0) fail_msg("%s missing: install Debian assimp-testmodels", p);
  return p;
}

static void test_parse_units(void **state) {
  (void)state;
  cv_err e;
  double u = 0;
  assert_int_equal(cv_parse_units("mm", &u, &e), CV_OK);
  assert_true(u == 0.001);
  assert_int_equal(cv_parse_units("cm", &u, &e), CV_OK);
  assert_true(u == 0.01);
  assert_int_equal(cv_parse_units("m", &u, &e), CV_OK);
  assert_true(u == 1.0);
  assert_int_equal(cv_parse_units("in", &u, &e), CV_OK);
  assert_true(u == 0.0254);
  assert_int_equal(cv_parse_units("ft", &u, &e), CV_OK);
  assert_true(u == 0.3048);
  assert_int_equal(cv_parse_units("0.5", &u, &e), CV_OK);
  assert_true(u == 0.5);
  const char *bad[] = {"furlong", "-1", "0", "nan", "inf", "", "1cm", "CM"};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    assert_int_equal(cv_parse_units(bad[i], &u, &e), CV_ERR_INVALID);
    assert_non_null(strstr(e.msg, "expected mm, cm, m, in, ft"));
  }
  char up = 0;
  assert_int_equal(cv_parse_up("Z", &up, &e), CV_OK);
  assert_int_equal(up, 'z');
  assert_int_equal(cv_parse_up("x", &up, &e), CV_ERR_INVALID);
}

/* One vertex through every stage: units, Z up, scale, rotation, translation. */
static void test_transform_order(void **state) {
  (void)state;
  cv_mesh *m;
  assert_int_equal(cv_mesh_create(&m), CV_OK);
  cv_mesh_add_vertex(m, 100, 200, 300, NULL); /* cm, Z up */
  cv_placement p;
  cv_placement_default(&p);
  p.unit_m = 0.01;
  p.up = 'z';
  p.scale = 2;
  p.rotate_deg[1] = 90; /* about +Y: (x, y, z) -> (z, y, -x) */
  p.translate[0] = 10;
  cv_err e;
  cv_placement_report r;
  assert_int_equal(cv_mesh_place(m, &p, NULL, &r, &e), CV_OK);
  /* cm: (1, 2, 3); Z up: (1, 3, -2); x2: (2, 6, -4); Ry 90: (-4, 6, -2); +T */
  assert_float_equal(m->pos[0], 6.0, 1e-5);
  assert_float_equal(m->pos[1], 6.0, 1e-5);
  assert_float_equal(m->pos[2], -2.0, 1e-5);
  assert_string_equal(r.unit_from, "option");
  assert_string_equal(r.up_from, "option");
  p.scale = 0;
  assert_int_equal(cv_mesh_place(m, &p, NULL, &r, &e), CV_ERR_INVALID);
  cv_mesh_destroy(m);
}

/* The case: regr01.obj (cm, Z up) was a 1.6 km house on its side. */
static void test_obj_cm_zup(void **state) {
  (void)state;
  const char *path = need_model("OBJ/regr01.obj");
  cv_mesh *m;
  cv_import_stats s;
  cv_err e;
  assert_int_equal(cv_mesh_import_ex(path, NULL, &m, &s, &e), CV_OK);
  assert_true(s.frame.unit_m == 0 && s.frame.up == 0); /* OBJ says nothing */
  cv_placement p;
  cv_placement_default(&p);
  cv_placement_report r;
  cv_mesh *raw;
  assert_int_equal(cv_mesh_clone(m, &raw), CV_OK);
  assert_int_equal(cv_mesh_place(raw, &p, &s.frame, &r, &e), CV_OK);
  assert_string_equal(r.unit_from, "default");
  assert_true(r.implausible_car); /* 1636 "m" */
  assert_float_equal(r.size[0], 1636.285, 0.01);
  cv_mesh_destroy(raw);

  p.unit_m = 0.01;
  p.up = 'z';
  assert_int_equal(cv_mesh_place(m, &p, &s.frame, &r, &e), CV_OK);
  /* raw x -194.20..1442.09, y -204.51..967.62, z 0..337.51 (cm) */
  assert_float_equal(r.lo[0], -1.942, 1e-3);
  assert_float_equal(r.hi[0], 14.421, 1e-3);
  assert_float_equal(r.lo[1], 0.0, 1e-4); /* stands on the ground */
  assert_float_equal(r.hi[1], 3.375, 1e-3); /* 3.4 m tall */
  assert_float_equal(r.lo[2], -9.676, 1e-3);
  assert_float_equal(r.hi[2], 2.045, 1e-3);
  assert_false(r.implausible_car); /* 16.4 m: under 20 */
  cv_mesh_destroy(m);
}

static void test_file_frames(void **state) {
  (void)state;
  cv_mesh *m;
  cv_import_stats s;
  cv_err e;
  cv_placement p;
  cv_placement_default(&p);
  cv_placement_report r;
  /* FBX with UnitScaleFactor 100 (cm per unit): 1 unit = 1 m, Y up */
  assert_int_equal(cv_mesh_import_ex(need_model("FBX/box.fbx"), NULL, &m, &s, &e), CV_OK);
  assert_float_equal(s.frame.unit_m, 1.0, 1e-12);
  assert_int_equal(s.frame.up, 'y');
  assert_int_equal(cv_mesh_place(m, &p, &s.frame, &r, &e), CV_OK);
  assert_string_equal(r.unit_from, "file");
  cv_mesh_destroy(m);
  /* glTF 2: metres, Y up by specification */
  assert_int_equal(cv_mesh_import_ex(need_model("glTF2/BoxTextured-glTF/BoxTextured.gltf"), NULL,
                                     &m, &s, &e), CV_OK);
  assert_true(s.frame.unit_m == 1.0 && s.frame.up == 'y');
  assert_non_null(strstr(s.frame.source, "glTF"));
  /* an option wins over the file */
  p.unit_m = 0.001;
  assert_int_equal(cv_mesh_place(m, &p, &s.frame, &r, &e), CV_OK);
  assert_string_equal(r.unit_from, "option");
  assert_true(r.implausible_car); /* a 1 mm box */
  cv_mesh_destroy(m);
  /* COLLADA: assimp applies <unit meter="0.01"> and Z_UP itself */
  assert_int_equal(cv_mesh_import_ex(need_model("Collada/regr01.dae"), NULL, &m, &s, &e), CV_OK);
  assert_true(s.frame.unit_m == 1.0 && s.frame.up == 'y');
  cv_mesh_destroy(m);
}

static const char *write_cfg(const char *name, const char *text) {
  static char p[1024];
  snprintf(p, sizeof p, "%s/%s", CV_TEST_TMP_DIR, name);
  FILE *f = fopen(p, "w");
  assert_non_null(f);
  fputs(text, f);
  fclose(f);
  return p;
}

static void test_scene_config_keys(void **state) {
  (void)state;
  cv_scene_config c;
  cv_err e;
  const char *p = write_cfg("place_ok.json",
                            "{\"mesh\": {\"path\": \"" MODELS "/OBJ/regr01.obj\", \"units\": \"cm\","
                            " \"up\": \"z\", \"transform\": {\"translate\": [1, 2, 3],"
                            " \"rotate_deg\": [0, 90, 0], \"scale\": 0.5}}}");
  assert_int_equal(cv_scene_config_load(p, &c, &e), CV_OK);
  assert_true(c.place.unit_m == 0.01 && c.place.up == 'z' && c.place.scale == 0.5);
  assert_true(c.place.translate[2] == 3 && c.place.rotate_deg[1] == 90);
  cv_scene_config_free(&c);
  p = write_cfg("place_num.json", "{\"mesh\": {\"path\": \"a.obj\", \"units\": 0.0254}}");
  assert_int_equal(cv_scene_config_load(p, &c, &e), CV_OK);
  assert_true(c.place.unit_m == 0.0254 && c.place.up == 0);
  cv_scene_config_free(&c);
  static const struct {
    const char *json, *field, *word;
  } bad[] = {
      {"{\"mesh\": {\"path\": \"a.obj\", \"units\": \"furlong\"}}", "mesh.units", "furlong"},
      {"{\"mesh\": {\"path\": \"a.obj\", \"units\": -2}}", "mesh.units", "expected"},
      {"{\"mesh\": {\"path\": \"a.obj\", \"up\": \"x\"}}", "mesh.up", "'x'"},
      {"{\"mesh\": {\"path\": \"a.obj\", \"transform\": {\"rotate\": [0,0,0]}}}",
       "mesh.transform.rotate", "unknown"},
      {"{\"mesh\": {\"path\": \"a.obj\", \"transform\": {\"scale\": 0}}}", "mesh.transform.scale",
       "outside"},
      {"{\"mesh\": {\"source\": \"cabin\", \"units\": \"cm\"}}", "mesh.units", "only for a mesh"},
  };
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    p = write_cfg("place_bad.json", bad[i].json);
    assert_int_equal(cv_scene_config_load(p, &c, &e), CV_ERR_CONFIG);
    if (!strstr(e.msg, bad[i].field) || !strstr(e.msg, bad[i].word) || strchr(e.msg, '\n'))
      fail_msg("case %zu: '%s'", i, e.msg);
  }
}

/* The case: an IFC house with nine materials named "Glas" got the
 * window tag on the first one only. */
static void test_glob_overrides(void **state) {
  (void)state;
  cv_mesh *m;
  cv_err e;
  assert_int_equal(cv_mesh_import(need_model("IFC/AC14-FZK-Haus.ifc"), NULL, &m, &e), CV_OK);
  size_t glas = 0, glas_tris = 0, kiefer = 0;
  for (size_t k = 0; k < m->nm; k++) {
    glas += !strcmp(m->mats[k].name, "Glas");
    kiefer += !strncmp(m->mats[k].name, "Kiefer", 6);
  }
  for (size_t t = 0; t < m->nt; t++) glas_tris += !strcmp(m->mats[m->tri_mat[t]].name, "Glas");
  assert_int_equal(glas, 9);
  cv_scene_config c;
  cv_scene_config_default(&c);
  snprintf(c.source, sizeof c.source, "haus.json");
  cv_scene_material ov[3] = {{.name = "Glas", .has_tag = 1, .flags = CV_MAT_WINDOW},
                             {.name = "*iefer*", .has_albedo = 1, .albedo = {0.1f, 0.2f, 0.3f}},
                             {.name = "Kiefer", .has_albedo = 1, .albedo = {0.9f, 0.9f, 0.9f}}};
  c.overrides = ov;
  c.n_overrides = 3;
  cv_override_count n[3];
  assert_int_equal(cv_scene_apply_overrides_ex(&c, m, n, &e), CV_OK);
  assert_int_equal(n[0].materials, 9);
  assert_int_equal(n[0].triangles, glas_tris);
  assert_int_equal(n[1].materials, kiefer);
  for (size_t k = 0; k < m->nm; k++) {
    const cv_material *mt = &m->mats[k];
    assert_int_equal(mt->flags == CV_MAT_WINDOW, !strcmp(mt->name, "Glas"));
    if (!strcmp(mt->name, "Kiefer")) assert_true(mt->albedo[0] == 0.9f); /* later entry wins */
    if (!strcmp(mt->name, "Kiefer,glänzend")) assert_true(mt->albedo[0] == 0.1f);
  }
  /* a pattern with no match: an error naming it, and nothing changed */
  cv_scene_material none[2] = {{.name = "Anstrich", .has_tag = 1, .flags = CV_MAT_LCD},
                               {.name = "*window*", .has_tag = 1, .flags = CV_MAT_WINDOW}};
  c.overrides = none;
  c.n_overrides = 2;
  assert_int_equal(cv_scene_apply_overrides(&c, m, &e), CV_ERR_CONFIG);
  assert_non_null(strstr(e.msg, "materials[1].name: pattern '*window*' matches none"));
  for (size_t k = 0; k < m->nm; k++) assert_false(m->mats[k].flags & CV_MAT_LCD);
  cv_mesh_destroy(m);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_parse_units),  cmocka_unit_test(test_transform_order),
      cmocka_unit_test(test_obj_cm_zup),   cmocka_unit_test(test_file_frames),
      cmocka_unit_test(test_scene_config_keys), cmocka_unit_test(test_glob_overrides),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
