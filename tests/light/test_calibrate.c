/* Env-map light levels (light/calibrate, prt/scene_light): the horizontal
 * illuminance of the upper hemisphere (a constant map of luminance L gives
 * pi L; light only below the horizon gives 0), the blender-data defaults,
 * and --illuminance LUX / auto through cv_scene_light_build: the upper
 * hemisphere of the lighting the renderer sees integrates to LUX. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>
#include "cv_test_near.h"

#include "io/exr.h"
#include "light/calibrate.h"
#include "light/envmap_cache.h"
#include "prt/lightmix.h"
#include "prt/scene_light.h"

static void test_constant_and_lower(void **state) {
  (void)state;
  cv_envmap *e;
  assert_int_equal(cv_envmap_create(64, 32, &e), CV_OK);
  for (size_t i = 0; i < 64 * 32 * 3; i++) e->img->px[i] = 2.0f;
  double E = cv_envmap_horizontal_illuminance(e);
  assert_near(E / (2 * M_PI), 1, 2e-3); /* midpoint rule on 16 rows */
  /* green only: luminance weight 0.7152 */
  for (size_t i = 0; i < 64 * 32; i++) e->img->px[3 * i] = e->img->px[3 * i + 2] = 0;
  assert_near(cv_envmap_horizontal_illuminance(e) / (0.7152 * 2 * M_PI), 1, 2e-3);
  /* light below the horizon (rows 16..31) does not count */
  memset(e->img->px, 0, 64 * 16 * 3 * sizeof(float));
  assert_true(cv_envmap_horizontal_illuminance(e) == 0.0);
  cv_envmap_destroy(e);
}

static void test_blender_defaults(void **state) {
  (void)state;
  char p[1024];
  snprintf(p, sizeof p, "%s/forest.exr", CAVE_BLENDER_WORLD_DIR);
  assert_true(cv_blender_map_default_lux(p) == 10000);
  snprintf(p, sizeof p, "%s/night.exr", CAVE_BLENDER_WORLD_DIR);
  assert_true(cv_blender_map_default_lux(p) == 10);
  assert_true(cv_blender_map_default_lux("/tmp/forest.exr") == 0); /* someone else's forest */
  assert_true(cv_blender_map_default_lux("forest.exr") == 0);
}

/* E_h of what the scene light shows (world frame, yaw 0), by lookups. */
static double lit_illuminance(const cv_scene_light *sl) {
  const int W = 512, H = 256;
  double E = 0;
  for (int j = 0; j < H / 2; j++) {
    double th = (j + 0.5) * M_PI / H;
    for (int i = 0; i < W; i++) {
      double ph = (i + 0.5) * 2 * M_PI / W;
      float d[3] = {(float)(sin(th) * sin(ph)), (float)cos(th), (float)(-sin(th) * cos(ph))};
      float rgb[3];
      cv_scene_light_background(sl, d, rgb);
      E += cv_luminance(rgb[0], rgb[1], rgb[2]) * cos(th) * sin(th) * (2 * M_PI / W) * (M_PI / H);
    }
  }
  return E;
}

static void test_scene_light_calibrated(void **state) {
  (void)state;
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  spec.kind = CV_LIGHT_ENV;
  spec.n_env = 1;
  spec.weight[0] = 1;
  spec.extract_sun = 0;
  snprintf(spec.env[0], sizeof spec.env[0], "%s/forest.exr", CAVE_BLENDER_WORLD_DIR);
  cv_err err;
  cv_scene_light *sl;
  assert_int_equal(cv_scene_light_build(&spec, 3, &sl, &err), CV_OK);
  const double raw = lit_illuminance(sl);
  cv_scene_light_destroy(sl);
  assert_true(raw > 0.5 && raw < 50); /* relative units */
  spec.illuminance = 25000;
  assert_int_equal(cv_scene_light_build(&spec, 3, &sl, &err), CV_OK);
  double E = lit_illuminance(sl);
  cv_scene_light_destroy(sl);
  if (fabs(E / 25000 - 1) > 0.01) fail_msg("calibrated E_h %g lux, expected 25000", E);
  spec.illuminance = CV_ILLUMINANCE_AUTO;
  assert_int_equal(cv_scene_light_build(&spec, 3, &sl, &err), CV_OK);
  E = lit_illuminance(sl);
  cv_scene_light_destroy(sl);
  if (fabs(E / 10000 - 1) > 0.01) fail_msg("auto E_h %g lux, expected 10000 (forest)", E);
  /* scale and illuminance together: an error, not a silent choice */
  spec.scale = 2;
  assert_int_equal(cv_scene_light_build(&spec, 3, &sl, &err), CV_ERR_CONFIG);
  assert_non_null(strstr(err.msg, "give one"));
}

/* The LCD worker's map cache (light/envmap_cache.h): a blend of two maps
 * built through the cache twice equals the uncached build bit for bit
 * (SH, background), each file decoded once; a missing file is an error
 * every time (not cached); NULL cache = uncached. */
/* Built with bands 0 (the background alone, as a lighting leader needs it):
 * the same background and sun as with SH, bit for bit, no SH, no split;
 * for a sky and for an env map. */
static void test_scene_light_no_sh(void **state) {
  (void)state;
  for (int kind = 0; kind < 2; kind++) {
    cv_light_spec spec;
    cv_light_spec_default(&spec);
    if (kind == 0) {
      spec.kind = CV_LIGHT_SKY;
      spec.sun_elevation_deg = 35, spec.sun_azimuth_deg = 120;
    } else {
      spec.kind = CV_LIGHT_ENV;
      spec.n_env = 1, spec.weight[0] = 1;
      snprintf(spec.env[0], sizeof spec.env[0], "%s/forest.exr", CAVE_BLENDER_WORLD_DIR);
    }
    spec.yaw_deg = 25;
    cv_err err;
    cv_scene_light *ref, *bg;
    assert_int_equal(cv_scene_light_build(&spec, 5, &ref, &err), CV_OK);
    assert_int_equal(cv_scene_light_build(&spec, 0, &bg, &err), CV_OK);
    const cv_lighting lr = cv_scene_light_sh(ref), lb = cv_scene_light_sh(bg);
    assert_int_equal(lb.bands, 0);
    for (int i = 0; i < 3 * 64; i++) assert_true(lb.sh[i] == 0);
    printf("kind %d: SH[0..2] %g %g %g, bands %d\n", kind, lr.sh[0], lr.sh[1], lr.sh[2], lr.bands);
    assert_true(lr.sh[0] > 0);
    assert_int_equal(lb.has_sun, lr.has_sun);
    assert_memory_equal(lb.sun_E, lr.sun_E, sizeof lb.sun_E);
    assert_memory_equal(lb.sun_dir, lr.sun_dir, sizeof lb.sun_dir);
    for (int k = 0; k < 64; k++) {
      const float d[3] = {(float)cos(0.7 * k), 0.9f - 0.03f * (float)k, (float)sin(0.7 * k)};
      float a[3], b[3];
      cv_scene_light_background(bg, d, a);
      cv_scene_light_background(ref, d, b);
      assert_memory_equal(a, b, sizeof a);
    }
    assert_int_equal(cv_scene_light_split(bg, NULL, 4, 16, &err), CV_ERR_INVALID);
    assert_non_null(strstr(err.msg, "without SH"));
    cv_scene_light_destroy(ref), cv_scene_light_destroy(bg);
  }
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  spec.kind = CV_LIGHT_SKY;
  cv_err err;
  cv_scene_light *sl;
  assert_int_equal(cv_scene_light_build(&spec, 1, &sl, &err), CV_ERR_RANGE);
  assert_int_equal(cv_scene_light_build(&spec, 9, &sl, &err), CV_ERR_RANGE);
}

static void test_scene_light_cached(void **state) {
  (void)state;
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  spec.kind = CV_LIGHT_ENV;
  spec.n_env = 2;
  spec.weight[0] = 0.3, spec.weight[1] = 0.7;
  snprintf(spec.env[0], sizeof spec.env[0], "%s/forest.exr", CAVE_BLENDER_WORLD_DIR);
  snprintf(spec.env[1], sizeof spec.env[1], "%s/city.exr", CAVE_BLENDER_WORLD_DIR);
  cv_err err;
  cv_scene_light *ref, *sl;
  assert_int_equal(cv_scene_light_build(&spec, 5, &ref, &err), CV_OK);
  const cv_lighting lr = cv_scene_light_sh(ref);
  cv_envmap_cache *c;
  assert_int_equal(cv_envmap_cache_create(&c), CV_OK);
  for (int k = 0; k < 3; k++) {
    spec.yaw_deg = k == 2 ? 40 : 0; /* a turned car: same maps, other SH */
    assert_int_equal(cv_scene_light_build_cached(&spec, 5, c, &sl, &err), CV_OK);
    if (k < 2) {
      const cv_lighting l = cv_scene_light_sh(sl);
      assert_memory_equal(l.sh, lr.sh, sizeof l.sh);
      assert_memory_equal(l.sun_E, lr.sun_E, sizeof l.sun_E);
      const float d[3] = {0.3f, 0.5f, -0.8f};
      float a[3], b[3];
      cv_scene_light_background(sl, d, a);
      cv_scene_light_background(ref, d, b);
      assert_memory_equal(a, b, sizeof a);
    }
    cv_scene_light_destroy(sl);
  }
  uint64_t dec, hits;
  cv_envmap_cache_counts(c, &dec, &hits);
  printf("3 builds of a 2-map blend: %llu decodes, %llu from the cache\n", (unsigned long long)dec,
         (unsigned long long)hits);
  assert_true(dec == 2 && hits == 4);
  snprintf(spec.env[1], sizeof spec.env[1], "/nonexistent/map.exr");
  for (int k = 0; k < 2; k++) {
    assert_int_not_equal(cv_scene_light_build_cached(&spec, 5, c, &sl, &err), CV_OK);
    assert_non_null(strstr(err.msg, "/nonexistent/map.exr"));
  }
  cv_envmap_cache_counts(c, &dec, &hits);
  assert_true(dec == 2 && hits == 6); /* forest twice more; the missing file never counted */
  cv_envmap_cache_destroy(c);
  cv_envmap_cache_destroy(NULL);
  cv_scene_light_destroy(ref);
}

/* The service's map drives (prt/lightmix): each map calibrated alike, so
 * a blend keeps the level. */
static void test_lightmix_calibrated(void **state) {
  (void)state;
  char f[1024], c[1024];
  snprintf(f, sizeof f, "%s/forest.exr", CAVE_BLENDER_WORLD_DIR);
  snprintf(c, sizeof c, "%s/city.exr", CAVE_BLENDER_WORLD_DIR);
  const char *paths[2] = {f, c};
  cv_lightmix *m;
  cv_err err;
  assert_int_equal(cv_lightmix_create_calibrated(paths, 2, 1.0, 8000, 3, &m, &err), CV_OK);
  const double w[3][2] = {{1, 0}, {0, 1}, {0.3, 0.7}};
  for (int k = 0; k < 3; k++) {
    cv_image *bg;
    assert_int_equal(cv_lightmix_background(m, w[k], 0, 0, 0, 512, &bg), CV_OK);
    cv_envmap *e;
    assert_int_equal(cv_envmap_from_image(bg, &e, &err), CV_OK);
    double E = cv_envmap_horizontal_illuminance(e);
    if (fabs(E / 8000 - 1) > 0.02) fail_msg("blend %d: E_h %g lux, expected 8000", k, E);
    cv_envmap_destroy(e);
    cv_image_destroy(bg);
  }
  cv_lightmix_destroy(m);
  /* someone else's forest.exr has no documented level */
  char own[1024];
  snprintf(own, sizeof own, "%s/forest.exr", CV_TEST_TMP_DIR);
  cv_image *im;
  assert_int_equal(cv_image_create(16, 8, 3, &im), CV_OK);
  for (size_t i = 0; i < 16 * 8 * 3; i++) im->px[i] = 1.0f;
  assert_int_equal(cv_exr_write(own, im, 0, CV_EXR_ZIP, &err), CV_OK);
  cv_image_destroy(im);
  const char *other[1] = {own};
  assert_int_equal(cv_lightmix_create_calibrated(other, 1, 1.0, CV_ILLUMINANCE_AUTO, 3, &m, &err),
                   CV_ERR_CONFIG);
  assert_non_null(strstr(err.msg, "not a blender-data map"));
  assert_int_equal(cv_lightmix_create_calibrated(paths, 1, 2.0, 100, 3, &m, &err), CV_ERR_INVALID);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_constant_and_lower),
      cmocka_unit_test(test_blender_defaults),
      cmocka_unit_test(test_scene_light_calibrated),
      cmocka_unit_test(test_lightmix_calibrated),
      cmocka_unit_test(test_scene_light_no_sh), cmocka_unit_test(test_scene_light_cached),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
