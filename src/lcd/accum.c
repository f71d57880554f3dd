/* Fixed-point progressive LCD images and their keys (see accum.h). */
#include "lcd/accum.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/outfile.h"

#define ACC_MAGIC "CVLCDACC"

double cv_lcd_unit_for_clamp(double clamp) { return ldexp(1.0, (int)ceil(log2(clamp)) - 40); }

int cv_lcd_accum_create(int w, int h, double clamp, cv_lcd_accum **out) {
  *out = NULL;
  if (w < 1 || h < 1 || w > 16384 || h > 16384 || !(clamp > 0) || !isfinite(clamp) ||
      clamp > 1e30)
    return CV_ERR_INVALID;
  cv_lcd_accum *a = calloc(1, sizeof *a);
  if (!a) return CV_ERR_NOMEM;
  a->w = w;
  a->h = h;
  a->clamp = clamp;
  a->unit = cv_lcd_unit_for_clamp(clamp);
  a->n = cv_lcd_accum_words(w, h);
  a->data = calloc(a->n, sizeof(int64_t));
  if (!a->data) {
    free(a);
    return CV_ERR_NOMEM;
  }
  *out = a;
  return CV_OK;
}

void cv_lcd_accum_destroy(cv_lcd_accum *a) {
  if (!a) return;
  free(a->data);
  free(a);
}

void cv_lcd_accum_clear(cv_lcd_accum *a) { memset(a->data, 0, a->n * sizeof(int64_t)); }

int cv_lcd_accum_clone(const cv_lcd_accum *a, cv_lcd_accum **out) {
  int st = cv_lcd_accum_create(a->w, a->h, a->clamp, out);
  if (st) return st;
  memcpy((*out)->data, a->data, a->n * sizeof(int64_t));
  return CV_OK;
}

int cv_lcd_accum_add(cv_lcd_accum *dst, const cv_lcd_accum *src) {
  if (dst->w != src->w || dst->h != src->h || dst->unit != src->unit || dst->n != src->n)
    return CV_ERR_INVALID;
  if (dst->data[CV_LCD_ACC_SPP] + src->data[CV_LCD_ACC_SPP] > CV_LCD_MAX_SPP) return CV_ERR_RANGE;
  for (size_t i = 0; i < dst->n; i++) dst->data[i] += src->data[i];
  return CV_OK;
}

int cv_lcd_accum_to_image(const cv_lcd_accum *a, const cv_image *emitted, cv_image **out) {
  *out = NULL;
  int64_t n = a->data[CV_LCD_ACC_SPP];
  if (n <= 0) return CV_ERR_EMPTY;
  if (emitted && (emitted->w != a->w || emitted->h != a->h || emitted->c != 3))
    return CV_ERR_INVALID;
  cv_image *img;
  int st = cv_image_create(a->w, a->h, 3, &img);
  if (st) return st;
  double s = a->unit / (double)n;
  for (int y = 0; y < a->h; y++)
    for (int x = 0; x < a->w; x++) {
      const int64_t *q = a->data + cv_lcd_acc_rgb(a, x, y);
      float *px = cv_image_at(img, x, y);
      const float *e = emitted ? cv_image_at(emitted, x, y) : NULL;
      for (int c = 0; c < 3; c++) px[c] = (float)((double)q[c] * s + (e ? e[c] : 0.0));
    }
  *out = img;
  return CV_OK;
}

int cv_lcd_accum_set_veil(cv_lcd_accum *a, int slot, double value, double se) {
  if (!a || slot < 0 || slot >= CV_LCD_ACC_VEIL_SLOTS || a->data[CV_LCD_ACC_ROUNDS] != 1 ||
      !(value >= 0) || !(se >= 0) || !(value < 0x1p38) || !(se < 0x1p38))
    return CV_ERR_INVALID;
  a->data[CV_LCD_ACC_VEIL + 2 * slot] = (int64_t)llround(value / CV_LCD_VEIL_UNIT);
  a->data[CV_LCD_ACC_VEIL + 2 * slot + 1] = (int64_t)llround(se / CV_LCD_VEIL_UNIT);
  a->data[CV_LCD_ACC_VEILS] = 1;
  return CV_OK;
}

int cv_lcd_accum_veil(const cv_lcd_accum *a, int slot, double *value, double *se) {
  const int64_t n = a->data[CV_LCD_ACC_VEILS];
  *value = *se = 0;
  if (n <= 0 || slot < 0 || slot >= CV_LCD_ACC_VEIL_SLOTS) return 0;
  *value = (double)a->data[CV_LCD_ACC_VEIL + 2 * slot] * CV_LCD_VEIL_UNIT / (double)n;
  *se = (double)a->data[CV_LCD_ACC_VEIL + 2 * slot + 1] * CV_LCD_VEIL_UNIT / (double)n;
  return 1;
}

int cv_lcd_accum_set_light(cv_lcd_accum *a, const double E[3]) {
  if (!a || a->data[CV_LCD_ACC_ROUNDS] != 1) return CV_ERR_INVALID;
  for (int k = 0; k < 3; k++)
    if (!(E[k] >= 0) || !(E[k] < 0x1p38)) return CV_ERR_INVALID;
  for (int k = 0; k < 3; k++) a->data[CV_LCD_ACC_LIGHT + k] = (int64_t)llround(E[k] / CV_LCD_VEIL_UNIT);
  a->data[CV_LCD_ACC_LIGHTS] = 1;
  return CV_OK;
}

int cv_lcd_accum_light(const cv_lcd_accum *a, double E[3]) {
  const int64_t n = a->data[CV_LCD_ACC_LIGHTS];
  for (int k = 0; k < 3; k++)
    E[k] = n > 0 ? (double)a->data[CV_LCD_ACC_LIGHT + k] * CV_LCD_VEIL_UNIT / (double)n : 0;
  return n > 0;
}

int cv_lcd_accum_error(const cv_lcd_accum *a, cv_lcd_error *e) {
  memset(e, 0, sizeof *e);
  int64_t n = a->data[CV_LCD_ACC_SPP];
  if (n <= 0) return CV_ERR_EMPTY;
  e->spp = (uint64_t)n;
  double sy = 0, sse = 0;
  for (int y = 0; y < a->h; y++)
    for (int x = 0; x < a->w; x++) {
      const int64_t *q = a->data + cv_lcd_acc_rgb(a, x, y);
      double m = (0.2126 * (double)q[0] + 0.7152 * (double)q[1] + 0.0722 * (double)q[2]) * a->unit / n;
      const int64_t *q2 = a->data + cv_lcd_acc_m2(a, x, y);
      double m2 = ((double)q2[0] * 0x1p40 + (double)q2[1]) * a->unit * a->unit / n;
      double var = m2 - m * m;
      if (!(var > 0)) var = 0;
      sy += m;
      sse += var / n;
    }
  double np = (double)a->w * a->h;
  e->mean_luminance = sy / np;
  e->rms_se = sqrt(sse / np);
  e->rel_rms = e->mean_luminance > 0 ? e->rms_se / e->mean_luminance : 0;
  return CV_OK;
}

/* --- files ------------------------------------------------------------- */

static void put_u64(unsigned char *p, uint64_t v) {
  for (int k = 0; k < 8; k++) p[k] = (unsigned char)(v >> (8 * k));
}
static uint64_t get_u64(const unsigned char *p) {
  uint64_t v = 0;
  for (int k = 0; k < 8; k++) v |= (uint64_t)p[k] << (8 * k);
  return v;
}

int cv_lcd_accum_write(const char *path, const cv_lcd_accum *a, cv_err *err) {
  cv_outfile o;
  int st = cv_outfile_open(&o, path, 1, err);
  if (st) return st;
  unsigned char hdr[40], buf[8 * 512];
  memcpy(hdr, ACC_MAGIC, 8);
  put_u64(hdr + 8, 2); /* version 2: 32 header words (veil slots) */
  put_u64(hdr + 16, (uint64_t)a->w);
  put_u64(hdr + 24, (uint64_t)a->h);
  uint64_t cb;
  memcpy(&cb, &a->clamp, 8);
  put_u64(hdr + 32, cb);
  int ok = fwrite(hdr, 1, sizeof hdr, o.f) == sizeof hdr;
  for (size_t i = 0; i < a->n && ok;) {
    size_t m = 0;
    for (; m < 512 && i < a->n; m++, i++) put_u64(buf + 8 * m, (uint64_t)a->data[i]);
    ok = fwrite(buf, 8, m, o.f) == m;
  }
  if (!ok) {
    cv_outfile_abort(&o);
    return cv_err_set(err, CV_ERR_IO, "%s: write failed", path);
  }
  return cv_outfile_commit(&o, err);
}

int cv_lcd_accum_read(const char *path, cv_lcd_accum **out, cv_err *err) {
  *out = NULL;
  FILE *f = fopen(path, "rb");
  if (!f) return cv_err_set(err, CV_ERR_IO, "%s: cannot open (%s)", path, strerror(errno));
  unsigned char hdr[40];
  if (fread(hdr, 1, sizeof hdr, f) != sizeof hdr || memcmp(hdr, ACC_MAGIC, 8) ||
      get_u64(hdr + 8) != 2) {
    fclose(f);
    return cv_err_set(err, CV_ERR_FORMAT, "%s: not an LCD accumulation file (magic %s, version 2)",
                      path, ACC_MAGIC);
  }
  uint64_t w = get_u64(hdr + 16), h = get_u64(hdr + 24), cb = get_u64(hdr + 32);
  double clamp;
  memcpy(&clamp, &cb, 8);
  cv_lcd_accum *a;
  if (w < 1 || h < 1 || w > 16384 || h > 16384 || cv_lcd_accum_create((int)w, (int)h, clamp, &a)) {
    fclose(f);
    return cv_err_set(err, CV_ERR_FORMAT, "%s: bad size %llux%llu or clamp %g", path,
                      (unsigned long long)w, (unsigned long long)h, clamp);
  }
  unsigned char buf[8 * 512];
  for (size_t i = 0; i < a->n;) {
    size_t m = a->n - i < 512 ? a->n - i : 512;
    if (fread(buf, 8, m, f) != m) {
      fclose(f);
      cv_lcd_accum_destroy(a);
      return cv_err_set(err, CV_ERR_FORMAT, "%s: truncated", path);
    }
    for (size_t j = 0; j < m; j++, i++) a->data[i] = (int64_t)get_u64(buf + 8 * j);
  }
  int extra = fgetc(f) != EOF;
  fclose(f);
  if (extra || a->data[CV_LCD_ACC_SPP] < 0 || a->data[CV_LCD_ACC_SPP] > CV_LCD_MAX_SPP) {
    cv_lcd_accum_destroy(a);
    return cv_err_set(err, CV_ERR_FORMAT, "%s: %s", path,
                      extra ? "trailing bytes" : "sample count out of range");
  }
  *out = a;
  return CV_OK;
}

/* --- keys ---------------------------------------------------------------- */

int cv_lcd_key_make(const float eye[3], double tolerance, uint64_t light_hash,
                    uint64_t setup_hash, cv_lcd_key *out) {
  memset(out, 0, sizeof *out);
  if (!(tolerance > 0) || !isfinite(tolerance)) return CV_ERR_INVALID;
  for (int k = 0; k < 3; k++) {
    if (!isfinite(eye[k])) return CV_ERR_INVALID;
    double q = floor((double)eye[k] / tolerance + 0.5);
    if (q < -2147483647.0 || q > 2147483647.0) return CV_ERR_RANGE;
    out->eye_q[k] = (int32_t)q;
  }
  out->light_hash = light_hash;
  out->setup_hash = setup_hash;
  return CV_OK;
}

void cv_lcd_key_eye(const cv_lcd_key *k, double tolerance, float eye[3]) {
  for (int i = 0; i < 3; i++) eye[i] = (float)(k->eye_q[i] * tolerance);
}

int cv_lcd_key_compare(const cv_lcd_key *a, const cv_lcd_key *b) {
  for (int i = 0; i < 3; i++)
    if (a->eye_q[i] != b->eye_q[i]) return a->eye_q[i] < b->eye_q[i] ? -1 : 1;
  if (a->light_hash != b->light_hash) return a->light_hash < b->light_hash ? -1 : 1;
  if (a->setup_hash != b->setup_hash) return a->setup_hash < b->setup_hash ? -1 : 1;
  return 0;
}

int cv_lcd_key_equal(const cv_lcd_key *a, const cv_lcd_key *b) {
  return cv_lcd_key_compare(a, b) == 0;
}

int cv_lcd_progress_submit(cv_lcd_progress *p, const cv_lcd_key *key, const cv_lcd_accum *buf,
                           int *restarted) {
  if (restarted) *restarted = 0;
  if (p->has_key && p->acc && cv_lcd_key_equal(&p->key, key)) return cv_lcd_accum_add(p->acc, buf);
  cv_lcd_accum *c;
  int st = cv_lcd_accum_clone(buf, &c);
  if (st) return st;
  if (p->has_key) p->restarts++;
  cv_lcd_accum_destroy(p->acc);
  p->acc = c;
  p->key = *key;
  p->has_key = 1;
  if (restarted) *restarted = 1;
  return CV_OK;
}

void cv_lcd_progress_free(cv_lcd_progress *p) {
  cv_lcd_accum_destroy(p->acc);
  memset(p, 0, sizeof *p);
}
