/* The relight on the CPU (opts.relight_cpu; by default with a software GL).
 *
 * llvmpipe runs the transform-feedback relight (relight.vert) on one
 * thread, fetching the transfer texel by texel: 35-39 ms for the 293K
 * vertices x 26 texels of the 571K cabin at 5 bands on this machine.  The
 * same sums as a plain loop over the texels in memory, four lanes at a
 * time, OpenMP threads over the vertices, then one glBufferSubData of the
 * radiance (16 bytes a vertex): docs/benchmarks.md has the figures.
 * With opts.half_transfer the transfer stays in half floats (half the
 * memory).  Where the CPU has AVX2, FMA and F16C, two texels at a time are
 * converted in registers and summed by 8-lane multiply-adds
 * (range_f16_avx2): 12-13 ms against 23-24 ms for the float transfer in the
 * same run (docs/benchmarks.md); elsewhere each vertex's texels are
 * converted into a buffer first (F16C or a portable conversion: the same
 * floats), which made the halves no faster than floats.
 *
 * The sums are relight.vert's, in float (the even and odd terms summed
 * apart, then added: the last bits differ from the shader's order), per vertex:
 *   d = sum_i l_i td_i, ind = sum_i ls_i ti_i (RGB), rad = albedo d + ind
 *   (+ the split lights' direct light), each channel that is negative or
 *   not finite set to 0 and counted in w.
 * A texel holds (td, ti_R, ti_G, ti_B); with the lighting in lanes 1..3
 * (lane 0 zero) both sums are one multiply-add of four lanes per texel. */
#include "render/renderer_internal.h"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define HAVE_F16C 1
#endif

#include "io/exr.h"

typedef float v4 __attribute__((vector_size(16)));

static inline v4 load4(const float *p) {
  v4 v;
  memcpy(&v, p, sizeof v);
  return v;
}

/* A vertex's radiance from its sums (lanes 1..3 of d, the direct transfer
 * against the lighting, and ind, the interreflected one) and albedo: rad =
 * albedo d + ind (+ the split lights'), each channel that is negative or
 * not finite set to 0; into out[4] with the clamp count. */
static inline float finish_vertex(const float *alb, v4 d, v4 ind, const float *split, float out[4]) {
  float n = 0;
  for (int c = 0; c < 3; c++) {
    float v = alb[c] * d[c + 1] + ind[c + 1];
    if (split) v += split[c];
    if (!(v >= 0) || isinf(v)) v = 0, n += 1;
    out[c] = v;
  }
  out[3] = n;
  return n;
}

/* One vertex: the relit RGB and its clamp count into out[4]; t: its nc + 1
 * texels. */
static inline float relight_vertex(const float *t, const v4 *l, const v4 *ls, int nc,
                                   const float *split, float out[4]) {
  v4 d = {0, 0, 0, 0}, ind = {0, 0, 0, 0}, d2 = d, ind2 = d;
  int i = 0;
  for (; i + 1 < nc; i += 2) { /* two chains: the adds' latency, not the loads, bound one */
    const v4 x = load4(t + 4 * i), y = load4(t + 4 * i + 4);
    d += l[i] * (v4){x[0], x[0], x[0], x[0]};
    ind += ls[i] * x;
    d2 += l[i + 1] * (v4){y[0], y[0], y[0], y[0]};
    ind2 += ls[i + 1] * y;
  }
  if (i < nc) {
    const v4 x = load4(t + 4 * i);
    d += l[i] * (v4){x[0], x[0], x[0], x[0]};
    ind += ls[i] * x;
  }
  return finish_vertex(t + 4 * nc, d + d2, ind + ind2, split, out);
}

/* Vertices [v0, v1) from float texels. */
static uint64_t range_f32(cv_renderer *r, const v4 *l, const v4 *ls, long v0, long v1) {
  const int nc = r->nc;
  const size_t per = 4 * (size_t)(nc + 1);
  const float *wl = r->n_split > 0 ? r->wl_cpu : NULL;
  uint64_t clamped = 0;
  for (long v = v0; v < v1; v++)
    clamped += (uint64_t)relight_vertex(r->tf_cpu + (size_t)v * per, l, ls, nc,
                                        wl ? wl + 4 * v : NULL, r->rad_cpu + 4 * v);
  return clamped;
}

/* n halves to floats; both exact, so the same floats (test_render checks
 * all 65,536 halves). */
void cvr_halves_soft(const uint16_t *h, float *f, size_t n) {
  for (size_t i = 0; i < n; i++) f[i] = cv_half_to_float(h[i]);
}

#ifdef HAVE_F16C
__attribute__((target("avx,f16c"))) static void halves_f16c(const uint16_t *h, float *f, size_t n) {
  size_t i = 0;
  for (; i + 8 <= n; i += 8)
    _mm256_storeu_ps(f + i, _mm256_cvtph_ps(_mm_loadu_si128((const __m128i *)(h + i))));
  for (; i < n; i++) f[i] = cv_half_to_float(h[i]);
}
#endif

int cvr_halves_f16c(const uint16_t *h, float *f, size_t n) {
#ifdef HAVE_F16C
  if (__builtin_cpu_supports("avx") && __builtin_cpu_supports("f16c")) {
    halves_f16c(h, f, n);
    return 1;
  }
#endif
  cvr_halves_soft(h, f, n);
  return 0;
}

/* Vertices [v0, v1) from half-float texels, each vertex's texels converted
 * into a buffer that stays in L1 (F16C when the CPU has it: 7x faster than
 * the portable conversion here). */
static uint64_t range_f16(cv_renderer *r, const v4 *l, const v4 *ls, long v0, long v1) {
  const int nc = r->nc;
  const size_t per = 4 * (size_t)(nc + 1);
  const float *wl = r->n_split > 0 ? r->wl_cpu : NULL;
  float t[4 * (CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS + 1)];
  uint64_t clamped = 0;
  for (long v = v0; v < v1; v++) {
    cvr_halves_f16c(r->th_cpu + (size_t)v * per, t, per);
    clamped += (uint64_t)relight_vertex(t, l, ls, nc, wl ? wl + 4 * v : NULL, r->rad_cpu + 4 * v);
  }
  return clamped;
}

#ifdef HAVE_F16C

/* range_f16 with the conversion in registers: two texels (8 halves) per
 * F16C conversion and per fused multiply-add of 8 lanes, the direct
 * transfer td broadcast within each texel by a permute; l8 / ls8: the
 * lighting of texels 2p and 2p + 1 in lanes 1..3 and 5..7.  The texel
 * left over when nc is odd and the albedo texel are read as 4 halves. */
__attribute__((target("avx2,fma,f16c"))) static uint64_t range_f16_avx2(
    cv_renderer *r, const v4 *l, const v4 *ls, long v0, long v1) {
  const int nc = r->nc, np = nc / 2;
  const size_t per = 4 * (size_t)(nc + 1);
  const float *wl = r->n_split > 0 ? r->wl_cpu : NULL;
  __m256 l8[32], ls8[32];
  for (int p = 0; p < np; p++) {
    l8[p] = _mm256_set_m128(_mm_loadu_ps((const float *)&l[2 * p + 1]), _mm_loadu_ps((const float *)&l[2 * p]));
    ls8[p] = _mm256_set_m128(_mm_loadu_ps((const float *)&ls[2 * p + 1]), _mm_loadu_ps((const float *)&ls[2 * p]));
  }
  const __m128 l4 = _mm_loadu_ps((const float *)&l[nc - 1]), ls4 = _mm_loadu_ps((const float *)&ls[nc - 1]);
  uint64_t clamped = 0;
  for (long v = v0; v < v1; v++) {
    const uint16_t *t = r->th_cpu + (size_t)v * per;
    __m256 d = _mm256_setzero_ps(), ind = d, d2 = d, ind2 = d;
    int p = 0;
    for (; p + 1 < np; p += 2) { /* two chains against the FMA's latency */
      const __m256 x = _mm256_cvtph_ps(_mm_loadu_si128((const __m128i *)(t + 8 * p)));
      const __m256 y = _mm256_cvtph_ps(_mm_loadu_si128((const __m128i *)(t + 8 * p + 8)));
      d = _mm256_fmadd_ps(l8[p], _mm256_permute_ps(x, 0), d);
      ind = _mm256_fmadd_ps(ls8[p], x, ind);
      d2 = _mm256_fmadd_ps(l8[p + 1], _mm256_permute_ps(y, 0), d2);
      ind2 = _mm256_fmadd_ps(ls8[p + 1], y, ind2);
    }
    if (p < np) {
      const __m256 x = _mm256_cvtph_ps(_mm_loadu_si128((const __m128i *)(t + 8 * p)));
      d = _mm256_fmadd_ps(l8[p], _mm256_permute_ps(x, 0), d);
      ind = _mm256_fmadd_ps(ls8[p], x, ind);
    }
    d = _mm256_add_ps(d, d2), ind = _mm256_add_ps(ind, ind2);
    __m128 d4 = _mm_add_ps(_mm256_castps256_ps128(d), _mm256_extractf128_ps(d, 1));
    __m128 i4 = _mm_add_ps(_mm256_castps256_ps128(ind), _mm256_extractf128_ps(ind, 1));
    if (nc & 1) {
      const __m128 x = _mm_cvtph_ps(_mm_loadl_epi64((const __m128i *)(t + 4 * (nc - 1))));
      d4 = _mm_fmadd_ps(l4, _mm_permute_ps(x, 0), d4);
      i4 = _mm_fmadd_ps(ls4, x, i4);
    }
    float alb[4], dd[4], ii[4];
    _mm_storeu_ps(alb, _mm_cvtph_ps(_mm_loadl_epi64((const __m128i *)(t + 4 * nc))));
    _mm_storeu_ps(dd, d4), _mm_storeu_ps(ii, i4);
    clamped += (uint64_t)finish_vertex(alb, load4(dd), load4(ii), wl ? wl + 4 * v : NULL, r->rad_cpu + 4 * v);
  }
  return clamped;
}

static int have_avx2_f16c(void) {
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
         __builtin_cpu_supports("f16c");
}
#endif

static int simd_allowed = 1;

int cvr_relight_simd(int allow) {
  simd_allowed = allow;
#ifdef HAVE_F16C
  return allow && have_avx2_f16c();
#else
  return 0;
#endif
}

/* Relights every vertex into rad_cpu and uploads it into buf_rad; ul / uls:
 * the lighting without / with the sun's SH projection (RGB in xyz of each
 * vec4, as relight.vert's u_l, u_ls).  Returns the clamped channels. */
uint64_t cvr_relight_cpu(cv_renderer *r, const float *ul, const float *uls) {
  v4 l[64], ls[64];
  for (int i = 0; i < r->nc; i++) {
    l[i] = (v4){0, ul[4 * i], ul[4 * i + 1], ul[4 * i + 2]};
    ls[i] = (v4){0, uls[4 * i], uls[4 * i + 1], uls[4 * i + 2]};
  }
  uint64_t (*range)(cv_renderer *, const v4 *, const v4 *, long, long) =
      r->th_cpu ? range_f16 : range_f32;
#ifdef HAVE_F16C
  if (r->th_cpu && simd_allowed && have_avx2_f16c()) range = range_f16_avx2;
#endif
  const long nv = (long)r->nv, step = 4096;
  uint64_t clamped = 0;
#pragma omp parallel for schedule(static, 1) reduction(+ : clamped) if (nv > 16384)
  for (long v0 = 0; v0 < nv; v0 += step) clamped += range(r, l, ls, v0, v0 + step < nv ? v0 + step : nv);
  glBindBuffer(GL_ARRAY_BUFFER, r->buf_rad);
  glBufferSubData(GL_ARRAY_BUFFER, 0, (GLsizeiptr)(4 * r->nv * sizeof(float)), r->rad_cpu);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  return clamped;
}
