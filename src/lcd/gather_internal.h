/* Internal to src/lcd's final gather (gather.c, lcd_light.c, lcd_strategies.c,
 * lcd_round.c, lcd_content.c): the gather's state, the environment
 * strategy's table cache, the per-block ray buffers and the sampling
 * strategies' inline parts.  Not for use outside src/lcd. */
#ifndef CV_LCD_GATHER_INTERNAL_H
#define CV_LCD_GATHER_INTERNAL_H

#include <math.h>
#include <omp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/fast_trig.h"
#include "core/hash.h"
#include "lcd/gather.h"
#include "light/sun.h"
#include "prt/relight.h"

/* lcd_strategies.c: this thread's CPU seconds (the phase_seconds hook). */
double lcdg_thread_seconds(void);

struct cv_lcd_gather {
  const cv_rt *rt;
  uint32_t *tri;
  size_t nt, nv;
  int has_windows;
  cv_lcd_panel panel;
  const cv_brdf *brdf;
  cv_brdf_sampler *smp;
  cv_sobol_tab sobol;
  /* window openings (one per window material) for window sampling: the
   * distinct vertices of each, xyz */
  int nopen;
  float **open_pos;
  int *open_nv;
  /* interior light sampling: vertex positions (3 nv) and per triangle the
   * unit normal and area (4 nt) */
  float *pos;
  float *tnA;
  float *envvis; /* ENV_RX x ENV_RY regions of VIS_H x VIS_W lat-long cells: the fraction of
                    probe rays from the region that reach the environment (NULL: no windows);
                    computed by cv_lcd_gather_create, like tgeo */
  /* the environment strategy's tables of the last (light, eye) (env_tables
   * below); a pure function of them, kept across calls under the lock */
  struct env_tables *etab;
  omp_lock_t etab_lock;
  int lock_ready;
  float *tgeo;  /* per triangle: unoccluded share of its light the panel receives, up to a
                   constant: cos at the triangle x cos at the panel / r^2 from the panel
                   centre, times the fraction of 5 panel points that see its centroid */
};

static inline float dot3(const float a[3], const float b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void cross3(const float a[3], const float b[3], float o[3]) {
  o[0] = a[1] * b[2] - a[2] * b[1];
  o[1] = a[2] * b[0] - a[0] * b[2];
  o[2] = a[0] * b[1] - a[1] * b[0];
}
static inline int normalize3(float a[3]) {
  float l = sqrtf(dot3(a, a));
  if (!(l > 0)) return 0;
  for (int k = 0; k < 3; k++) a[k] /= l;
  return 1;
}


/* Regions of the panel for the environment strategy: ENV_RX x ENV_RY equal
 * parts of the panel rectangle (a block belongs to the one that holds its
 * centre); VIS_W x VIS_H lat-long cells (layout of light/env_sample.h). */
#define ENV_RX 4
#define ENV_RY 3
#define VIS_W 128
#define VIS_H 64


/* The environment strategy's tables for one (light, eye): the light's
 * tables restricted to the panel's front and, with windows, the region
 * tables (env_regions).  About 12 ms to build on the default cabin, so
 * they are kept for the last (light, eye) a call used: a progressive
 * gather renders round after round, tile after tile, with the same light
 * and eye.  Reference-counted (the cache holds one reference, each round
 * using them another), so a call never sees them freed under it; being a
 * pure function of (gather, light, eye), whoever builds them, the samples
 * are the same. */
typedef struct env_tables {
  int refs;
  uint64_t light_hash;
  float eye[3];
  cv_env_sampler *esr;                   /* restricted to the panel's front */
  cv_env_sampler *ereg[ENV_RX * ENV_RY]; /* per region (NULL: esr for all) */
} env_tables;

/* Trace blocks: the gather rays of BLOCK x BLOCK texels (aligned to the
 * panel's texel grid, clipped to the panel, never to the tile) and at most
 * CHUNK_SPP samples per texel are sorted by direction and traced in packets
 * of CV_RT_PACKET_MAX.  Rays of one texel spread over the BRDF lobe, but the
 * mirror direction moves slowly across the panel, so sorting thousands of
 * rays by direction gathers nearly parallel rays from nearby origins into
 * each packet, which Embree's coherent packet traversal walks together.
 * The composition of every packet depends only on (panel size, block,
 * samples), never on the tile, split or thread count: a tile that cuts a
 * block still traces the whole block (and keeps its own texels), so that
 * every ray's hit, and hence every texel's sums, are bit-identical whatever
 * the tiling (Embree's packet kernels may round t, u, v differently for
 * another packet composition). */
#define BLOCK 16
#define CHUNK_SPP 64

/* Clamps one sample's RGB (counted) and adds it in fixed point. */
static inline void add_sample(float v[3], double clamp, double inv_unit, int64_t s[3],
                              int64_t s2[2], int64_t *cnt) {
  for (int c = 0; c < 3; c++) {
    if (!isfinite(v[c]) || v[c] < 0) {
      v[c] = 0;
      cnt[CV_LCD_ACC_NONFINITE]++;
    } else if (v[c] > clamp) {
      v[c] = (float)clamp;
      cnt[CV_LCD_ACC_CLAMPED]++;
    }
    s[c] += (int64_t)((double)v[c] * inv_unit + 0.5);
  }
  double y = 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
  unsigned __int128 q = (uint64_t)(y * inv_unit + 0.5);
  q *= q; /* < 2^81: the clamp bounds y */
  s2[0] += (int64_t)(q >> CV_LCD_M2_SHIFT);
  s2[1] += (int64_t)(q & ((1ull << CV_LCD_M2_SHIFT) - 1));
}

/* Strategies (gather.h). */
enum { STRAT_BRDF = 0, STRAT_COS, STRAT_WIN, STRAT_ENV, STRAT_INT, NSTRAT };

/* Per-texel state of a block. */
typedef struct texel_state {
  int in_tile;        /* its sums go to the buffer */
  int behind;         /* the eye sees the panel's back: no rays */
  size_t aix;         /* buffer texel (in_tile only) */
  float pc[3], off[3], tn[3], bn[3];
  int kb;
  float tb;
  uint32_t seed[NSTRAT], dseed[NSTRAT][4]; /* one sequence per strategy */
  float nee[3];       /* sun term of the round */
  int64_t s[3], s2[2];
} texel_state;

/* Window-strategy rectangles of one block, in the panel's projected disk
 * (a, b) = (w.u, w.v): cosine-weighted directions restricted to them have
 * the density p_w = cos * (rectangles holding (a, b)) / (their total area). */
typedef struct win_rects {
  int n;
  float r[CV_LCD_MAX_OPENINGS][4]; /* a0, a1, b0, b1 */
  float cum[CV_LCD_MAX_OPENINGS];  /* cumulative areas */
  float total;
} win_rects;

/* Scratch of one thread: the rays of one block and chunk. */
typedef struct block_buf {
  size_t cap;
  float *org, *dir;      /* 3 per ray */
  float *fc;             /* f cos (RGB) and the interior MIS denominator c_b p_b + c_c p_c;
                            window-strategy rays: the local direction and -1 (f and p_b are
                            evaluated only if the ray leaves through a window) */
  uint32_t *tex;         /* texel in the block; | TEX_WIN for window- and environment-strategy
                            rays */
  uint16_t *key;
  uint32_t *ord, *tmp;
  /* the rays permuted into direction order (traced and shaded in order) */
  float *sorg, *sdir, *sfc;
  uint32_t *stex;
  uint32_t *want, *swant;/* interior-strategy rays: the triangle aimed at (the sample counts
                            only if it is the first hit); other rays: NO_TRI */
  uint32_t *htri;        /* hit triangle (kind 1) */
  float *huv;            /* its barycentrics u, v */
  float *ht;             /* its distance */
  uint8_t *kind;
  texel_state *ts;       /* BLOCK * BLOCK */
} block_buf;

#define TEX_WIN 0x80000000u
#define NO_TRI 0xFFFFFFFFu

/* Density of the window strategy for a world direction d (1/sr). */
static inline float window_pdf(const cv_lcd_panel *pn, const win_rects *wr, const float d[3]) {
  const float z = dot3(d, pn->normal);
  if (!(z > 0) || !(wr->total > 0)) return 0;
  const float a = dot3(d, pn->u), b = dot3(d, pn->v);
  int in = 0;
  for (int k = 0; k < wr->n; k++)
    in += a >= wr->r[k][0] && a < wr->r[k][1] && b >= wr->r[k][2] && b < wr->r[k][3];
  return z * (float)in / wr->total;
}

/* A window-strategy direction from u[0..1]: a rectangle by area, a point in
 * it (u0 rescaled within the rectangle's share, so the map stays monotone
 * in each), lifted to the hemisphere.  Returns 0 outside the disk. */
static inline int window_sample(const cv_lcd_panel *pn, const win_rects *wr, const float u[2],
                                float d[3]) {
  if (!(wr->total > 0)) return 0;
  const float x = u[0] * wr->total;
  int k = 0;
  while (k < wr->n - 1 && wr->cum[k] <= x) k++;
  const float c0 = k ? wr->cum[k - 1] : 0.0f, w = wr->cum[k] - c0;
  float s = w > 0 ? (x - c0) / w : 0.5f;
  s = s < 0 ? 0 : (s > 1 ? 1 : s);
  const float *r = wr->r[k];
  const float a = r[0] + s * (r[1] - r[0]), b = r[2] + u[1] * (r[3] - r[2]);
  const float z2 = 1 - a * a - b * b;
  if (!(z2 > 0)) return 0;
  const float z = sqrtf(z2);
  for (int i = 0; i < 3; i++) d[i] = a * pn->u[i] + b * pn->v[i] + z * pn->normal[i];
  return 1;
}

/* 16-bit sort key of a unit direction: Morton order of its octahedral
 * coordinates quantised to 8 bits each (cells of about 1 degree). */
static inline uint16_t dir_key(const float d[3]) {
  float s = fabsf(d[0]) + fabsf(d[1]) + fabsf(d[2]);
  float x = d[0] / s, y = d[1] / s;
  if (d[2] < 0) {
    float ox = x;
    x = (1 - fabsf(y)) * (x >= 0 ? 1.0f : -1.0f);
    y = (1 - fabsf(ox)) * (y >= 0 ? 1.0f : -1.0f);
  }
  uint32_t qx = (uint32_t)((x * 0.5f + 0.5f) * 255.0f + 0.5f);
  uint32_t qy = (uint32_t)((y * 0.5f + 0.5f) * 255.0f + 0.5f);
  qx &= 255, qy &= 255;
  qx = (qx | (qx << 4)) & 0x0F0Fu;
  qx = (qx | (qx << 2)) & 0x3333u;
  qx = (qx | (qx << 1)) & 0x5555u;
  qy = (qy | (qy << 4)) & 0x0F0Fu;
  qy = (qy | (qy << 2)) & 0x3333u;
  qy = (qy | (qy << 1)) & 0x5555u;
  return (uint16_t)(qx | (qy << 1));
}

/* The phase_seconds hook: with ph non-NULL, the thread time since the last
 * mark (*tm) is added to ph[k] (k == CV_LCD_PHASES: a mark only). */
static inline void phase_mark(double *ph, int k, double *tm) {
  if (!ph) return;
  const double t = lcdg_thread_seconds();
  if (k < CV_LCD_PHASES) ph[k] += t - *tm;
  *tm = t;
}

/* Bilinear lookup of a lat-long table in float (the layout and filter of
 * light/envmap.c's cv_envmap_lookup, without its double-precision
 * trigonometry), in two steps so that the texels of many rays can be
 * prefetched before any is read: env_texel gives the top-left texel
 * (y0 << 16 | x0) and the weights of d (unit), env_fetch filters. */
static inline uint32_t env_texel(const cv_image *img, const float d[3], float *tx, float *ty) {
  const int w = img->w, h = img->h;
  float y = d[1];
  y = y > 1 ? 1 : (y < -1 ? -1 : y);
  float u = 0.5f + cv_fast_atan2(d[0], -d[2]) * (float)(0.5 * M_1_PI);
  if (u >= 1) u -= 1;
  if (u < 0) u = 0;
  const float v = acosf(y) * (float)M_1_PI;
  const float fx = u * (float)w - 0.5f, fy = v * (float)h - 0.5f;
  const float flx = floorf(fx), fly = floorf(fy);
  *tx = fx - flx;
  *ty = fy - fly;
  int x0 = (int)flx;
  if (x0 < 0) x0 += w;
  if (x0 >= w) x0 -= w;
  int y0 = (int)fly;
  if (y0 < 0) {
    y0 = 0;
    *ty = 0;
  } else if (y0 + 1 >= h) {
    y0 = h - 1;
    *ty = 0;
  }
  return (uint32_t)y0 << 16 | (uint32_t)x0;
}

static inline const float *env_px(const cv_image *img, uint32_t t) {
  return img->px + 3 * ((size_t)(t >> 16) * (size_t)img->w + (t & 0xFFFFu));
}

static inline void env_fetch(const cv_image *img, uint32_t t, float tx, float ty, float rgb[3]) {
  const int w = img->w, x0 = (int)(t & 0xFFFFu), x1 = x0 + 1 == w ? 0 : x0 + 1;
  const float *p00 = env_px(img, t), *p10 = p00 + 3 * (x1 - x0);
  const size_t row = ty > 0 ? 3 * (size_t)w : 0; /* ty = 0: the lower row has no weight */
  const float *p01 = p00 + row, *p11 = p10 + row;
  for (int c = 0; c < 3; c++) {
    const float a = p00[c] + tx * (p10[c] - p00[c]), b = p01[c] + tx * (p11[c] - p01[c]);
    rgb[c] = a + ty * (b - a);
  }
}

/* Interior light sampling: triangles drawn by area x mean luminance of the
 * PRT exit radiance at their vertices x tgeo (what the panel receives of
 * them: view factor to the panel centre and visibility, computed once per
 * gather) (Walker's alias table, Vose's construction), a point uniform on
 * the triangle; only triangles with a vertex in front of the panel's plane
 * take part.  The density of a point
 * (area measure) is pa[t] = luminance(t) / total; a direction d that first
 * hits triangle t at distance r has the density pa[t] r^2 / |d . n_t|. */
typedef struct int_table {
  size_t n;
  float *prob;   /* alias acceptance */
  uint32_t *alias;
  float *pa;     /* area density of each triangle's points (0: never drawn) */
  double total;
} int_table;

/* An interior-strategy direction from o: u[0] picks the triangle (alias
 * table; its remainder and u[1] the point), h a third uniform coordinate.
 * Returns the triangle, or NO_TRI when the point is degenerate; *pd = the
 * direction's density pa r^2 / |d . n| (1/sr). */
static inline uint32_t interior_sample(const cv_lcd_gather *g, const int_table *it, const float o[3],
                                       const float u[2], uint32_t h, float d[3], float *pd) {
  const float x = u[0] * (float)it->n;
  size_t i = (size_t)x;
  if (i >= it->n) i = it->n - 1;
  float fr = x - (float)i;
  uint32_t t = (uint32_t)i;
  if (fr >= it->prob[i]) t = it->alias[i];
  const float s = sqrtf(u[1]), b1 = (float)(h >> 8) * 0x1p-24f;
  const float w1 = (1 - b1) * s, w2 = b1 * s, w0 = 1 - s;
  const uint32_t *v = g->tri + 3 * (size_t)t;
  const float *p0 = g->pos + 3 * (size_t)v[0], *p1 = g->pos + 3 * (size_t)v[1], *p2 = g->pos + 3 * (size_t)v[2];
  float r2 = 0;
  for (int k = 0; k < 3; k++) {
    d[k] = w0 * p0[k] + w1 * p1[k] + w2 * p2[k] - o[k];
    r2 += d[k] * d[k];
  }
  if (!(r2 > 0)) return NO_TRI;
  const float r = sqrtf(r2);
  for (int k = 0; k < 3; k++) d[k] /= r;
  const float c = fabsf(dot3(d, g->tnA + 4 * (size_t)t));
  if (!(c > 1e-6f) || !(it->pa[t] > 0)) return NO_TRI;
  *pd = it->pa[t] * r2 / c;
  return t;
}

/* The density of the interior strategy for a ray that first hits triangle
 * t at distance r along d. */
static inline float interior_pdf(const cv_lcd_gather *g, const int_table *it, uint32_t t, float r,
                                 const float d[3]) {
  const float c = fabsf(dot3(d, g->tnA + 4 * (size_t)t));
  return c > 1e-6f ? it->pa[t] * r * r / c : 0.0f;
}

/* The sun as a uniform disc of angular radius CV_LCD_SUN_HALF_ANGLE_DEG
 * around sun_dir (its irradiance at normal incidence E = L pi sin^2(alpha)
 * is the light's sun_E): radiance L, a frame around its centre, and the
 * one-direction estimate's factor L Omega = E 2 / (1 + cos alpha) (a
 * direction drawn uniformly in the cone has the density 1 / Omega). */
typedef struct sun_disc {
  float dir[3], t[3], b[3];
  float cos_a;      /* cos(alpha) */
  float L[3];       /* disc radiance */
  float E_omega[3]; /* L Omega */
} sun_disc;

/* A direction uniform in the disc's cone from two hashed integers. */
static inline void sun_disc_dir(const sun_disc *sf, uint32_t h0, uint32_t h1, float d[3]) {
  const float u0 = (float)(h0 >> 8) * 0x1p-24f, u1 = (float)(h1 >> 8) * 0x1p-24f;
  const float ct = 1 - u0 * (1 - sf->cos_a), st = sqrtf(fmaxf(0.0f, 1 - ct * ct));
  float sp, cp;
  cv_fast_sincos2pi(u1, &sp, &cp);
  const float a = st * cp, b = st * sp;
  for (int k = 0; k < 3; k++) d[k] = ct * sf->dir[k] + a * sf->t[k] + b * sf->b[k];
}

/* --- shared between the files of the gather (prefix lcdg_) ---------------- */

/* gather.c: the environment strategy's tables of (l, eye), from the cache or
 * built (one reference for the caller; NULL: out of memory), and their release. */
env_tables *lcdg_env_tables_get(const cv_lcd_gather *cg, const cv_lcd_light *l, const float eye[3]);
void lcdg_env_tables_release(const cv_lcd_gather *cg, env_tables *t);

/* lcd_strategies.c: block buffers, window rectangles, ray order and tracing,
 * the interior table and the sun disc. */
void lcdg_block_buf_free(block_buf *b);
int lcdg_block_buf_alloc(block_buf *b, size_t cap);
void lcdg_block_rects(const cv_lcd_gather *g, const float c[3], float hd, win_rects *wr);
void lcdg_sort_by_key(const uint16_t *key, size_t n, uint32_t *ord, uint32_t *tmp);
void lcdg_trace_sorted(const cv_rt *rt, int has_windows, block_buf *b, size_t n, double *ph,
                       double *tm);
void lcdg_int_table_free(int_table *it);
int lcdg_int_table_build(const cv_lcd_gather *g, const cv_lcd_light *l, int_table *it);
void lcdg_sun_disc_init(const cv_lcd_light *l, sun_disc *sf);

#endif
