/* Sun extraction from lat-long HDR maps (see sun.h). */
#include "light/sun.h"

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sh/latlong.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

void cv_sun_params_default(cv_sun_params *p) {
  p->rel_threshold = 0.05;
  p->median_factor = 20.0;
  p->max_solid_angle = 0.01;
  p->min_energy_fraction = 0.05;
  p->dilate = 1;
}

/* k-th smallest of a[0..n-1] (reorders a): Wirth's selection. */
static float select_kth(float *a, size_t n, size_t kk) {
  ptrdiff_t l = 0, m = (ptrdiff_t)n - 1;
  const ptrdiff_t k = (ptrdiff_t)kk;
  while (l < m) {
    const float x = a[k];
    ptrdiff_t i = l, j = m;
    do {
      while (a[i] < x) i++;
      while (x < a[j]) j--;
      if (i <= j) {
        const float t = a[i];
        a[i] = a[j];
        a[j] = t;
        i++;
        j--;
      }
    } while (i <= j);
    if (j < k) l = i;
    if (k < i) m = j;
  }
  return a[k];
}

/* Growable FIFO of pixel indices. */
typedef struct queue {
  size_t *v;
  size_t n, cap;
} queue;
static int q_push(queue *q, size_t i) {
  if (q->n == q->cap) {
    const size_t nc = q->cap ? 2 * q->cap : 1024;
    size_t *nv = realloc(q->v, nc * sizeof *nv);
    if (!nv) return CV_ERR_NOMEM;
    q->v = nv;
    q->cap = nc;
  }
  q->v[q->n++] = i;
  return CV_OK;
}

/* The 8 neighbours of pixel (x, y): u wraps; a step past the top or bottom
 * row crosses the pole to the opposite azimuth. */
static int neighbours(int x, int y, int w, int h, size_t out[8]) {
  int k = 0;
  for (int dy = -1; dy <= 1; dy++)
    for (int dx = -1; dx <= 1; dx++) {
      if (!dx && !dy) continue;
      int nx = x + dx, ny = y + dy;
      if (ny < 0 || ny >= h) {
        ny = ny < 0 ? 0 : h - 1;
        nx += w / 2;
      }
      nx %= w;
      if (nx < 0) nx += w;
      const size_t idx = (size_t)ny * (size_t)w + (size_t)nx;
      int dup = 0;
      for (int j = 0; j < k; j++) dup |= out[j] == idx;
      if (!dup && !(nx == x && ny == y)) out[k++] = idx;
    }
  return k;
}

/* The map being scanned: its luminance, per-row pixel solid angle, the
 * region mask (1: region, 2: the ring just outside) and the region's pixels
 * in q (the thresholded region first, then the dilation rings). */
typedef struct sun_scan {
  const cv_image *img;
  int w, h;
  size_t np;
  float *lum;
  uint8_t *mask;
  double *row_sa;
  queue q;
} sun_scan;

static int sun_params_ok(const cv_sun_params *p) {
  return p->rel_threshold > 0.0 && p->rel_threshold <= 1.0 && p->median_factor >= 0.0 &&
         p->max_solid_angle > 0.0 && p->min_energy_fraction >= 0.0 &&
         p->min_energy_fraction <= 1.0 && p->dilate >= 0 && p->dilate <= 16;
}

/* Luminance, the peak (first in scan order), the total energy and the
 * median into info, the threshold max(rel_threshold x peak, median_factor x
 * median).  tmp: scratch of np floats.  Returns the peak pixel. */
static size_t luminance_stats(sun_scan *S, const cv_sun_params *p, float *tmp, cv_sun_info *info) {
  size_t peak = 0;
  double total = 0.0;
  for (size_t i = 0; i < S->np; i++) {
    const float *px = S->img->px + 3 * i;
    S->lum[i] = (float)cv_luminance(px[0], px[1], px[2]);
    if (S->lum[i] > S->lum[peak]) peak = i;
    total += S->lum[i] * S->row_sa[i / (size_t)S->w];
  }
  memcpy(tmp, S->lum, S->np * sizeof *tmp);
  const double median = select_kth(tmp, S->np, S->np / 2);
  info->peak_luminance = S->lum[peak];
  info->median_luminance = median;
  info->threshold = fmax(p->rel_threshold * S->lum[peak], p->median_factor * median);
  info->total_energy = total;
  return peak;
}

/* The region: grown from the peak over pixels above thr (breadth first),
 * then `dilate` rings added, each the neighbours of the previous one.
 * Returns the status. */
static int grow_region(sun_scan *S, size_t peak, double thr, int dilate) {
  const int w = S->w, h = S->h;
  size_t nb[8];
  int st;
  S->mask[peak] = 1;
  if ((st = q_push(&S->q, peak)) != CV_OK) return st;
  for (size_t head = 0; head < S->q.n; head++) {
    const size_t i = S->q.v[head];
    const int k = neighbours((int)(i % (size_t)w), (int)(i / (size_t)w), w, h, nb);
    for (int j = 0; j < k; j++)
      if (!S->mask[nb[j]] && S->lum[nb[j]] > thr) {
        S->mask[nb[j]] = 1;
        if ((st = q_push(&S->q, nb[j])) != CV_OK) return st;
      }
  }
  size_t ring_start = 0;
  for (int r = 0; r < dilate; r++) {
    const size_t ring_end = S->q.n;
    for (size_t head = ring_start; head < ring_end; head++) {
      const size_t i = S->q.v[head];
      const int k = neighbours((int)(i % (size_t)w), (int)(i / (size_t)w), w, h, nb);
      for (int j = 0; j < k; j++)
        if (!S->mask[nb[j]]) {
          S->mask[nb[j]] = 1;
          if ((st = q_push(&S->q, nb[j])) != CV_OK) return st;
        }
    }
    ring_start = ring_end;
  }
  return CV_OK;
}

/* The fill colour: the solid-angle weighted mean of the ring just outside
 * the region (marked 2). */
static void region_fill(sun_scan *S, double fill[3]) {
  const int w = S->w, h = S->h;
  size_t nb[8];
  double fill_w = 0.0;
  fill[0] = fill[1] = fill[2] = 0.0;
  for (size_t head = 0; head < S->q.n; head++) {
    const size_t i = S->q.v[head];
    const int k = neighbours((int)(i % (size_t)w), (int)(i / (size_t)w), w, h, nb);
    for (int j = 0; j < k; j++)
      if (!S->mask[nb[j]]) {
        S->mask[nb[j]] = 2;
        const double sa = S->row_sa[nb[j] / (size_t)w];
        const float *px = S->img->px + 3 * nb[j];
        for (int c = 0; c < 3; c++) fill[c] += sa * px[c];
        fill_w += sa;
      }
  }
  if (fill_w > 0.0)
    for (int c = 0; c < 3; c++) fill[c] /= fill_w;
}

/* The region's solid angle, energy, RGB over the fill and direction (the
 * centroid of its excess luminance, else the peak) into info, and whether
 * it is a sun. */
static void region_stats(const sun_scan *S, size_t peak, const double fill[3],
                         const cv_sun_params *p, cv_sun_info *info) {
  const int w = S->w, h = S->h;
  double sa_sum = 0.0, e_region = 0.0, rgb[3] = {0.0, 0.0, 0.0}, cen[3] = {0.0, 0.0, 0.0};
  const double fill_lum = cv_luminance(fill[0], fill[1], fill[2]);
  for (size_t head = 0; head < S->q.n; head++) {
    const size_t i = S->q.v[head];
    const int x = (int)(i % (size_t)w), y = (int)(i / (size_t)w);
    const double sa = S->row_sa[y];
    const float *px = S->img->px + 3 * i;
    sa_sum += sa;
    e_region += S->lum[i] * sa;
    for (int c = 0; c < 3; c++) rgb[c] += (px[c] - fill[c]) * sa;
    const double ex = (S->lum[i] - fill_lum) * sa;
    if (ex > 0.0) {
      double d[3];
      cv_latlong_pixel_dir(x, y, w, h, d);
      for (int c = 0; c < 3; c++) cen[c] += ex * d[c];
    }
  }
  const double cl = sqrt(cen[0] * cen[0] + cen[1] * cen[1] + cen[2] * cen[2]);
  if (cl > 0.0) {
    for (int c = 0; c < 3; c++) info->dir[c] = cen[c] / cl;
  } else {
    cv_latlong_pixel_dir((int)(peak % (size_t)w), (int)(peak / (size_t)w), w, h, info->dir);
  }
  info->elevation_deg = asin(fmax(-1.0, fmin(1.0, info->dir[1]))) * 180.0 / M_PI;
  info->solid_angle = sa_sum;
  info->energy_fraction = e_region / info->total_energy;
  info->pixels = (long)S->q.n;
  for (int c = 0; c < 3; c++) {
    info->rgb[c] = rgb[c] > 0.0 ? rgb[c] : 0.0;
    info->rgb_clamped += rgb[c] < 0.0;
  }
  memcpy(info->fill_rgb, fill, 3 * sizeof *fill);
  info->found = sa_sum <= p->max_solid_angle && info->energy_fraction >= p->min_energy_fraction;
}

int cv_sun_extract(const cv_envmap *env, const cv_sun_params *p, cv_sun_info *info,
                   cv_envmap **residual) {
  if (residual) *residual = NULL;
  if (!env || !env->img || !info) return CV_ERR_INVALID;
  cv_sun_params def;
  cv_sun_params_default(&def);
  if (!p) p = &def;
  if (!sun_params_ok(p)) return CV_ERR_INVALID;
  memset(info, 0, sizeof *info);
  sun_scan S = {.img = env->img, .w = env->img->w, .h = env->img->h};
  S.np = (size_t)S.w * (size_t)S.h;
  S.lum = malloc(S.np * sizeof *S.lum);
  float *tmp = malloc(S.np * sizeof *tmp);
  S.mask = calloc(S.np, 1);
  S.row_sa = malloc((size_t)S.h * sizeof *S.row_sa);
  int st = (!S.lum || !tmp || !S.mask || !S.row_sa) ? CV_ERR_NOMEM : CV_OK;
  if (!st) {
    for (int y = 0; y < S.h; y++) S.row_sa[y] = cv_latlong_pixel_solid_angle(y, S.w, S.h);
    const size_t peak = luminance_stats(&S, p, tmp, info);
    const int candidate = S.lum[peak] > info->threshold && info->total_energy > 0.0;
    if (candidate) st = grow_region(&S, peak, info->threshold, p->dilate);
    if (candidate && !st) {
      double fill[3];
      region_fill(&S, fill);
      region_stats(&S, peak, fill, p, info);
    }
  }
  if (!st && residual && (st = cv_envmap_clone(env, residual)) == CV_OK && info->found)
    for (size_t head = 0; head < (size_t)info->pixels; head++) {
      float *px = (*residual)->img->px + 3 * S.q.v[head];
      for (int c = 0; c < 3; c++) px[c] = (float)info->fill_rgb[c];
    }
  free(S.lum);
  free(tmp);
  free(S.mask);
  free(S.row_sa);
  free(S.q.v);
  if (st != CV_OK) {
    if (residual) {
      cv_envmap_destroy(*residual);
      *residual = NULL;
    }
    memset(info, 0, sizeof *info);
  }
  return st;
}

void cv_sun_info_print(FILE *f, const cv_sun_info *s) {
  const double az = atan2(s->dir[0], -s->dir[2]) * 180.0 / M_PI;
  fprintf(f,
          "sun: %s, dir (%.4f, %.4f, %.4f) elevation %.2f deg azimuth %.2f deg (from -Z towards "
          "+X), %ld px, %.3g sr, energy fraction %.4f, irradiance RGB (%.4g, %.4g, %.4g), "
          "peak L %.4g, median L %.4g, threshold %.4g%s\n",
          s->found ? "found" : "none", s->dir[0], s->dir[1], s->dir[2], s->elevation_deg, az,
          s->pixels, s->solid_angle, s->energy_fraction, s->rgb[0], s->rgb[1], s->rgb[2],
          s->peak_luminance, s->median_luminance, s->threshold,
          s->rgb_clamped ? " (negative irradiance channels set to 0)" : "");
}
