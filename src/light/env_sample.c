/* Luminance importance sampling of a lat-long map (see env_sample.h). */
#include "light/env_sample.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/fast_trig.h"

void cv_env_sampler_destroy(cv_env_sampler *s) {
  if (!s) return;
  free(s->marg);
  free(s->cond);
  free(s->cos_edge);
  free(s->inv_sa);
  free(s->mguide);
  free(s->cguide);
  free(s);
}

/* guide[g] = the largest i in [0, n) with cdf[i] <= g / CV_ENV_GUIDE (g in
 * [0, CV_ENV_GUIDE]); cdf non-decreasing with cdf[0] = 0. */
static void build_guide(const float *cdf, int n, uint16_t *guide) {
  int i = 0;
  for (int g = 0; g <= CV_ENV_GUIDE; g++) {
    const float x = (float)g / CV_ENV_GUIDE; /* exact: CV_ENV_GUIDE is a power of two */
    while (i < n - 1 && cdf[i + 1] <= x) i++;
    guide[g] = (uint16_t)i;
  }
}

/* marg, cond, their guides and total from per-cell weights cw (w * h, >= 0). */
static void build_cdfs(cv_env_sampler *s, const double *cw, double *row, double *cum) {
  const int w = s->w, h = s->h;
  double total = 0;
  for (int y = 0; y < h; y++) {
    cum[0] = 0;
    for (int x = 0; x < w; x++) cum[x + 1] = cum[x] + cw[(size_t)y * (size_t)w + (size_t)x];
    row[y] = cum[w];
    float *c = s->cond + (size_t)y * (size_t)(w + 1);
    for (int x = 0; x <= w; x++) c[x] = row[y] > 0 ? (float)(cum[x] / row[y]) : (float)x / (float)w;
    c[w] = 1.0f;
    total += row[y];
  }
  s->total = total;
  double acc = 0;
  s->marg[0] = 0;
  for (int y = 0; y < h; y++) {
    acc += row[y];
    s->marg[y + 1] = total > 0 ? (float)(acc / total) : 0.0f;
  }
  if (total > 0) s->marg[h] = 1.0f;
  build_guide(s->marg, h, s->mguide);
  for (int y = 0; y < h; y++)
    build_guide(s->cond + (size_t)y * (size_t)(w + 1), w, s->cguide + (size_t)y * (CV_ENV_GUIDE + 1));
}

static cv_env_sampler *sampler_alloc(int w, int h, int f) {
  cv_env_sampler *s = calloc(1, sizeof *s);
  if (!s) return NULL;
  s->w = w;
  s->h = h;
  s->f = f;
  s->marg = malloc((size_t)(h + 1) * sizeof(float));
  s->cond = malloc((size_t)h * (size_t)(w + 1) * sizeof(float));
  s->cos_edge = malloc((size_t)(h + 1) * sizeof(float));
  s->inv_sa = malloc((size_t)h * sizeof(float));
  s->mguide = malloc((CV_ENV_GUIDE + 1) * sizeof(uint16_t));
  s->cguide = malloc((size_t)h * (CV_ENV_GUIDE + 1) * sizeof(uint16_t));
  if (!s->marg || !s->cond || !s->cos_edge || !s->inv_sa || !s->mguide || !s->cguide) {
    cv_env_sampler_destroy(s);
    return NULL;
  }
  return s;
}

int cv_env_sampler_create(const cv_envmap *env, cv_env_sampler **out) {
  *out = NULL;
  if (!env || !env->img || env->img->w < 1 || env->img->h < 1 || env->img->w >= 65536 ||
      env->img->h >= 65536 || env->img->c < 3)
    return CV_ERR_INVALID;
  const int pw = env->img->w, ph = env->img->h, nc = env->img->c;
  /* cells of f x f pixels: f the smallest power of two that brings the
   * width to at most CV_ENV_SAMPLE_MAX_W while dividing both sizes */
  int f = 1;
  while (pw / f > CV_ENV_SAMPLE_MAX_W && pw % (2 * f) == 0 && ph % (2 * f) == 0) f *= 2;
  const int w = pw / f, h = ph / f;
  cv_env_sampler *s = sampler_alloc(w, h, f);
  if (!s) return CV_ERR_NOMEM;
  double *row = malloc((size_t)h * sizeof(double));
  double *cum = malloc((size_t)(w + 1) * sizeof(double));
  double *cw = calloc((size_t)w * (size_t)h, sizeof(double));
  if (!row || !cum || !cw) {
    free(row);
    free(cum);
    free(cw);
    cv_env_sampler_destroy(s);
    return CV_ERR_NOMEM;
  }
  for (int y = 0; y <= h; y++) s->cos_edge[y] = (float)cos(M_PI * y / h);
  s->cos_edge[0] = 1.0f;
  s->cos_edge[h] = -1.0f;
  for (int y = 0; y < h; y++) {
    /* the solid angle of the float cell edges the sampler uses */
    const double sa = 2 * M_PI / w * ((double)s->cos_edge[y] - (double)s->cos_edge[y + 1]);
    s->inv_sa[y] = sa > 0 ? (float)(1 / sa) : 0.0f;
    /* a cell's weight: the sum of its pixels' Y x their solid angle */
    double *cr = cw + (size_t)y * (size_t)w;
    for (int py = y * f; py < (y + 1) * f; py++) {
      const double psa = 2 * M_PI / pw * (cos(M_PI * py / ph) - cos(M_PI * (py + 1) / ph));
      const float *px = env->img->px + (size_t)py * (size_t)pw * (size_t)nc;
      for (int x = 0; x < pw; x++) {
        const float *q = px + (size_t)x * (size_t)nc;
        double Y = cv_luminance(q[0], q[1], q[2]);
        if (!(Y > 0) || !isfinite(Y)) Y = 0;
        cr[x / f] += Y * psa;
      }
    }
  }
  build_cdfs(s, cw, row, cum);
  free(row);
  free(cum);
  free(cw);
  *out = s;
  return CV_OK;
}

/* Unit direction at lat-long (u, cos theta). */
static void dir_at(double u, double ct, double d[3]) {
  const double st = sqrt(fmax(0.0, 1 - ct * ct)), ph = 2 * M_PI * (u - 0.5);
  d[0] = st * sin(ph);
  d[1] = ct;
  d[2] = -st * cos(ph);
}

/* A sampler over src's grid whose cell weights are src's cell probabilities
 * times weight(src, x, y, ctx) (>= 0); its total is scaled by src's. */
typedef double (*cell_weight_fn)(const cv_env_sampler *src, int x, int y, const void *ctx);

static int derive_sampler(const cv_env_sampler *src, cell_weight_fn weight, const void *ctx,
                          cv_env_sampler **out) {
  const int w = src->w, h = src->h;
  cv_env_sampler *s = sampler_alloc(w, h, src->f);
  double *row = malloc((size_t)h * sizeof(double));
  double *cum = malloc((size_t)(w + 1) * sizeof(double));
  double *cw = malloc((size_t)w * (size_t)h * sizeof(double) + 1);
  if (!s || !row || !cum || !cw) {
    cv_env_sampler_destroy(s);
    free(row);
    free(cum);
    free(cw);
    return CV_ERR_NOMEM;
  }
  memcpy(s->cos_edge, src->cos_edge, (size_t)(h + 1) * sizeof(float));
  memcpy(s->inv_sa, src->inv_sa, (size_t)h * sizeof(float));
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      const double p = cv_env_sampler_cell_prob(src, x, y);
      cw[(size_t)y * (size_t)w + (size_t)x] = p > 0 ? p * weight(src, x, y, ctx) : 0.0;
    }
  build_cdfs(s, cw, row, cum);
  s->total *= src->total;
  free(row);
  free(cum);
  free(cw);
  *out = s;
  return CV_OK;
}

/* 1 when some of cell (x, y) lies in front of the plane with normal n
 * (3 x 3 points of the cell tested), else 0. */
static double front_weight(const cv_env_sampler *src, int x, int y, const void *ctx) {
  const float *n = ctx;
  double front = 0;
  for (int j = 0; j < 3; j++)
    for (int i = 0; i < 3; i++) {
      double d[3];
      const double ct = src->cos_edge[y] + 0.5 * j * ((double)src->cos_edge[y + 1] - src->cos_edge[y]);
      dir_at((x + 0.5 * i) / src->w, ct, d);
      front = fmax(front, d[0] * n[0] + d[1] * n[1] + d[2] * n[2]);
    }
  return front > 0 ? 1.0 : 0.0;
}

int cv_env_sampler_restrict(const cv_env_sampler *src, const float n[3], cv_env_sampler **out) {
  *out = NULL;
  if (!src || !n) return CV_ERR_INVALID;
  return derive_sampler(src, front_weight, n, out);
}

/* The caller's weight of cell (x, y); a negative or non-finite one is 0. */
static double table_weight(const cv_env_sampler *src, int x, int y, const void *ctx) {
  const double k = ((const float *)ctx)[(size_t)y * (size_t)src->w + (size_t)x];
  return k > 0 && isfinite(k) ? k : 0.0;
}

int cv_env_sampler_reweight(const cv_env_sampler *src, const float *cell_w, cv_env_sampler **out) {
  *out = NULL;
  if (!src || !cell_w) return CV_ERR_INVALID;
  return derive_sampler(src, table_weight, cell_w, out);
}

double cv_env_sampler_cell_prob(const cv_env_sampler *s, int x, int y) {
  if (!(s->total > 0) || x < 0 || y < 0 || x >= s->w || y >= s->h) return 0;
  const float *c = s->cond + (size_t)y * (size_t)(s->w + 1);
  return ((double)s->marg[y + 1] - s->marg[y]) * ((double)c[x + 1] - c[x]);
}

/* The i in [0, n) with cdf[i] <= u < cdf[i + 1] (cdf[0] = 0 <= u < cdf[n] = 1):
 * never an empty interval.  It lies between the guides of u's bucket
 * (Chen & Asau's cutpoint method): a binary search over those few cells
 * instead of the whole CDF, with the same answer. */
static inline int cdf_find(const float *cdf, const uint16_t *guide, float u) {
  int g = (int)(u * CV_ENV_GUIDE); /* u < 1: g < CV_ENV_GUIDE */
  g = g < 0 ? 0 : g;
  int lo = guide[g], hi = guide[g + 1] + 1; /* cdf[lo] <= u < cdf[hi] */
  while (hi - lo > 1) {
    const int mid = (lo + hi) >> 1;
    if (cdf[mid] <= u) lo = mid;
    else hi = mid;
  }
  return lo;
}

int cv_env_sampler_sample(const cv_env_sampler *s, const float u[2], float d[3], float *pdf) {
  if (!(s->total > 0)) return 0;
  const int w = s->w;
  const float u0 = u[0] < 1.0f ? u[0] : 0x1.fffffep-1f, u1 = u[1] < 1.0f ? u[1] : 0x1.fffffep-1f;
  const int y = cdf_find(s->marg, s->mguide, u1);
  const float *c = s->cond + (size_t)y * (size_t)(w + 1);
  const int x = cdf_find(c, s->cguide + (size_t)y * (CV_ENV_GUIDE + 1), u0);
  const float pr = s->marg[y + 1] - s->marg[y], pc = c[x + 1] - c[x];
  float r1 = (u1 - s->marg[y]) / pr, r0 = (u0 - c[x]) / pc;
  r0 = r0 < 0 ? 0 : (r0 >= 1 ? 0x1.fffffep-1f : r0);
  r1 = r1 < 0 ? 0 : (r1 >= 1 ? 0x1.fffffep-1f : r1);
  const float ct = s->cos_edge[y] + r1 * (s->cos_edge[y + 1] - s->cos_edge[y]);
  const float st = sqrtf(fmaxf(0.0f, 1 - ct * ct));
  float sp, cp;
  cv_fast_sincos2pi(((float)x + r0) / (float)w - 0.5f, &sp, &cp);
  d[0] = st * sp;
  d[1] = ct;
  d[2] = -st * cp;
  *pdf = (float)((double)pr * (double)pc * (double)s->inv_sa[y]);
  return 1;
}

float cv_env_sampler_pdf(const cv_env_sampler *s, const float d[3]) {
  if (!(s->total > 0)) return 0;
  const int w = s->w, h = s->h;
  const float ct = d[1] > 1 ? 1 : (d[1] < -1 ? -1 : d[1]);
  int y = (int)(acosf(ct) * (float)M_1_PI * (float)h);
  y = y < 0 ? 0 : (y >= h ? h - 1 : y);
  /* the row whose (cos_edge[y + 1], cos_edge[y]] holds ct, as sampled */
  while (y > 0 && ct > s->cos_edge[y]) y--;
  while (y < h - 1 && ct <= s->cos_edge[y + 1]) y++;
  float uu = 0.5f + cv_fast_atan2(d[0], -d[2]) * (float)(0.5 * M_1_PI);
  if (uu >= 1) uu -= 1;
  if (uu < 0) uu = 0;
  int x = (int)(uu * (float)w);
  x = x >= w ? w - 1 : x;
  const float *c = s->cond + (size_t)y * (size_t)(w + 1);
  return (float)(((double)s->marg[y + 1] - s->marg[y]) * ((double)c[x + 1] - c[x]) *
                 (double)s->inv_sa[y]);
}
