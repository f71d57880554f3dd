/* Absolute light, illuminance at the eye, the verdict (light_level.h). */
#include "lcd/light_level.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "light/calibrate.h"
#include "light/envmap.h"
#include "rt/rt.h"

void cv_lcd_calibration(const cv_light_spec *spec, const char *origin, cv_lcd_calib *out) {
  memset(out, 0, sizeof *out);
  const char *o = origin && *origin ? origin : "lighting";
  switch (spec->kind) {
  case CV_LIGHT_SKY:
    out->absolute = 1;
    snprintf(out->source, sizeof out->source, "%.200s: Preetham sky (cd/m2, its sun in lx)", o);
    return;
  case CV_LIGHT_CONSTANT:
    out->absolute = 1;
    snprintf(out->source, sizeof out->source, "%.200s: constant environment taken as cd/m2", o);
    return;
  case CV_LIGHT_ENV:
    break;
  default:
    snprintf(out->source, sizeof out->source, "%.200s: no lighting", o);
    return;
  }
  const char *map = spec->n_env > 0 ? spec->env[0] : "(no map)";
  const char *base = strrchr(map, '/') ? strrchr(map, '/') + 1 : map;
  if (spec->illuminance > 0) {
    out->absolute = 1;
    snprintf(out->source, sizeof out->source, "%.200s: illuminance %g lx", o, spec->illuminance);
  } else if (spec->illuminance == CV_ILLUMINANCE_AUTO) {
    out->absolute = out->assumed = 1;
    snprintf(out->source, sizeof out->source,
             "%.200s: illuminance auto: ASSUMED blender-data level of %.200s, %g lx (a representative "
             "value, not a measurement)",
             o, base, cv_blender_map_default_lux(map));
  } else if (spec->absolute) {
    out->absolute = 1;
    snprintf(out->source, sizeof out->source, "%.200s: scale %g declared absolute (\"absolute\": true)",
             o, spec->scale);
  } else {
    snprintf(out->source, sizeof out->source,
             "%.200s: %.200s in its own relative units (scale %g): uncalibrated; give --illuminance LUX",
             o, base, spec->scale);
  }
}

double cv_lcd_outdoor_illuminance(const cv_lcd_light *l) {
  double E = l->env ? cv_envmap_horizontal_illuminance(l->env) : 0;
  if (l->has_sun && l->sun_dir[1] > 0)
    E += cv_luminance(l->sun_E[0], l->sun_E[1], l->sun_E[2]) * l->sun_dir[1];
  return E > 0 && isfinite(E) ? E : 0;
}

/* A uniform number in [0, 1) from (plane, i, j): the jitter (splitmix64). */
static double jitter(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  x ^= x >> 31;
  return (double)(x >> 11) * 0x1p-53;
}

#define STRATA 128

/* Illuminance on the plane with unit normal n at eye: cosine-weighted
 * stratified directions (E = pi mean L), the strata's spread as the error
 * (pairs of neighbouring strata, as the veil), plus the visible sun. */
static void plane_illuminance(const cv_lcd_gather *g, const cv_lcd_light *l, const float eye[3],
                              const double n[3], uint64_t seed, double *E, double *se) {
  double t[3] = {1, 0, 0};
  if (fabs(n[0]) > 0.9) t[0] = 0, t[1] = 1;
  double b[3] = {n[1] * t[2] - n[2] * t[1], n[2] * t[0] - n[0] * t[2], n[0] * t[1] - n[1] * t[0]};
  const double bl = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
  for (int k = 0; k < 3; k++) b[k] /= bl;
  const double u[3] = {b[1] * n[2] - b[2] * n[1], b[2] * n[0] - b[0] * n[2], b[0] * n[1] - b[1] * n[0]};
  double sum = 0, var = 0;
  for (int i = 0; i < STRATA; i++) {
    double prev = 0;
    for (int j = 0; j < STRATA; j++) {
      const uint64_t id = (seed << 32) ^ ((uint64_t)i << 16) ^ (uint64_t)j;
      const double s = (i + jitter(2 * id)) / STRATA, p = 2 * M_PI * (j + jitter(2 * id + 1)) / STRATA;
      const double r = sqrt(s), z = sqrt(1 - s), x = r * cos(p), y = r * sin(p);
      float d[3], rgb[3];
      for (int k = 0; k < 3; k++) d[k] = (float)(x * u[k] + y * b[k] + z * n[k]);
      cv_lcd_eye_radiance(g, l, eye, d, rgb);
      const double L = cv_luminance(rgb[0], rgb[1], rgb[2]);
      sum += L;
      if (j % 2) var += (L - prev) * (L - prev); /* a pair of neighbouring strata */
      prev = L;
    }
  }
  const double N = (double)STRATA * STRATA;
  /* each stratum's variance ~ (a - b)^2 / 2 from its pair, two strata per
   * pair: var(mean) = sum over pairs of (a - b)^2 / N^2 (slightly
   * conservative, as the veil's) */
  *E = M_PI * sum / N;
  *se = M_PI * sqrt(var) / N;
  if (l->has_sun && cv_lcd_sun_visible(g, l, eye)) {
    const double c = l->sun_dir[0] * n[0] + l->sun_dir[1] * n[1] + l->sun_dir[2] * n[2];
    if (c > 0) *E += cv_luminance(l->sun_E[0], l->sun_E[1], l->sun_E[2]) * c;
  }
}

void cv_lcd_illuminance(const cv_lcd_gather *g, const cv_lcd_light *l, const float eye[3],
                        cv_lcd_illum *out) {
  memset(out, 0, sizeof *out);
  cv_rt_thread_init();
  out->outdoor_h = cv_lcd_outdoor_illuminance(l);
  static const double up[3] = {0, 1, 0}, ahead[3] = {0, 0, -1};
  plane_illuminance(g, l, eye, up, 1, &out->eye_h, &out->eye_h_se);
  plane_illuminance(g, l, eye, ahead, 2, &out->eye_v, &out->eye_v_se);
}

cv_lcd_verdict_kind cv_lcd_verdict(const cv_lcd_readability *rd, const cv_lcd_read_params *p,
                                   int absolute, char *why, size_t why_n) {
  char tmp[8];
  if (!why) why = tmp, why_n = sizeof tmp;
  if (!absolute) {
    snprintf(why, why_n, "uncalibrated light");
    return CV_LCD_UNCALIBRATED;
  }
  if (rd->cr_mean.value < p->cr_min) {
    snprintf(why, why_n, "CR %.3g < %g", rd->cr_mean.value, p->cr_min);
    return CV_LCD_UNREADABLE;
  }
  if (rd->frac_ok.value < p->area_min) {
    snprintf(why, why_n, "%.1f%% of the area meets %g:1 < %.0f%%", 100 * rd->frac_ok.value,
             p->cr_min, 100 * p->area_min);
    return CV_LCD_UNREADABLE;
  }
  if (rd->vl.value < p->vl_min) {
    snprintf(why, why_n, "VL %.3g < %g", rd->vl.value, p->vl_min);
    return CV_LCD_UNREADABLE;
  }
  snprintf(why, why_n, "CR %.3g >= %g, %.1f%% of the area >= %.0f%%, VL %.3g >= %g",
           rd->cr_mean.value, p->cr_min, 100 * rd->frac_ok.value, 100 * p->area_min, rd->vl.value,
           p->vl_min);
  return CV_LCD_READABLE;
}

const char *cv_lcd_verdict_name(cv_lcd_verdict_kind v) {
  return v == CV_LCD_READABLE ? "READABLE" : v == CV_LCD_UNREADABLE ? "UNREADABLE" : "uncalibrated";
}
