/* The frame's passes (not installed; layer 4, on render_scene.h,
 * render_light.h and render_texture.h): the render targets, the
 * luminance, depth and PRT shading passes with the Drago table, the
 * supersampling resolve, the read-back and the luminance statistics, the
 * unlit reference.  Reads the light's and the textures' state, draws the
 * scene; owns its programs, targets and table. */
#ifndef CV_RENDER_PASSES_H
#define CV_RENDER_PASSES_H

#include "render/render_gl.h"
#include "render/render_light.h"
#include "render/render_scene.h"
#include "render/render_texture.h"

enum { F_SUN = 1, F_TRANSFER = 2, F_DISP = 4, F_HDR = 8, F_LUM = 16, F_PANEL = 32, F_EXACT = 64,
       F_TEX = 128 /* albedo textures (render_texture.c) */ };
#define NVARIANT 256
enum { K_PRT = 0, K_BG = 1 };

/* The render targets: the luminance pass; shading (display, HDR: textures,
 * + depth); the supersampling resolve (the display image as a texture, the
 * GPU post pass reads it; the HDR image as a renderbuffer); the luminance
 * statistics of the HDR target (lum_reduce.frag: the luminance image, the
 * (max, invalid) pairs; lum_block.frag: those pairs in blocks, red_cpu
 * their read-back, 2 floats a block); the HDR read-back for statistics on
 * the CPU. */
typedef struct cvr_targets {
  GLuint fbo_lum, rb_lum, rb_lum_depth;
  int lum_w, lum_h;
  GLuint fbo_main, tex_disp, tex_hdr, rb_depth;
  int main_w, main_h;
  GLenum main_fmt;
  GLuint fbo_res, tex_res_disp, rb_res_hdr;
  int res_w, res_h;
  GLenum res_fmt;
  GLuint fbo_red, rb_red, tex_red_mb, fbo_blk, rb_blk;
  int red_w, red_h;
  float *red_cpu;
  cv_image *hdr_scratch;
} cvr_targets;

/* The Drago table (LUT_* in render_gl.h): texture buffer, the constants it
 * was built for, whether it passed LUT_TOL, its measured error, its
 * uniforms. */
typedef struct cvr_tone {
  GLuint buf, tex;
  cv_drago_consts dc;
  int built, ok;
  double err;
  float lut_k, lut_tail;
} cvr_tone;

typedef struct cvr_passes {
  GLuint prog_unlit, prog_down, prog_lumred, prog_lumblk;
  GLuint prog_var[2][NVARIANT]; /* prt.frag / background.frag per F_* flags, on first use */
  cvr_targets targets;
  cvr_tone tone;
  cvr_image_ref disp; /* where the display image of the last shade is (0: none yet) */
} cvr_passes;

/* What the passes draw and read: the scene, the lighting, the textures. */
typedef struct cvr_inputs {
  cvr_scene *sc;
  const cvr_light *lt;
  const cvr_texture *tx;
} cvr_inputs;

int cvr_passes_init(cvr_passes *ps, cv_err *err); /* the programs */
void cvr_passes_free(cvr_passes *ps);              /* GL objects (context current) */
void cvr_passes_free_cpu(cvr_passes *ps);
/* Whether the luminance statistics run on the GPU (opts.lum_stats_gpu). */
int cvr_lum_stats_gpu(const cvr_ctx *c);
int cvr_passes_luminance(cvr_ctx *c, cvr_passes *ps, const cvr_inputs *in, const cv_render_view *v,
                         cv_image *out, cv_frame_timing *t, cv_err *err);
/* cv_renderer_shade_stats, and with keep the display image drawn and left
 * on the GPU (cv_renderer_shade_gpu) instead of read back. */
int cvr_passes_shade(cvr_ctx *c, cvr_passes *ps, const cvr_inputs *in, const cv_render_view *v,
                     const cv_drago_consts *dc, int transfer, cv_image *out_display, int keep,
                     cv_image *out_hdr, cv_image *out_lum, double *max_y, uint64_t *n_invalid,
                     cv_frame_timing *t, cv_err *err);
int cvr_passes_unlit(cvr_ctx *c, cvr_passes *ps, const cvr_inputs *in, const cv_render_view *v, cv_image *out,
                     cv_frame_timing *t, cv_err *err);
/* The luminance statistics (cv_renderer_shade_stats) of targets.tex_hdr,
 * which holds W x H pixels of ss x ss texels, into lum (c = 1). */
int cvr_reduce_luminance(cvr_ctx *c, cvr_passes *ps, int W, int H, int ss, cv_image *lum, double *max_y,
                         uint64_t *n_invalid, cv_err *err);

#endif
