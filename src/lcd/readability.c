/* Readability figures of the LCD panel (see readability.h). */
#include "lcd/readability.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/hash.h"

#define DEG (M_PI / 180.0)

/* --- disability glare ------------------------------------------------------ */

double cv_cie_glare(double th, double age, double p) {
  if (!(th >= CV_GLARE_THETA_MIN_DEG && th <= CV_GLARE_THETA_MAX_DEG)) return 0;
  const double a = age / 62.5, a4 = a * a * a * a;
  return 10.0 / (th * th * th) + (5.0 / (th * th) + 0.1 * p / th) * (1.0 + a4) + 0.0025 * p;
}

void cv_lcd_veil_params_default(cv_lcd_veil_params *p) {
  p->age = 40;
  p->pigment = 0.5;
  p->rows = 48;
  p->cols = 96;
  p->spc = 4;
  p->seed = 1;
}

/* splitmix64: the sample stream of one cell. */
static uint64_t mix_next(uint64_t *s) {
  uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
static double mix_uniform(uint64_t *s) { return (double)(mix_next(s) >> 11) * 0x1p-53; }

/* Two unit vectors completing gaze to an orthonormal frame. */
static void frame_of(const double n[3], double t1[3], double t2[3]) {
  const double a[3] = {fabs(n[0]) < 0.9 ? 1.0 : 0.0, fabs(n[0]) < 0.9 ? 0.0 : 1.0, 0.0};
  t1[0] = a[1] * n[2] - a[2] * n[1];
  t1[1] = a[2] * n[0] - a[0] * n[2];
  t1[2] = a[0] * n[1] - a[1] * n[0];
  const double l = sqrt(t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]);
  for (int k = 0; k < 3; k++) t1[k] /= l;
  t2[0] = n[1] * t1[2] - n[2] * t1[1];
  t2[1] = n[2] * t1[0] - n[0] * t1[2];
  t2[2] = n[0] * t1[1] - n[1] * t1[0];
}

static int unit_ok(const double d[3]) {
  const double l = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  return isfinite(l) && fabs(l - 1.0) < 1e-6;
}

int cv_lcd_veil(const double gaze[3], const cv_lcd_veil_params *p, cv_lcd_luminance_fn fn,
                void *ctx, const cv_lcd_point_source *src, int nsrc, cv_lcd_figure *lv) {
  lv->value = lv->se = 0;
  if (!p || !gaze || !unit_ok(gaze) || !(p->age >= 0) || !isfinite(p->age) ||
      !(p->pigment >= 0 && p->pigment <= 1) || p->rows < 1 || p->cols < 1 || p->spc < 2 || p->spc % 2 ||
      (!fn && nsrc <= 0) || nsrc < 0 || (nsrc > 0 && !src))
    return CV_ERR_INVALID;
  for (int s = 0; s < nsrc; s++)
    if (!unit_ok(src[s].dir) || !(src[s].E >= 0) || !isfinite(src[s].E)) return CV_ERR_INVALID;
  double sum = 0, var = 0;
  if (fn) {
    double t1[3], t2[3];
    frame_of(gaze, t1, t2);
    const double lr = log(CV_GLARE_THETA_MAX_DEG / CV_GLARE_THETA_MIN_DEG);
    const double dlog = lr / p->rows, dphi = 2 * M_PI / p->cols;
    int nt = (int)floor(sqrt((double)p->spc)), np;
    while (nt > 1 && (p->spc % nt || (p->spc / nt) % 2)) nt--;
    np = p->spc / nt;
    for (int r = 0; r < p->rows; r++) {
      const double th0 = CV_GLARE_THETA_MIN_DEG * exp(lr * r / p->rows);
      for (int c = 0; c < p->cols; c++) {
        uint64_t st = cv_hash64_u64(cv_hash64_u64(cv_hash64_u64(cv_hash64_init(), p->seed),
                                                  (uint64_t)r), (uint64_t)c);
        /* one jittered sample per sub-stratum (nt x np of the cell); the
         * variance of the cell's mean from pairs of neighbouring sub-strata:
         * var(sum v) ~ sum over pairs (v_a - v_b)^2 (slightly conservative) */
        double s1 = 0, pv = 0, prev = 0;
        for (int k = 0; k < p->spc; k++) {
          const int kt = k / np, kp = k % np;
          const double thd = th0 * exp(dlog * (kt + mix_uniform(&st)) / nt); /* degrees */
          const double phi = dphi * (c + (kp + mix_uniform(&st)) / np);
          const double th = thd * DEG, ct = cos(th), stt = sin(th);
          double d[3];
          for (int i = 0; i < 3; i++)
            d[i] = ct * gaze[i] + stt * (cos(phi) * t1[i] + sin(phi) * t2[i]);
          double L = fn(ctx, d);
          if (!isfinite(L) || L < 0) L = 0;
          /* L g cos sin / pdf, pdf = 1 / (theta ln(th1/th0) dphi) in radians */
          const double v = L * cv_cie_glare(thd, p->age, p->pigment) * ct * stt * th * dlog * dphi;
          s1 += v;
          if (kp & 1) pv += (v - prev) * (v - prev);
          prev = v;
        }
        const double n = p->spc, m = s1 / n;
        sum += m;
        var += pv / (n * n);
      }
    }
  }
  for (int s = 0; s < nsrc; s++) {
    double c = src[s].dir[0] * gaze[0] + src[s].dir[1] * gaze[1] + src[s].dir[2] * gaze[2];
    c = c > 1 ? 1 : (c < -1 ? -1 : c);
    sum += cv_cie_glare(acos(c) / DEG, p->age, p->pigment) * src[s].E * c;
  }
  lv->value = sum;
  lv->se = sqrt(var);
  return CV_OK;
}

/* --- threshold versus intensity -------------------------------------------- */

double cv_tvi_ferwerda(double La) {
  if (!(La > 0)) La = 1e-9;
  const double x = log10(La);
  double cone, rod;
  if (x <= -2.6) cone = -0.72;
  else if (x >= 1.9) cone = x - 1.255;
  else cone = pow(0.249 * x + 0.65, 2.7) - 0.72;
  if (x <= -3.94) rod = -2.86;
  else if (x >= -1.44) rod = x - 0.395;
  else rod = pow(0.405 * x + 1.6, 2.18) - 2.86;
  return pow(10.0, cone < rod ? cone : rod);
}

/* --- the panel's figures ----------------------------------------------------- */

void cv_lcd_read_params_default(cv_lcd_read_params *p) {
  p->white = 250;
  p->black = 0.5;
  p->cr_min = 3;
  p->adaptation = 0;
  p->area_min = 0.95;
  p->vl_min = 5;
}

int cv_lcd_read_params_check(const cv_lcd_read_params *p, cv_err *err) {
  if (!(p->white >= 0) || !isfinite(p->white))
    return cv_err_set(err, CV_ERR_INVALID, "white_luminance: %g: expected cd/m^2 >= 0", p->white);
  if (!(p->black >= 0) || !isfinite(p->black))
    return cv_err_set(err, CV_ERR_INVALID, "black_luminance: %g: expected cd/m^2 >= 0", p->black);
  if (p->white < p->black)
    return cv_err_set(err, CV_ERR_INVALID,
                      "white_luminance: %g is below black_luminance %g (expected white >= black)",
                      p->white, p->black);
  if (!(p->cr_min >= 1) || !isfinite(p->cr_min))
    return cv_err_set(err, CV_ERR_INVALID, "cr_min: %g: expected a ratio >= 1", p->cr_min);
  if (!(p->area_min >= 0 && p->area_min <= 1))
    return cv_err_set(err, CV_ERR_INVALID, "area_min: %g: expected a share in 0..1", p->area_min);
  if (!(p->vl_min >= 0) || !isfinite(p->vl_min))
    return cv_err_set(err, CV_ERR_INVALID, "vl_min: %g: expected a visibility level >= 0", p->vl_min);
  if (!(p->adaptation >= 0) || !isfinite(p->adaptation))
    return cv_err_set(err, CV_ERR_INVALID, "adaptation: %g: expected cd/m^2 >= 0 (0 = automatic)",
                      p->adaptation);
  return CV_OK;
}

void cv_lcd_readability_free(cv_lcd_readability *r) {
  free(r->lr);
  free(r->lr_se);
  free(r->cr);
  free(r->cr_smooth);
  memset(r, 0, sizeof *r);
}

static double contrast(double W, double B, double add) {
  const double den = B + add;
  return den > 0 ? (W + add) / den : (W > 0 ? 1e6 : 1.0); /* no light at all: capped */
}

/* Box filter of radius rad (edges clamped), separable, into out (w*h). */
static int box_filter(const float *in, int w, int h, int rad, float *out) {
  float *tmp = malloc((size_t)w * (size_t)h * sizeof(float));
  if (!tmp) return CV_ERR_NOMEM;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      double s = 0;
      int n = 0;
      for (int k = x - rad; k <= x + rad; k++)
        if (k >= 0 && k < w) s += in[(size_t)y * w + k], n++;
      tmp[(size_t)y * w + x] = (float)(s / n);
    }
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      double s = 0;
      int n = 0;
      for (int k = y - rad; k <= y + rad; k++)
        if (k >= 0 && k < h) s += tmp[(size_t)k * w + x], n++;
      out[(size_t)y * w + x] = (float)(s / n);
    }
  free(tmp);
  return CV_OK;
}

static double vl_of(double W, double B, double La) { return (W - B) / cv_tvi_ferwerda(La); }

int cv_lcd_readability_compute(const cv_lcd_accum *acc, const cv_lcd_read_params *p,
                               const cv_lcd_figure *lv, cv_lcd_readability *out, cv_err *err) {
  return cv_lcd_readability_compute_scaled(acc, p, lv, 1.0, out, err);
}

int cv_lcd_readability_compute_scaled(const cv_lcd_accum *acc, const cv_lcd_read_params *p,
                                      const cv_lcd_figure *lv, double k,
                                      cv_lcd_readability *out, cv_err *err) {
  memset(out, 0, sizeof *out);
  int st = cv_lcd_read_params_check(p, err);
  if (st) return st;
  if (!(k > 0) || !isfinite(k))
    return cv_err_set(err, CV_ERR_INVALID, "light scale: %g: expected a finite factor > 0", k);
  if (!lv || !isfinite(lv->value) || lv->value < 0 || !isfinite(lv->se) || lv->se < 0)
    return cv_err_set(err, CV_ERR_INVALID, "veiling luminance: expected a finite value >= 0");
  const int64_t n = acc->data[CV_LCD_ACC_SPP];
  if (n <= 0) return cv_err_set(err, CV_ERR_EMPTY, "readability: no sample yet");
  const size_t nt = (size_t)acc->w * (size_t)acc->h;
  out->w = acc->w;
  out->h = acc->h;
  out->lr = malloc(nt * sizeof(float));
  out->lr_se = malloc(nt * sizeof(float));
  out->cr = malloc(nt * sizeof(float));
  out->cr_smooth = malloc(nt * sizeof(float));
  /* the variance of each texel's L_r, then box means of L_r and of it */
  float *var = malloc(nt * sizeof(float)), *var_sm = malloc(nt * sizeof(float));
  if (!out->lr || !out->lr_se || !out->cr || !out->cr_smooth || !var || !var_sm) {
    free(var);
    free(var_sm);
    cv_lcd_readability_free(out);
    return cv_err_set(err, CV_ERR_NOMEM, "readability: out of memory");
  }
  const double W = p->white, B = p->black, Lv = lv->value, sv2 = lv->se * lv->se;
  double sy = 0, sse = 0, worst = INFINITY, bern = 0;
  uint64_t ok = 0;
  out->smooth_radius = acc->w / 80 > 1 ? acc->w / 80 : 1;
  for (int y = 0; y < acc->h; y++)
    for (int x = 0; x < acc->w; x++) {
      const size_t i = (size_t)y * (size_t)acc->w + (size_t)x;
      const int64_t *q = acc->data + cv_lcd_acc_rgb(acc, x, y);
      const int64_t *q2 = acc->data + cv_lcd_acc_m2(acc, x, y);
      const double m = k * (0.2126 * (double)q[0] + 0.7152 * (double)q[1] + 0.0722 * (double)q[2]) *
                       acc->unit / (double)n;
      const double m2 = k * k * ((double)q2[0] * 0x1p40 + (double)q2[1]) * acc->unit * acc->unit / (double)n;
      double vs = m2 - m * m; /* variance of one sample */
      if (!(vs > 0)) vs = 0;
      const double se2 = vs / (double)n;
      const double cr = contrast(W, B, m + Lv);
      out->lr[i] = (float)m;
      out->lr_se[i] = (float)sqrt(se2);
      out->cr[i] = (float)cr;
      var[i] = (float)se2;
      sy += m;
      sse += se2;
      if (cr < worst) worst = cr;
    }
  /* the area meeting the requirement on the CR of the box-filtered L_r (the
   * contour of the heat map): single-texel noise would bias a raw count
   * (towards 50% near the requirement, and upwards as CR is convex in L_r) */
  const int rad = out->smooth_radius;
  const double nbox = (double)(2 * rad + 1) * (2 * rad + 1);
  if (box_filter(out->lr, acc->w, acc->h, rad, out->cr_smooth) ||
      box_filter(var, acc->w, acc->h, rad, var_sm)) {
    free(var);
    free(var_sm);
    cv_lcd_readability_free(out);
    return cv_err_set(err, CV_ERR_NOMEM, "readability: out of memory");
  }
  for (size_t i = 0; i < nt; i++) {
    const double lr = out->cr_smooth[i], dn = B + lr + Lv;
    const double c = contrast(W, B, lr + Lv);
    const double sd = dn > 0 ? (W - B) / (dn * dn) * sqrt(var_sm[i] / nbox) : 0;
    out->cr_smooth[i] = (float)c;
    if (c >= p->cr_min) ok++;
    if (sd > 0) {
      const double pi = 0.5 * erfc(-(c - p->cr_min) / (sd * M_SQRT2));
      bern += pi * (1 - pi);
    }
  }
  free(var);
  free(var_sm);
  const double N = (double)nt;
  out->spp = (uint64_t)n;
  out->cr_min = p->cr_min;
  out->cr_worst = worst;
  out->white = W;
  out->black = B;
  out->L_r.value = sy / N;
  out->L_r.se = sqrt(sse) / N;
  out->L_v = *lv;
  const double add = out->L_r.value + Lv, den = B + add;
  const double s_add = sqrt(out->L_r.se * out->L_r.se + sv2);
  out->cr_mean.value = contrast(W, B, add);
  out->cr_mean.se = den > 0 ? (W - B) / (den * den) * s_add : 0;
  out->frac_ok.value = (double)ok / N;
  out->frac_ok.se = sqrt(bern * nbox) / N; /* a box's texels move together */
  if (out->frac_ok.se < 1e-9) out->frac_ok.se = 0; /* certain: no rounding residue */
  if (p->adaptation > 0) {
    out->L_a.value = p->adaptation;
    out->L_a.se = 0;
  } else {
    out->L_a.value = den;
    out->L_a.se = s_add;
  }
  const double La = out->L_a.value > 1e-9 ? out->L_a.value : 1e-9;
  out->dL_threshold = cv_tvi_ferwerda(La);
  out->vl.value = vl_of(W, B, La);
  /* first-order error through the threshold's slope at La (central difference) */
  const double h = 1e-4 * La;
  const double dvl = (vl_of(W, B, La + h) - vl_of(W, B, La > h ? La - h : La)) / (La > h ? 2 * h : h);
  out->vl.se = fabs(dvl) * out->L_a.se;
  return CV_OK;
}

/* --- heat map ------------------------------------------------------------------ */

void cv_lcd_viridis(double t, uint8_t rgb[3]) {
  static const double a[5][3] = {
      {68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}};
  t = t < 0 ? 0 : (t > 1 ? 1 : t);
  const double f = t * 4;
  int k = (int)f;
  if (k > 3) k = 3;
  const double w = f - k;
  for (int c = 0; c < 3; c++) rgb[c] = (uint8_t)lrint(a[k][c] + w * (a[k + 1][c] - a[k][c]));
}

static double cr_pos(double cr) { return cr > 0 ? log10(cr) : 0; } /* CR 1..10 -> 0..1 */

int cv_lcd_heatmap_rgb(const cv_lcd_readability *r, int bar_h, uint8_t *px) {
  const int w = r->w, h = r->h;
  const float *sm = r->cr_smooth ? r->cr_smooth : r->cr;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      const size_t i = (size_t)y * (size_t)w + (size_t)x;
      uint8_t *o = px + 3 * i;
      const int ok = sm[i] >= r->cr_min;
      int edge = 0;
      if (x > 0) edge |= (sm[i - 1] >= r->cr_min) != ok;
      if (x + 1 < w) edge |= (sm[i + 1] >= r->cr_min) != ok;
      if (y > 0) edge |= (sm[i - (size_t)w] >= r->cr_min) != ok;
      if (y + 1 < h) edge |= (sm[i + (size_t)w] >= r->cr_min) != ok;
      if (edge) o[0] = o[1] = o[2] = 255;
      else cv_lcd_viridis(cr_pos(r->cr[i]), o);
    }
  const int mark = w > 1 ? (int)lrint(cr_pos(r->cr_min) * (w - 1)) : 0;
  for (int y = 0; y < bar_h; y++)
    for (int x = 0; x < w; x++) {
      uint8_t *o = px + 3 * ((size_t)(h + y) * (size_t)w + (size_t)x);
      const double t = w > 1 ? (double)x / (w - 1) : 0;
      cv_lcd_viridis(t, o);
      /* ticks at CR = 1, 2, ..., 10 in the bar's top third (black) */
      for (int c = 1; c <= 10 && y < bar_h / 3; c++)
        if (x == (int)lrint(log10((double)c) * (w - 1))) o[0] = o[1] = o[2] = 0;
      if (abs(x - mark) <= 1) o[0] = o[1] = o[2] = 255;
    }
  return CV_OK;
}
