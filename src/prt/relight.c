/* CPU relighting (see relight.h). */
#include "prt/relight.h"

#include <math.h>
#include <string.h>

#include "sh/sh.h"

int cv_prt_relight(const cv_prt *p, const cv_lighting *l, const cv_tracer *tr, int sun_samples,
                   float *out_rgb, cv_relight_stats *stats) {
  return cv_prt_relight_ex(p, l, NULL, 0, tr, sun_samples, out_rgb, stats);
}

int cv_split_direct(const cv_prt *p, const cv_tracer *tr, const cv_dir_light *extra,
                    int n_extra, int sun_samples, float *out_rgb) {
  if (n_extra < 0 || (n_extra > 0 && (!extra || !tr))) return CV_ERR_INVALID;
  for (int k = 0; k < n_extra; k++) {
    int st = cv_sun_direct(tr, extra[k].dir, extra[k].E, sun_samples, p->meta.seed + 1u + (uint32_t)k,
                           out_rgb);
    if (st) return st;
  }
  return CV_OK;
}

void cv_relight_opts_default(cv_relight_opts *o) {
  o->sun_samples = 16;
  o->split_samples = CV_SPLIT_SAMPLES_DEFAULT;
  o->sun_direct = 1;
  o->extra_direct = 1;
  o->clamp = 1;
}

int cv_prt_relight_ex(const cv_prt *p, const cv_lighting *l, const cv_dir_light *extra,
                      int n_extra, const cv_tracer *tr, int sun_samples, float *out_rgb,
                      cv_relight_stats *stats) {
  cv_relight_opts o;
  cv_relight_opts_default(&o);
  o.sun_samples = o.split_samples = sun_samples;
  return cv_prt_relight_opt(p, l, extra, n_extra, tr, &o, out_rgb, stats);
}

int cv_prt_relight_opt(const cv_prt *p, const cv_lighting *l, const cv_dir_light *extra,
                       int n_extra, const cv_tracer *tr, const cv_relight_opts *o,
                       float *out_rgb, cv_relight_stats *stats) {
  if ((uint32_t)l->bands < p->bands) return CV_ERR_RANGE;
  if (n_extra < 0 || (n_extra > 0 && (!extra || !tr))) return CV_ERR_INVALID;
  const int nc = (int)(p->bands * p->bands);
  /* Lighting as planar [c][i] in the PRT's band count. */
  double L[3][CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS], S[3][CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS];
  for (int c = 0; c < 3; c++)
    for (int i = 0; i < nc; i++) {
      L[c][i] = l->sh[3 * i + c];
      S[c][i] = 0;
    }
  if (l->has_sun) {
    /* A directional light of irradiance E is E * delta(w - s); its SH
     * projection is E * y_i(s).  Used only with the indirect transfer, which
     * is smooth, so the truncation's ringing stays small there. */
    double y[CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS];
    cv_sh_eval_d((int)p->bands, l->sun_dir, y);
    for (int c = 0; c < 3; c++)
      for (int i = 0; i < nc; i++) S[c][i] = l->sun_E[c] * y[i];
  }
  for (int k = 0; k < n_extra; k++) { /* extra lights: indirect as the sun's */
    double y[CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS];
    cv_sh_eval_d((int)p->bands, extra[k].dir, y);
    for (int c = 0; c < 3; c++)
      for (int i = 0; i < nc; i++) S[c][i] += extra[k].E[c] * y[i];
  }
  const size_t nv = p->nv;
#pragma omp parallel for schedule(static)
  for (size_t v = 0; v < nv; v++) {
    const float *td = p->td + v * nc;
    for (int c = 0; c < 3; c++) {
      double d = 0, ind = 0;
      for (int i = 0; i < nc; i++) d += L[c][i] * td[i];
      d *= p->albedo[3 * v + c];
      if (p->ti) {
        const float *ti = p->ti + (v * 3 + c) * nc;
        for (int i = 0; i < nc; i++) ind += (L[c][i] + S[c][i]) * ti[i];
      }
      out_rgb[3 * v + c] = (float)(d + ind);
    }
  }
  if (l->has_sun && tr && o->sun_direct) {
    int st = cv_sun_direct(tr, l->sun_dir, l->sun_E, o->sun_samples, p->meta.seed, out_rgb);
    if (st) return st;
  }
  if (n_extra > 0 && o->extra_direct) {
    int st = cv_split_direct(p, tr, extra, n_extra, o->split_samples, out_rgb);
    if (st) return st;
  }
  cv_relight_stats s = {0, 0};
  for (size_t i = 0; i < 3 * nv; i++) {
    if (!isfinite(out_rgb[i])) {
      out_rgb[i] = 0;
      s.nonfinite++;
    } else if (out_rgb[i] < 0) {
      if (o->clamp) out_rgb[i] = 0;
      s.clamped_negative++;
    }
  }
  if (stats) *stats = s;
  return CV_OK;
}
