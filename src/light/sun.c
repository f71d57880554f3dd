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

int cv_sun_extract(const cv_envmap *env, const cv_sun_params *p, cv_sun_info *info,
                   cv_envmap **residual) {
  if (residual) *residual = NULL;
  if (!env || !env->img || !info) return CV_ERR_INVALID;
  cv_sun_params def;
  cv_sun_params_default(&def);
  if (!p) p = &def;
  if (!(p->rel_threshold > 0.0 && p->rel_threshold <= 1.0) || !(p->median_factor >= 0.0) ||
      !(p->max_solid_angle > 0.0) ||
      !(p->min_energy_fraction >= 0.0 && p->min_energy_fraction <= 1.0) || p->dilate < 0 ||
      p->dilate > 16)
    return CV_ERR_INVALID;
  memset(info, 0, sizeof *info);
  const cv_image *img = env->img;
  const int w = img->w, h = img->h;
  const size_t np = (size_t)w * (size_t)h;

  float *lum = malloc(np * sizeof *lum);
  float *tmp = malloc(np * sizeof *tmp);
  uint8_t *mask = calloc(np, 1);
  double *row_sa = malloc((size_t)h * sizeof *row_sa);
  queue q = {0};
  int st = CV_OK;
  if (!lum || !tmp || !mask || !row_sa) {
    st = CV_ERR_NOMEM;
    goto done;
  }
  for (int y = 0; y < h; y++) row_sa[y] = cv_latlong_pixel_solid_angle(y, w, h);

  /* luminance, peak (first in scan order), total energy */
  size_t peak = 0;
  double total = 0.0;
  for (size_t i = 0; i < np; i++) {
    const float *px = img->px + 3 * i;
    lum[i] = (float)cv_luminance(px[0], px[1], px[2]);
    if (lum[i] > lum[peak]) peak = i;
    total += lum[i] * row_sa[i / (size_t)w];
  }
  memcpy(tmp, lum, np * sizeof *tmp);
  const double median = select_kth(tmp, np, np / 2);
  const double thr = fmax(p->rel_threshold * lum[peak], p->median_factor * median);
  info->peak_luminance = lum[peak];
  info->median_luminance = median;
  info->threshold = thr;
  info->total_energy = total;
  if (!(lum[peak] > thr) || !(total > 0.0)) goto copy; /* no candidate */

  /* grow the thresholded region from the peak (breadth first) */
  size_t nb[8];
  mask[peak] = 1;
  if ((st = q_push(&q, peak)) != CV_OK) goto done;
  for (size_t head = 0; head < q.n; head++) {
    const size_t i = q.v[head];
    const int k = neighbours((int)(i % (size_t)w), (int)(i / (size_t)w), w, h, nb);
    for (int j = 0; j < k; j++)
      if (!mask[nb[j]] && lum[nb[j]] > thr) {
        mask[nb[j]] = 1;
        if ((st = q_push(&q, nb[j])) != CV_OK) goto done;
      }
  }
  /* dilation rings: q.v[0..q.n) lists the region; each pass appends the
   * neighbours of the previous ring */
  size_t ring_start = 0;
  for (int r = 0; r < p->dilate; r++) {
    const size_t ring_end = q.n;
    for (size_t head = ring_start; head < ring_end; head++) {
      const size_t i = q.v[head];
      const int k = neighbours((int)(i % (size_t)w), (int)(i / (size_t)w), w, h, nb);
      for (int j = 0; j < k; j++)
        if (!mask[nb[j]]) {
          mask[nb[j]] = 1;
          if ((st = q_push(&q, nb[j])) != CV_OK) goto done;
        }
    }
    ring_start = ring_end;
  }
  const size_t region_n = q.n;

  /* ring just outside the region (marked 2): the fill colour */
  double fill[3] = {0.0, 0.0, 0.0}, fill_w = 0.0;
  for (size_t head = 0; head < region_n; head++) {
    const size_t i = q.v[head];
    const int k = neighbours((int)(i % (size_t)w), (int)(i / (size_t)w), w, h, nb);
    for (int j = 0; j < k; j++)
      if (!mask[nb[j]]) {
        mask[nb[j]] = 2;
        const double sa = row_sa[nb[j] / (size_t)w];
        const float *px = img->px + 3 * nb[j];
        for (int c = 0; c < 3; c++) fill[c] += sa * px[c];
        fill_w += sa;
      }
  }
  if (fill_w > 0.0)
    for (int c = 0; c < 3; c++) fill[c] /= fill_w;

  /* region statistics */
  double sa_sum = 0.0, e_region = 0.0, rgb[3] = {0.0, 0.0, 0.0}, cen[3] = {0.0, 0.0, 0.0};
  const double fill_lum = cv_luminance(fill[0], fill[1], fill[2]);
  for (size_t head = 0; head < region_n; head++) {
    const size_t i = q.v[head];
    const int x = (int)(i % (size_t)w), y = (int)(i / (size_t)w);
    const double sa = row_sa[y];
    const float *px = img->px + 3 * i;
    sa_sum += sa;
    e_region += lum[i] * sa;
    for (int c = 0; c < 3; c++) rgb[c] += (px[c] - fill[c]) * sa;
    const double ex = (lum[i] - fill_lum) * sa;
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
  info->energy_fraction = e_region / total;
  info->pixels = (long)region_n;
  for (int c = 0; c < 3; c++) {
    info->rgb[c] = rgb[c] > 0.0 ? rgb[c] : 0.0;
    info->rgb_clamped += rgb[c] < 0.0;
  }
  memcpy(info->fill_rgb, fill, sizeof fill);
  info->found = sa_sum <= p->max_solid_angle && info->energy_fraction >= p->min_energy_fraction;

copy:
  if (residual) {
    if ((st = cv_envmap_clone(env, residual)) != CV_OK) goto done;
    if (info->found)
      for (size_t head = 0; head < (size_t)info->pixels; head++) {
        float *px = (*residual)->img->px + 3 * q.v[head];
        for (int c = 0; c < 3; c++) px[c] = (float)info->fill_rgb[c];
      }
  }
done:
  free(lum);
  free(tmp);
  free(mask);
  free(row_sa);
  free(q.v);
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
