/* PRT bake (see bake.h for the sampling scheme). */
#include "prt/bake.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "core/hash.h"
#include "core/progress.h"
#include "core/sobol.h"
#include "prt/tracer_internal.h"
#include "sh/sh.h"

/* One hit of the bounce pass and the function that adds it to the sums
 * (defined with the bounce pass below). */
typedef struct bounce_hit bounce_hit;
typedef void (*bounce_add_fn)(const bounce_hit *h, size_t rec, int nc, double *acc,
                              double *accr);

/* Mixing of the two strategies in the direct pass: a pilot of PILOT_RAYS
 * cosine rays (own seed, not part of the estimate, so the estimator stays
 * unbiased) measures the fraction f of directions that leave through a
 * window; the window strategy gets a = MAX_WINDOW_FRACTION * (1 - f / F_COS)
 * (0 when f >= F_COS), i.e. full MIS where almost nothing escapes and plain
 * cosine sampling where the sky is in plain view.  Measured on the cabin
 * (tess 2, 1024 rays, 25 coefficients, per-vertex mean / energy-weighted
 * error): a = 0.5: 9.2% / 4.1%, 0.75: 7.7% / 4.1%, 0.9: 7.0% / 4.1%; 0.75
 * keeps the balance-heuristic weight below 1 / (1 - a) = 4. */
#define PILOT_RAYS 32
#define MAX_WINDOW_FRACTION 0.75f
#define F_COS 0.3f

/* Direct pass for one vertex: acc[i] estimates (1/pi) * integral of
 * y_i(w) V(w) max(n.w, 0) dw; alb = mean albedo of the sampled triangles.
 *
 * Light reaches the interior only through the windows (V = 0 elsewhere), so
 * with windows present (and a pilot saying little sky is in view, see
 * MAX_WINDOW_FRACTION) each sample picks, by its 7th Sobol dimension, either
 * a cosine-weighted direction or a direction towards a uniform point on an
 * opening chosen with probability P_v(g) (window_probs), and is weighted by
 * the one-sample balance heuristic (Veach 1997): f / (a p_win + (1-a) p_cos)
 * with p_cos = cos / pi and p_win = P_v(g) d^2 / (|cos_q| A_g) from the
 * window crossing at distance d on opening g.  A
 * ray that leaves through a window crosses exactly one window triangle in a
 * convex shell; a second crossing would re-enter the car and be blocked. */
/* The albedo a triangle's own vertices store: 1 on a textured material (the
 * texture multiplies the irradiance per pixel), else the material's. */
static const float k_one[3] = {1.0f, 1.0f, 1.0f};
static const float *recv_albedo(const cv_mesh *m, uint32_t t) {
  uint32_t i = m->tri_mat[t];
  return m->mat_tex && m->mat_tex[i][0] ? k_one : m->mats[i].albedo;
}

/* With rf non-NULL, rgb[3] also gets the same estimator of
 * (1/pi) integral L(w) V cos dw for rf's radiance (same rays as acc). */
static void vertex_direct_rf(const cv_tracer *tr, uint32_t v, int bands, int rays, uint32_t seed,
                             double *acc, double alb[3], double albr[3],
                             const cv_radiance_fn *rf, double rgb[3]) {
  int nc = bands * bands;
  float Lr[3];
  if (rgb) rgb[0] = rgb[1] = rgb[2] = 0;
  float y[CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS];
  memset(acc, 0, (size_t)nc * sizeof(double));
  alb[0] = alb[1] = alb[2] = 0;
  albr[0] = albr[1] = albr[2] = 0;
  if (tr->fan_off[v + 1] == tr->fan_off[v]) return;
  vseq q;
  vseq_init(&q, seed, v);
  int mis = tr->window_mis && tr->ngroup > 0;
  float a = MAX_WINDOW_FRACTION;
  if (mis) {
    vseq pq;
    vseq_init(&pq, cv_hash_combine(seed, 0x9170u), v);
    int esc = 0;
    for (int j = 0; j < PILOT_RAYS; j++) {
      float u[6], p[3], org[3], dir[3];
      vseq_sample(&tr->sobol, &pq, (uint32_t)j, 6, u);
      const float *n = tr->tri_n + 3 * fan_point(tr, v, u, p);
      cv_rt_offset_origin(p, n, org);
      cosine_dir(n, u[0], u[1], dir);
      esc += cv_rt_reaches_env(tr->rt, org, dir, 0.0f);
    }
    float f = (float)esc / PILOT_RAYS;
    a = f >= F_COS ? 0.0f : MAX_WINDOW_FRACTION * (1.0f - f / F_COS);
    if (a <= 0.0f) mis = 0;
  }
  /* Opening probabilities from the vertex (position and normal of its fan). */
  double prob[64], cdf[64];
  if (mis) {
    float vn[3] = {0, 0, 0};
    for (size_t k = tr->fan_off[v]; k < tr->fan_off[v + 1]; k++)
      for (int c = 0; c < 3; c++) vn[c] += tr->tri_n[3 * (tr->fan_tri[k] >> 2) + c];
    mis = tr->ngroup <= 64 && window_probs(tr, tr->m->pos + 3 * v, vn, prob);
    double acc_p = 0;
    for (int g = 0; mis && g < tr->ngroup; g++) cdf[g] = (acc_p += prob[g]);
  }
  for (int j = 0; j < rays; j++) {
    float u[7], p[3], org[3], dir[3];
    vseq_sample(&tr->sobol, &q, (uint32_t)j, mis ? 7 : 6, u);
    uint32_t t = fan_point(tr, v, u, p);
    const float *n = tr->tri_n + 3 * t;
    const float *al = tr->m->mats[tr->m->tri_mat[t]].albedo, *ar = recv_albedo(tr->m, t);
    for (int k = 0; k < 3; k++) {
      alb[k] += al[k];
      albr[k] += ar[k];
    }
    cv_rt_offset_origin(p, n, org);
    if (!mis) {
      cosine_dir(n, u[0], u[1], dir);
      if (!cv_rt_reaches_env(tr->rt, org, dir, 0.0f)) continue;
      cv_sh_eval(bands, dir, y);
      for (int i = 0; i < nc; i++) acc[i] += y[i];
      if (rf) {
        rf->fn(rf->ctx, dir, Lr);
        for (int c = 0; c < 3; c++) rgb[c] += Lr[c];
      }
      continue;
    }
    if (u[6] < a) {
      float wq[3], l2 = 0, r0 = u[0];
      int g = 0; /* opening by cdf, u0 rescaled within its bucket */
      while (g < tr->ngroup - 1 && cdf[g] <= r0) g++;
      double c0 = g ? cdf[g - 1] : 0.0, pw = cdf[g] - c0;
      r0 = pw > 0 ? (float)((r0 - c0) / pw) : 0.5f;
      if (r0 >= 1.0f) r0 = 0x1.fffffep-1f;
      window_point(tr, g, r0, u[1], wq);
      for (int k = 0; k < 3; k++) {
        dir[k] = wq[k] - org[k];
        l2 += dir[k] * dir[k];
      }
      if (!(l2 > 0)) continue;
      float il = 1.0f / sqrtf(l2);
      for (int k = 0; k < 3; k++) dir[k] *= il;
    } else {
      cosine_dir(n, u[0], u[1], dir);
    }
    float cos_o = n[0] * dir[0] + n[1] * dir[1] + n[2] * dir[2];
    if (cos_o <= 0.0f) continue;
    /* Most directions are blocked: test that first, then find the crossing. */
    if (cv_rt_occluded(tr->rt, org, dir, 0.0f, INFINITY)) continue;
    cv_hit wh;
    if (!cv_rt_window_hit(tr->rt, org, dir, 0.0f, &wh)) continue;
    double nl = sqrt((double)wh.ng[0] * wh.ng[0] + (double)wh.ng[1] * wh.ng[1] +
                     (double)wh.ng[2] * wh.ng[2]);
    double cos_q = fabs((wh.ng[0] * dir[0] + wh.ng[1] * dir[1] + wh.ng[2] * dir[2]) / nl);
    const struct win_group *G = &tr->groups[tr->tri_group[wh.tri]];
    double p_win = cos_q > 0 ? prob[tr->tri_group[wh.tri]] * (double)wh.t * wh.t / (cos_q * G->area)
                             : 0.0;
    double p_cos = cos_o / M_PI;
    double w = (cos_o / M_PI) / (a * p_win + (1 - a) * p_cos);
    cv_sh_eval(bands, dir, y);
    for (int i = 0; i < nc; i++) acc[i] += w * y[i];
    if (rf) {
      rf->fn(rf->ctx, dir, Lr);
      for (int c = 0; c < 3; c++) rgb[c] += w * Lr[c];
    }
  }
  for (int i = 0; i < nc; i++) acc[i] /= rays;
  if (rgb)
    for (int c = 0; c < 3; c++) rgb[c] /= rays;
  for (int k = 0; k < 3; k++) {
    alb[k] /= rays;
    albr[k] /= rays;
  }
}

/* Prefetches the cache lines of the bytes [p, p + n), n > 0 (hint only). */
static inline void prefetch_range(const void *p, size_t n) {
  uintptr_t a = (uintptr_t)p & ~(uintptr_t)63, e = (uintptr_t)p + n;
  for (; a < e; a += 64) __builtin_prefetch((const void *)a, 0, 1);
}

/* --- the previous bounce as the bounce pass reads it ------------------------
 * Each hit interpolates three vertex records scattered over the whole mesh, so
 * the pass is bound by the bytes it pulls from memory.  A record holds a float
 * scale (the largest |value|) and the 3 * n * n values divided by it as IEEE
 * half floats (11 significant bits: relative rounding <= 2^-12 of the record's
 * largest value); records are STRIDE bytes apart, a multiple of 32 so that a
 * 25-coefficient record (154 bytes) spans exactly 3 cache lines instead of the
 * 5-6 of 75 floats, in memory aligned for (and advised to use) 2 MB pages. */
struct cv_bounce_records {
  size_t nv, rec, stride; /* vertices, values per record, bytes per record */
  unsigned char *data;
  size_t bytes;
};

#define HUGE_PAGE ((size_t)2 << 20)

/* Half float (bits) of x, |x| <= 1 and finite; rounds to nearest even
 * (after F. Giesen's float_to_half_fast3_rtne, public domain).  Below the
 * smallest normal half (2^-14) the FPU does the rounding: adding 0.5, whose
 * ulp (2^-24) is the half denormal's, leaves the denormal's bits in the low
 * mantissa.  (The magic number was once 2^8, whose ulp is 2^-15: denormals
 * came out 2^9 times too small, at most 2^-14 of the record's scale off.) */
static uint16_t half_from_float(float x) {
  uint32_t f, sign;
  memcpy(&f, &x, 4);
  sign = f & 0x80000000u;
  f ^= sign;
  uint16_t o;
  if (f < (113u << 23)) { /* below 2^-14, the smallest normal half */
    if (f < (102u << 23)) { /* below 2^-25, half the smallest denormal: 0 (also under DAZ) */
      o = 0;
    } else {
      float d, magic;
      const uint32_t mb = 126u << 23; /* 0.5 */
      memcpy(&magic, &mb, 4);
      memcpy(&d, &f, 4);
      d += magic;
      memcpy(&f, &d, 4);
      o = (uint16_t)(f - mb);
    }
  } else {
    uint32_t mant_odd = (f >> 13) & 1u;
    f += ((uint32_t)(15 - 127) << 23) + 0xfffu;
    f += mant_odd;
    o = (uint16_t)(f >> 13);
  }
  return (uint16_t)(o | (sign >> 16));
}

/* Float of half bits h (finite halves only), exact, also with the bake's
 * flush-to-zero / denormals-are-zero on (cv_rt_thread_init); the same values
 * as F16C's vcvtph2ps.  The exponent is rebiased in the integer bits; a
 * denormal half m x 2^-24 is first read as the normal float 2^-14 (1 + m /
 * 1024), then 2^-14 is subtracted (exact), so no float denormal is ever made
 * (DAZ would read it as 0).  Integer masks, no branch: loops of it vectorise. */
static inline float half_to_float(uint16_t h) {
  const uint32_t mag = h & 0x7fffu, sign = (uint32_t)(h & 0x8000u) << 16;
  const uint32_t den = (uint32_t)-(int32_t)(mag < 0x400u); /* all ones for a denormal */
  uint32_t bits = (mag << 13) + ((uint32_t)(127 - 15) << 23) + (den & (1u << 23));
  const uint32_t magic = den & (113u << 23); /* 2^-14 or +0 */
  float f, mf;
  memcpy(&f, &bits, 4);
  memcpy(&mf, &magic, 4);
  f -= mf;
  memcpy(&bits, &f, 4);
  bits |= sign;
  memcpy(&f, &bits, 4);
  return f;
}

int cv_bounce_records_create(int bands, size_t nv, cv_bounce_records **out) {
  *out = NULL;
  if (bands < 1 || bands > CV_PRT_MAX_BANDS) return CV_ERR_RANGE;
  cv_bounce_records *r = calloc(1, sizeof *r);
  if (!r) return CV_ERR_NOMEM;
  r->nv = nv;
  r->rec = 3 * (size_t)bands * (size_t)bands;
  r->stride = (sizeof(float) + 2 * r->rec + 31) & ~(size_t)31;
  r->bytes = (nv * r->stride + HUGE_PAGE - 1) / HUGE_PAGE * HUGE_PAGE;
  if (r->bytes == 0) r->bytes = HUGE_PAGE;
  r->data = aligned_alloc(HUGE_PAGE, r->bytes);
  if (!r->data) {
    free(r);
    return CV_ERR_NOMEM;
  }
#ifdef MADV_HUGEPAGE
  madvise(r->data, r->bytes, MADV_HUGEPAGE); /* a hint: fewer TLB misses */
#endif
  memset(r->data, 0, r->bytes);
  *out = r;
  return CV_OK;
}

void cv_bounce_records_destroy(cv_bounce_records *r) {
  if (!r) return;
  free(r->data);
  free(r);
}

void cv_bounce_records_set(cv_bounce_records *r, size_t v, const float *val) {
  unsigned char *p = r->data + v * r->stride;
  float scale = 0;
  for (size_t i = 0; i < r->rec; i++) scale = fmaxf(scale, fabsf(val[i]));
  uint16_t *h = (uint16_t *)(void *)(p + sizeof(float));
  if (!(scale > 0) || !isfinite(scale)) scale = 0;
  const float inv = scale > 0 ? 1.0f / scale : 0.0f;
  for (size_t i = 0; i < r->rec; i++) {
    float x = val[i] * inv;
    h[i] = half_from_float(x > 1.0f ? 1.0f : (x < -1.0f ? -1.0f : x));
  }
  memcpy(p, &scale, sizeof scale);
}

void cv_bounce_records_get(const cv_bounce_records *r, size_t v, float *val) {
  const unsigned char *p = r->data + v * r->stride;
  float scale;
  memcpy(&scale, p, sizeof scale);
  const uint16_t *h = (const uint16_t *)(const void *)(p + sizeof(float));
  for (size_t i = 0; i < r->rec; i++) val[i] = scale * half_to_float(h[i]);
}

/* --- the bounce pass's sums -------------------------------------------------
 * One hit adds albedo(from) x (the three vertex records of the hit triangle
 * weighted by barycentrics and scales) to the vertex's 75 double sums.  Two
 * versions give the same bits: AVX2 + F16C (8 halves converted per
 * instruction, 4 doubles per add), chosen at run time when the CPU has both,
 * and a portable one; both compute each value as ((w0 h0 + w1 h1) + w2 h2) in
 * float with no fused multiply-add, then o += (double)a * value. */
struct bounce_hit {
  const unsigned char *rec[3]; /* records of the hit triangle's vertices */
  float b[3];                  /* barycentric weights of those vertices */
  const float *al, *alr;       /* albedo of the ray's origin triangle; receiver's own */
};

/* w[k] = barycentric k times record k's scale; q[k] = its half values. */
static inline void hit_weights(const bounce_hit *h, float w[3], const uint16_t *q[3]) {
  for (int k = 0; k < 3; k++) {
    float s;
    memcpy(&s, h->rec[k], sizeof s);
    w[k] = h->b[k] * s;
    q[k] = (const uint16_t *)(const void *)(h->rec[k] + sizeof(float));
  }
}

static void bounce_add_portable(const bounce_hit *h, size_t rec, int nc, double *acc,
                                double *accr) {
  float tmp[3 * CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS], w[3];
  const uint16_t *q[3];
  hit_weights(h, w, q);
#pragma omp simd
  for (size_t i = 0; i < rec; i++)
    tmp[i] = w[0] * half_to_float(q[0][i]) + w[1] * half_to_float(q[1][i]) +
             w[2] * half_to_float(q[2][i]);
  for (int pass = 0; pass < 2; pass++) {
    const float *al = pass ? h->alr : h->al;
    double *out = pass ? accr : acc;
    if (!out) continue;
    for (int c = 0; c < 3; c++) {
      const double a = al[c];
      double *o = out + c * nc;
      const float *t = tmp + c * nc;
#pragma omp simd
      for (int i = 0; i < nc; i++) o[i] += a * t[i];
    }
  }
}

#ifdef CV_BAKE_X86_SIMD
__attribute__((target("avx2,f16c"))) static void bounce_add_avx2(const bounce_hit *h,
                                                                  size_t rec, int nc,
                                                                  double *acc, double *accr) {
  float tmp[3 * CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS], w[3];
  const uint16_t *q[3];
  hit_weights(h, w, q);
  const __m256 w0 = _mm256_set1_ps(w[0]), w1 = _mm256_set1_ps(w[1]), w2 = _mm256_set1_ps(w[2]);
  size_t i = 0;
  for (; i + 8 <= rec; i += 8) {
    const __m256 a = _mm256_cvtph_ps(_mm_loadu_si128((const __m128i *)(const void *)(q[0] + i)));
    const __m256 b = _mm256_cvtph_ps(_mm_loadu_si128((const __m128i *)(const void *)(q[1] + i)));
    const __m256 c = _mm256_cvtph_ps(_mm_loadu_si128((const __m128i *)(const void *)(q[2] + i)));
    const __m256 s = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(w0, a), _mm256_mul_ps(w1, b)),
                                   _mm256_mul_ps(w2, c));
    _mm256_storeu_ps(tmp + i, s);
  }
  for (; i < rec; i++)
    tmp[i] = w[0] * half_to_float(q[0][i]) + w[1] * half_to_float(q[1][i]) +
             w[2] * half_to_float(q[2][i]);
  for (int pass = 0; pass < 2; pass++) {
    const float *al = pass ? h->alr : h->al;
    double *out = pass ? accr : acc;
    if (!out) continue;
    for (int c = 0; c < 3; c++) {
      const double as = al[c];
      const __m256d a = _mm256_set1_pd(as);
      double *o = out + c * nc;
      const float *t = tmp + c * nc;
      int k = 0;
      for (; k + 4 <= nc; k += 4)
        _mm256_storeu_pd(o + k, _mm256_add_pd(_mm256_loadu_pd(o + k),
                                              _mm256_mul_pd(a, _mm256_cvtps_pd(_mm_loadu_ps(t + k)))));
      for (; k < nc; k++) o[k] += as * t[k];
    }
  }
}
#endif

/* The tracer's sums: AVX2 when cv_tracer_set_simd chose them, else portable. */
static bounce_add_fn bounce_add_pick(int simd) {
#ifdef CV_BAKE_X86_SIMD
  if (simd) return bounce_add_avx2; /* the CPU's support checked by cv_tracer_set_simd */
#else
  (void)simd;
#endif
  return bounce_add_portable;
}

/* Bounce pass for one vertex: acc[c*nc+i] = mean of albedo_c(t) * prev(q)[c][i].
 * Rays are traced in packets of BOUNCE_BATCH consecutive samples
 * (rtcIntersect16 through cv_rt_intersect_packet_soa): their origins share
 * the vertex's fan, which makes them coherent enough that the packet beats 16
 * rtcIntersect1 calls (docs/benchmarks.md).  A packet is always samples
 * j0..j0+15 of this vertex, so the result does not depend on threads.  Each
 * hit reads three vertex records scattered over the whole previous bounce,
 * so the work is a three-stage software pipeline, one packet per stage:
 * packet k is sampled and traced (the index entries of its hit primitives
 * prefetched), packet k-1's vertices are read and their records prefetched,
 * and packet k-2 (whose records were requested one packet earlier) is
 * summed, in ray order. */
#define BOUNCE_BATCH CV_RT_PACKET_MAX
typedef struct {
  int n;
  uint32_t from[BOUNCE_BATCH], prim[BOUNCE_BATCH];
  float u[BOUNCE_BATCH], v[BOUNCE_BATCH];
  const unsigned char *rec[BOUNCE_BATCH][3];
} bounce_packet;

/* Stage 1: samples rays j0..j0+n-1 of v and traces them. */
static void bounce_trace(const cv_tracer *tr, uint32_t v, int j0, int n, const vseq *q,
                         bounce_packet *pk) {
  cv_ray_soa r;
  pk->n = n;
  for (int b = 0; b < n; b++) {
    float org[3], dir[3];
    pk->from[b] = sample_ray(tr, v, (uint32_t)(j0 + b), q, org, dir);
    for (int k = 0; k < 3; k++) {
      r.org[k][b] = org[k];
      r.dir[k][b] = dir[k];
    }
  }
  cv_rt_intersect_packet_soa(tr->rt, n, &r, 0.0f, INFINITY, pk->prim, pk->u, pk->v);
  const uint32_t *ov = cv_rt_opaque_vertices(tr->rt);
  for (int b = 0; b < n; b++)
    if (pk->prim[b] != CV_RT_NO_HIT) __builtin_prefetch(ov + 3 * (size_t)pk->prim[b], 0, 1);
}

/* Stage 2: the hit vertices' records located and prefetched. */
static void bounce_locate(const cv_tracer *tr, const cv_bounce_records *R, bounce_packet *pk) {
  const uint32_t *ov = cv_rt_opaque_vertices(tr->rt);
  const size_t used = sizeof(float) + 2 * R->rec; /* bytes of a record that are read */
  for (int b = 0; b < pk->n; b++) {
    if (pk->prim[b] == CV_RT_NO_HIT) continue;
    const uint32_t *tv = ov + 3 * (size_t)pk->prim[b];
    for (int k = 0; k < 3; k++) {
      pk->rec[b][k] = R->data + (size_t)tv[k] * R->stride;
      prefetch_range(pk->rec[b][k], used);
    }
  }
}

/* Stage 3: the packet's hits added to the sums, in ray order. */
static void bounce_sum(const cv_tracer *tr, const cv_bounce_records *R, int nc,
                       const bounce_packet *pk, double *acc, double *accr) {
  const bounce_add_fn add = bounce_add_pick(tr->simd);
  const cv_mesh *m = tr->m;
  for (int b = 0; b < pk->n; b++) {
    if (pk->prim[b] == CV_RT_NO_HIT) continue;
    bounce_hit h;
    for (int k = 0; k < 3; k++) h.rec[k] = pk->rec[b][k];
    h.b[0] = 1.0f - pk->u[b] - pk->v[b];
    h.b[1] = pk->u[b];
    h.b[2] = pk->v[b];
    h.al = m->mats[m->tri_mat[pk->from[b]]].albedo;
    h.alr = accr ? recv_albedo(m, pk->from[b]) : NULL;
    add(&h, R->rec, nc, acc, accr);
  }
}

static void vertex_bounce(const cv_tracer *tr, uint32_t v, int bands, int rays, uint32_t seed,
                          const cv_bounce_records *R, double *acc, double *accr) {
  int nc = bands * bands;
  memset(acc, 0, 3 * (size_t)nc * sizeof(double));
  if (accr) memset(accr, 0, 3 * (size_t)nc * sizeof(double));
  if (tr->fan_off[v + 1] == tr->fan_off[v]) return;
  vseq q;
  vseq_init(&q, seed, v);
  bounce_packet pk[3];
  const int npk = (rays + BOUNCE_BATCH - 1) / BOUNCE_BATCH;
  for (int k = 0; k < npk + 2; k++) {
    if (k < npk) {
      const int j0 = k * BOUNCE_BATCH;
      bounce_trace(tr, v, j0, rays - j0 < BOUNCE_BATCH ? rays - j0 : BOUNCE_BATCH, &q, &pk[k % 3]);
    }
    if (k >= 1 && k - 1 < npk) bounce_locate(tr, R, &pk[(k - 1) % 3]);
    if (k >= 2) bounce_sum(tr, R, nc, &pk[(k - 2) % 3], acc, accr);
  }
  for (int i = 0; i < 3 * nc; i++) acc[i] /= rays;
  for (int i = 0; accr && i < 3 * nc; i++) accr[i] /= rays;
}

static void vertex_direct(const cv_tracer *tr, uint32_t v, int bands, int rays, uint32_t seed,
                          double *acc, double alb[3], double albr[3]) {
  vertex_direct_rf(tr, v, bands, rays, seed, acc, alb, albr, NULL, NULL);
}

int cv_bake_direct_radiance_subset(const cv_tracer *tr, int bands, int rays, uint32_t seed,
                                   const cv_radiance_fn *rf, const uint32_t *verts, size_t count,
                                   float *td, float *rgb, float *alb_out) {
  if (bands < 1 || bands > CV_PRT_MAX_BANDS || rays < 1 || !rf || !rf->fn) return CV_ERR_RANGE;
  int nc = bands * bands;
#pragma omp parallel
  {
    cv_rt_thread_init();
    double acc[CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS], alb[3], albr[3], L[3];
#pragma omp for schedule(dynamic, 4)
    for (size_t k = 0; k < count; k++) {
      vertex_direct_rf(tr, verts[k], bands, rays, seed, acc, alb, albr, rf, L);
      for (int i = 0; i < nc; i++) td[k * nc + i] = (float)acc[i];
      for (int c = 0; c < 3; c++) {
        rgb[3 * k + c] = (float)L[c];
        alb_out[3 * k + c] = (float)alb[c];
      }
    }
  }
  return CV_OK;
}

int cv_bake_direct_subset(const cv_tracer *tr, int bands, int rays, uint32_t seed,
                          const uint32_t *verts, size_t count, float *out) {
  if (bands < 1 || bands > CV_PRT_MAX_BANDS || rays < 1) return CV_ERR_RANGE;
  int nc = bands * bands;
#pragma omp parallel
  {
    cv_rt_thread_init();
    double acc[CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS], alb[3], albr[3];
#pragma omp for schedule(dynamic, 16)
    for (size_t k = 0; k < count; k++) {
      vertex_direct(tr, verts[k], bands, rays, seed, acc, alb, albr);
      for (int i = 0; i < nc; i++) out[k * nc + i] = (float)acc[i];
    }
  }
  return CV_OK;
}

int cv_bake_bounce_subset(const cv_tracer *tr, int bands, int rays, uint32_t seed,
                          const cv_bounce_records *prev, const uint32_t *verts, size_t count,
                          float *out) {
  if (bands < 1 || bands > CV_PRT_MAX_BANDS || rays < 1) return CV_ERR_RANGE;
  if (prev->rec != 3 * (size_t)bands * (size_t)bands || prev->nv != tr->m->nv) return CV_ERR_INVALID;
  const size_t rec = 3 * (size_t)bands * (size_t)bands;
#pragma omp parallel
  {
    cv_rt_thread_init();
    double acc[3 * CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS];
#pragma omp for schedule(dynamic, 1)
    for (size_t k = 0; k < count; k++) {
      vertex_bounce(tr, verts[k], bands, rays, seed, prev, acc, NULL);
      for (size_t i = 0; i < rec; i++) out[k * rec + i] = (float)acc[i];
    }
  }
  return CV_OK;
}

int cv_bake_params_validate(const cv_bake_params *p, cv_err *err) {
  if (p->bands < 2 || p->bands > CV_PRT_MAX_BANDS)
    return cv_err_set(err, CV_ERR_RANGE, "prt.bands = %d, expected 2..%d", p->bands,
                      CV_PRT_MAX_BANDS);
  if (p->rays < 1 || p->rays > (1 << 24))
    return cv_err_set(err, CV_ERR_RANGE, "prt.rays = %d, expected 1..16777216", p->rays);
  if (!(p->spread >= 0.0f && p->spread <= 1.0f))
    return cv_err_set(err, CV_ERR_RANGE, "prt.spread = %g, expected 0..1", (double)p->spread);
  if (p->bounces < 0 || p->bounces > 16)
    return cv_err_set(err, CV_ERR_RANGE, "prt.bounces = %d, expected 0..16", p->bounces);
  return CV_OK;
}

uint64_t cv_prt_input_hash(const cv_mesh *m, const cv_bake_params *p) {
  uint64_t h = cv_hash64_init();
  uint32_t spread_bits;
  memcpy(&spread_bits, &p->spread, sizeof spread_bits);
  /* The estimator's identity: bump when the sampling changes results. */
  /* +4 with bounces: the bounce passes read half-float records of the
   * previous bounce and trace 16-ray packets (+2, results moved by ~1e-4),
   * and the records' half denormals are right (+4: values below 2^-14 of a
   * record's largest were 2^9 too small, then read as 0); +16 with the
   * geometric tail. */
  const uint32_t estimator = (p->cosine_only ? 1u : 2u) + (p->bounces > 0 ? 4u : 0u) +
                             (p->tail && p->bounces > 0 ? 16u : 0u);
  uint32_t hdr[7] = {CV_PRT_VERSION, (uint32_t)p->bands, (uint32_t)p->rays,
                     (uint32_t)p->bounces, p->seed, spread_bits, estimator};
  h = cv_hash64_update(h, hdr, sizeof hdr);
  uint64_t sz[3] = {m->nv, m->nt, m->nm};
  h = cv_hash64_update(h, sz, sizeof sz);
  h = cv_hash64_update(h, m->pos, 3 * m->nv * sizeof(float));
  h = cv_hash64_update(h, m->tri, 3 * m->nt * sizeof(uint32_t));
  h = cv_hash64_update(h, m->tri_mat, m->nt * sizeof(uint32_t));
  for (size_t i = 0; i < m->nm; i++) {
    h = cv_hash64_update(h, m->mats[i].name, strlen(m->mats[i].name));
    h = cv_hash64_update(h, m->mats[i].albedo, sizeof m->mats[i].albedo);
    h = cv_hash64_update(h, &m->mats[i].flags, sizeof m->mats[i].flags);
  }
  if (m->mat_tex) {
    for (size_t i = 0; i < m->nm; i++) h = cv_hash64_update(h, m->mat_tex[i], strlen(m->mat_tex[i]) + 1);
    if (m->tri_uv) h = cv_hash64_update(h, m->tri_uv, 6 * m->nt * sizeof(float));
  }
  return h;
}

int cv_prt_bake(const cv_mesh *m, const cv_bake_params *p, cv_prt **out, cv_bake_stats *stats,
                cv_err *err) {
  *out = NULL;
  int st = cv_bake_params_validate(p, err);
  if (st) return st;
  cv_tracer *tr;
  st = cv_tracer_create(m, &tr, err);
  if (st) return st;
  cv_tracer_set_spread(tr, p->spread);
  cv_tracer_set_window_sampling(tr, !p->cosine_only);
  st = cv_prt_bake_tracer(tr, p, out, stats, err);
  cv_tracer_destroy(tr);
  return st;
}

/* Runs fn(v) for every vertex in blocks on OpenMP threads with a progress bar. */
#define FOR_VERTICES(label, nv, quiet, BODY)                                   \
  do {                                                                         \
    cv_progress *prog_ = NULL;                                                 \
    if (!(quiet)) cv_progress_create((label), (nv), &prog_);                   \
    const size_t block_ = 64;                                                  \
    _Pragma("omp parallel") {                                                  \
      cv_rt_thread_init();                                                     \
      double acc[3 * CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS], alb[3];             \
      (void)alb;                                                               \
      _Pragma("omp for schedule(dynamic, 1)")                                  \
      for (size_t b0 = 0; b0 < (nv); b0 += block_) {                           \
        size_t b1 = b0 + block_ < (nv) ? b0 + block_ : (nv);                   \
        for (size_t v = b0; v < b1; v++) { BODY }                             \
        cv_progress_add(prog_, b1 - b0);                                       \
      }                                                                        \
    }                                                                          \
    cv_progress_finish(prog_);                                                 \
    cv_progress_destroy(prog_);                                                \
  } while (0)

/* Stores every vertex's 3*n*n values of vals (layout as the transfer) in r. */
static void records_fill(cv_bounce_records *r, const float *vals, size_t nv) {
  const size_t rec = r->rec;
#pragma omp parallel for schedule(static)
  for (size_t v = 0; v < nv; v++) cv_bounce_records_set(r, v, vals + v * rec);
}

/* Interreflection pass `pass`: cur = the bounce carried by the records prev (albedo
 * applied), ti += the same without a textured receiver's own albedo. */
static void propagate_pass(const cv_tracer *tr, int bands, int rays, uint32_t seed, int pass,
                           int quiet, const cv_bounce_records *prev, float *cur, float *ti,
                           cv_bake_stats *stats) {
  const size_t nv = tr->m->nv;
  const int nc = bands * bands;
  char label[32];
  snprintf(label, sizeof label, "bake bounce %d", pass);
  double t0 = cv_now_seconds();
  const int textured = tr->m->mat_tex != NULL;
  FOR_VERTICES(label, nv, quiet, {
    double accr[3 * CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS];
    vertex_bounce(tr, (uint32_t)v, bands, rays, seed, prev, acc, textured ? accr : NULL);
    const double *own = textured ? accr : acc; /* transfer without a texture's albedo */
    for (int i = 0; i < 3 * nc; i++) {
      cur[v * 3 * nc + i] = (float)acc[i];
      ti[v * 3 * nc + i] += (float)own[i];
    }
  });
  if (stats && pass <= 16) {
    stats->seconds[pass] = cv_now_seconds() - t0;
    stats->rays[pass] = (uint64_t)(nv - stats->empty_fans) * (uint64_t)rays;
    stats->total_rays += stats->rays[pass];
  }
}

int cv_prt_propagate(const cv_tracer *tr, int bands, int rays, uint32_t seed, int bounces,
                     int quiet, float *prev, float *ti, cv_bake_stats *stats) {
  const size_t nv = tr->m->nv;
  if (bounces <= 0) return CV_OK;
  cv_bounce_records *src = NULL;
  if (cv_bounce_records_create(bands, nv, &src)) return CV_ERR_NOMEM;
  records_fill(src, prev, nv);
  for (int pass = 1; pass <= bounces; pass++) {
    /* src holds the previous bounce, so prev is free to take this one. */
    propagate_pass(tr, bands, rays, seed, pass, quiet, src, prev, ti, stats);
    if (pass < bounces) records_fill(src, prev, nv);
  }
  cv_bounce_records_destroy(src);
  return CV_OK;
}

/* Area of each vertex's share of its opaque fan (a third of each triangle). */
static double vertex_area(const cv_tracer *tr, uint32_t v) {
  double a = 0;
  for (uint32_t k = tr->fan_off[v]; k < tr->fan_off[v + 1]; k++) {
    const uint32_t *t = tr->m->tri + 3 * (tr->fan_tri[k] >> 2);
    const float *p0 = tr->m->pos + 3 * t[0], *p1 = tr->m->pos + 3 * t[1], *p2 = tr->m->pos + 3 * t[2];
    double e1[3], e2[3];
    for (int c = 0; c < 3; c++) {
      e1[c] = (double)p1[c] - p0[c];
      e2[c] = (double)p2[c] - p0[c];
    }
    double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
           cz = e1[0] * e2[1] - e1[1] * e2[0];
    a += sqrt(cx * cx + cy * cy + cz * cz) / 6.0;
  }
  return a;
}

int cv_prt_tail_ratio(const cv_tracer *tr, int bands, const float *before, const float *last,
                      double ratio[3]) {
  const size_t nv = tr->m->nv;
  const int nc = bands * bands;
  double num[3] = {0, 0, 0}, den[3] = {0, 0, 0};
  for (size_t v = 0; v < nv; v++) {
    double a = vertex_area(tr, (uint32_t)v);
    for (int c = 0; c < 3; c++) {
      num[c] += a * last[(v * 3 + c) * nc];
      den[c] += a * before[(v * 3 + c) * nc];
    }
  }
  int clamped = 0;
  for (int c = 0; c < 3; c++) {
    double r = den[c] > 0 ? num[c] / den[c] : 0.0;
    if (!(r >= 0)) r = 0, clamped = 1;
    if (r > CV_BAKE_TAIL_MAX_RATIO) r = CV_BAKE_TAIL_MAX_RATIO, clamped = 1;
    ratio[c] = r;
  }
  return clamped;
}

/* Passes 1..bounces as cv_prt_propagate, then the geometric tail: every
 * vertex's last bounce B (without a textured receiver's own albedo) times
 * r / (1 - r), r per channel from cv_prt_tail_ratio of bounces B and B - 1
 * (B - 1 = 0: the direct exit transfer). */
static int propagate_with_tail(const cv_tracer *tr, const cv_bake_params *p, float *prev,
                               float *ti, cv_bake_stats *stats) {
  const size_t nv = tr->m->nv;
  const int nc = p->bands * p->bands;
  const size_t n = 3 * nv * (size_t)nc;
  float *cur = malloc(n * sizeof(float) + 1), *last = malloc(n * sizeof(float) + 1);
  cv_bounce_records *rec = NULL;
  if (!cur || !last || cv_bounce_records_create(p->bands, nv, &rec)) {
    free(cur);
    free(last);
    return CV_ERR_NOMEM;
  }
  records_fill(rec, prev, nv);
  for (int pass = 1; pass <= p->bounces; pass++) {
    if (pass == p->bounces) memcpy(last, ti, n * sizeof(float));
    propagate_pass(tr, p->bands, p->rays, p->seed, pass, p->quiet, rec, cur, ti, stats);
    if (pass < p->bounces) {
      memcpy(prev, cur, n * sizeof(float));
      records_fill(rec, cur, nv);
    }
  }
  cv_bounce_records_destroy(rec);
  double r[3];
  stats->tail_clamped = cv_prt_tail_ratio(tr, p->bands, prev, cur, r);
  for (int c = 0; c < 3; c++) stats->tail_ratio[c] = r[c];
  for (size_t v = 0; v < nv; v++)
    for (int c = 0; c < 3; c++) {
      const double f = r[c] / (1.0 - r[c]);
      for (int i = 0; i < nc; i++) {
        const size_t k = (v * 3 + c) * (size_t)nc + (size_t)i;
        ti[k] += (float)(f * ((double)ti[k] - last[k]));
      }
    }
  free(cur);
  free(last);
  return CV_OK;
}

int cv_prt_bake_tracer(const cv_tracer *tr, const cv_bake_params *p, cv_prt **out,
                       cv_bake_stats *stats, cv_err *err) {
  *out = NULL;
  int st = cv_bake_params_validate(p, err);
  if (st) return st;
  if (tr->spread != p->spread)
    return cv_err_set(err, CV_ERR_INVALID, "bake spread %g differs from the tracer's %g",
                      (double)p->spread, (double)tr->spread);
  if (tr->window_mis == !!p->cosine_only)
    return cv_err_set(err, CV_ERR_INVALID, "bake cosine_only %d differs from the tracer's window sampling",
                      p->cosine_only);
  const cv_mesh *m = tr->m;
  cv_bake_stats local;
  if (!stats) stats = &local;
  memset(stats, 0, sizeof *stats);
  cv_prt *prt;
  st = cv_prt_alloc((uint32_t)p->bands, m->nv, m->nt, m->nm, p->bounces > 0, &prt);
  if (st) return cv_err_set(err, st, "cannot allocate transfer for %zu vertices", m->nv);
  memcpy(prt->pos, m->pos, 3 * m->nv * sizeof(float));
  memcpy(prt->tri, m->tri, 3 * m->nt * sizeof(uint32_t));
  memcpy(prt->tri_mat, m->tri_mat, m->nt * sizeof(uint32_t));
  memcpy(prt->mats, m->mats, m->nm * sizeof(cv_material));
  if (m->mat_tex) {
    if (cv_prt_alloc_textures(prt)) {
      cv_prt_destroy(prt);
      return cv_err_set(err, CV_ERR_NOMEM, "cannot allocate texture references");
    }
    memcpy(prt->mat_tex, m->mat_tex, m->nm * (size_t)CV_TEX_PATH_MAX);
    if (m->tri_uv) memcpy(prt->tri_uv, m->tri_uv, 6 * m->nt * sizeof(float));
  }
  cv_mesh_vertex_normals(m, prt->nrm);
  prt->meta.input_hash = cv_prt_input_hash(m, p);
  prt->meta.rays = (uint32_t)p->rays;
  prt->meta.bounces = (uint32_t)p->bounces;
  prt->meta.seed = p->seed;
  prt->meta.spread = p->spread;
  if (!p->cosine_only && tr->nwin > 0) prt->flags |= CV_PRT_WINDOW_SAMPLING;

  const size_t nv = m->nv;
  const int nc = p->bands * p->bands;
  for (size_t v = 0; v < nv; v++)
    if (tr->fan_off[v + 1] == tr->fan_off[v]) stats->empty_fans++;
  float *prev = NULL;
  if (p->bounces > 0 && !(prev = malloc(3 * nv * nc * sizeof(float) + 1))) {
    cv_prt_destroy(prt);
    return cv_err_set(err, CV_ERR_NOMEM, "cannot allocate bounce buffers");
  }
  double t_all = cv_now_seconds();
  FOR_VERTICES("bake direct", nv, p->quiet, {
    double albr[3];
    vertex_direct(tr, (uint32_t)v, p->bands, p->rays, p->seed, acc, alb, albr);
    for (int i = 0; i < nc; i++) prt->td[v * nc + i] = (float)acc[i];
    for (int k = 0; k < 3; k++) prt->albedo[3 * v + k] = (float)albr[k];
    if (prev)
      for (int c = 0; c < 3; c++)
        for (int i = 0; i < nc; i++) prev[(v * 3 + c) * nc + i] = (float)(alb[c] * acc[i]);
  });
  stats->seconds[0] = cv_now_seconds() - t_all;
  stats->rays[0] = (uint64_t)(nv - stats->empty_fans) * (uint64_t)p->rays;
  stats->total_rays = stats->rays[0];
  if (prev) {
    st = p->tail && p->bounces > 0 ? propagate_with_tail(tr, p, prev, prt->ti, stats)
                 : cv_prt_propagate(tr, p->bands, p->rays, p->seed, p->bounces, p->quiet, prev,
                                    prt->ti, stats);
    free(prev);
    if (st) {
      cv_prt_destroy(prt);
      return cv_err_set(err, st, "out of memory propagating bounces");
    }
  }
  stats->total_seconds = cv_now_seconds() - t_all;
  prt->meta.bake_seconds = stats->total_seconds;
  *out = prt;
  return CV_OK;
}

/* Direct light of one vertex from a directional light (see cv_sun_direct). */
static void sun_vertex(const cv_tracer *tr, uint32_t v, const float s[3], const double E[3],
                       int samples, uint32_t sseed, float *out3) {
  if (tr->fan_off[v + 1] == tr->fan_off[v]) return;
  double acc[3] = {0, 0, 0};
  vseq q;
  vseq_init(&q, sseed, v);
  for (int j = 0; j < samples; j++) {
    float u[6], p[3], org[3];
    vseq_sample(&tr->sobol, &q, (uint32_t)j, 6, u);
    uint32_t t = fan_point(tr, v, u, p);
    const float *n = tr->tri_n + 3 * t;
    float c = n[0] * s[0] + n[1] * s[1] + n[2] * s[2];
    if (c <= 0) continue;
    cv_rt_offset_origin(p, n, org);
    if (!cv_rt_reaches_env(tr->rt, org, s, 0.0f)) continue;
    const float *a = recv_albedo(tr->m, t);
    for (int k = 0; k < 3; k++) acc[k] += (double)a[k] * c;
  }
  for (int k = 0; k < 3; k++) out3[k] += (float)(E[k] / M_PI * acc[k] / samples);
}

int cv_sun_direct_subset(const cv_tracer *tr, const double sun_dir[3], const double E[3],
                         int samples, uint32_t seed, const uint32_t *verts, size_t count,
                         float *out_rgb) {
  if (samples < 1) return CV_ERR_RANGE;
  double l = sqrt(sun_dir[0] * sun_dir[0] + sun_dir[1] * sun_dir[1] + sun_dir[2] * sun_dir[2]);
  if (!(l > 0) || !isfinite(l)) return CV_ERR_INVALID;
  const float s[3] = {(float)(sun_dir[0] / l), (float)(sun_dir[1] / l), (float)(sun_dir[2] / l)};
  const size_t nv = verts ? count : tr->m->nv;
  const uint32_t sseed = cv_hash_combine(seed, 0x5317u);
#pragma omp parallel
  {
    cv_rt_thread_init();
#pragma omp for schedule(dynamic, 256)
    for (size_t k = 0; k < nv; k++) {
      const uint32_t v = verts ? verts[k] : (uint32_t)k;
      sun_vertex(tr, v, s, E, samples, sseed, out_rgb + 3 * (verts ? k : (size_t)v));
    }
  }
  return CV_OK;
}

int cv_sun_direct(const cv_tracer *tr, const double sun_dir[3], const double E[3], int samples,
                  uint32_t seed, float *out_rgb) {
  return cv_sun_direct_subset(tr, sun_dir, E, samples, seed, NULL, 0, out_rgb);
}
