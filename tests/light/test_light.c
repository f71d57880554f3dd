/* Unit tests of the light module that need no files: Preetham sky and sun,
 * environment-map lookup, blending, car rotation, map rotation against SH
 * rotation, and sun extraction on synthetic maps.  Tolerances are stated at
 * each check; measured figures are printed. */
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

#include "core/image.h"
#include "core/status.h"
#include "light/envmap.h"
#include "light/sky.h"
#include "light/sun.h"
#include "sh/latlong.h"
#include "sh/sh.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static double deg(double r) { return r * 180.0 / M_PI; }
static double rad(double d) { return d * M_PI / 180.0; }
static double lum709(const double rgb[3]) { /* Y row of the RGB -> XYZ matrix */
  return 0.2126729 * rgb[0] + 0.7151522 * rgb[1] + 0.0721750 * rgb[2];
}
/* Unit direction at elevation el and azimuth az (degrees; az from -Z towards +X). */
static void dir_el_az(double el, double az, double d[3]) {
  d[0] = cos(rad(el)) * sin(rad(az));
  d[1] = sin(rad(el));
  d[2] = -cos(rad(el)) * cos(rad(az));
}
static double angle_deg(const double a[3], const double b[3]) {
  const double c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  return deg(acos(fmax(-1.0, fmin(1.0, c))));
}
static void transpose3(const double R[9], double T[9]) {
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) T[3 * j + i] = R[3 * i + j];
}
static void mat_vec(const double R[9], const double v[3], double o[3]) {
  for (int i = 0; i < 3; i++) o[i] = R[3 * i] * v[0] + R[3 * i + 1] * v[1] + R[3 * i + 2] * v[2];
}

/* ---- sky ------------------------------------------------------------------ */

static void test_sky_zenith(void **state) {
  (void)state;
  /* zenith Y (kcd/m^2) and x, y from the paper's formulas evaluated
   * independently (Python, double): (T, elevation) = (3, 30), (6, 60) */
  const struct { double T, el, Y, x, y; } cases[2] = {
      {3.0, 30.0, 5.139156036248174, 0.244928593542038, 0.2525731242208065},
      {6.0, 60.0, 22.066707635245116, 0.26312666889674574, 0.2759851454160776}};
  for (int k = 0; k < 2; k++) {
    double sd[3];
    dir_el_az(cases[k].el, 40.0, sd);
    cv_sky *sky = NULL;
    cv_err err;
    assert_int_equal(cv_sky_create(cases[k].T, sd, 0.2, &sky, &err), CV_OK);
    cv_sky_info info;
    cv_sky_get_info(sky, &info);
    /* the formula again, inline: Y = (4.0453 T - 4.9710) tan chi - 0.2155 T + 2.4192 */
    const double T = cases[k].T, ts = rad(90.0 - cases[k].el);
    const double chi = (4.0 / 9.0 - T / 120.0) * (M_PI - 2.0 * ts);
    const double Yf = (4.0453 * T - 4.9710) * tan(chi) - 0.2155 * T + 2.4192;
    printf("  T=%g elev %g: zenith Y %.6f kcd/m2 (expected %.6f), x %.6f y %.6f\n", T,
           cases[k].el, info.zenith_xyY[2] / 1000.0, cases[k].Y, info.zenith_xyY[0],
           info.zenith_xyY[1]);
    assert_near(Yf, cases[k].Y, 1e-12);
    assert_near(info.zenith_xyY[2] / 1000.0, cases[k].Y, 1e-9 * cases[k].Y);
    assert_near(info.zenith_xyY[0], cases[k].x, 1e-12);
    assert_near(info.zenith_xyY[1], cases[k].y, 1e-12);

    /* Perez ratio at the zenith is 1: radiance there has the zenith
     * luminance (tol 1e-4: 7-digit colour matrices) */
    const double up[3] = {0.0, 1.0, 0.0};
    double rgb[3];
    assert_int_equal(cv_sky_radiance(sky, up, rgb), 0);
    const double ratio = lum709(rgb) / info.zenith_xyY[2];
    printf("  Y(zenith)/Y_z = %.8f (tol 1e-4)\n", ratio);
    assert_near(ratio, 1.0, 1e-4);
    /* and the Perez function itself */
    const double c[5] = {-1.1, -0.3, 5.3, -2.5, 0.3};
    assert_near(cv_perez(c, 0.0, 0.0), (1 - 1.1 * exp(-0.3)) * (1 + 5.3 + 0.3), 1e-12);
    cv_sky_destroy(sky);
  }
}

static void test_sky_range(void **state) {
  (void)state;
  /* finite and >= 0 for T = 2..10, sun elevation -5..90, over a grid of
   * directions including the horizon, the sun itself and the nadir */
  long bad = 0, clamped = 0, evals = 0;
  for (double T = 2.0; T <= 10.0; T += 1.0)
    for (double el = -5.0; el <= 90.0; el += 5.0) {
      double sd[3];
      dir_el_az(el, 75.0, sd);
      cv_sky *sky = NULL;
      assert_int_equal(cv_sky_create(T, sd, 0.3, &sky, NULL), CV_OK);
      for (double e = -90.0; e <= 90.0; e += 7.5)
        for (double a = 0.0; a < 360.0; a += 15.0) {
          double d[3], rgb[3];
          dir_el_az(e, a, d);
          clamped += cv_sky_radiance(sky, d, rgb);
          evals++;
          for (int c = 0; c < 3; c++) bad += !(isfinite(rgb[c]) && rgb[c] >= 0.0);
        }
      const double extra[4][3] = {{sd[0], sd[1], sd[2]}, {1, 1e-12, 0}, {0, -1, 0}, {0, 0, 0}};
      for (int k = 0; k < 4; k++) {
        double rgb[3];
        clamped += cv_sky_radiance(sky, extra[k], rgb);
        for (int c = 0; c < 3; c++) bad += !(isfinite(rgb[c]) && rgb[c] >= 0.0);
      }
      double dir[3], sun[3], sa;
      cv_sky_sun(sky, dir, sun, &sa);
      for (int c = 0; c < 3; c++) bad += !(isfinite(sun[c]) && sun[c] >= 0.0);
      if (el <= 0.0)
        for (int c = 0; c < 3; c++) assert_true(sun[c] == 0.0);
      cv_sky_destroy(sky);
    }
  printf("  sky over T 2..10, elevation -5..90: %ld evaluations, %ld bad, %ld channels clamped\n",
         evals, bad, clamped);
  assert_int_equal(bad, 0);
}

static void test_sun_light(void **state) {
  (void)state;
  /* Clear sky, sun 60 degrees up, T = 3: the beam is about 70-100 klux in
   * measurements; accept 50..110 klux. */
  double sd[3];
  dir_el_az(60.0, 0.0, sd);
  cv_sky *sky = NULL;
  assert_int_equal(cv_sky_create(3.0, sd, 0.2, &sky, NULL), CV_OK);
  double dir[3], rgb[3], sa;
  cv_sky_sun(sky, dir, rgb, &sa);
  cv_sky_info info;
  cv_sky_get_info(sky, &info);
  printf("  sun T=3 elev 60: %.0f lux (XYZ Y %.0f), RGB (%.0f, %.0f, %.0f), sky on horizontal %.0f lux, "
         "ground L %.0f cd/m2\n",
         lum709(rgb), info.sun_xyz[1], rgb[0], rgb[1], rgb[2], info.sky_horizontal_lux,
         lum709(info.ground_rgb));
  assert_true(info.sun_xyz[1] > 50e3 && info.sun_xyz[1] < 110e3);
  assert_near(lum709(rgb), info.sun_xyz[1], 1e-3 * info.sun_xyz[1]);
  assert_true(sa == CV_SUN_SOLID_ANGLE);
  assert_true(angle_deg(dir, sd) < 1e-9);
  /* the sun at noon is near white: no channel below half of the largest */
  assert_true(fmin(rgb[0], fmin(rgb[1], rgb[2])) > 0.5 * fmax(rgb[0], fmax(rgb[1], rgb[2])));
  /* diffuse illuminance of the dome on a horizontal plane: measured clear
   * skies give 10-20 klux here; Preetham's dome is known to be too bright
   * (Zotti et al. 2007), about 31 klux: accept 5-40 klux */
  assert_true(info.sky_horizontal_lux > 5e3 && info.sky_horizontal_lux < 40e3);
  /* ground = albedo (E_sky + E_sun sin(el)) / pi */
  for (int c = 0; c < 3; c++) {
    const double e = 0.2 * (info.sky_horizontal_rgb[c] + rgb[c] * sd[1]) / M_PI;
    assert_near(info.ground_rgb[c], e, 1e-9 * e);
  }
  const double down[3] = {0.3, -0.9, 0.1};
  double g[3];
  cv_sky_radiance(sky, down, g);
  for (int c = 0; c < 3; c++) assert_true(g[c] == info.ground_rgb[c]);

  /* independent check of the dome integral: sum over a lat-long rendering */
  cv_image *img = NULL;
  long ncl = -1;
  assert_int_equal(cv_sky_to_latlong(sky, 1024, 512, &img, &ncl), CV_OK);
  double Eh = 0.0, maxL = 0.0;
  for (int y = 0; y < 256; y++) {
    const double sa_row = cv_latlong_pixel_solid_angle(y, 1024, 512);
    for (int x = 0; x < 1024; x++) {
      double d[3];
      cv_latlong_pixel_dir(x, y, 1024, 512, d);
      const float *p = cv_image_at(img, x, y);
      const double rgbp[3] = {p[0], p[1], p[2]};
      Eh += lum709(rgbp) * d[1] * sa_row;
      maxL = fmax(maxL, lum709(rgbp));
    }
  }
  printf("  dome illuminance: quadrature %.1f lux, lat-long sum %.1f lux; brightest sky pixel %.0f "
         "cd/m2 (sun disc %.3g cd/m2 not drawn); %ld channels clamped\n",
         info.sky_horizontal_lux, Eh, maxL, info.sun_xyz[1] / CV_SUN_SOLID_ANGLE, ncl);
  assert_near(Eh, info.sky_horizontal_lux, 0.01 * info.sky_horizontal_lux);
  assert_true(maxL < 0.01 * info.sun_xyz[1] / CV_SUN_SOLID_ANGLE);
  cv_image_destroy(img);
  cv_sky_destroy(sky);

  /* monotone: higher sun -> more light; hazier -> less direct light */
  double prev = 0.0;
  for (double el = 5.0; el <= 90.0; el += 5.0) {
    dir_el_az(el, 10.0, sd);
    assert_int_equal(cv_sky_create(3.0, sd, 0.2, &sky, NULL), CV_OK);
    cv_sky_get_info(sky, &info);
    assert_true(info.sun_xyz[1] > prev);
    prev = info.sun_xyz[1];
    cv_sky_destroy(sky);
  }
  dir_el_az(40.0, 10.0, sd);
  double t2, t9;
  assert_int_equal(cv_sky_create(2.0, sd, 0.2, &sky, NULL), CV_OK);
  cv_sky_get_info(sky, &info);
  t2 = info.sun_xyz[1];
  cv_sky_destroy(sky);
  assert_int_equal(cv_sky_create(9.0, sd, 0.2, &sky, NULL), CV_OK);
  cv_sky_get_info(sky, &info);
  t9 = info.sun_xyz[1];
  cv_sky_destroy(sky);
  printf("  sun at 40 deg: T=2 %.0f lux, T=9 %.0f lux\n", t2, t9);
  assert_true(t9 < t2);
}

static void test_sky_errors(void **state) {
  (void)state;
  const double up[3] = {0, 1, 0}, longv[3] = {0, 2, 0};
  cv_sky *sky = (cv_sky *)&sky;
  cv_err err;
  assert_int_equal(cv_sky_create(1.9, up, 0.2, &sky, &err), CV_ERR_RANGE);
  assert_null(sky);
  assert_non_null(strstr(err.msg, "turbidity"));
  assert_int_equal(cv_sky_create(10.1, up, 0.2, &sky, &err), CV_ERR_RANGE);
  assert_int_equal(cv_sky_create(NAN, up, 0.2, &sky, &err), CV_ERR_RANGE);
  assert_int_equal(cv_sky_create(3.0, up, -0.1, &sky, &err), CV_ERR_RANGE);
  assert_non_null(strstr(err.msg, "ground_albedo"));
  assert_int_equal(cv_sky_create(3.0, up, 1.5, &sky, &err), CV_ERR_RANGE);
  assert_int_equal(cv_sky_create(3.0, longv, 0.2, &sky, &err), CV_ERR_RANGE);
  assert_non_null(strstr(err.msg, "sun_dir"));
  assert_int_equal(cv_sky_create(3.0, NULL, 0.2, &sky, &err), CV_ERR_INVALID);
  assert_int_equal(cv_sky_create(2.0, up, 0.0, &sky, &err), CV_OK); /* the limits are valid */
  cv_sky_destroy(sky);
  assert_int_equal(cv_sky_create(10.0, up, 1.0, &sky, NULL), CV_OK);
  cv_image *img = NULL;
  assert_int_equal(cv_sky_to_latlong(sky, 8, 1, &img, NULL), CV_ERR_INVALID);
  cv_sky_destroy(sky);
  cv_sky_destroy(NULL);
}

/* ---- environment maps ---------------------------------------------------- */

/* A smooth, positive test radiance. */
static void smooth_rgb(const double d[3], double rgb[3]) {
  rgb[0] = 1.0 + 0.8 * d[1] + 0.3 * d[0] * d[2];
  rgb[1] = exp(0.7 * d[0] - 0.5 * d[2]);
  rgb[2] = 2.0 + d[0] * d[1] - 0.5 * d[2] * d[2] * d[2];
}
static cv_envmap *smooth_map(int w, int h) {
  cv_envmap *env = NULL;
  assert_int_equal(cv_envmap_create(w, h, &env), CV_OK);
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      double d[3], rgb[3];
      cv_latlong_pixel_dir(x, y, w, h, d);
      smooth_rgb(d, rgb);
      float *p = cv_image_at(env->img, x, y);
      for (int c = 0; c < 3; c++) p[c] = (float)rgb[c];
    }
  return env;
}

static void test_envmap_basic(void **state) {
  (void)state;
  cv_envmap *env = smooth_map(64, 32);
  /* lookup at a pixel centre returns the pixel (float rounding of the
   * direction only) */
  for (int y = 0; y < 32; y += 5)
    for (int x = 0; x < 64; x += 7) {
      double d[3];
      cv_latlong_pixel_dir(x, y, 64, 32, d);
      const float df[3] = {(float)d[0], (float)d[1], (float)d[2]};
      float rgb[3];
      cv_envmap_lookup(env, df, rgb);
      const float *p = cv_image_at(env->img, x, y);
      for (int c = 0; c < 3; c++) assert_near(rgb[c], p[c], 1e-4f * fabsf(p[c]) + 1e-5f);
    }
  /* across the seam behind the car (u = 0 = 1) the lookup is continuous */
  float a[3], b[3];
  const float l[3] = {-1e-4f, 0.2f, 0.98f}, r[3] = {1e-4f, 0.2f, 0.98f};
  cv_envmap_lookup(env, l, a);
  cv_envmap_lookup(env, r, b);
  for (int c = 0; c < 3; c++) assert_near(a[c], b[c], 1e-3f);
  /* degenerate direction: black */
  const float z[3] = {0, 0, 0};
  cv_envmap_lookup(env, z, a);
  assert_true(a[0] == 0 && a[1] == 0 && a[2] == 0);
  cv_envmap_destroy(env);

  /* from_image: grey, negatives clamped and counted, NaN refused with the pixel */
  cv_image *img = NULL;
  assert_int_equal(cv_image_create(8, 4, 1, &img), CV_OK);
  for (int i = 0; i < 32; i++) img->px[i] = 0.5f;
  img->px[3] = -1.0f;
  cv_err err;
  assert_int_equal(cv_envmap_from_image(img, &env, &err), CV_OK);
  assert_int_equal(env->negative_clamped, 3);
  assert_true(env->img->px[9] == 0.0f && env->img->px[10] == 0.0f && env->img->px[0] == 0.5f);
  cv_envmap_destroy(env);
  img->px[13] = NAN;
  assert_int_equal(cv_envmap_from_image(img, &env, &err), CV_ERR_NONFINITE);
  assert_null(env);
  assert_non_null(strstr(err.msg, "(5, 1)"));
  cv_image_destroy(img);
  assert_int_equal(cv_image_create(8, 1, 3, &img), CV_OK);
  assert_int_equal(cv_envmap_from_image(img, &env, &err), CV_ERR_INVALID);
  cv_image_destroy(img);
  assert_int_equal(cv_envmap_create(8, 1, &env), CV_ERR_INVALID);
  cv_envmap_destroy(NULL);
}

static void test_envmap_blend(void **state) {
  (void)state;
  cv_envmap *a = NULL, *b = NULL, *c = smooth_map(64, 32), *out = NULL;
  assert_int_equal(cv_envmap_create(64, 32, &a), CV_OK);
  assert_int_equal(cv_envmap_create(128, 64, &b), CV_OK); /* resampled */
  for (int i = 0; i < 64 * 32 * 3; i++) a->img->px[i] = 1.0f;
  for (int i = 0; i < 128 * 64; i++) {
    b->img->px[3 * i] = 2.0f;
    b->img->px[3 * i + 1] = 3.0f;
    b->img->px[3 * i + 2] = 4.0f;
  }
  const cv_envmap *maps[3] = {a, b, c};
  const double wts[3] = {0.25, 2.0, 0.5}; /* sum 2.75: blends need not be normalised */
  cv_err err;
  assert_int_equal(cv_envmap_blend(maps, wts, 3, 64, 32, &out, &err), CV_OK);
  double worst = 0.0;
  for (int i = 0; i < 64 * 32; i++)
    for (int ch = 0; ch < 3; ch++) {
      const double e = 0.25 + 2.0 * (2.0 + ch) + 0.5 * c->img->px[3 * i + ch];
      worst = fmax(worst, fabs(out->img->px[3 * i + ch] - e) / e);
    }
  printf("  blend of 3 maps (one resampled 2:1): max rel err %.2e (tol 1e-6)\n", worst);
  assert_true(worst < 1e-6);
  cv_envmap_destroy(out);
  /* enlarging: a smooth map blended at 256x128 from 64x32 stays close */
  const cv_envmap *one[1] = {c};
  const double w1[1] = {1.0};
  assert_int_equal(cv_envmap_blend(one, w1, 1, 256, 128, &out, &err), CV_OK);
  assert_int_equal(out->img->w, 256);
  cv_envmap_destroy(out);
  /* validation */
  const double neg[3] = {0.25, -1.0, 0.5}, nan3[3] = {0.25, NAN, 0.5};
  assert_int_equal(cv_envmap_blend(maps, neg, 3, 64, 32, &out, &err), CV_ERR_INVALID);
  assert_null(out);
  assert_non_null(strstr(err.msg, "weight 1"));
  assert_int_equal(cv_envmap_blend(maps, nan3, 3, 64, 32, &out, &err), CV_ERR_INVALID);
  assert_int_equal(cv_envmap_blend(maps, wts, 0, 64, 32, &out, &err), CV_ERR_INVALID);
  assert_int_equal(cv_envmap_blend(maps, wts, 3, 64, 1, &out, &err), CV_ERR_INVALID);
  cv_envmap_destroy(a);
  cv_envmap_destroy(b);
  cv_envmap_destroy(c);
}

static void test_car_rotation(void **state) {
  (void)state;
  double R[9], o[3];
  const double fwd[3] = {0, 0, -1}, right[3] = {1, 0, 0}, up[3] = {0, 1, 0};
  cv_car_rotation(90.0, 0.0, 0.0, R); /* yaw left: the nose points to -X */
  mat_vec(R, fwd, o);
  assert_near(o[0], -1.0, 1e-12);
  assert_near(o[1], 0, 1e-12);
  assert_near(o[2], 0, 1e-12);
  cv_car_rotation(0.0, 10.0, 0.0, R); /* pitch: the nose goes up */
  mat_vec(R, fwd, o);
  assert_near(o[1], sin(rad(10)), 1e-12);
  assert_true(o[2] < 0);
  cv_car_rotation(0.0, 0.0, 10.0, R); /* roll: the right side goes down */
  mat_vec(R, right, o);
  assert_near(o[1], -(sin(rad(10))), 1e-12);
  mat_vec(R, fwd, o);
  assert_near(o[2], -1.0, 1e-12);
  /* order: roll, then pitch, then yaw */
  double Ry[9], Rp[9], Rr[9], T[9], C[9];
  cv_car_rotation(30.0, 0.0, 0.0, Ry);
  cv_car_rotation(0.0, -12.0, 0.0, Rp);
  cv_car_rotation(0.0, 0.0, 7.0, Rr);
  cv_car_rotation(30.0, -12.0, 7.0, R);
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      T[3 * i + j] = 0;
      for (int k = 0; k < 3; k++) T[3 * i + j] += Rp[3 * i + k] * Rr[3 * k + j];
    }
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      C[3 * i + j] = 0;
      for (int k = 0; k < 3; k++) C[3 * i + j] += Ry[3 * i + k] * T[3 * k + j];
    }
  for (int k = 0; k < 9; k++) assert_near(C[k], R[k], 1e-12);
  mat_vec(R, up, o);
  assert_near(o[0] * o[0] + o[1] * o[1] + o[2] * o[2], 1.0, 1e-12);
}

static void test_envmap_rotate(void **state) {
  (void)state;
  const int w = 512, h = 256;
  cv_envmap *env = smooth_map(w, h), *rot = NULL, *back = NULL;
  double R[9], Rt[9];
  cv_car_rotation(35.0, 8.0, -5.0, R);
  transpose3(R, Rt);
  assert_int_equal(cv_envmap_rotate(env, R, &rot), CV_OK);
  /* out(d) = env(R d) = f(R d), checked at random-ish directions
   * (bilinear interpolation error of a smooth map: tol 2e-3 relative) */
  double worst = 0.0;
  for (int k = 0; k < 500; k++) {
    const double el = -80.0 + 160.0 * ((k * 37) % 101) / 100.0, az = (k * 53) % 360;
    double d[3], e[3], f[3];
    dir_el_az(el, az, d);
    mat_vec(R, d, e);
    smooth_rgb(e, f);
    const float df[3] = {(float)d[0], (float)d[1], (float)d[2]};
    float got[3];
    cv_envmap_lookup(rot, df, got);
    for (int c = 0; c < 3; c++) worst = fmax(worst, fabs(got[c] - f[c]) / fabs(f[c]));
  }
  printf("  rotated map vs f(R d): max rel err %.2e (tol 2e-3)\n", worst);
  assert_true(worst < 2e-3);
  /* round trip R then R^T gives the map back up to two bilinear passes */
  assert_int_equal(cv_envmap_rotate(rot, Rt, &back), CV_OK);
  worst = 0.0;
  for (int i = 0; i < w * h * 3; i++)
    worst = fmax(worst, fabs(back->img->px[i] - env->img->px[i]) / fabs(env->img->px[i]));
  printf("  rotate(R) then rotate(R^T): max rel err %.2e (tol 5e-3)\n", worst);
  assert_true(worst < 5e-3);

  /* SH: projecting the rotated map = rotating the projection by R^T.
   * Smooth map, n = 8; relative L2 over all 3*64 coefficients (tol 1e-3). */
  double c[3 * 64], cr[3 * 64], cp[3 * 64];
  assert_int_equal(cv_envmap_project_sh(env, 8, c), CV_OK);
  assert_int_equal(cv_envmap_project_sh(rot, 8, cp), CV_OK);
  cv_sh_rotation *sr = NULL;
  assert_int_equal(cv_sh_rotation_create(8, Rt, &sr), CV_OK);
  cv_sh_rotate(sr, c, cr, 3);
  double num = 0.0, den = 0.0;
  for (int i = 0; i < 3 * 64; i++) {
    num += (cp[i] - cr[i]) * (cp[i] - cr[i]);
    den += c[i] * c[i];
  }
  printf("  smooth map: |proj(rotated map) - rotate(R^T, proj(map))| / |proj| = %.2e (tol 1e-3)\n",
         sqrt(num / den));
  assert_true(sqrt(num / den) < 1e-3);
  cv_sh_rotation_destroy(sr);

  const double bad[9] = {1, 0, 0, 0, 1, 0, 0, 0, 2};
  cv_envmap *x = NULL;
  assert_int_equal(cv_envmap_rotate(env, bad, &x), CV_ERR_INVALID);
  assert_null(x);
  cv_envmap_destroy(env);
  cv_envmap_destroy(rot);
  cv_envmap_destroy(back);
}

/* ---- sun extraction ------------------------------------------------------ */

/* Constant sky `sky` plus a disc of radius r_deg around dir with radiance L
 * added in proportion to pixel coverage (8x8 sub-samples per pixel, uniform
 * in u, v).  disc_energy gets the pixel sum of the disc's L * dOmega. */
static cv_envmap *disc_map(int w, int h, double sky, const double dir[3], double r_deg, double L,
                           double *disc_energy) {
  cv_envmap *env = NULL;
  assert_int_equal(cv_envmap_create(w, h, &env), CV_OK);
  const double cr = cos(rad(r_deg));
  double energy = 0.0;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      double d[3];
      cv_latlong_pixel_dir(x, y, w, h, d);
      float *p = cv_image_at(env->img, x, y);
      double cov = 0.0;
      if (d[0] * dir[0] + d[1] * dir[1] + d[2] * dir[2] > cos(rad(r_deg + 1.0))) {
        for (int j = 0; j < 8; j++)
          for (int i = 0; i < 8; i++) {
            double e[3];
            cv_latlong_dir((x + (i + 0.5) / 8) / w, (y + (j + 0.5) / 8) / h, e);
            cov += (e[0] * dir[0] + e[1] * dir[1] + e[2] * dir[2] > cr) ? 1.0 : 0.0;
          }
        cov /= 64.0;
      }
      for (int c = 0; c < 3; c++) p[c] = (float)(sky + L * cov);
      energy += L * cov * cv_latlong_pixel_solid_angle(y, w, h);
    }
  if (disc_energy) *disc_energy = energy;
  return env;
}

static void test_sun_synthetic(void **state) {
  (void)state;
  const int w = 1024, h = 512;
  double sd[3];
  dir_el_az(35.0, 120.0, sd);
  double pix_energy;
  cv_envmap *env = disc_map(w, h, 1.0, sd, 2.0, 5e4, &pix_energy);
  const double exact = 5e4 * 2.0 * M_PI * (1.0 - cos(rad(2.0)));
  cv_sun_info info;
  cv_envmap *res = NULL;
  assert_int_equal(cv_sun_extract(env, NULL, &info, &res), CV_OK);
  cv_sun_info_print(stdout, &info);
  assert_true(info.found);
  const double ang = angle_deg(info.dir, sd);
  double E = 0.0;
  for (int c = 0; c < 3; c++) E += info.rgb[c] / 3.0;
  printf("  synthetic sun: direction error %.3f deg (tol 1), energy %.3f vs disc %.3f (%.2f%%, tol "
         "2%%)\n",
         ang, E, exact, 100.0 * (E - exact) / exact);
  assert_true(ang < 1.0);
  assert_near(E, exact, 0.02 * exact);
  /* residual: no pixel above sky + 1%, and residual + sun = original */
  double maxr = 0.0, e_orig = 0.0, e_res = 0.0;
  for (int y = 0; y < h; y++) {
    const double sa = cv_latlong_pixel_solid_angle(y, w, h);
    for (int x = 0; x < w; x++) {
      const float *p = cv_image_at(res->img, x, y), *q = cv_image_at(env->img, x, y);
      maxr = fmax(maxr, fmax(p[0], fmax(p[1], p[2])));
      e_res += sa * p[1];
      e_orig += sa * q[1];
    }
  }
  printf("  residual max %.5f (tol 1.01); energy original %.4f = residual %.4f + sun %.4f\n", maxr,
         e_orig, e_res, info.rgb[1]);
  assert_true(maxr <= 1.01);
  assert_near(e_orig, (e_res + info.rgb[1]), 1e-5 * e_orig);
  assert_true(info.solid_angle < 0.01 && info.energy_fraction > 0.9);
  cv_envmap_destroy(res);
  cv_envmap_destroy(env);

  /* a sun straddling the seam behind the car and near the zenith */
  dir_el_az(80.0, 180.0, sd);
  env = disc_map(w, h, 1.0, sd, 2.0, 5e4, NULL);
  assert_int_equal(cv_sun_extract(env, NULL, &info, NULL), CV_OK);
  assert_true(info.found);
  E = info.rgb[1];
  printf("  sun across the seam at 80 deg: direction error %.3f deg, energy %.2f%%\n",
         angle_deg(info.dir, sd), 100.0 * (E - exact) / exact);
  assert_true(angle_deg(info.dir, sd) < 1.0);
  assert_near(E, exact, 0.02 * exact);
  cv_envmap_destroy(env);
}

static void test_sun_absent(void **state) {
  (void)state;
  cv_sun_info info;
  cv_envmap *env = NULL, *res = NULL;
  /* constant: no pixel above the threshold */
  assert_int_equal(cv_envmap_create(256, 128, &env), CV_OK);
  for (int i = 0; i < 256 * 128 * 3; i++) env->img->px[i] = 2.0f;
  assert_int_equal(cv_sun_extract(env, NULL, &info, &res), CV_OK);
  assert_false(info.found);
  assert_int_equal(info.pixels, 0);
  assert_memory_equal(res->img->px, env->img->px, sizeof(float) * 256 * 128 * 3);
  cv_envmap_destroy(res);
  cv_envmap_destroy(env);
  /* smooth gradient, bright towards the zenith (peak 400x the horizon): the
   * region above threshold is large, so not compact -> not a sun */
  assert_int_equal(cv_envmap_create(256, 128, &env), CV_OK);
  for (int y = 0; y < 128; y++)
    for (int x = 0; x < 256; x++) {
      double d[3];
      cv_latlong_pixel_dir(x, y, 256, 128, d);
      const double L = 1.0 + 400.0 * pow(fmax(d[1], 0.0), 8);
      for (int c = 0; c < 3; c++) cv_image_at(env->img, x, y)[c] = (float)L;
    }
  assert_int_equal(cv_sun_extract(env, NULL, &info, NULL), CV_OK);
  cv_sun_info_print(stdout, &info);
  assert_false(info.found);
  assert_true(info.solid_angle > 0.01);
  cv_envmap_destroy(env);
  /* compact but weak: a 1-degree disc of 100 on a sky of 1 (energy
   * fraction < 1%) */
  double sd[3];
  dir_el_az(20.0, -60.0, sd);
  env = disc_map(1024, 512, 1.0, sd, 1.0, 100.0, NULL);
  assert_int_equal(cv_sun_extract(env, NULL, &info, NULL), CV_OK);
  cv_sun_info_print(stdout, &info);
  assert_false(info.found);
  assert_true(info.solid_angle < 0.01 && info.energy_fraction < 0.05);
  /* the same with a lower energy bar is accepted */
  cv_sun_params p;
  cv_sun_params_default(&p);
  p.min_energy_fraction = 0.001;
  assert_int_equal(cv_sun_extract(env, &p, &info, NULL), CV_OK);
  assert_true(info.found);
  p.rel_threshold = 0.0;
  assert_int_equal(cv_sun_extract(env, &p, &info, NULL), CV_ERR_INVALID);
  cv_envmap_destroy(env);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_sky_zenith),   cmocka_unit_test(test_sky_range),
      cmocka_unit_test(test_sun_light),    cmocka_unit_test(test_sky_errors),
      cmocka_unit_test(test_envmap_basic), cmocka_unit_test(test_envmap_blend),
      cmocka_unit_test(test_car_rotation), cmocka_unit_test(test_envmap_rotate),
      cmocka_unit_test(test_sun_synthetic), cmocka_unit_test(test_sun_absent),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
