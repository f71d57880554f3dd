/* Shared lighting without MPI (src/render/render_share.c): a leader
 * renderer exports each lighting change into one buffer, an importer takes
 * it instead of computing, a third renderer computes every change itself.
 * Over a sequence of changes (a sun, the sun turned by far less than a
 * shadow texel so the leader keeps its map, turned by 3 degrees, no sun, the
 * sun back) the importer's images equal the computing renderer's byte for
 * byte (linear HDR and 8-bit display), also after the importer computed one
 * change itself in between (a late leader in `cave run`), and the leader
 * after a prefetch that did not come true (its own export taken back, then
 * the real change), and a renderer importing what an importer exported.
 * Errors: export
 * before any lighting, a truncated or foreign buffer, another shadow size,
 * another transfer storage (half/float). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "mesh/cabin.h"
#include "prt/bake.h"
#include "prt/scene_light.h"
#include "render/renderer.h"
#include "tonemap/drago.h"
#include "view/offaxis.h"

static cv_prt *g_prt;
static cv_cabin_info g_info;

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
  if (cv_cabin_generate_ex(&cp, &m, &g_info, &err)) return -1;
  cv_bake_params bp = {.bands = 5, .rays = 8, .bounces = 1, .seed = 5,
                       .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  const int st = cv_prt_bake(m, &bp, &g_prt, NULL, &err);
  cv_mesh_destroy(m);
  return st ? -1 : 0;
}

static int teardown(void **state) {
  (void)state;
  cv_prt_destroy(g_prt);
  return 0;
}

/* The driver's view: a 1.6 x 1.2 m wall 1 m ahead of the eye. */
static cv_render_view view(void) {
  cv_render_view v;
  memset(&v, 0, sizeof v);
  const float *e = g_info.eye;
  double pa[3], pb[3], pc[3], eye[3];
  const double d[3][3] = {{-0.8, -0.6, -1}, {0.8, -0.6, -1}, {-0.8, 0.6, -1}};
  for (int j = 0; j < 3; j++) {
    pa[j] = e[j] + d[0][j], pb[j] = e[j] + d[1][j], pc[j] = e[j] + d[2][j];
    eye[j] = e[j] + (j == 0 ? 0.15 : 0.0);
  }
  assert_int_equal(cv_offaxis_compute(pa, pb, pc, eye, 0.02, 20, &v.proj), CV_OK);
  v.w = 160, v.h = 120, v.supersample = 1;
  return v;
}

/* Renders r (HDR and 8-bit display) into hdr/disp. */
static void shade(cv_renderer *r, cv_image *hdr, cv_image *disp) {
  cv_err err;
  cv_render_view v = view();
  cv_drago d;
  cv_drago_default(&d);
  d.lwa = 0.3, d.lwmax = 20;
  cv_drago_consts dc;
  cv_drago_prepare(&d, &dc);
  OK(cv_renderer_shade(r, &v, &dc, 1, disp, hdr, NULL, &err));
}

static size_t differing(const cv_image *a, const cv_image *b) {
  size_t n = 0;
  for (size_t i = 0; i < 3 * (size_t)a->w * a->h; i++) n += memcmp(&a->px[i], &b->px[i], sizeof(float)) != 0;
  return n;
}

static void test_export_import_identical(void **state) {
  (void)state;
  cv_err err;
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  spec.kind = CV_LIGHT_SKY;
  spec.turbidity = 3, spec.sun_elevation_deg = 35, spec.sun_azimuth_deg = 30;
  cv_scene_light *sl;
  assert_int_equal(cv_scene_light_build(&spec, 5, &sl, &err), CV_OK);
  const cv_lighting base = cv_scene_light_sh(sl);
  cv_scene_light_destroy(sl);
  assert_true(base.has_sun);
  cv_renderer *leader, *importer, *own;
  OK(cv_renderer_create(g_prt, NULL, &leader, &err));
  OK(cv_renderer_create(g_prt, NULL, &importer, &err));
  OK(cv_renderer_create(g_prt, NULL, &own, &err));
  const cv_render_view v0 = view();
  const size_t nv0 = cv_renderer_view_triangles(leader, &v0);
  printf("the driver's view draws %zu of %zu triangles\n", nv0, (size_t)g_prt->nt);
  assert_true(nv0 > 0 && nv0 <= g_prt->nt);
  const size_t cap = cv_renderer_lighting_bytes(leader);
  assert_true(cap > 0 && cap == cv_renderer_lighting_bytes(importer));
  assert_true(cv_renderer_lighting_scene(leader) == cv_renderer_lighting_scene(importer));
  uint8_t *buf = calloc(cap, 1);
  assert_non_null(buf);
  /* export before any lighting */
  assert_int_equal(cv_renderer_lighting_export(leader, buf, cap, &err), CV_ERR_INVALID);
  const cv_render_view v = view();
  cv_image *hi, *ho, *di, *dn;
  assert_int_equal(cv_image_create(v.w, v.h, 3, &hi), CV_OK);
  assert_int_equal(cv_image_create(v.w, v.h, 3, &ho), CV_OK);
  assert_int_equal(cv_image_create(v.w, v.h, 3, &di), CV_OK);
  assert_int_equal(cv_image_create(v.w, v.h, 3, &dn), CV_OK);
  /* sun turns (radians about the vertical; the second by far less than a
   * texel: the leader keeps its map); step 3 has no sun; at step 4 the
   * importer computes itself (a late leader) */
  const double turn[6] = {0, 1e-6, 0.05, 0, 0.02, 0.3};
  double total = 0;
  for (int step = 0; step < 6; step++) {
    cv_lighting l = base;
    total += turn[step];
    const double c = cos(total), s = sin(total);
    l.sun_dir[0] = c * base.sun_dir[0] + s * base.sun_dir[2];
    l.sun_dir[2] = -s * base.sun_dir[0] + c * base.sun_dir[2];
    if (step == 3) l.has_sun = 0;
    cv_frame_timing tl = {0}, ti = {0};
    OK(cv_renderer_set_lighting(leader, &l, NULL, &tl, &err));
    OK(cv_renderer_lighting_export(leader, buf, cap, &err));
    if (step == 4) OK(cv_renderer_set_lighting(importer, &l, NULL, &ti, &err));
    else OK(cv_renderer_lighting_import(importer, buf, cap, &ti, &err));
    OK(cv_renderer_set_lighting(own, &l, NULL, NULL, &err));
    shade(importer, hi, di);
    shade(own, ho, dn);
    const size_t dh = differing(hi, ho), dd = differing(di, dn);
    printf("step %d (sun %s, leader's map %s, importer's %s): %zu HDR, %zu display values differ\n", step,
           l.has_sun ? "on" : "off", !l.has_sun ? "-" : (tl.shadow_reused ? "kept" : "redrawn"),
           step == 4 ? "computed" : (!l.has_sun ? "-" : (ti.shadow_reused ? "kept" : "uploaded")), dh, dd);
    assert_int_equal(dh, 0);
    assert_int_equal(dd, 0);
    if (step == 1) assert_int_equal(tl.shadow_reused, 1);
    if (step == 1) assert_int_equal(ti.shadow_reused, 1);
    if (step == 2) assert_int_equal(ti.shadow_reused, 0);
  }
  /* An importer's export (its map is the imported one, in its R32F
   * texture) imported by a fourth renderer: the same images. */
  {
    cv_renderer *second;
    OK(cv_renderer_create(g_prt, NULL, &second, &err));
    uint8_t *buf2 = calloc(cap, 1);
    assert_non_null(buf2);
    OK(cv_renderer_lighting_export(importer, buf2, cap, &err));
    OK(cv_renderer_lighting_import(second, buf2, cap, NULL, &err));
    shade(second, hi, di);
    printf("an importer's export, imported again: %zu HDR, %zu display values differ\n", differing(hi, ho),
           differing(di, dn));
    assert_int_equal(differing(hi, ho), 0);
    assert_int_equal(differing(di, dn), 0);
    free(buf2);
    cv_renderer_destroy(second);
  }
  /* The leader's prefetch that does not come true (cluster/lightshare.c):
   * it draws another sun, then takes its own export back (restore) and
   * computes the real next lighting; a sun moved by far less than a texel
   * after the restore keeps the restored map, as the computing renderer
   * keeps its own: the images stay bit-equal. */
  {
    cv_lighting cur = base, wrong = base, next = base;
    const double a = total, c = cos(a), s = sin(a), c2 = cos(a + 1.0), s2 = sin(a + 1.0);
    cur.sun_dir[0] = c * base.sun_dir[0] + s * base.sun_dir[2];
    cur.sun_dir[2] = -s * base.sun_dir[0] + c * base.sun_dir[2];
    wrong.sun_dir[0] = c2 * base.sun_dir[0] + s2 * base.sun_dir[2];
    wrong.sun_dir[2] = -s2 * base.sun_dir[0] + c2 * base.sun_dir[2];
    next = cur;
    next.sun_dir[1] += 1e-7;
    cv_frame_timing tl = {0};
    OK(cv_renderer_lighting_export(leader, buf, cap, &err)); /* the published lighting */
    OK(cv_renderer_set_lighting(leader, &wrong, NULL, NULL, &err)); /* the prefetch */
    OK(cv_renderer_lighting_import(leader, buf, cap, NULL, &err));  /* restored */
    OK(cv_renderer_set_lighting(leader, &next, NULL, &tl, &err));
    OK(cv_renderer_set_lighting(own, &next, NULL, NULL, &err));
    shade(leader, hi, di);
    shade(own, ho, dn);
    printf("prefetch restored, then a sun moved 1e-7 (map %s): %zu HDR, %zu display values differ\n",
           tl.shadow_reused ? "kept" : "redrawn", differing(hi, ho), differing(di, dn));
    assert_int_equal(tl.shadow_reused, 1);
    assert_int_equal(differing(hi, ho), 0);
    assert_int_equal(differing(di, dn), 0);
  }
  /* a truncated buffer, a foreign one */
  assert_int_equal(cv_renderer_lighting_import(importer, buf, cap - 8, NULL, &err), CV_ERR_FORMAT);
  assert_int_equal(cv_renderer_lighting_import(importer, buf, 16, NULL, &err), CV_ERR_FORMAT);
  uint8_t junk[512] = {0};
  assert_int_equal(cv_renderer_lighting_import(importer, junk, sizeof junk, NULL, &err), CV_ERR_FORMAT);
  printf("foreign buffer: %s\n", err.msg);
  /* another shadow size: another fingerprint, refused */
  cv_render_opts o;
  cv_render_default_opts(&o);
  o.shadow_res = 512;
  cv_renderer *small;
  OK(cv_renderer_create(g_prt, &o, &small, &err));
  assert_true(cv_renderer_lighting_scene(small) != cv_renderer_lighting_scene(leader));
  assert_int_equal(cv_renderer_lighting_import(small, buf, cap, NULL, &err), CV_ERR_INVALID);
  printf("other shadow size: %s\n", err.msg);
  assert_int_equal(cv_renderer_lighting_export(leader, buf, cap / 2, &err), CV_ERR_RANGE);
  cv_renderer_destroy(small);
  /* the other transfer storage: its relit colours differ in the last bits, refused */
  cv_render_default_opts(&o);
  o.half_transfer = !cv_renderer_half_transfer(leader);
  cv_renderer *other;
  OK(cv_renderer_create(g_prt, &o, &other, &err));
  assert_true(cv_renderer_lighting_scene(other) != cv_renderer_lighting_scene(leader));
  assert_int_equal(cv_renderer_lighting_import(other, buf, cap, NULL, &err), CV_ERR_INVALID);
  printf("other transfer storage (%s): %s\n", o.half_transfer ? "half" : "float", err.msg);
  cv_renderer_destroy(other);
  cv_image_destroy(hi), cv_image_destroy(ho), cv_image_destroy(di), cv_image_destroy(dn);
  free(buf);
  cv_renderer_destroy(leader);
  cv_renderer_destroy(importer);
  cv_renderer_destroy(own);
}

int main(void) {
  const struct CMUnitTest tests[] = {cmocka_unit_test(test_export_import_identical)};
  return cmocka_run_group_tests(tests, setup, teardown);
}
