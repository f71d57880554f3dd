/* The relight (render_relight.h): by transform feedback on a GPU
 * (relight.vert, relight_gpu), or on the CPU (opts.relight_cpu; by default
 * with a software GL):
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
#include "render/render_relight.h"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define HAVE_F16C 1
#endif

#include "io/exr.h"

typedef float v4 __attribute__((vector_size(16)));

/* One CPU relight's inputs and output. */
typedef struct job {
  int nc;
  const float *tf, *wl; /* float texels, or th: half ones; the split lights' direct light or NULL */
  const uint16_t *th;
  float *rad;
} job;

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
static uint64_t range_f32(const job *r, const v4 *l, const v4 *ls, long v0, long v1) {
  const int nc = r->nc;
  const size_t per = 4 * (size_t)(nc + 1);
  const float *wl = r->wl;
  uint64_t clamped = 0;
  for (long v = v0; v < v1; v++)
    clamped += (uint64_t)relight_vertex(r->tf + (size_t)v * per, l, ls, nc,
                                        wl ? wl + 4 * v : NULL, r->rad + 4 * v);
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
static uint64_t range_f16(const job *r, const v4 *l, const v4 *ls, long v0, long v1) {
  const int nc = r->nc;
  const size_t per = 4 * (size_t)(nc + 1);
  const float *wl = r->wl;
  float t[4 * (CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS + 1)];
  uint64_t clamped = 0;
  for (long v = v0; v < v1; v++) {
    cvr_halves_f16c(r->th + (size_t)v * per, t, per);
    clamped += (uint64_t)relight_vertex(t, l, ls, nc, wl ? wl + 4 * v : NULL, r->rad + 4 * v);
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
    const job *r, const v4 *l, const v4 *ls, long v0, long v1) {
  const int nc = r->nc, np = nc / 2;
  const size_t per = 4 * (size_t)(nc + 1);
  const float *wl = r->wl;
  __m256 l8[32], ls8[32];
  for (int p = 0; p < np; p++) {
    l8[p] = _mm256_set_m128(_mm_loadu_ps((const float *)&l[2 * p + 1]), _mm_loadu_ps((const float *)&l[2 * p]));
    ls8[p] = _mm256_set_m128(_mm_loadu_ps((const float *)&ls[2 * p + 1]), _mm_loadu_ps((const float *)&ls[2 * p]));
  }
  const __m128 l4 = _mm_loadu_ps((const float *)&l[nc - 1]), ls4 = _mm_loadu_ps((const float *)&ls[nc - 1]);
  uint64_t clamped = 0;
  for (long v = v0; v < v1; v++) {
    const uint16_t *t = r->th + (size_t)v * per;
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
    clamped += (uint64_t)finish_vertex(alb, load4(dd), load4(ii), wl ? wl + 4 * v : NULL, r->rad + 4 * v);
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

/* Relights every vertex into rad_cpu and uploads it into buf_rad.
 * Returns the clamped channels. */
static uint64_t relight_cpu(cvr_relight *rl, const cvr_scene *sc, const cvr_split *wl,
                            const float *ul, const float *uls) {
  const job jb = {sc->nc, rl->tf_cpu, wl->n > 0 ? wl->cpu : NULL, rl->th_cpu, rl->rad_cpu};
  const job *r = &jb;
  v4 l[64], ls[64];
  for (int i = 0; i < r->nc; i++) {
    l[i] = (v4){0, ul[4 * i], ul[4 * i + 1], ul[4 * i + 2]};
    ls[i] = (v4){0, uls[4 * i], uls[4 * i + 1], uls[4 * i + 2]};
  }
  uint64_t (*range)(const job *, const v4 *, const v4 *, long, long) =
      r->th ? range_f16 : range_f32;
#ifdef HAVE_F16C
  if (r->th && simd_allowed && have_avx2_f16c()) range = range_f16_avx2;
#endif
  const long nv = (long)sc->nv, step = 4096;
  uint64_t clamped = 0;
#pragma omp parallel for schedule(static, 1) reduction(+ : clamped) if (nv > 16384)
  for (long v0 = 0; v0 < nv; v0 += step) clamped += range(r, l, ls, v0, v0 + step < nv ? v0 + step : nv);
  glBindBuffer(GL_ARRAY_BUFFER, sc->buf_rad);
  glBufferSubData(GL_ARRAY_BUFFER, 0, (GLsizeiptr)(4 * sc->nv * sizeof(float)), r->rad);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  return clamped;
}

/* The relight by transform feedback; with count the clamped channels
 * (mapping the buffer back: NULL *m when it cannot). */
static uint64_t relight_gpu(const cvr_ctx *c, const cvr_relight *rl, const cvr_scene *r,
                            const cvr_split *wl, const float *ul, const float *uls, int count,
                            const float **m) {
  uint64_t clamped = 0;
  GLuint p = rl->prog;
  glUseProgram(p);
  glUniform4fv(glGetUniformLocation(p, "u_l"), r->nc, ul);
  glUniform4fv(glGetUniformLocation(p, "u_ls"), r->nc, uls);
  cvr_split_bind(wl, p);
  glActiveTexture(GL_TEXTURE0 + U_TRANSFER);
  glBindTexture(GL_TEXTURE_BUFFER, rl->tex_transfer);
  glBindFramebuffer(GL_FRAMEBUFFER, rl->fbo_tiny);
  glBindVertexArray(c->vao_empty);
  glEnable(GL_RASTERIZER_DISCARD);
  glBindBufferBase(GL_TRANSFORM_FEEDBACK_BUFFER, 0, r->buf_rad);
  glBeginTransformFeedback(GL_POINTS);
  glDrawArrays(GL_POINTS, 0, (GLsizei)r->nv);
  glEndTransformFeedback();
  glBindBufferBase(GL_TRANSFORM_FEEDBACK_BUFFER, 0, 0);
  glDisable(GL_RASTERIZER_DISCARD);
  glBindVertexArray(0);
  /* Clamp count: sum of the captured w (exact in double), only when asked
   * for (mapping the buffer waits for the relight and reads 16 bytes a
   * vertex back). */
  if (count) {
    glBindBuffer(GL_ARRAY_BUFFER, r->buf_rad);
    *m = glMapBufferRange(GL_ARRAY_BUFFER, 0, (GLsizeiptr)(4 * r->nv * sizeof(float)), GL_MAP_READ_BIT);
    if (*m) {
      for (size_t v = 0; v < r->nv; v++) clamped += (uint64_t)(*m)[4 * v + 3];
      glUnmapBuffer(GL_ARRAY_BUFFER);
    }
    glBindBuffer(GL_ARRAY_BUFFER, 0);
  }
  return clamped;
}

int cvr_relight_run(const cvr_ctx *c, cvr_relight *rl, const cvr_scene *sc, const cvr_split *wl,
                    const float *ul, const float *uls, int count, uint64_t *clamped, cv_err *err) {
  const float *m = NULL;
  if (rl->on_cpu) {
    *clamped = relight_cpu(rl, sc, wl, ul, uls);
    m = rl->rad_cpu;
  } else {
    *clamped = relight_gpu(c, rl, sc, wl, ul, uls, count, &m);
  }
  int st = cvr_gl_check("relighting", err);
  if (st) return st;
  if (count && !m) return cv_err_set(err, CV_ERR_BACKEND, "cannot map the relit vertex buffer");
  return CV_OK;
}

int cvr_relight_init(cvr_relight *rl, int nc, cv_err *err) {
  char defs[64];
  snprintf(defs, sizeof defs, "#define NC %d\n", nc);
  int st = cvr_build("relight.vert", NULL, defs, "v_out", &rl->prog, err);
  if (st) return st;
  rl->rb_tiny = cvr_make_rb(GL_R8, 1, 1);
  glGenFramebuffers(1, &rl->fbo_tiny);
  glBindFramebuffer(GL_FRAMEBUFFER, rl->fbo_tiny);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rl->rb_tiny);
  return cvr_fbo_complete("1x1", 1, 1, err);
}

int cvr_relight_upload(const cvr_ctx *c, cvr_relight *rl, const cv_prt *p, const uint32_t *old_of,
                       const float *usc, cv_err *err) {
  const int nc = (int)(p->bands * p->bands);
  const size_t texels = p->nv * (size_t)(nc + 1);
  rl->on_cpu = c->o->relight_cpu < 0 ? c->egl->software : c->o->relight_cpu != 0;
  rl->half_on = c->o->half_transfer < 0 ? rl->on_cpu : c->o->half_transfer != 0;
  float *tf = malloc(4 * texels * sizeof *tf + 4);
  uint16_t *th = rl->half_on ? malloc(4 * texels * sizeof *th + 4) : NULL;
  if (!tf || (rl->half_on && !th)) {
    free(tf), free(th);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory uploading the scene");
  }
  for (size_t nvx = 0; nvx < p->nv; nvx++) {
    const size_t v = old_of[nvx];
    float *o = tf + 4 * nvx * (size_t)(nc + 1);
    for (int i = 0; i < nc; i++) {
      o[4 * i] = p->td[v * nc + i];
      for (int k = 0; k < 3; k++)
        o[4 * i + 1 + k] = p->ti ? p->ti[(v * 3 + k) * nc + i] * usc[3 * v + k] : 0.0f;
    }
    for (int k = 0; k < 3; k++) o[4 * nc + k] = p->albedo[3 * v + k] * usc[3 * v + k];
    o[4 * nc + 3] = 0;
  }
  if (th)
    for (size_t i = 0; i < 4 * texels; i++) th[i] = cv_float_to_half(tf[i]);
  if (rl->on_cpu) { /* the CPU reads what the texture buffer would hold */
    rl->rad_cpu = malloc(4 * p->nv * sizeof *rl->rad_cpu + 4);
    if (!rl->rad_cpu) {
      free(tf), free(th);
      return cv_err_set(err, CV_ERR_NOMEM, "out of memory uploading the scene");
    }
    if (th) rl->th_cpu = th, th = NULL; /* kept: half the bytes to read per relight */
    else rl->tf_cpu = tf, tf = NULL;
  } else {
    rl->tex_transfer = th ? cvr_make_tbo(&rl->buf_transfer, GL_RGBA16F, th, 4 * texels * sizeof *th)
                          : cvr_make_tbo(&rl->buf_transfer, GL_RGBA32F, tf, 4 * texels * sizeof *tf);
  }
  free(tf), free(th);
  return CV_OK;
}

void cvr_relight_free(cvr_relight *rl) {
  glDeleteBuffers(1, &rl->buf_transfer);
  glDeleteTextures(1, &rl->tex_transfer);
  glDeleteFramebuffers(1, &rl->fbo_tiny);
  glDeleteRenderbuffers(1, &rl->rb_tiny);
  glDeleteProgram(rl->prog);
  rl->buf_transfer = rl->tex_transfer = rl->fbo_tiny = rl->rb_tiny = rl->prog = 0;
}

void cvr_relight_free_cpu(cvr_relight *rl) {
  free(rl->tf_cpu), free(rl->th_cpu), free(rl->rad_cpu);
  rl->tf_cpu = rl->rad_cpu = NULL, rl->th_cpu = NULL;
}
