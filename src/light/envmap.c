/* Lat-long HDR environment maps: load, lookup, blend, rotate, project (see
 * envmap.h). */
#include "light/envmap.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "io/exr.h"
#include "sh/latlong.h"
#include "sh/sh.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

int cv_envmap_create(int w, int h, cv_envmap **out) {
  if (!out) return CV_ERR_INVALID;
  *out = NULL;
  if (w < 1 || h < 2) return CV_ERR_INVALID;
  cv_envmap *env = calloc(1, sizeof *env);
  if (!env) return CV_ERR_NOMEM;
  const int st = cv_image_create(w, h, 3, &env->img);
  if (st != CV_OK) {
    free(env);
    return st;
  }
  *out = env;
  return CV_OK;
}

void cv_envmap_destroy(cv_envmap *env) {
  if (!env) return;
  cv_image_destroy(env->img);
  free(env);
}

int cv_envmap_from_image(const cv_image *img, cv_envmap **out, cv_err *err) {
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "environment map: no output pointer");
  *out = NULL;
  if (!img || !img->px)
    return cv_err_set(err, CV_ERR_INVALID, "environment map: no image");
  if (img->c != 1 && img->c != 3 && img->c != 4)
    return cv_err_set(err, CV_ERR_INVALID,
                      "environment map: %d channels, expected 1 (grey), 3 (RGB) or 4 (RGBA)",
                      img->c);
  if (img->w < 1 || img->h < 2)
    return cv_err_set(err, CV_ERR_INVALID,
                      "environment map: %d x %d pixels, expected a lat-long map at least 2 high",
                      img->w, img->h);
  cv_envmap *env = NULL;
  int st = cv_envmap_create(img->w, img->h, &env);
  if (st != CV_OK) return cv_err_set(err, st, "environment map: %s", cv_status_str(st));
  const size_t np = (size_t)img->w * (size_t)img->h;
  for (size_t i = 0; i < np; i++) {
    const float *s = img->px + i * (size_t)img->c;
    float *d = env->img->px + 3 * i;
    for (int ch = 0; ch < 3; ch++) {
      const float v = s[img->c == 1 ? 0 : ch];
      if (!isfinite(v)) {
        static const char names[] = "RGB";
        cv_envmap_destroy(env);
        return cv_err_set(err, CV_ERR_NONFINITE,
                          "environment map: pixel (%zu, %zu) channel %c is %s",
                          i % (size_t)img->w, i / (size_t)img->w,
                          img->c == 1 ? 'Y' : names[ch], isnan(v) ? "NaN" : "Inf");
      }
      if (v < 0.0f) {
        d[ch] = 0.0f;
        env->negative_clamped++;
      } else {
        d[ch] = v;
      }
    }
  }
  *out = env;
  return CV_OK;
}

int cv_envmap_clone(const cv_envmap *env, cv_envmap **out) {
  if (!out) return CV_ERR_INVALID;
  *out = NULL;
  if (!env || !env->img) return CV_ERR_INVALID;
  cv_envmap *c = NULL;
  const int st = cv_envmap_create(env->img->w, env->img->h, &c);
  if (st != CV_OK) return st;
  memcpy(c->img->px, env->img->px, sizeof(float) * 3 * (size_t)env->img->w * (size_t)env->img->h);
  c->negative_clamped = env->negative_clamped;
  *out = c;
  return CV_OK;
}

int cv_envmap_load(const char *path, cv_envmap **out, cv_err *err) {
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "environment map: no output pointer");
  *out = NULL;
  if (!path) return cv_err_set(err, CV_ERR_INVALID, "environment map: no path");
  cv_image *img = NULL;
  cv_exr_read_info info;
  memset(&info, 0, sizeof info);
  int st = cv_exr_read_ex(path, &img, &info, err);
  if (st != CV_OK) return st;
  if (img->h < 2) {
    st = cv_err_set(err, CV_ERR_FORMAT,
                    "%s: environment map is %d x %d pixels, expected a lat-long map at least 2 "
                    "pixels high",
                    path, img->w, img->h);
    cv_image_destroy(img);
    return st;
  }
  /* the reader returns RGB float, finite: adopt the image without a copy */
  cv_envmap *env = calloc(1, sizeof *env);
  if (!env) {
    cv_image_destroy(img);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  }
  if (img->c != 3) { /* defensive: the reader promises RGB */
    cv_envmap *conv = NULL;
    st = cv_envmap_from_image(img, &conv, err);
    cv_image_destroy(img);
    free(env);
    if (st != CV_OK) return cv_err_prefix(err, "%s", path);
    conv->negative_clamped += info.negative_clamped;
    *out = conv;
    return CV_OK;
  }
  env->img = img;
  env->negative_clamped = info.negative_clamped;
  *out = env;
  return CV_OK;
}

/* Bilinear sample between pixel centres at (u, v); u wraps, v clamps. */
static void sample_img(const cv_image *img, double u, double v, float rgb[3]) {
  const int w = img->w, h = img->h;
  if (!isfinite(u) || !isfinite(v)) {
    rgb[0] = rgb[1] = rgb[2] = 0.0f;
    return;
  }
  const double fx = u * w - 0.5, fy = v * h - 0.5;
  const double flx = floor(fx), fly = floor(fy);
  const double tx = fx - flx;
  double ty = fy - fly;
  long x0 = (long)fmod(flx, (double)w);
  if (x0 < 0) x0 += w;
  const long x1 = (x0 + 1 == w) ? 0 : x0 + 1;
  long y0 = (long)fly, y1 = y0 + 1;
  if (y0 < 0) {
    y0 = y1 = 0;
    ty = 0.0;
  } else if (y1 >= h) {
    y0 = y1 = h - 1;
    ty = 0.0;
  }
  const float *p00 = cv_image_at(img, (int)x0, (int)y0), *p10 = cv_image_at(img, (int)x1, (int)y0);
  const float *p01 = cv_image_at(img, (int)x0, (int)y1), *p11 = cv_image_at(img, (int)x1, (int)y1);
  for (int c = 0; c < 3; c++) {
    const double a = p00[c] + tx * (p10[c] - p00[c]);
    const double b = p01[c] + tx * (p11[c] - p01[c]);
    rgb[c] = (float)(a + ty * (b - a));
  }
}

void cv_envmap_sample_uv(const cv_envmap *env, double u, double v, float rgb[3]) {
  sample_img(env->img, u, v, rgb);
}

void cv_envmap_lookup(const cv_envmap *env, const float d[3], float rgb[3]) {
  const double dd[3] = {d[0], d[1], d[2]};
  if (!isfinite(dd[0]) || !isfinite(dd[1]) || !isfinite(dd[2]) ||
      (dd[0] == 0.0 && dd[1] == 0.0 && dd[2] == 0.0)) {
    rgb[0] = rgb[1] = rgb[2] = 0.0f;
    return;
  }
  double u, v;
  cv_latlong_uv(dd, &u, &v);
  sample_img(env->img, u, v, rgb);
}

int cv_envmap_blend(const cv_envmap *const *maps, const double *weights, int count, int out_w,
                    int out_h, cv_envmap **out, cv_err *err) {
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "blend: no output pointer");
  *out = NULL;
  if (!maps || !weights || count < 1)
    return cv_err_set(err, CV_ERR_INVALID, "blend: %d maps, expected at least 1", count);
  if (out_w < 1 || out_h < 2)
    return cv_err_set(err, CV_ERR_INVALID, "blend: output size %d x %d, expected w >= 1, h >= 2",
                      out_w, out_h);
  for (int k = 0; k < count; k++) {
    if (!maps[k] || !maps[k]->img)
      return cv_err_set(err, CV_ERR_INVALID, "blend: map %d is missing", k);
    if (!isfinite(weights[k]) || weights[k] < 0.0)
      return cv_err_set(err, CV_ERR_INVALID, "blend: weight %d is %g, expected finite and >= 0",
                        k, weights[k]);
  }
  cv_envmap *res = NULL;
  int st = cv_envmap_create(out_w, out_h, &res);
  if (st != CV_OK) return cv_err_set(err, st, "blend: %s", cv_status_str(st));
#pragma omp parallel for schedule(static)
  for (int y = 0; y < out_h; y++) {
    for (int x = 0; x < out_w; x++) {
      double acc[3] = {0.0, 0.0, 0.0};
      for (int k = 0; k < count; k++) {
        const cv_image *src = maps[k]->img;
        const double wk = weights[k];
        if (wk == 0.0) continue;
        if (src->w == out_w && src->h == out_h) {
          const float *p = cv_image_at(src, x, y);
          for (int c = 0; c < 3; c++) acc[c] += wk * p[c];
          continue;
        }
        const int sx = (src->w + out_w - 1) / out_w, sy = (src->h + out_h - 1) / out_h;
        double s[3] = {0.0, 0.0, 0.0};
        for (int j = 0; j < sy; j++)
          for (int i = 0; i < sx; i++) {
            float rgb[3];
            sample_img(src, (x + (i + 0.5) / sx) / out_w, (y + (j + 0.5) / sy) / out_h, rgb);
            for (int c = 0; c < 3; c++) s[c] += rgb[c];
          }
        const double norm = wk / ((double)sx * sy);
        for (int c = 0; c < 3; c++) acc[c] += norm * s[c];
      }
      float *o = cv_image_at(res->img, x, y);
      for (int c = 0; c < 3; c++) o[c] = (float)acc[c];
    }
  }
  *out = res;
  return CV_OK;
}

void cv_car_rotation(double yaw_deg, double pitch_deg, double roll_deg, double R[9]) {
  const double k = M_PI / 180.0;
  const double cy = cos(yaw_deg * k), sy = sin(yaw_deg * k);
  const double cp = cos(pitch_deg * k), sp = sin(pitch_deg * k);
  const double cr = cos(roll_deg * k), sr = sin(roll_deg * k);
  /* right-handed rotations about +Y, +X, and about -Z (= about +Z by -roll) */
  const double Ry[9] = {cy, 0, sy, 0, 1, 0, -sy, 0, cy};
  const double Rx[9] = {1, 0, 0, 0, cp, -sp, 0, sp, cp};
  const double Rz[9] = {cr, sr, 0, -sr, cr, 0, 0, 0, 1};
  double T[9];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++)
      T[3 * i + j] = Rx[3 * i] * Rz[j] + Rx[3 * i + 1] * Rz[3 + j] + Rx[3 * i + 2] * Rz[6 + j];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++)
      R[3 * i + j] = Ry[3 * i] * T[j] + Ry[3 * i + 1] * T[3 + j] + Ry[3 * i + 2] * T[6 + j];
}

static int is_rotation(const double R[9]) {
  for (int k = 0; k < 9; k++)
    if (!isfinite(R[k])) return 0;
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      double dot = 0.0;
      for (int k = 0; k < 3; k++) dot += R[3 * i + k] * R[3 * j + k];
      if (fabs(dot - (i == j ? 1.0 : 0.0)) > 1e-6) return 0;
    }
  const double det = R[0] * (R[4] * R[8] - R[5] * R[7]) - R[1] * (R[3] * R[8] - R[5] * R[6]) +
                     R[2] * (R[3] * R[7] - R[4] * R[6]);
  return det > 0.0;
}

int cv_envmap_rotate(const cv_envmap *env, const double R[9], cv_envmap **out) {
  if (!out) return CV_ERR_INVALID;
  *out = NULL;
  if (!env || !env->img || !R || !is_rotation(R)) return CV_ERR_INVALID;
  const int w = env->img->w, h = env->img->h;
  cv_envmap *res = NULL;
  const int st = cv_envmap_create(w, h, &res);
  if (st != CV_OK) return st;
  res->negative_clamped = env->negative_clamped;
#pragma omp parallel for schedule(static)
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      double d[3], e[3], u, v;
      cv_latlong_pixel_dir(x, y, w, h, d);
      for (int i = 0; i < 3; i++) e[i] = R[3 * i] * d[0] + R[3 * i + 1] * d[1] + R[3 * i + 2] * d[2];
      cv_latlong_uv(e, &u, &v);
      sample_img(env->img, u, v, cv_image_at(res->img, x, y));
    }
  *out = res;
  return CV_OK;
}

int cv_envmap_project_sh(const cv_envmap *env, int n, double *coeffs) {
  if (!env || !env->img) return CV_ERR_INVALID;
  return cv_sh_project_latlong(env->img, n, coeffs);
}
