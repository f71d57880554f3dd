/* The relight of the renderer (not installed; layer 2, on render_scene.h
 * and render_split.h): exit radiance per vertex = lighting SH . transfer,
 * into the scene's radiance buffer, by transform feedback on a GPU
 * (relight.vert) or by an OpenMP loop on the CPU (opts.relight_cpu, a
 * software GL; render_relight.c has the details). */
#ifndef CV_RENDER_RELIGHT_H
#define CV_RENDER_RELIGHT_H

#include "render/render_gl.h"
#include "render/render_scene.h"
#include "render/render_split.h"

/* on_cpu: the CPU relight is used; half_on: opts.half_transfer resolved.
 * On the GPU the transfer is a texture buffer (tex_transfer: per vertex
 * nc texels (td_i, ti_R,i, ti_G,i, ti_B,i) then the albedo), drawn by prog
 * into fbo_tiny (1x1: a complete framebuffer, as a surfaceless context has
 * none).  On the CPU it stays in memory as the texture buffer would hold
 * it (floats in tf_cpu, or half floats in th_cpu), the radiance in
 * rad_cpu before its upload. */
typedef struct cvr_relight {
  int on_cpu, half_on;
  GLuint prog, buf_transfer, tex_transfer, fbo_tiny, rb_tiny;
  float *tf_cpu, *rad_cpu;
  uint16_t *th_cpu;
} cvr_relight;

/* The program for nc coefficients and the 1x1 target. */
int cvr_relight_init(cvr_relight *rl, int nc, cv_err *err);
/* At the upload: resolves on_cpu and half_on, packs p's transfer in the
 * renumbered order old_of, scaled by usc per vertex of p. */
int cvr_relight_upload(const cvr_ctx *c, cvr_relight *rl, const cv_prt *p, const uint32_t *old_of,
                       const float *usc, cv_err *err);
/* Relights every vertex of sc into sc->buf_rad (ul / uls: the lighting
 * without / with the sun's SH projection, RGB in xyz of each vec4, as
 * relight.vert's u_l, u_ls; the split lights' direct light added).  With
 * count, *clamped gets the clamped channels. */
int cvr_relight_run(const cvr_ctx *c, cvr_relight *rl, const cvr_scene *sc, const cvr_split *wl,
                    const float *ul, const float *uls, int count, uint64_t *clamped, cv_err *err);
void cvr_relight_free(cvr_relight *rl); /* GL objects (context current) */
void cvr_relight_free_cpu(cvr_relight *rl);

/* n halves to floats: portably, or by F16C when the CPU has it (returns 1
 * then); the same floats. */
void cvr_halves_soft(const uint16_t *h, float *f, size_t n);
int cvr_halves_f16c(const uint16_t *h, float *f, size_t n);
/* Lets the CPU relight of a half-float transfer use its vector path (F16C +
 * FMA) when the CPU has them (1, the default) or not (0: the portable
 * conversion, for tests).  Returns 1 when the vector path will be used. */
int cvr_relight_simd(int allow);

#endif
