/* Internal to the bake and the tracer (bake.c, tracer.c): the tracer's
 * state and the sampling steps both use (inline: the bake's inner loops). */
#ifndef CV_PRT_TRACER_INTERNAL_H
#define CV_PRT_TRACER_INTERNAL_H

#include <math.h>

#include "core/hash.h"
#include "core/sobol.h"
#include "prt/tracer.h"

/* gcc only, as src/compensate/solve.c: clang 14 (the fuzz build) rejects
 * __builtin_cpu_supports("f16c"). */
#if defined(__GNUC__) && !defined(__clang__) && (defined(__x86_64__) || defined(__i386__))
#include <immintrin.h>
#define CV_BAKE_X86_SIMD 1
#endif

struct cv_tracer {
  cv_mesh *m;
  cv_rt *rt;
  float *tri_n;        /* 3*nt unit geometric normals */
  size_t *fan_off;     /* nv+1, CSR offsets into fan_tri/fan_cdf */
  uint32_t *fan_tri;   /* triangle index << 2 | corner of v in it */
  float *fan_cdf;      /* cumulative area fraction within the fan */
  cv_sobol_tab sobol;  /* shared read-only by all threads */
  float spread;        /* fraction of the fan that ray origins cover */
  /* Window importance sampling (direct pass): the window triangles grouped
   * by material (one group per opening), by area within each group. */
  size_t nwin;
  uint32_t *win_tri;   /* mesh triangle indices, grouped */
  float *win_cdf;      /* cumulative area fraction within the triangle's group */
  double win_area;     /* total window area, m^2 */
  int ngroup;
  struct win_group {
    size_t begin, end; /* range in win_tri */
    double area, centroid[3], normal[3];
  } *groups;
  int *tri_group;      /* nt: group of a window triangle, -1 otherwise */
  int window_mis;      /* 1: MIS of cosine and window sampling when nwin > 0 */
  int simd;            /* 1: the bounce pass sums hits with AVX2 + F16C (cv_tracer_set_simd) */
};

/* Cosine-weighted direction about unit n from (u0, u1): Shirley-Chiu
 * concentric disk (keeps the Sobol stratification), lifted to the hemisphere;
 * orthonormal basis after Duff et al. 2017. */
static inline void cosine_dir(const float n[3], float u0, float u1, float d[3]) {
  float a = 2.0f * u0 - 1.0f, b = 2.0f * u1 - 1.0f, r, phi;
  if (a == 0.0f && b == 0.0f) {
    r = 0.0f;
    phi = 0.0f;
  } else if (fabsf(a) > fabsf(b)) {
    r = a;
    phi = (float)M_PI_4 * (b / a);
  } else {
    r = b;
    phi = (float)M_PI_2 - (float)M_PI_4 * (a / b);
  }
  float x = r * cosf(phi), y = r * sinf(phi);
  float z = sqrtf(fmaxf(0.0f, 1.0f - x * x - y * y));
  float sign = copysignf(1.0f, n[2]);
  float aa = -1.0f / (sign + n[2]), bb = n[0] * n[1] * aa;
  float t[3] = {1.0f + sign * n[0] * n[0] * aa, sign * bb, -sign * n[0]};
  float s[3] = {bb, sign + n[1] * n[1] * aa, -n[1]};
  /* t, s, n orthonormal and x^2 + y^2 + z^2 = 1: d is unit to rounding. */
  for (int k = 0; k < 3; k++) d[k] = x * t[k] + y * s[k] + z * n[k];
}

/* Picks fan triangle and point for sample u (6 dims: u[2], u[3], u[5] place
 * the point, u[4] picks the triangle); returns the triangle. */
static inline uint32_t fan_point(const cv_tracer *tr, uint32_t v, const float *u, float p[3]) {
  size_t lo = tr->fan_off[v], hi = tr->fan_off[v + 1] - 1;
  while (lo < hi) { /* first entry with cdf > u4 */
    size_t mid = (lo + hi) / 2;
    if (tr->fan_cdf[mid] > u[4]) hi = mid;
    else lo = mid + 1;
  }
  uint32_t t = tr->fan_tri[lo] >> 2, c = tr->fan_tri[lo] & 3u;
  /* Point density proportional to v's barycentric b_v (the hat function):
   * barycentrics ~ Dirichlet(2,1,1).  With three uniforms sorted
   * s0 <= s1 <= s2, the spacings (s0, s1-s0, s2-s1, 1-s2) are
   * Dirichlet(1,1,1,1); merging the first two gives (s1, s2-s1, 1-s2). */
  float a = u[2], b = u[3], c2 = u[5], tmp;
  if (a > b) { tmp = a; a = b; b = tmp; }
  if (b > c2) { tmp = b; b = c2; c2 = tmp; }
  if (a > b) { tmp = a; a = b; b = tmp; }
  float bv = b, b1 = c2 - b, b2 = 1.0f - c2;
  const uint32_t *tv = tr->m->tri + 3 * t;
  const float *P0 = tr->m->pos + 3 * tv[c], *P1 = tr->m->pos + 3 * tv[(c + 1) % 3],
              *P2 = tr->m->pos + 3 * tv[(c + 2) % 3];
  /* Shrink towards v by the spread (1 = the whole hat, as in the paper). */
  const float lam = tr->spread;
  bv = 1.0f - lam * (1.0f - bv);
  b1 *= lam;
  b2 *= lam;
  for (int k = 0; k < 3; k++) p[k] = bv * P0[k] + b1 * P1[k] + b2 * P2[k];
  return t;
}

/* Per-vertex sequence state: two independently shuffled Owen-scrambled
 * Sobol chunks ("padding", Burley 2020 section 4): a 2-D chunk for the
 * direction and a 4-D chunk for the starting point (triangle choice and three
 * barycentric uniforms).  Each chunk keeps the good low-dimensional
 * stratification that one 6-D point would lose. */
typedef struct {
  uint32_t sa, d[7];
} vseq;

static inline void vseq_init(vseq *q, uint32_t seed, uint32_t v) {
  uint32_t vs = cv_hash_combine(seed, v);
  q->sa = cv_hash_combine(vs, 0xD1u);
  cv_sobol_dim_seeds(q->sa, 7, q->d);
}

/* u[0..1] direction, u[2], u[3], u[5] barycentric uniforms, u[4] triangle,
 * u[6] (when ndims = 7) the sampling strategy of the direct pass. */
static inline void vseq_sample(const cv_sobol_tab *tab, const vseq *q, uint32_t j, int ndims,
                               float *u) {
  cv_sobol_owen_tab(tab, j, q->sa, q->d, ndims, u);
}

static inline uint32_t sample_ray(const cv_tracer *tr, uint32_t v, uint32_t j, const vseq *q,
                                  float org[3], float dir[3]) {
  float u[6], p[3];
  vseq_sample(&tr->sobol, q, j, 6, u);
  uint32_t t = fan_point(tr, v, u, p);
  const float *n = tr->tri_n + 3 * t;
  cosine_dir(n, u[0], u[1], dir);
  cv_rt_offset_origin(p, n, org);
  return t;
}

/* Per-vertex choice of an opening: probabilities proportional to a rough
 * estimate of each opening's contribution seen from p with normal n
 * (area x cosines / distance^2, as for many-light selection), plus a small
 * floor so no opening that might be visible is starved.  Any choice is
 * unbiased because the pdf below uses these same probabilities. */
static inline int window_probs(const cv_tracer *tr, const float p[3], const float n[3], double *prob) {
  double sum = 0;
  for (int g = 0; g < tr->ngroup; g++) {
    const struct win_group *G = &tr->groups[g];
    double d[3], d2 = 0;
    for (int k = 0; k < 3; k++) {
      d[k] = G->centroid[k] - p[k];
      d2 += d[k] * d[k];
    }
    double dl = sqrt(d2) + 1e-9;
    double co = (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) / dl;
    double cq = fabs(G->normal[0] * d[0] + G->normal[1] * d[1] + G->normal[2] * d[2]) / dl;
    /* a large opening close by can be in front even when its centroid is not */
    double reach = sqrt(G->area);
    double front = co > 0 ? co : (dl < 2 * reach ? 0.25 : 0.0);
    prob[g] = G->area * (front + 0.05) * (cq + 0.1) / (d2 + G->area);
    sum += prob[g];
  }
  if (!(sum > 0)) return 0;
  for (int g = 0; g < tr->ngroup; g++) prob[g] /= sum;
  return 1;
}

/* Uniform point on opening g from (u0, u1): the triangle by area within the
 * group, then u0 rescaled within its CDF bucket and the square-root mapping. */
static inline void window_point(const cv_tracer *tr, int g, float u0, float u1, float q[3]) {
  size_t lo = tr->groups[g].begin, hi = tr->groups[g].end - 1, first = lo;
  while (lo < hi) {
    size_t mid = (lo + hi) / 2;
    if (tr->win_cdf[mid] > u0) hi = mid;
    else lo = mid + 1;
  }
  float c0 = lo > first ? tr->win_cdf[lo - 1] : 0.0f, w = tr->win_cdf[lo] - c0;
  float r = w > 0 ? (u0 - c0) / w : 0.5f;
  r = r < 0 ? 0 : (r > 1 ? 1 : r);
  const uint32_t *tv = tr->m->tri + 3 * tr->win_tri[lo];
  const float *A = tr->m->pos + 3 * tv[0], *B = tr->m->pos + 3 * tv[1], *C = tr->m->pos + 3 * tv[2];
  float su = sqrtf(r), b0 = 1.0f - su, b1 = u1 * su, b2 = 1.0f - b0 - b1;
  for (int k = 0; k < 3; k++) q[k] = b0 * A[k] + b1 * B[k] + b2 * C[k];
}

#endif
