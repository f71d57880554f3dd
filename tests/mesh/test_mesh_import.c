/* Mesh import tests (io/mesh_import through assimp): OBJ + MTL materials
 * (albedo from Kd, window/lcd tags, clamping, overrides), PLY, glTF with an
 * embedded base64 buffer and a node translation, GLB, and the errors:
 * malformed OBJ (bad index, garbage number, NaN), nonexistent file, points
 * and lines only, broken glTF.  Files are written as text into
 * CV_TEST_TMP_DIR by the tests themselves. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>
#include "cv_test_near.h"

#include "io/mesh_import.h"
#include "io/png.h"
#include "mesh_check.h"

static const char *tmp_path(const char *name) {
  static char buf[8][1024];
  static int k = 0;
  k = (k + 1) % 8;
  snprintf(buf[k], sizeof buf[k], "%s/%s", CV_TEST_TMP_DIR, name);
  return buf[k];
}

static const char *write_file(const char *name, const void *data, size_t n) {
  const char *p = tmp_path(name);
  FILE *f = fopen(p, "wb");
  assert_non_null(f);
  assert_int_equal(fwrite(data, 1, n, f), n);
  fclose(f);
  return p;
}
static const char *write_text(const char *name, const char *text) {
  return write_file(name, text, strlen(text));
}

static const cv_material *mat_named(const cv_mesh *m, const char *name) {
  int k = cv_mesh_find_material(m, name);
  assert_true(k >= 0);
  return &m->mats[k];
}

static size_t tris_with(const cv_mesh *m, const char *name) {
  int k = cv_mesh_find_material(m, name);
  size_t n = 0;
  for (size_t t = 0; t < m->nt; t++) n += (int)m->tri_mat[t] == k;
  return n;
}

static const char *k_mtl =
    "newmtl seat\nKd 0.4 0.35 0.3\n"
    "newmtl Window_Front\nKd 0.9 0.9 0.9\n"
    "newmtl LCD_main\nKd 0.02 0.03 0.04\n"
    "newmtl hot\nKd 1.5 0.5 -0.2\n"
    "newmtl unused\nKd 0.1 0.1 0.1\n";
static const char *k_obj =
    "# test scene\nmtllib mi_test.mtl\n"
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\n"
    "usemtl seat\nf 1 2 3 4\n"
    "usemtl Window_Front\nf 1 2 5\n"
    "usemtl LCD_main\nf 2/1 3/1 5/1\n"
    "usemtl hot\nf -3 -2 -1\n"
    "vt 0.5 0.5\n";

static void test_obj_mtl(void **state) {
  (void)state;
  write_text("mi_test.mtl", k_mtl);
  const char *p = write_text("mi_test.obj", k_obj);
  cv_mesh *m = NULL;
  cv_import_stats s;
  cv_err err;
  int st = cv_mesh_import_ex(p, NULL, &m, &s, &err);
  if (st) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(st, CV_OK);
  assert_int_equal(m->nt, 5); /* quad -> 2 */
  assert_int_equal(m->nm, 4); /* "unused" and assimp's default are not kept */
  const cv_material *seat = mat_named(m, "seat"), *win = mat_named(m, "Window_Front"),
                    *lcd = mat_named(m, "LCD_main"), *hot = mat_named(m, "hot");
  assert_near(seat->albedo[0], 0.4f, 1e-6f);
  assert_near(seat->albedo[1], 0.35f, 1e-6f);
  assert_near(seat->albedo[2], 0.3f, 1e-6f);
  assert_int_equal(seat->flags, 0);
  assert_int_equal(win->flags, CV_MAT_WINDOW);
  assert_int_equal(lcd->flags, CV_MAT_LCD);
  assert_near(lcd->albedo[2], 0.04f, 1e-6f);
  assert_true(hot->albedo[0] == 1.0f);
  assert_near(hot->albedo[1], 0.5f, 1e-6f);
  assert_true(hot->albedo[2] == 0.0f);
  assert_int_equal(s.albedo_clamped, 2);
  assert_int_equal(tris_with(m, "seat"), 2);
  assert_int_equal(tris_with(m, "hot"), 1);
  /* the quad's two triangles cover the unit square */
  assert_near(mc_area_named(m, "seat"), 1.0, 1e-6);
  assert_int_equal(cv_mesh_validate(m, NULL), CV_OK);
  cv_mesh_destroy(m);

  /* overrides: exact names; an unknown name is reported unused */
  cv_material_override ov[2];
  memset(ov, 0, sizeof ov);
  strcpy(ov[0].name, "seat");
  ov[0].has_albedo = 1;
  ov[0].albedo[0] = ov[0].albedo[1] = ov[0].albedo[2] = 0.2f;
  ov[0].has_flags = 1;
  ov[0].flags = CV_MAT_LCD;
  strcpy(ov[1].name, "nonexistent");
  ov[1].has_flags = 1;
  cv_import_opts o;
  cv_import_opts_default(&o);
  o.overrides = ov;
  o.n_overrides = 2;
  o.scale = 2.0;
  assert_int_equal(cv_mesh_import_ex(p, &o, &m, &s, &err), CV_OK);
  seat = mat_named(m, "seat");
  assert_true(seat->albedo[0] == 0.2f && seat->flags == CV_MAT_LCD);
  assert_int_equal(mat_named(m, "Window_Front")->flags, CV_MAT_WINDOW);
  assert_int_equal(s.overrides_applied, 1);
  assert_int_equal(s.overrides_unused, 1);
  float lo[3], hi[3];
  cv_mesh_bounds(m, lo, hi);
  assert_true(hi[0] == 2.0f && hi[2] == 2.0f);
  cv_mesh_destroy(m);
}

static void test_points_lines_dropped(void **state) {
  (void)state;
  const char *p = write_text("mi_lines.obj",
                             "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nl 1 4\nl 2 4\n");
  cv_mesh *m = NULL;
  cv_import_stats s;
  cv_err err;
  assert_int_equal(cv_mesh_import_ex(p, NULL, &m, &s, &err), CV_OK);
  assert_int_equal(m->nt, 1);
  assert_int_equal(s.lines_dropped, 2);
  assert_int_equal(m->mats[0].albedo[0] >= 0 && m->mats[0].albedo[0] <= 1, 1);
  cv_mesh_destroy(m);

  p = write_text("mi_only_lines.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\nl 2 3\n");
  assert_int_equal(cv_mesh_import_ex(p, NULL, &m, &s, &err), CV_ERR_EMPTY);
  assert_null(m);
  assert_non_null(strstr(err.msg, p));
}

static void test_ply(void **state) {
  (void)state;
  const char *p = write_text("mi_test.ply",
                             "ply\nformat ascii 1.0\n"
                             "element vertex 5\nproperty float x\nproperty float y\n"
                             "property float z\n"
                             "element face 2\nproperty list uchar int vertex_indices\n"
                             "end_header\n"
                             "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0.5 1\n"
                             "4 0 1 2 3\n3 0 1 4\n");
  cv_mesh *m = NULL;
  cv_err err;
  int st = cv_mesh_import(p, NULL, &m, &err);
  if (st) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(st, CV_OK);
  assert_int_equal(m->nt, 3);
  double area = 0;
  for (size_t t = 0; t < m->nt; t++) area += mc_tri_area(m, t);
  /* unit square + triangle (0,0,0) (1,0,0) (0.5,0.5,1): 0.5 * |(1,0,0) x (0.5,0.5,1)| */
  double expect = 1.0 + 0.5 * sqrt(1.0 + 0.25);
  assert_near(area, expect, 1e-6);
  assert_int_equal(cv_mesh_validate(m, NULL), CV_OK);
  cv_mesh_destroy(m);
}

static void b64(const unsigned char *in, size_t n, char *out) {
  static const char *tab = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  size_t o = 0;
  for (size_t i = 0; i < n; i += 3) {
    uint32_t v = (uint32_t)in[i] << 16 | (i + 1 < n ? (uint32_t)in[i + 1] << 8 : 0) |
                 (i + 2 < n ? in[i + 2] : 0);
    out[o++] = tab[v >> 18 & 63];
    out[o++] = tab[v >> 12 & 63];
    out[o++] = i + 1 < n ? tab[v >> 6 & 63] : '=';
    out[o++] = i + 2 < n ? tab[v & 63] : '=';
  }
  out[o] = '\0';
}

/* 6 uint16 indices (12 bytes) then 4 float positions (48 bytes): a unit quad. */
static void gltf_buffer(unsigned char buf[60]) {
  const uint16_t idx[6] = {0, 1, 2, 0, 2, 3};
  const float pos[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  memcpy(buf, idx, 12); /* little-endian host assumed (x86/arm) */
  memcpy(buf + 12, pos, 48);
}

static const char *k_gltf_fmt =
    "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],"
    "\"nodes\":[{\"mesh\":0,\"translation\":[0,0,-2]}],"
    "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":1},\"indices\":0,"
    "\"material\":0}]}],"
    "\"materials\":[{\"name\":\"window_glass\",\"pbrMetallicRoughness\":"
    "{\"baseColorFactor\":[0.2,0.4,0.6,1.0]}}],"
    "\"buffers\":[{\"byteLength\":60%s}],"
    "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":12,\"target\":34963},"
    "{\"buffer\":0,\"byteOffset\":12,\"byteLength\":48,\"target\":34962}],"
    "\"accessors\":[{\"bufferView\":0,\"componentType\":5123,\"count\":6,\"type\":\"SCALAR\"},"
    "{\"bufferView\":1,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\","
    "\"min\":[0,0,0],\"max\":[1,1,0]}]}";

static void check_gltf_mesh(const cv_mesh *m) {
  assert_int_equal(m->nt, 2);
  assert_int_equal(m->nm, 1);
  assert_string_equal(m->mats[0].name, "window_glass");
  assert_int_equal(m->mats[0].flags, CV_MAT_WINDOW);
  assert_near(m->mats[0].albedo[0], 0.2f, 1e-6f);
  assert_near(m->mats[0].albedo[1], 0.4f, 1e-6f);
  assert_near(m->mats[0].albedo[2], 0.6f, 1e-6f);
  for (size_t v = 0; v < m->nv; v++) assert_true(m->pos[3 * v + 2] == -2.0f); /* node transform */
  assert_near(mc_area_flags(m, CV_MAT_WINDOW), 1.0, 1e-6);
}

static void test_gltf(void **state) {
  (void)state;
  unsigned char buf[60];
  gltf_buffer(buf);
  char enc[128], uri[256], json[4096];
  b64(buf, 60, enc);
  snprintf(uri, sizeof uri, ",\"uri\":\"data:application/octet-stream;base64,%s\"", enc);
  snprintf(json, sizeof json, k_gltf_fmt, uri);
  const char *p = write_text("mi_test.gltf", json);
  cv_mesh *m = NULL;
  cv_err err;
  int st = cv_mesh_import(p, NULL, &m, &err);
  if (st) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(st, CV_OK);
  check_gltf_mesh(m);
  cv_mesh_destroy(m);

  /* the same as GLB: header, JSON chunk (space-padded), BIN chunk */
  snprintf(json, sizeof json, k_gltf_fmt, "");
  size_t jl = strlen(json), jp = (jl + 3) & ~(size_t)3;
  size_t total = 12 + 8 + jp + 8 + 60;
  unsigned char *glb = calloc(1, total);
  uint32_t hdr[5] = {0x46546C67u, 2, (uint32_t)total, (uint32_t)jp, 0x4E4F534Au};
  memcpy(glb, hdr, 20);
  memset(glb + 20, ' ', jp);
  memcpy(glb + 20, json, jl);
  uint32_t bh[2] = {60, 0x004E4942u};
  memcpy(glb + 20 + jp, bh, 8);
  memcpy(glb + 28 + jp, buf, 60);
  p = write_file("mi_test.glb", glb, total);
  free(glb);
  st = cv_mesh_import(p, NULL, &m, &err);
  if (st) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(st, CV_OK);
  check_gltf_mesh(m);
  cv_mesh_destroy(m);
}


/* A textured material's albedo is its colour times the texture's mean linear
 * RGB (sRGB decoded); a missing texture is counted and the colour kept. */
static double lin(double v) { return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4); }
static void test_texture_mean(void **state) {
  (void)state;
  const uint8_t px[2 * 2 * 3] = {255, 0, 0, 0, 255, 0, 0, 0, 255, 128, 128, 128};
  cv_err err;
  assert_int_equal(cv_png_write(tmp_path("mi_tex.png"), 2, 2, 3, px, &err), CV_OK);
  write_text("mi_tex.mtl", "newmtl painted\nKd 0.5 0.8 1.0\nmap_Kd mi_tex.png\n"
                           "newmtl lost\nKd 0.3 0.3 0.3\nmap_Kd mi_no_such.png\n");
  const char *p = write_text("mi_tex.obj", "mtllib mi_tex.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\n"
                                           "v 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                                           "usemtl painted\nf 1/1 2/2 3/3\n"
                                           "usemtl lost\nf 1/1 3/3 4/4\n");
  cv_mesh *m = NULL;
  cv_import_stats s;
  int st = cv_mesh_import_ex(p, NULL, &m, &s, &err);
  if (st) fprintf(stderr, "%s\n", err.msg);
  assert_int_equal(st, CV_OK);
  assert_int_equal(s.textures_averaged, 1);
  assert_int_equal(s.textures_unread, 1);
  const double g = lin(128 / 255.0), mean = (1.0 + g) / 4.0; /* every channel */
  const double kd[3] = {0.5, 0.8, 1.0};
  const cv_material *a = mat_named(m, "painted");
  for (int k = 0; k < 3; k++) assert_near(a->albedo[k], kd[k] * mean, 1e-6);
  assert_true(mat_named(m, "lost")->albedo[0] == 0.3f);
  /* the texture path (found) and the corner UVs are kept */
  assert_non_null(m->mat_tex);
  assert_string_equal(m->mat_tex[cv_mesh_find_material(m, "painted")], tmp_path("mi_tex.png"));
  assert_string_equal(m->mat_tex[cv_mesh_find_material(m, "lost")], "");
  assert_non_null(m->tri_uv);
  for (size_t t = 0; t < m->nt; t++)
    for (int k = 0; k < 3; k++) {
      const float *q = m->pos + 3 * m->tri[3 * t + k]; /* vt = (x, y) here */
      assert_true(m->tri_uv[6 * t + 2 * k] == q[0] && m->tri_uv[6 * t + 2 * k + 1] == q[1]);
    }
  cv_mesh_destroy(m);
}

static void expect_error(const char *p, int status, const char *needle) {
  cv_mesh *m = (cv_mesh *)1;
  cv_err err;
  int st = cv_mesh_import(p, NULL, &m, &err);
  printf("  %s -> %d: %s\n", p, st, err.msg);
  assert_int_equal(st, status);
  assert_null(m);
  assert_non_null(strstr(err.msg, p));
  if (needle) assert_non_null(strstr(err.msg, needle));
  assert_null(strchr(err.msg, '\n'));
}

static void test_errors(void **state) {
  (void)state;
  expect_error(tmp_path("mi_does_not_exist.obj"), CV_ERR_IO, "cannot open");
  expect_error(write_text("mi_bad_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\n"),
               CV_ERR_FORMAT, ":4:");
  expect_error(write_text("mi_bad_number.obj", "v 0 0 0\nv 1 abc 0\nv 0 1 0\nf 1 2 3\n"),
               CV_ERR_FORMAT, ":2:");
  expect_error(write_text("mi_nan.obj", "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n"),
               CV_ERR_FORMAT, ":2:");
  expect_error(write_text("mi_bad_neg.obj", "v 0 0 0\nf -1 -2 -3\nv 1 0 0\nv 0 1 0\n"),
               CV_ERR_FORMAT, ":2:");
  expect_error(write_text("mi_zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"),
               CV_ERR_FORMAT, ":4:");
  expect_error(write_text("mi_empty.obj", "# nothing here\n"), CV_ERR_EMPTY, "no faces");
  expect_error(write_text("mi_no_faces.obj", "# vertices only\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"),
               CV_ERR_EMPTY, NULL);
  expect_error(write_text("mi_broken.gltf", "{\"asset\":{\"version\":\"2.0\"}, \"meshes\": [ {"),
               CV_ERR_FORMAT, "assimp");
  expect_error(write_text("mi_nan.ply", "ply\nformat ascii 1.0\nelement vertex 3\n"
                                        "property float x\nproperty float y\nproperty float z\n"
                                        "element face 1\nproperty list uchar int vertex_indices\n"
                                        "end_header\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n"),
               CV_ERR_NONFINITE, NULL);
  expect_error(write_text("mi_bad_index.ply", "ply\nformat ascii 1.0\nelement vertex 3\n"
                                              "property float x\nproperty float y\n"
                                              "property float z\nelement face 1\n"
                                              "property list uchar int vertex_indices\n"
                                              "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"),
               CV_ERR_FORMAT, NULL);
  cv_mesh *m;
  cv_import_opts o;
  cv_import_opts_default(&o);
  o.scale = -1;
  cv_err err;
  assert_int_equal(cv_mesh_import(tmp_path("x.obj"), &o, &m, &err), CV_ERR_INVALID);
}

static double wall_s(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The guarded import: an OFF header claiming 353535235358 vertices (as
 * assimp's invalid/OutOfMemory.off) stops at the memory limit, not after
 * minutes; an import that blocks (a FIFO nobody writes) stops at the time
 * limit; the message names file, format and the limit hit. */
static void test_guard(void **state) {
  (void)state;
  cv_import_opts o;
  cv_import_opts_default(&o);
  assert_true(o.limit_seconds > 0 && o.limit_memory_mb > 0);
  o.limit_memory_mb = 256;
  o.limit_seconds = 30;
#if defined(__SANITIZE_ADDRESS__)
  o.limit_seconds = 3; /* no memory limit under ASan: the time limit stops it */
#endif
  const char *p = write_text("huge.off", "OFF\n353535235358 1 0\n0 0 0\n3 0 0 0\n");
  cv_mesh *m = NULL;
  cv_err err;
  double t0 = wall_s();
  int st = cv_mesh_import(p, &o, &m, &err);
  double took = wall_s() - t0;
  print_message("huge.off: %s (%.2f s)\n", err.msg, took);
  assert_int_not_equal(st, CV_OK);
  assert_null(m);
  assert_non_null(strstr(err.msg, "huge.off"));
  assert_true(took < o.limit_seconds + 5);
#if !defined(__SANITIZE_ADDRESS__)
  assert_int_equal(st, CV_ERR_NOMEM);
  assert_non_null(strstr(err.msg, "import (OFF) stopped: memory limit 256 MB hit"));
#endif

  const char *fifo = tmp_path("blocked.off");
  unlink(fifo);
  assert_int_equal(mkfifo(fifo, 0600), 0);
  o.limit_seconds = 1;
  t0 = wall_s();
  st = cv_mesh_import(fifo, &o, &m, &err);
  took = wall_s() - t0;
  print_message("blocked.off: %s (%.2f s)\n", err.msg, took);
  assert_int_equal(st, CV_ERR_RANGE);
  assert_null(m);
  assert_non_null(strstr(err.msg, "blocked.off: import (OFF) stopped after"));
  assert_non_null(strstr(err.msg, "time limit 1 s hit"));
  assert_true(took >= 1.0 && took < 10.0);
  unlink(fifo);

  /* the guarded result equals the in-process one */
  p = write_text("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
  cv_mesh *a, *b;
  cv_import_stats sa, sb;
  cv_import_opts_default(&o);
  assert_int_equal(cv_mesh_import_ex(p, &o, &a, &sa, &err), CV_OK);
  assert_int_equal(cv_mesh_import_direct(p, &o, &b, &sb, &err), CV_OK);
  assert_int_equal(a->nv, b->nv);
  assert_int_equal(a->nt, 2);
  assert_int_equal(a->nt, b->nt);
  assert_int_equal(a->nm, b->nm);
  assert_memory_equal(a->pos, b->pos, 3 * a->nv * sizeof(float));
  assert_memory_equal(a->tri, b->tri, 3 * a->nt * sizeof(uint32_t));
  assert_memory_equal(a->mats, b->mats, a->nm * sizeof(cv_material));
  assert_memory_equal(&sa, &sb, sizeof sa);
  cv_mesh_destroy(a);
  cv_mesh_destroy(b);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_obj_mtl), cmocka_unit_test(test_points_lines_dropped),
      cmocka_unit_test(test_ply),     cmocka_unit_test(test_gltf),
      cmocka_unit_test(test_errors),  cmocka_unit_test(test_guard),
      cmocka_unit_test(test_texture_mean),
  };
  return cmocka_run_group_tests_name("mesh_import", tests, NULL, NULL);
}
