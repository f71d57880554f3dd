/* The bottom layer of the wall-eye renderer (not installed): the GL helpers
 * every feature of src/render uses, and the small context they share.
 * It includes no feature header and calls no feature function (the layers:
 * renderer_internal.h, docs/architecture.md; checked by
 * tests/render/check_layers.sh).
 *
 *   cvr_ctx          what every feature reads: the renderer's options and
 *                    EGL context, the empty VAO of fullscreen draws, the
 *                    GL's size limit, the read-back/upload counters and
 *                    scratch, the GPU timer query
 *   programs         compile/build with the embedded GLSL, sampler units,
 *                    uniforms
 *   objects          textures, renderbuffers, texture buffers, framebuffer
 *                    completeness, GL error check
 *   read-back        cvr_read_image (rows flipped, 8-bit or float)
 *   timing           wall and CPU ms, ticks after glFinish (opts.timing)
 *   matrices         4x4 inverse, a view's scene-frame matrices
 *   keys             Morton codes, a 64-bit hash, u64 comparison */
#ifndef CV_RENDER_GL_H
#define CV_RENDER_GL_H

#define GL_GLEXT_PROTOTYPES 1
#include "render/renderer.h"

#include <GL/glcorearb.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "render/egl_context.h"
#include "render/shaders.h"

/* Texture units of the shaders' samplers (cvr_set_samplers). */
enum { U_TRANSFER = 0, U_SHADOW = 2, U_BG = 3, U_SRC = 4, U_PANEL = 5, U_TONE = 6,
       U_ALBEDO = 7 };

/* Drago table (common.glsl, cv_drago_table; built by render_passes.c): Ld
 * as a function of y = x / Lwmax' over [2^-126, 1), a piecewise cubic with
 * one RGBA32F texel of coefficients per segment and a segment per 1/16
 * octave of y (picked by its float exponent and top 4 mantissa bits).  The
 * segment count is a define of every shader that includes common.glsl. */
#define LUT_PER_OCT 16
#define LUT_DRAGO_E0 1                      /* first biased exponent */
#define LUT_DRAGO_SEGS (126 * LUT_PER_OCT)  /* 2^-126 .. 1 */
/* Largest table error accepted (relative, with a floor of 1e-4 on Ld): the
 * display values then stay within ~1e-6 of cv_drago_image.  Beyond it the
 * shader computes the curve (DRAGO_EXACT). */
#define LUT_TOL 2e-6

/* What every feature shares (the renderer embeds one; features get a
 * pointer).  o and egl point into the renderer. */
typedef struct cvr_ctx {
  const cv_render_opts *o; /* the renderer's options */
  cv_egl *egl;             /* its context (made current by each entry point) */
  GLuint vao_empty;        /* fullscreen draws (vertices from gl_VertexID) */
  GLint max_rb;            /* largest renderbuffer / texture side */
  /* bytes read back from and uploaded to the GL since create (cv_renderer_io) */
  uint64_t io_read, io_up;
  uint8_t *rgba8;          /* read-back scratch of 8-bit targets */
  size_t rgba8_cap;
  /* GPU time of the frame (timer queries: cv_renderer_gpu_timer_*) */
  GLuint gpu_query;
  int gpu_query_on;
  double gpu_query_t0;     /* wall ms at its begin */
} cvr_ctx;

/* A colour image held by the GL: its texture, a framebuffer holding it as
 * attachment 0, size, float or 8-bit (tex 0: none). */
typedef struct cvr_image_ref {
  GLuint tex, fbo;
  int w, h, is_float;
} cvr_image_ref;

void cvr_ctx_free(cvr_ctx *c); /* GL objects (context current) and scratch */

/* timing */
double cvr_now_ms(void);
double cvr_tick(const cvr_ctx *c);
void cvr_timer_begin(cvr_ctx *c);
void cvr_timer_end(cvr_ctx *c);
double cvr_timer_result(cvr_ctx *c);

/* programs */
int cvr_gl_check(const char *where, cv_err *err);
GLuint cvr_compile(GLenum type, const char *name, const char *defines, cv_err *err);
void cvr_set_samplers(GLuint p);
int cvr_build(const char *vs_name, const char *fs_name, const char *defines, const char *tf,
              GLuint *out, cv_err *err);
void cvr_uni_mat(GLuint p, const char *name, const float m[16]);
void cvr_uni_f(GLuint p, const char *name, float v);
void cvr_uni_v3(GLuint p, const char *name, const float v[3]);
int cvr_has_extension(const char *name);

/* objects */
GLuint cvr_make_tbo(GLuint *buf, GLenum fmt, const void *data, size_t bytes);
GLuint cvr_make_rb(GLenum fmt, int w, int h);
GLuint cvr_make_tex(GLenum fmt, int w, int h);
int cvr_fbo_complete(const char *what, int w, int h, cv_err *err);
void cvr_draw_fullscreen(const cvr_ctx *c);
/* Reads attachment att of the bound read framebuffer into img (counted in
 * c->io_read); CV_ERR_NOMEM when the scratch cannot grow. */
int cvr_read_image(cvr_ctx *c, GLenum att, int is8, cv_image *img);

/* matrices */
int cvr_invert4(const double m[16], double inv[16]);
int cvr_view_matrices(const cv_render_view *v, float mvp[16], float inv[16], float eye[3],
                      float *facing);

/* keys */
uint64_t cvr_morton3(uint32_t x, uint32_t y, uint32_t z);
int cvr_cmp_u64(const void *a, const void *b);
uint64_t cvr_hash64(uint64_t k);

#endif
