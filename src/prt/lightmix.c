/* Per-frame lighting from preprocessed maps: see lightmix.h. */
#include "prt/lightmix.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "io/scene_config.h"
#include "light/calibrate.h"
#include "light/envmap.h"
#include "light/sun.h"
#include "sh/sh.h"

typedef struct mixmap {
  cv_envmap *env;     /* scaled, sun included (backgrounds) */
  double sh[3 * 64];  /* residual (sun removed) in the world frame */
  int has_sun;
  double sun_dir[3];  /* world */
  double sun_E[3];
} mixmap;

struct cv_lightmix {
  int n, bands;
  mixmap *maps;
};

void cv_lightmix_destroy(cv_lightmix *m) {
  if (!m) return;
  for (int i = 0; i < m->n; i++) cv_envmap_destroy(m->maps[i].env);
  free(m->maps);
  free(m);
}

int cv_lightmix_count(const cv_lightmix *m) { return m ? m->n : 0; }

int cv_lightmix_create(const char *const *paths, int n, double scale, int bands,
                       cv_lightmix **out, cv_err *err) {
  return cv_lightmix_create_calibrated(paths, n, scale, 0.0, bands, out, err);
}

int cv_lightmix_create_calibrated(const char *const *paths, int n, double scale,
                                  double illuminance, int bands, cv_lightmix **out, cv_err *err) {
  *out = NULL;
  if (!paths || n < 1 || !(scale > 0) || bands < 2 || bands > 8 ||
      (illuminance != 0 && scale != 1.0))
    return cv_err_set(err, CV_ERR_INVALID, "lightmix: %d maps, scale %g, illuminance %g, %d bands",
                      n, scale, illuminance, bands);
  cv_lightmix *m = calloc(1, sizeof *m);
  if (!m) return cv_err_set(err, CV_ERR_NOMEM, "lightmix: out of memory");
  m->maps = calloc((size_t)n, sizeof *m->maps);
  if (!m->maps) {
    free(m);
    return cv_err_set(err, CV_ERR_NOMEM, "lightmix: out of memory");
  }
  m->n = n;
  m->bands = bands;
  for (int i = 0; i < n; i++) {
    mixmap *mm = &m->maps[i];
    int st = cv_envmap_load(paths[i], &mm->env, err);
    if (st) {
      cv_lightmix_destroy(m);
      return st;
    }
    double f = scale;
    if (illuminance != 0 && (st = cv_envmap_calibration(paths[i], mm->env, illuminance, &f, err))) {
      cv_lightmix_destroy(m);
      return st;
    }
    if (f != 1.0) {
      size_t k = (size_t)mm->env->img->w * mm->env->img->h * 3;
      for (size_t j = 0; j < k; j++) mm->env->img->px[j] *= (float)f;
    }
    cv_sun_params sp;
    cv_sun_params_default(&sp);
    cv_sun_info si;
    cv_envmap *residual = NULL;
    st = cv_sun_extract(mm->env, &sp, &si, &residual);
    if (st) {
      cv_lightmix_destroy(m);
      return cv_err_set(err, st, "sun extraction failed on %s", paths[i]);
    }
    const cv_envmap *proj = mm->env;
    if (si.found) {
      mm->has_sun = 1;
      memcpy(mm->sun_dir, si.dir, sizeof si.dir);
      memcpy(mm->sun_E, si.rgb, sizeof si.rgb);
      proj = residual;
    }
    st = cv_envmap_project_sh(proj, bands, mm->sh);
    cv_envmap_destroy(residual);
    if (st) {
      cv_lightmix_destroy(m);
      return cv_err_set(err, st, "SH projection of %s failed", paths[i]);
    }
  }
  *out = m;
  return CV_OK;
}

static int norm_weights(const cv_lightmix *m, const double *w, double *wn) {
  double s = 0;
  for (int i = 0; i < m->n; i++) {
    if (!(w[i] >= 0) || !isfinite(w[i])) return CV_ERR_INVALID;
    s += w[i];
  }
  if (!(s > 0)) return CV_ERR_INVALID;
  for (int i = 0; i < m->n; i++) wn[i] = w[i] / s;
  return CV_OK;
}

int cv_lightmix_lighting(const cv_lightmix *m, const double *w, double yaw_deg, double pitch_deg,
                         double roll_deg, cv_lighting *out) {
  if (!m || !w || !out) return CV_ERR_INVALID;
  double *wn = malloc((size_t)m->n * sizeof *wn);
  if (!wn) return CV_ERR_NOMEM;
  int st = norm_weights(m, w, wn);
  if (st) {
    free(wn);
    return st;
  }
  const int nc = m->bands * m->bands;
  double world[3 * 64] = {0};
  int best = -1;
  double best_y = 0;
  for (int i = 0; i < m->n; i++) {
    if (wn[i] == 0) continue;
    for (int k = 0; k < 3 * nc; k++) world[k] += wn[i] * m->maps[i].sh[k];
    if (m->maps[i].has_sun) {
      const double *E = m->maps[i].sun_E;
      const double y = wn[i] * cv_luminance(E[0], E[1], E[2]);
      if (y > best_y) {
        best_y = y;
        best = i;
      }
    }
  }
  /* The other suns as delta lights in the SH: coefficients w E y(d). */
  double y[64];
  for (int i = 0; i < m->n; i++) {
    if (i == best || wn[i] == 0 || !m->maps[i].has_sun) continue;
    cv_sh_eval_d(m->bands, m->maps[i].sun_dir, y);
    for (int k = 0; k < nc; k++)
      for (int c = 0; c < 3; c++) world[3 * k + c] += wn[i] * m->maps[i].sun_E[c] * y[k];
  }
  /* Into the car frame: f_car(d) = f_world(R d), i.e. rotated by R^T. */
  double R[9], Rt[9];
  cv_car_rotation(yaw_deg, pitch_deg, roll_deg, R);
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) Rt[3 * i + j] = R[3 * j + i];
  cv_sh_rotation *rot;
  if ((st = cv_sh_rotation_create(m->bands, Rt, &rot))) {
    free(wn);
    return st;
  }
  memset(out, 0, sizeof *out);
  cv_sh_rotate(rot, world, out->sh, 3);
  cv_sh_rotation_destroy(rot);
  out->bands = m->bands;
  if (best >= 0) {
    const mixmap *mm = &m->maps[best];
    out->has_sun = 1;
    for (int i = 0; i < 3; i++) {
      out->sun_dir[i] = R[i] * mm->sun_dir[0] + R[3 + i] * mm->sun_dir[1] + R[6 + i] * mm->sun_dir[2];
      out->sun_E[i] = wn[best] * mm->sun_E[i];
    }
  }
  free(wn);
  return CV_OK;
}

int cv_lightmix_background(const cv_lightmix *m, const double *w, double yaw_deg,
                           double pitch_deg, double roll_deg, int width, cv_image **out) {
  *out = NULL;
  if (!m || !w || width < 2) return CV_ERR_INVALID;
  double wn[64];
  if (m->n > 64) return CV_ERR_INVALID;
  int st = norm_weights(m, w, wn);
  if (st) return st;
  double R[9];
  cv_car_rotation(yaw_deg, pitch_deg, roll_deg, R);
  const int h = width / 2;
  cv_image *img;
  if ((st = cv_image_create(width, h, 3, &img))) return st;
#pragma omp parallel for schedule(static)
  for (int yy = 0; yy < h; yy++) {
    const double th = M_PI * (yy + 0.5) / h;
    for (int x = 0; x < width; x++) {
      const double a = 2 * M_PI * ((x + 0.5) / width - 0.5);
      const double d[3] = {sin(th) * sin(a), cos(th), -sin(th) * cos(a)};
      float wd[3];
      for (int i = 0; i < 3; i++) wd[i] = (float)(R[3 * i] * d[0] + R[3 * i + 1] * d[1] + R[3 * i + 2] * d[2]);
      double acc[3] = {0, 0, 0};
      for (int k = 0; k < m->n; k++) {
        if (wn[k] == 0) continue;
        float rgb[3];
        cv_envmap_lookup(m->maps[k].env, wd, rgb);
        for (int c = 0; c < 3; c++) acc[c] += wn[k] * rgb[c];
      }
      float *px = cv_image_at(img, x, yy);
      for (int c = 0; c < 3; c++) px[c] = (float)acc[c];
    }
  }
  *out = img;
  return CV_OK;
}
