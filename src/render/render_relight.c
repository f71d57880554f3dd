/* The relight on the CPU (opts.relight_cpu; by default with a software GL).
 *
 * llvmpipe runs the transform-feedback relight (relight.vert) on one
 * thread, fetching the transfer texel by texel: 35-39 ms for the 293K
 * vertices x 26 texels of the 571K cabin at 5 bands on this machine.  The
 * same sums as a plain loop over the texels in memory, four lanes at a
 * time, OpenMP threads over the vertices, then one glBufferSubData of the
 * radiance (16 bytes a vertex): docs/benchmarks.md has the figures.
 *
 * The sums are relight.vert's, in float (the even and odd terms summed
 * apart, then added: the last bits differ from the shader's order), per vertex:
 *   d = sum_i l_i td_i, ind = sum_i ls_i ti_i (RGB), rad = albedo d + ind
 *   (+ the split lights' direct light), each channel that is negative or
 *   not finite set to 0 and counted in w.
 * A texel holds (td, ti_R, ti_G, ti_B); with the lighting in lanes 1..3
 * (lane 0 zero) both sums are one multiply-add of four lanes per texel. */
#include "render/renderer_internal.h"

typedef float v4 __attribute__((vector_size(16)));

static inline v4 load4(const float *p) {
  v4 v;
  memcpy(&v, p, sizeof v);
  return v;
}

/* One vertex: the relit RGB and its clamp count into out[4]. */
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

/* Relights every vertex into rad_cpu and uploads it into buf_rad; ul / uls:
 * the lighting without / with the sun's SH projection (RGB in xyz of each
 * vec4, as relight.vert's u_l, u_ls).  Returns the clamped channels. */
uint64_t cvr_relight_cpu(cv_renderer *r, const float *ul, const float *uls) {
  v4 l[64], ls[64];
  for (int i = 0; i < r->nc; i++) {
    l[i] = (v4){0, ul[4 * i], ul[4 * i + 1], ul[4 * i + 2]};
    ls[i] = (v4){0, uls[4 * i], uls[4 * i + 1], uls[4 * i + 2]};
  }
  const int nc = r->nc;
  const float *wl = r->n_split > 0 ? r->wl_cpu : NULL;
  const long nv = (long)r->nv;
  uint64_t clamped = 0;
#pragma omp parallel for schedule(static, 4096) reduction(+ : clamped) if (nv > 16384)
  for (long v = 0; v < nv; v++)
    clamped += (uint64_t)relight_vertex(r->tf_cpu + 4 * (size_t)v * (size_t)(nc + 1), l, ls, nc,
                                        wl ? wl + 4 * v : NULL, r->rad_cpu + 4 * v);
  glBindBuffer(GL_ARRAY_BUFFER, r->buf_rad);
  glBufferSubData(GL_ARRAY_BUFFER, 0, (GLsizeiptr)(4 * r->nv * sizeof(float)), r->rad_cpu);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  return clamped;
}
