/* Internals of the wall-eye renderer shared by its files (not installed):
 *   renderer.c        context, programs, matrices, scene upload, create/destroy
 *   render_light.c    relighting by transform feedback, the sun's shadow map
 *                     and split, background, dashboard LCD image
 *   render_passes.c   targets, read-back, the luminance / depth / shading
 *                     passes, Drago tables, the unlit reference
 *   render_present.c  window presentation and swap
 *   render_texture.c  albedo textures: vertex split at UV seams, texture array
 *   render_share.c    shared lighting: the set_lighting products exported / imported
 *   render_casters.c  the sun's shadow casters: a simplified copy of the opaque mesh
 *   render_relight.c  the relight on the CPU (software GL)
 *   render_edges.c    directed-edge sets (closedness), triangle normals
 *   render_post.c     the frame's end on the GPU: patch means, equation 7,
 *                     the 8-bit projector image per eye (owns struct cvr_post)
 * The GL objects are described in renderer.c. */
#ifndef CV_RENDER_RENDERER_INTERNAL_H
#define CV_RENDER_RENDERER_INTERNAL_H

#define GL_GLEXT_PROTOTYPES 1
#include "render/renderer.h"

#include <GL/glcorearb.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "io/exr.h"
#include "render/egl_context.h"
#include "tonemap/foveal.h"
#include "render/shaders.h"
#include "render/window.h"
#include "view/cave.h"
#include "sh/sh.h"

enum { F_SUN = 1, F_TRANSFER = 2, F_DISP = 4, F_HDR = 8, F_LUM = 16, F_PANEL = 32, F_EXACT = 64,
       F_TEX = 128 /* albedo textures (render_texture.c) */ };
#define NVARIANT 256
enum { K_PRT = 0, K_BG = 1 };
enum { U_TRANSFER = 0, U_SHADOW = 2, U_BG = 3, U_SRC = 4, U_PANEL = 5, U_TONE = 6,
       U_ALBEDO = 7 }; /* texture units */

/* Drago table (common.glsl, cv_drago_table): Ld as a function of y = x / Lwmax'
 * over [2^-126, 1), a piecewise cubic with one RGBA32F texel of
 * coefficients per segment and a segment per 1/16 octave of y (picked by
 * its float exponent and top 4 mantissa bits), rebuilt when the Drago
 * constants change. */
#define LUT_PER_OCT 16
#define LUT_DRAGO_E0 1                      /* first biased exponent */
#define LUT_DRAGO_SEGS (126 * LUT_PER_OCT)  /* 2^-126 .. 1 */
/* Largest table error accepted (relative, with a floor of 1e-4 on Ld): the
 * display values then stay within ~1e-6 of cv_drago_image.  Beyond it the
 * shader computes the curve (DRAGO_EXACT). */
#define LUT_TOL 2e-6


typedef struct cvr_post cvr_post; /* render_post.c */

struct cv_renderer {
  cv_egl egl;
  cvr_post *post;     /* the GPU post pass (render_post.c), made on first use */
  /* the display image of the last shade: its texture, the framebuffer holding it as
   * attachment 0, size, float or 8-bit (0: none yet) */
  GLuint disp_src, disp_fbo;
  int disp_w, disp_h, disp_float;
  /* bytes read back from and uploaded to the GL since create (cv_renderer_io) */
  uint64_t io_read, io_up;
  /* GPU time of the frame (timer queries: cv_renderer_gpu_timer_*) */
  GLuint gpu_query;
  int gpu_query_on;
  double gpu_query_t0; /* wall ms at its begin */
  cv_window *win;     /* opts.window: the X11 window (NULL headless) */
  GLuint prog_present, tex_present[2]; /* cv_renderer_present: the uploaded codes per eye */
  int present_w, present_h, present_made[2];
  cv_render_opts o;
  char gl_name[256];
  int nc;             /* SH coefficients */
  size_t nv, nt;      /* vertices, opaque triangles drawn */
  double lo[3], hi[3];/* scene bounds */
  GLuint vao_geom, vao_empty;
  GLuint buf_pos, buf_rad, buf_idx, buf_transfer, buf_alb;
  GLuint tex_transfer, tex_bg;
  /* the dashboard LCD image (cv_renderer_set_panel) */
  GLuint tex_panel;
  int panel_on;
  uint64_t panel_bad;
  float panel_c[3], panel_u[3], panel_v[3], panel_n[3], panel_half[2];
  GLuint prog_relight, prog_depth, prog_unlit, prog_down, prog_lumred, prog_lumblk;
  GLuint prog_var[2][NVARIANT];
  /* the Drago table (LUT_*): texture buffer, the constants it was built
   * for, whether it passed LUT_TOL, its measured error, its uniforms */
  GLuint buf_tone, tex_tone;
  cv_drago_consts tone_dc;
  int tone_built, tone_ok;
  double tone_err;
  float lut_k, lut_tail;
  /* lighting */
  int lit, has_sun;
  /* the sun: E/pi, the scene -> shadow-map texel space matrix (prt.frag),
   * its axis scales (D^2, -D_z), the sign of its determinant, the bias */
  float sun_e[3], shadow_q[16], shadow_k[4], shadow_bias;
  int shadow_detsign;
  GLuint fbo_shadow, tex_shadow;
  /* an imported shadow map (render_share.c) lives in tex_shadow_imp, an R32F
   * texture of shadow_imp_res texels (a colour upload is a copy; llvmpipe
   * converts a depth upload texel by texel, 16 ms for 2048^2);
   * shadow_from_import: the current map is that one */
  GLuint tex_shadow_imp, fbo_shadow_imp; /* fbo_shadow_imp: to read it back (re-export) */
  int shadow_imp_res, shadow_from_import;
  int shadow_depth_res; /* tex_shadow's size (0: none yet) */
  /* the current map: drawn for opts.shadow_res (shadow_res; an imported one
   * may differ) in its lower-left shadow_w x shadow_h texels (square texels
   * of the beam's longer side over shadow_res: the shorter side takes fewer) */
  int shadow_res, shadow_w, shadow_h;
  int half_on; /* opts.half_transfer resolved */
  /* targets */
  GLuint fbo_lum, rb_lum, rb_lum_depth;
  int lum_w, lum_h;
  GLuint fbo_main, tex_disp, tex_hdr, rb_depth;
  int main_w, main_h;
  GLenum main_fmt;
  uint8_t *rgba8;     /* read-back scratch of 8-bit display targets */
  size_t rgba8_cap;
  GLuint fbo_res, tex_res_disp, rb_res_hdr;
  int res_w, res_h;
  GLenum res_fmt;
  /* the luminance statistics of the HDR target (lum_reduce.frag) */
  GLuint fbo_red, rb_red, tex_red_mb; /* the luminance image, the (max, invalid) pairs */
  GLuint fbo_blk, rb_blk;             /* those pairs in blocks (lum_block.frag) */
  int red_w, red_h;
  float *red_cpu;     /* the blocks' read-back, 2 floats a block */
  cv_image *hdr_scratch; /* the HDR read-back for statistics on the CPU */
  GLuint fbo_tiny, rb_tiny; /* 1x1: a complete framebuffer for the relight draw (a
                               surfaceless context has no default framebuffer) */
  GLint max_rb;
  /* Frustum culling: the opaque triangles sorted along a Morton curve of
   * their centroids, in chunks of CHUNK triangles with their bounds. */
  size_t nchunks;
  float *chunk_box;   /* 6 per chunk: lo xyz, hi xyz */
  uint32_t *run;      /* scratch: 2 per chunk (first triangle, count) */
  /* The sun split (set_lighting with a sun): within each chunk the
   * triangles facing the sun first (chunk_nf of them), then the others, in
   * buf_idx_sun; the shading pass draws the second part without the sun's
   * per-pixel code.  idx_cpu / pos_cpu: the uploaded triangles and positions. */
  uint32_t *idx_cpu, *chunk_nf;
  float *pos_cpu;
  GLuint buf_idx_sun;
  int sun_split;
  /* Split window lights (cv_renderer_set_split, render_split.c): wl_src
   * gives each renderer vertex its PRT vertex (renumbering and texture seam
   * copies undone); tex_wl (texture buffer, RGBA32F per renderer vertex,
   * used while n_split > 0) holds their direct light, added in relight.vert
   * before the clamp; split_sh their SH projection sum_k E_k y_i(s_k)
   * ([3*i + c]) for the interreflected transfer.  tex_orig: per vertex of
   * the seam-split PRT its original vertex, until the upload. */
  uint32_t *wl_src, *tex_orig;
  float *wl_usc; /* textured PRT drawn without its textures: their mean albedo folded back
                    (cv_prt_untextured_scale) per renderer vertex; else NULL */
  GLuint buf_wl, tex_wl;
  double split_sh[3 * CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS];
  int n_split;
  GLsizei *md_count;  /* scratch for glMultiDrawElements: 1 per chunk */
  const void **md_off;
  /* Lighting changes (opts.shadow_cull, shadow_reuse, split_margin): the
   * split is three parts per chunk, n_t . s > m (chunk_na of them), then
   * |n_t . s| <= m, then n_t . s < -m (chunk_nf = the first two; the culled
   * shadow map draws the last two), m = split_margin, for the direction
   * split_s; tri_n the triangles' unit winding normals (built on first use);
   * shadow_s the sun of the current shadow map, shadow_texel its texel (m);
   * nv_used the vertices of opaque triangles (numbered first). */
  uint32_t *chunk_na;
  float *tri_n;
  double split_s[3], shadow_s[3], shadow_texel, shadow_ext;
  int split_valid, shadow_valid;
  size_t nv_used;
  int closed;         /* cv_renderer_mesh_closed */
  /* Shared lighting (render_share.c): shadow maps drawn and splits made
   * here so far (the generation an export names), the exporter's generation
   * of the imported ones (0: made here), the scene's fingerprint (0: not
   * computed yet). */
  uint64_t shadow_gen, split_gen, shadow_import, split_import, share_scene;
  /* albedo textures (render_texture.c): the array (0 = none), its layers and
   * size, textures that could not be read (+ the first message), vertices
   * added by the split, and (u, v, layer) per vertex until the upload */
  GLuint tex_albedo, buf_uvl;
  int tex_layers, tex_w, tex_h, tex_missing;
  size_t tex_split;
  char tex_msg[320];
  float *tex_uvl;
  /* the sun's shadow casters (render_casters.c, opts.shadow_casters): built
   * on the first map; positions, triangles, their unit normals, the culled
   * list of the last map (cast_drawn triangles), whether culling applies,
   * the simplifier's error (m) and the build's wall ms */
  GLuint vao_cast, buf_cast_pos, buf_cast_idx;
  float *cast_pos, *cast_n;
  uint32_t *cast_idx, *cast_draw;
  size_t cast_nt, cast_drawn, cast_defects;
  int cast_built, cast_culled;
  double cast_err, cast_ms;
  /* the CPU relight (render_relight.c, opts.relight_cpu): 1 when used; the
   * transfer as the GL's texture buffer would hold it (nc + 1 RGBA texels a
   * vertex, not uploaded then: floats in tf_cpu, or with opts.half_transfer
   * half floats in th_cpu), the split lights' direct light (RGBA a vertex,
   * NULL without), the relit radiance before its upload */
  int relight_on_cpu;
  float *tf_cpu, *wl_cpu, *rad_cpu;
  uint16_t *th_cpu;
};

enum { DRAW_ALL = 0, DRAW_SUNLIT = 1, DRAW_UNSUNLIT = 2, DRAW_SHADOW = 3 }; /* draw_mesh parts */

#define CHUNK 1024

/* Helpers shared between the renderer's files. */
double cvr_now_ms(void);
double cvr_tick(const cv_renderer *r);
int cvr_gl_check(const char *where, cv_err *err);
GLuint cvr_compile(GLenum type, const char *name, const char *defines, cv_err *err);
void cvr_set_samplers(GLuint p);
int cvr_build(const char *vs_name, const char *fs_name, const char *defines, const char *tf,
                 GLuint *out, cv_err *err);
int cvr_variant(cv_renderer *r, int kind, int flags, GLuint *out, cv_err *err);
void cvr_uni_mat(GLuint p, const char *name, const float m[16]);
void cvr_uni_f(GLuint p, const char *name, float v);
void cvr_uni_v3(GLuint p, const char *name, const float v[3]);
int cvr_invert4(const double m[16], double inv[16]);
int cvr_view_matrices(const cv_render_view *v, float mvp[16], float inv[16], float eye[3],
                         float *facing);
GLuint cvr_make_tbo(GLuint *buf, GLenum fmt, const void *data, size_t bytes);
uint64_t cvr_morton3(uint32_t x, uint32_t y, uint32_t z);
int cvr_cmp_u64(const void *a, const void *b);
int cvr_upload_background(cv_renderer *r, int w, int h, const float *rgb, cv_err *err);
int cvr_upload_scene(cv_renderer *r, const cv_prt *p, cv_err *err);
void cvr_sun_matrices(cv_renderer *r, const double s[3], float clip[16], float *texel, int size[2]);
int cvr_shadow_culled(const cv_renderer *r);
int cvr_shadow_target(cv_renderer *r, int n, cv_err *err);
int cvr_render_shadow(cv_renderer *r, const double s[3], cv_err *err);
int cvr_draw_casters(cv_renderer *r, const double s[3], cv_err *err);
/* Directed edges of triangles on welded indices (render_edges.c):
 * degenerate triangles skipped, dup = directed edges met again. */
typedef struct cvr_edges {
  uint64_t *set;
  size_t cap, dup;
} cvr_edges;
uint64_t cvr_hash64(uint64_t k);
int cvr_edges_build(cvr_edges *e, const uint32_t *tri, size_t nt);
/* a's border edges (reverse not in a) that are not border edges of b (all
 * of them when b is NULL). */
size_t cvr_edges_border_unmatched(const cvr_edges *a, const cvr_edges *b);
void cvr_edges_free(cvr_edges *e);
/* Unit winding normals of nt triangles (0 for a degenerate one) into out[3 nt]. */
void cvr_unit_normals(const float *pos, const uint32_t *idx, size_t nt, float *out);
uint64_t cvr_relight_cpu(cv_renderer *r, const float *ul, const float *uls);
/* n halves to floats: portably, or by F16C when the CPU has it (returns 1
 * then); the same floats (render_relight.c). */
void cvr_halves_soft(const uint16_t *h, float *f, size_t n);
int cvr_halves_f16c(const uint16_t *h, float *f, size_t n);
/* Lets the CPU relight of a half-float transfer use its vector path (F16C +
 * FMA) when the CPU has them (1, the default) or not (0: the portable
 * conversion, for tests).  Returns 1 when the vector path will be used. */
int cvr_relight_simd(int allow);
void cvr_casters_free(cv_renderer *r);
int cvr_sun_split(cv_renderer *r, const double s[3], cv_err *err);
void cvr_split_buffer_bind(cv_renderer *r);
void cvr_split_bind(const cv_renderer *r, GLuint prog);
void cvr_split_free(cv_renderer *r);
GLuint cvr_make_rb(GLenum fmt, int w, int h);
GLuint cvr_make_tex(GLenum fmt, int w, int h);
/* The luminance statistics (cv_renderer_shade_stats) of r->tex_hdr, which
 * holds W x H pixels of ss x ss texels, into lum (c = 1). */
int cvr_reduce_luminance(cv_renderer *r, int W, int H, int ss, cv_image *lum, double *max_y,
                         uint64_t *n_invalid, cv_err *err);
int cvr_fbo_complete(const char *what, int w, int h, cv_err *err);
int cvr_ensure_lum(cv_renderer *r, int w, int h, cv_err *err);
GLenum cvr_disp_fmt(const cv_renderer *r, int resolve_target, int ss);
int cvr_ensure_main(cv_renderer *r, int w, int h, GLenum dfmt, cv_err *err);
int cvr_ensure_res(cv_renderer *r, int w, int h, cv_err *err);
int cvr_read_image(cv_renderer *r, GLenum att, int is8, cv_image *img);
void cvr_set_cull(const cv_renderer *r, int on);
int cvr_check_view(const cv_renderer *r, const cv_render_view *v, cv_err *err);
void cvr_bind_shading(const cv_renderer *r, GLuint p, const float mvp[16], const float inv[16],
                         float facing, const cv_drago_consts *dc);
double cvr_drago_raw(const cv_drago_consts *c, double y);
double cvr_fit_table(double (*fn)(const cv_drago_consts *, double), const cv_drago_consts *c,
                        int e0, int nseg, double floor, float *out);
void cvr_tone_table(cv_renderer *r, const cv_drago_consts *dc);
int cvr_box_outside(const float mvp[16], const float *lo, const float *hi);
size_t cvr_draw_mesh(cv_renderer *r, const float *mvp, int part);
void cvr_draw_fullscreen(const cv_renderer *r);
void cvr_depth_pass(cv_renderer *r, const float mvp[16], int W, int H);
void cvr_shading_depth_state(const cv_renderer *r);
int cvr_texture_prepare(cv_renderer *r, const cv_prt *p, cv_prt **split, cv_err *err);
void cvr_post_free(cv_renderer *r);
/* The 8-bit projector image of slot (0 none: no grid), its size. */
GLuint cvr_post_slot_texture(const cv_renderer *r, int slot, int *w, int *h);

#endif
