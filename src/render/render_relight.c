/* The relight on the CPU (opts.relight_cpu; by default with a software GL).
 *
 * llvmpipe runs the transform-feedback relight (relight.vert) on one
 * thread, fetching the transfer texel by texel: 35-39 ms for the 293K
 * vertices x 26 texels of the 571K cabin at 5 bands on this machine.  The
 * same sums as a plain loop over the texels in memory, four lanes at a
 * time, OpenMP threads over the vertices, then one glBufferSubData of the
 * radiance (16 bytes a vertex): docs/benchmarks.md has the figures.
 * With opts.half_transfer the transfer stays in half floats (half the
 * memory; not faster: reading the float transfer and summing it cost about
 * the same, so halving the bytes alone gains nothing) and each vertex's
 * texels are converted by F16C (or a portable conversion: the same floats)
 * as they are read.
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
  d += d2, ind += ind2;
  const float *alb = t + 4 * nc;
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
  const long nv = (long)r->nv, step = 4096;
  uint64_t clamped = 0;
#pragma omp parallel for schedule(static, 1) reduction(+ : clamped) if (nv > 16384)
  for (long v0 = 0; v0 < nv; v0 += step) clamped += range(r, l, ls, v0, v0 + step < nv ? v0 + step : nv);
  glBindBuffer(GL_ARRAY_BUFFER, r->buf_rad);
  glBufferSubData(GL_ARRAY_BUFFER, 0, (GLsizeiptr)(4 * r->nv * sizeof(float)), r->rad_cpu);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  return clamped;
}
