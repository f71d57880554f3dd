/* Drago et al. 2003 adaptive logarithmic tone mapping (see drago.h): the
 * CPU reference of the renderer's fragment shader and the `cave tonemap`
 * operator.  The per-pixel map uses the float constants of cv_drago_prepare
 * (the shader's uniforms) so CPU and GPU agree to float rounding. */
#include "tonemap/drago.h"

#include "core/status.h"
#include "tonemap/foveal.h"

#include <math.h>
#include <string.h>
#include <stddef.h>

void cv_drago_default(cv_drago *d) {
  d->bias = 0.85;
  d->ldmax = 100.0;
  d->lwa = 1.0;
  d->lwmax = 100.0;
}

void cv_drago_prepare(const cv_drago *d, cv_drago_consts *out) {
  double bias = d->bias, ldmax = d->ldmax, lwa = d->lwa, lwmax = d->lwmax;
  if (!(bias > 0.0 && bias < 1.0)) bias = 0.85;
  if (!(ldmax > 0.0) || !isfinite(ldmax)) ldmax = 100.0;
  /* All-black frames give lwa = 0 (or the eps floor); NaN must not propagate. */
  if (!(lwa > 0.0) || !isfinite(lwa)) lwa = CV_LUM_EPS;
  if (!isfinite(lwmax) || !(lwmax >= lwa * 1e-6)) lwmax = lwa;
  double ratio = lwmax / lwa;
  /* Keep lwmax_a representable as a float (beyond that the curve is a step). */
  if (ratio > 1e30) ratio = 1e30;
  out->lwa = (float)lwa;
  out->lwmax_a = (float)ratio;
  out->scale = (float)(ldmax * 0.01 / log10(ratio + 1.0));
  out->p_exp = (float)(log(bias) / log(0.5));
  out->ld_top = (float)(ldmax * 0.01 < 1.0 ? ldmax * 0.01 : 1.0);
}

double cv_drago_map(const cv_drago_consts *c, double lw) {
  const double top = (double)c->ld_top;
  if (!(lw > 0.0)) return 0.0; /* NaN, negative, zero */
  double x = lw / (double)c->lwa;
  /* At and beyond Lwmax the raw curve turns down again: saturate. */
  if (x >= (double)c->lwmax_a) return top;
  double ld = (double)c->scale * log1p(x) /
              log(2.0 + 8.0 * pow(x / (double)c->lwmax_a, (double)c->p_exp));
  /* Below Lwmax the raw curve overshoots Ld(Lwmax) once Lwmax/Lwa passes
   * ~2.2e5 (bias 0.85): the clamp keeps the map monotone. */
  if (!(ld > 0.0)) return 0.0;
  return ld < top ? ld : top;
}

double cv_rec709_transfer(double e) {
  if (!(e > 0.0)) return 0.0;
  if (e > 1.0) e = 1.0;
  return e <= 0.012 ? 6.75 * e : 1.099 * pow(e, 0.9 / 2.2) - 0.099;
}

uint8_t cv_rec709_code_exact(float e) {
  float t = (float)cv_rec709_transfer(e);
  t = t > 0 ? (t < 1 ? t : 1) : 0;
  return (uint8_t)lrintf(t * 255.0f);
}

static uint8_t rec709_bisect(const cv_rec709_lut *t, float e);

void cv_rec709_lut_init(cv_rec709_lut *t) {
  for (int k = 0; k < 255; k++) {
    /* smallest float e in (0, 1] with code > k: bisect on the float bits
     * (positive floats order as their bit patterns) */
    uint32_t lo = 0, hi = 0x3f800000u; /* 0 .. 1.0f; code(1) = 255 > k */
    while (hi - lo > 1) {
      uint32_t mid = lo + (hi - lo) / 2;
      float e;
      memcpy(&e, &mid, sizeof e);
      if (cv_rec709_code_exact(e) > k) hi = mid;
      else lo = mid;
    }
    memcpy(&t->step[k], &hi, sizeof hi);
  }
  t->step[255] = INFINITY;
  t->adv = 0;
  for (uint32_t b = 0; b < CV_REC709_BUCKETS; b++) {
    const uint32_t bits = b << CV_REC709_SHIFT, last = bits | ((1u << CV_REC709_SHIFT) - 1); /* the bucket's ends */
    float e, e1;
    memcpy(&e, &bits, sizeof e);
    memcpy(&e1, &last, sizeof e1);
    t->first[b] = rec709_bisect(t, e);
    const int a = (e1 >= 1.0f ? 255 : rec709_bisect(t, e1)) - t->first[b];
    if (a > t->adv) t->adv = (uint8_t)a;
  }
}

/* The number of steps <= e (the code of e > 0) by bisection. */
static uint8_t rec709_bisect(const cv_rec709_lut *t, float e) {
  int lo = 0, hi = 255;
  while (lo < hi) {
    int mid = (lo + hi) / 2;
    if (t->step[mid] <= e) lo = mid + 1;
    else hi = mid;
  }
  return (uint8_t)lo;
}

uint8_t cv_rec709_code(const cv_rec709_lut *t, float e) {
  if (!(e > 0)) return 0; /* NaN, 0, negative */
  if (e >= 1.0f) return 255;
  uint32_t bits;
  memcpy(&bits, &e, sizeof bits);
  unsigned k = t->first[bits >> CV_REC709_SHIFT]; /* steps <= the bucket's lower end */
  k += t->step[k] <= e; /* step[255] = +Inf: k stays <= 255 */
  if (t->adv > 1) /* not for this curve (init measures it); kept exact for any */
    while (t->step[k] <= e) k++;
  return (uint8_t)k;
}

void cv_rec709_codes(const cv_rec709_lut *t, const float *e, size_t n, uint8_t *out) {
  for (size_t i = 0; i < n; i++) out[i] = cv_rec709_code(t, e[i]);
}

static int finite_nonneg(float v) { return isfinite(v) && v >= 0.0f; }

int cv_drago_image_counts(const cv_image *in, const cv_drago *d, int apply_transfer,
                          cv_image *out, uint64_t *n_invalid, uint64_t *n_clamped) {
  if (n_invalid) *n_invalid = 0;
  if (n_clamped) *n_clamped = 0;
  if (!in || !d || !out || !in->px || !out->px || in->w <= 0 || in->h <= 0 ||
      out->w != in->w || out->h != in->h || out->c != in->c ||
      !(in->c == 1 || in->c == 3 || in->c == 4))
    return CV_ERR_INVALID;
  cv_drago_consts k;
  cv_drago_prepare(d, &k);
  const int w = in->w, h = in->h, c = in->c;
  uint64_t bad = 0, clamped = 0;
#pragma omp parallel for schedule(static) reduction(+ : bad, clamped)
  for (int y = 0; y < h; y++) {
    const float *src = cv_image_at(in, 0, y);
    float *dst = cv_image_at(out, 0, y);
    for (int x = 0; x < w; x++, src += c, dst += c) {
      int nc = c == 1 ? 1 : 3;
      int ok = 1;
      for (int i = 0; i < c; i++) ok &= finite_nonneg(src[i]);
      if (!ok) {
        bad++;
        for (int i = 0; i < c; i++) dst[i] = 0.0f;
        continue;
      }
      double v[3];
      if (nc == 1) {
        v[0] = cv_drago_map(&k, src[0]);
      } else {
        double r = src[0], g = src[1], b = src[2];
        double lw = 0.2126 * r + 0.7152 * g + 0.0722 * b;
        double ld = cv_drago_map(&k, lw);
        double s = lw > 0.0 ? ld / lw : 0.0;
        v[0] = r * s;
        v[1] = g * s;
        v[2] = b * s;
      }
      int cl = 0;
      for (int i = 0; i < nc; i++) {
        double e = v[i];
        if (!(e <= 1.0)) { /* saturated colour after the Ld/Lw ratio */
          e = 1.0;
          cl = 1;
        }
        dst[i] = (float)(apply_transfer ? cv_rec709_transfer(e) : e);
      }
      if (c == 4) dst[3] = src[3];
      clamped += (uint64_t)cl;
    }
  }
  if (n_invalid) *n_invalid = bad;
  if (n_clamped) *n_clamped = clamped;
  return CV_OK;
}

int cv_drago_image(const cv_image *in, const cv_drago *d, int apply_transfer, cv_image *out,
                   uint64_t *n_invalid) {
  return cv_drago_image_counts(in, d, apply_transfer, out, n_invalid, NULL);
}
