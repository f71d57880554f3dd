/* The wall-eye renderer (see renderer.h): GL objects, programs and passes.
 *
 * GL objects:
 *   buf_pos      vertex positions (scene frame), attribute 0
 *   buf_rad      relit radiance per vertex (vec4: RGB, channels clamped),
 *                written by transform feedback, attribute 1
 *   buf_idx      the opaque triangles (windows dropped)
 *   tex_transfer texture buffer over the transfer: per vertex nc texels
 *                (td_i, ti_R,i, ti_G,i, ti_B,i) then the albedo
 *   buf_alb      vertex albedo, attribute 2 (the sun's direct term)
 *   fbo_main     shading targets (display, HDR: RGBA32F textures) + depth
 *   fbo_res      the supersampling resolve targets; fbo_lum the luminance pass
 *   fbo_shadow   the sun's shadow map (depth texture with compare mode) */
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
#include "render/shaders.h"
#include "render/window.h"
#include "view/cave.h"
#include "sh/sh.h"

enum { F_SUN = 1, F_TRANSFER = 2, F_DISP = 4, F_HDR = 8, F_LUM = 16, F_PANEL = 32, F_EXACT = 64 };
#define NVARIANT 128
enum { K_PRT = 0, K_BG = 1 };
enum { U_TRANSFER = 0, U_SHADOW = 2, U_BG = 3, U_SRC = 4, U_PANEL = 5, U_TONE = 6 }; /* texture units */

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

struct cv_renderer {
  cv_egl egl;
  cv_window *win;     /* opts.window: the X11 window (NULL headless) */
  GLuint prog_present, tex_present;
  int present_w, present_h;
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
  GLuint prog_relight, prog_depth, prog_unlit, prog_down;
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
  int shadow_res;
  /* targets */
  GLuint fbo_lum, rb_lum, rb_lum_depth;
  int lum_w, lum_h;
  GLuint fbo_main, tex_disp, tex_hdr, rb_depth;
  int main_w, main_h;
  GLenum main_fmt;
  uint8_t *rgba8;     /* read-back scratch of 8-bit display targets */
  size_t rgba8_cap;
  GLuint fbo_res, rb_res_disp, rb_res_hdr;
  int res_w, res_h;
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
  GLsizei *md_count;  /* scratch for glMultiDrawElements: 1 per chunk */
  const void **md_off;
};

enum { DRAW_ALL = 0, DRAW_SUNLIT = 1, DRAW_UNSUNLIT = 2 }; /* draw_mesh parts */

#define CHUNK 1024

void cv_render_default_opts(cv_render_opts *o) {
  memset(o, 0, sizeof *o);
  o->shadow_res = 2048;
  o->timing = 1;
  o->cull_frustum = 1;
  o->sun_split = 1;
  o->gpu = CV_GPU_AUTO;
}

const char *cv_renderer_gl_name(const cv_renderer *r) { return r->gl_name; }
int cv_renderer_is_software(const cv_renderer *r) { return r->egl.software; }
int cv_renderer_hw_devices(const cv_renderer *r) { return r->egl.hw_devices; }
const char *cv_renderer_platform(const cv_renderer *r) { return r->egl.platform; }

static double now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/* Time stamp after the GL queue has drained (opts.timing), else 0: wall
 * clock, or with opts.timing == 2 the CPU time of the whole process (every
 * llvmpipe thread's work, insensitive to other load on the machine). */
static double tick(const cv_renderer *r) {
  if (!r->o.timing) return 0;
  glFinish();
  if (r->o.timing == 2) {
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
  }
  return now_ms();
}

static int gl_check(const char *where, cv_err *err) {
  GLenum e = glGetError(), first = e;
  while (e != GL_NO_ERROR) e = glGetError();
  if (first == GL_NO_ERROR) return CV_OK;
  return cv_err_set(err, CV_ERR_BACKEND, "OpenGL error 0x%04x in %s", (unsigned)first, where);
}

static GLuint make_rb(GLenum fmt, int w, int h);
static int fbo_complete(const char *what, int w, int h, cv_err *err);
static void set_cull(const cv_renderer *r, int on);
static size_t draw_mesh(cv_renderer *r, const float *mvp, int part);

/* ---------------------------------------------------------------- programs */

static GLuint compile(GLenum type, const char *name, const char *defines, cv_err *err) {
  const char *text = cv_shader_find(name);
  const char *common = cv_shader_find("common.glsl");
  if (!text || !common) {
    cv_err_set(err, CV_ERR_NOT_FOUND, "shader %s is not embedded in the binary", name);
    return 0;
  }
  const char *src[5] = {"#version 330 core\n", defines, "", "#line 1\n", text};
  if (type == GL_FRAGMENT_SHADER) src[2] = common;
  GLuint s = glCreateShader(type);
  glShaderSource(s, 5, src, NULL);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[400] = "";
    glGetShaderInfoLog(s, sizeof log, NULL, log);
    for (char *p = log; *p; p++)
      if (*p == '\n') *p = ' ';
    glDeleteShader(s);
    cv_err_set(err, CV_ERR_BACKEND, "shaders/%s (%s): %s", name, defines, log);
    return 0;
  }
  return s;
}

static void set_samplers(GLuint p) {
  static const struct {
    const char *name;
    int unit;
  } tab[] = {{"u_transfer", U_TRANSFER}, {"u_shadow", U_SHADOW},
             {"u_bg", U_BG}, {"u_src", U_SRC}, {"u_panel", U_PANEL},
             {"u_tone", U_TONE}};
  glUseProgram(p);
  for (size_t i = 0; i < sizeof tab / sizeof tab[0]; i++) {
    GLint loc = glGetUniformLocation(p, tab[i].name);
    if (loc >= 0) glUniform1i(loc, tab[i].unit);
  }
}

static int build(const char *vs_name, const char *fs_name, const char *defines, const char *tf,
                 GLuint *out, cv_err *err) {
  GLuint vs = compile(GL_VERTEX_SHADER, vs_name, defines, err);
  if (!vs) return CV_ERR_BACKEND;
  GLuint fs = 0;
  if (fs_name && !(fs = compile(GL_FRAGMENT_SHADER, fs_name, defines, err))) {
    glDeleteShader(vs);
    return CV_ERR_BACKEND;
  }
  GLuint p = glCreateProgram();
  glAttachShader(p, vs);
  if (fs) glAttachShader(p, fs);
  if (tf) glTransformFeedbackVaryings(p, 1, &tf, GL_INTERLEAVED_ATTRIBS);
  glLinkProgram(p);
  glDeleteShader(vs);
  if (fs) glDeleteShader(fs);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[400] = "";
    glGetProgramInfoLog(p, sizeof log, NULL, log);
    glDeleteProgram(p);
    return cv_err_set(err, CV_ERR_BACKEND, "linking %s + %s: %s", vs_name, fs_name ? fs_name : "-",
                      log);
  }
  set_samplers(p);
  *out = p;
  return CV_OK;
}

/* The prt.frag (K_PRT) or background.frag (K_BG) program for flags F_*,
 * compiled on first use. */
static int variant(cv_renderer *r, int kind, int flags, GLuint *out, cv_err *err) {
  if (!r->prog_var[kind][flags]) {
    char defs[320];
    snprintf(defs, sizeof defs, "%s%s%s%s%s%s%s#define LUT_DRAGO_SEGS %d\n",
             flags & F_SUN ? "#define SUN\n" : "",
             flags & F_TRANSFER ? "#define TRANSFER\n" : "",
             flags & F_DISP ? "#define OUT_DISPLAY\n" : "", flags & F_HDR ? "#define OUT_HDR\n" : "",
             flags & F_LUM ? "#define OUT_LUM\n" : "", flags & F_PANEL ? "#define PANEL\n" : "",
             flags & F_EXACT ? "#define DRAGO_EXACT\n" : "", LUT_DRAGO_SEGS);
    int st = kind == K_PRT ? build("geom.vert", "prt.frag", defs, NULL, &r->prog_var[kind][flags], err)
                           : build("fullscreen.vert", "background.frag", defs, NULL,
                                   &r->prog_var[kind][flags], err);
    if (st) return st;
  }
  *out = r->prog_var[kind][flags];
  return CV_OK;
}

static void uni_mat(GLuint p, const char *name, const float m[16]) {
  GLint loc = glGetUniformLocation(p, name);
  if (loc >= 0) glUniformMatrix4fv(loc, 1, GL_FALSE, m);
}
static void uni_f(GLuint p, const char *name, float v) {
  GLint loc = glGetUniformLocation(p, name);
  if (loc >= 0) glUniform1f(loc, v);
}
static void uni_v3(GLuint p, const char *name, const float v[3]) {
  GLint loc = glGetUniformLocation(p, name);
  if (loc >= 0) glUniform3fv(loc, 1, v);
}

/* ------------------------------------------------------------ matrices */

/* Column-major 4x4 inverse (cofactors, double); 0 when singular. */
static int invert4(const double m[16], double inv[16]) {
  double t[16];
  t[0] = m[5] * m[10] * m[15] - m[5] * m[11] * m[14] - m[9] * m[6] * m[15] + m[9] * m[7] * m[14] +
         m[13] * m[6] * m[11] - m[13] * m[7] * m[10];
  t[4] = -m[4] * m[10] * m[15] + m[4] * m[11] * m[14] + m[8] * m[6] * m[15] - m[8] * m[7] * m[14] -
         m[12] * m[6] * m[11] + m[12] * m[7] * m[10];
  t[8] = m[4] * m[9] * m[15] - m[4] * m[11] * m[13] - m[8] * m[5] * m[15] + m[8] * m[7] * m[13] +
         m[12] * m[5] * m[11] - m[12] * m[7] * m[9];
  t[12] = -m[4] * m[9] * m[14] + m[4] * m[10] * m[13] + m[8] * m[5] * m[14] - m[8] * m[6] * m[13] -
          m[12] * m[5] * m[10] + m[12] * m[6] * m[9];
  t[1] = -m[1] * m[10] * m[15] + m[1] * m[11] * m[14] + m[9] * m[2] * m[15] - m[9] * m[3] * m[14] -
         m[13] * m[2] * m[11] + m[13] * m[3] * m[10];
  t[5] = m[0] * m[10] * m[15] - m[0] * m[11] * m[14] - m[8] * m[2] * m[15] + m[8] * m[3] * m[14] +
         m[12] * m[2] * m[11] - m[12] * m[3] * m[10];
  t[9] = -m[0] * m[9] * m[15] + m[0] * m[11] * m[13] + m[8] * m[1] * m[15] - m[8] * m[3] * m[13] -
         m[12] * m[1] * m[11] + m[12] * m[3] * m[9];
  t[13] = m[0] * m[9] * m[14] - m[0] * m[10] * m[13] - m[8] * m[1] * m[14] + m[8] * m[2] * m[13] +
          m[12] * m[1] * m[10] - m[12] * m[2] * m[9];
  t[2] = m[1] * m[6] * m[15] - m[1] * m[7] * m[14] - m[5] * m[2] * m[15] + m[5] * m[3] * m[14] +
         m[13] * m[2] * m[7] - m[13] * m[3] * m[6];
  t[6] = -m[0] * m[6] * m[15] + m[0] * m[7] * m[14] + m[4] * m[2] * m[15] - m[4] * m[3] * m[14] -
         m[12] * m[2] * m[7] + m[12] * m[3] * m[6];
  t[10] = m[0] * m[5] * m[15] - m[0] * m[7] * m[13] - m[4] * m[1] * m[15] + m[4] * m[3] * m[13] +
          m[12] * m[1] * m[7] - m[12] * m[3] * m[5];
  t[14] = -m[0] * m[5] * m[14] + m[0] * m[6] * m[13] + m[4] * m[1] * m[14] - m[4] * m[2] * m[13] -
          m[12] * m[1] * m[6] + m[12] * m[2] * m[5];
  t[3] = -m[1] * m[6] * m[11] + m[1] * m[7] * m[10] + m[5] * m[2] * m[11] - m[5] * m[3] * m[10] -
         m[9] * m[2] * m[7] + m[9] * m[3] * m[6];
  t[7] = m[0] * m[6] * m[11] - m[0] * m[7] * m[10] - m[4] * m[2] * m[11] + m[4] * m[3] * m[10] +
         m[8] * m[2] * m[7] - m[8] * m[3] * m[6];
  t[11] = -m[0] * m[5] * m[11] + m[0] * m[7] * m[9] + m[4] * m[1] * m[11] - m[4] * m[3] * m[9] -
          m[8] * m[1] * m[7] + m[8] * m[3] * m[5];
  t[15] = m[0] * m[5] * m[10] - m[0] * m[6] * m[9] - m[4] * m[1] * m[10] + m[4] * m[2] * m[9] +
          m[8] * m[1] * m[6] - m[8] * m[2] * m[5];
  double det = m[0] * t[0] + m[1] * t[4] + m[2] * t[8] + m[3] * t[12];
  if (!(fabs(det) > 0) || !isfinite(det)) return 0;
  for (int i = 0; i < 16; i++) inv[i] = t[i] / det;
  return 1;
}

/* Scene frame -> clip: the CAVE view-projection after the translation by
 * -scene_offset (scene point = CAVE point + offset), in double. */
static int view_matrices(const cv_render_view *v, float mvp[16], float inv[16], float eye[3],
                         float *facing) {
  double m[16], mi[16];
  const double *a = v->proj.viewproj_d;
  for (int i = 0; i < 12; i++) m[i] = a[i];
  for (int row = 0; row < 4; row++)
    m[12 + row] = a[12 + row] - (a[row] * v->scene_offset[0] + a[4 + row] * v->scene_offset[1] +
                                 a[8 + row] * v->scene_offset[2]);
  if (!invert4(m, mi)) return CV_ERR_INVALID;
  /* The eye: the point the projection sends to clip (0, 0, z, 0), i.e.
   * inverse * (0, 0, 1, 0) up to scale. */
  if (!(fabs(mi[11]) > 0)) return CV_ERR_INVALID;
  for (int j = 0; j < 3; j++) eye[j] = (float)(mi[8 + j] / mi[11]);
  /* Orientation of the view (prt.frag, u_sigma): +1 when the cross product
   * of the scene-frame steps along window x then y points towards the eye.
   * For any plane it is the same sign (the steps are those of the eye's rays
   * and n . ray ~ (dray/dx x dray/dy) . ray), so three points unprojected
   * from NDC (0,0,0), (0.5,0,0), (0,0.5,0) give it. */
  double P[3][3];
  for (int k = 0; k < 3; k++) {
    const double nx = k == 1 ? 0.5 : 0, ny = k == 2 ? 0.5 : 0;
    double h[4];
    for (int row = 0; row < 4; row++) h[row] = mi[row] * nx + mi[4 + row] * ny + mi[12 + row];
    if (!(fabs(h[3]) > 0)) return CV_ERR_INVALID;
    for (int j = 0; j < 3; j++) P[k][j] = h[j] / h[3];
  }
  double ax[3], ay[3], cr[3], dot = 0;
  for (int j = 0; j < 3; j++) ax[j] = P[1][j] - P[0][j], ay[j] = P[2][j] - P[0][j];
  cr[0] = ax[1] * ay[2] - ax[2] * ay[1];
  cr[1] = ax[2] * ay[0] - ax[0] * ay[2];
  cr[2] = ax[0] * ay[1] - ax[1] * ay[0];
  for (int j = 0; j < 3; j++) dot += cr[j] * ((double)eye[j] - P[0][j]);
  *facing = dot < 0 ? -1.0f : 1.0f;
  for (int i = 0; i < 16; i++) {
    if (!isfinite(m[i]) || !isfinite(mi[i])) return CV_ERR_INVALID;
    mvp[i] = (float)m[i];
    inv[i] = (float)mi[i];
  }
  return CV_OK;
}

/* ---------------------------------------------------------------- create */

static GLuint make_tbo(GLuint *buf, GLenum fmt, const void *data, size_t bytes) {
  GLuint tex;
  glGenBuffers(1, buf);
  glBindBuffer(GL_TEXTURE_BUFFER, *buf);
  glBufferData(GL_TEXTURE_BUFFER, (GLsizeiptr)bytes, data, GL_STATIC_DRAW);
  glGenTextures(1, &tex);
  glBindTexture(GL_TEXTURE_BUFFER, tex);
  glTexBuffer(GL_TEXTURE_BUFFER, fmt, *buf);
  glBindTexture(GL_TEXTURE_BUFFER, 0);
  glBindBuffer(GL_TEXTURE_BUFFER, 0);
  return tex;
}

/* Interleaves the bits of three 10-bit integers (Morton order). */
static uint64_t morton3(uint32_t x, uint32_t y, uint32_t z) {
  uint64_t m = 0;
  for (int b = 0; b < 10; b++)
    m |= (uint64_t)((x >> b) & 1) << (3 * b) | (uint64_t)((y >> b) & 1) << (3 * b + 1) |
         (uint64_t)((z >> b) & 1) << (3 * b + 2);
  return m;
}

static int cmp_u64(const void *a, const void *b) {
  uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
  return x < y ? -1 : x > y;
}

static int upload_background(cv_renderer *r, int w, int h, const float *rgb, cv_err *err) {
  if (!r->tex_bg) glGenTextures(1, &r->tex_bg);
  glBindTexture(GL_TEXTURE_2D, r->tex_bg);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, w, h, 0, GL_RGB, GL_FLOAT, rgb);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glBindTexture(GL_TEXTURE_2D, 0);
  return gl_check("background upload", err);
}

static int upload_scene(cv_renderer *r, const cv_prt *p, cv_err *err) {
  const int nc = r->nc;
  GLint max_tbo = 0;
  glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &max_tbo);
  size_t nt = 0;
  for (size_t t = 0; t < p->nt; t++)
    if (!(p->mats[p->tri_mat[t]].flags & CV_MAT_WINDOW)) nt++;
  const size_t texels = p->nv * (size_t)(nc + 1);
  if (texels > (size_t)max_tbo || p->nv > 0x7fffffff)
    return cv_err_set(err, CV_ERR_RANGE,
                      "scene too large for this GL: %zu vertices x %d coefficients (texture buffers "
                      "hold %d texels)",
                      p->nv, nc, (int)max_tbo);
  r->nt = nt;
  uint32_t *idx = malloc(3 * nt * sizeof *idx + 4);
  float *tf = malloc(4 * texels * sizeof *tf + 4);
  uint16_t *th = r->o.half_transfer ? malloc(4 * texels * sizeof *th + 4) : NULL;
  if (!idx || !tf || (r->o.half_transfer && !th)) {
    free(idx), free(tf), free(th);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory uploading the scene");
  }
  /* Bounds first (Morton codes are relative to them). */
  for (int j = 0; j < 3; j++) r->lo[j] = INFINITY, r->hi[j] = -INFINITY;
  for (size_t v = 0; v < p->nv; v++)
    for (int j = 0; j < 3; j++) {
      if (p->pos[3 * v + j] < r->lo[j]) r->lo[j] = p->pos[3 * v + j];
      if (p->pos[3 * v + j] > r->hi[j]) r->hi[j] = p->pos[3 * v + j];
    }
  uint64_t *order = malloc(nt * sizeof *order + 8);
  r->nchunks = (nt + CHUNK - 1) / CHUNK;
  r->chunk_box = malloc(6 * r->nchunks * sizeof *r->chunk_box + 4);
  r->run = malloc(2 * r->nchunks * sizeof *r->run + 4);
  if (!order || !r->chunk_box || !r->run) {
    free(idx), free(tf), free(th), free(order);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory uploading the scene");
  }
  size_t k = 0;
  for (size_t t = 0; t < p->nt; t++) {
    if (p->mats[p->tri_mat[t]].flags & CV_MAT_WINDOW) continue;
    uint32_t q[3];
    for (int j = 0; j < 3; j++) {
      double c = (p->pos[3 * p->tri[3 * t] + j] + p->pos[3 * p->tri[3 * t + 1] + j] +
                  p->pos[3 * p->tri[3 * t + 2] + j]) / 3;
      double ext = r->hi[j] - r->lo[j];
      double u = ext > 0 ? (c - r->lo[j]) / ext : 0;
      q[j] = (uint32_t)fmin(fmax(u * 1023.0, 0), 1023);
    }
    order[k++] = (morton3(q[0], q[1], q[2]) << 32) | (uint64_t)t;
  }
  qsort(order, nt, sizeof *order, cmp_u64);
  for (k = 0; k < nt; k++) {
    const size_t t = (size_t)(order[k] & 0xffffffffu);
    const uint32_t *v = p->tri + 3 * t;
    for (int j = 0; j < 3; j++) idx[3 * k + j] = v[j]; /* renumbered below */
    float *box = r->chunk_box + 6 * (k / CHUNK);
    if (k % CHUNK == 0)
      for (int j = 0; j < 3; j++) box[j] = INFINITY, box[3 + j] = -INFINITY;
    for (int i = 0; i < 3; i++)
      for (int j = 0; j < 3; j++) {
        float x = p->pos[3 * v[i] + j];
        if (x < box[j]) box[j] = x;
        if (x > box[3 + j]) box[3 + j] = x;
      }
  }
  free(order);
  /* Vertices renumbered in order of first use by the sorted triangles, so
   * each draw segment references a compact index range (llvmpipe's vertex
   * cache is indexed by vertex number; a GPU's post-transform cache also
   * likes it).  Vertices of no opaque triangle go last. */
  uint32_t *old_of = malloc(p->nv * sizeof *old_of + 4), *new_of = malloc(p->nv * sizeof *new_of + 4);
  float *pos = malloc(3 * p->nv * sizeof *pos + 4), *alb = malloc(3 * p->nv * sizeof *alb + 4);
  if (!old_of || !new_of || !pos || !alb) {
    free(idx), free(tf), free(th), free(old_of), free(new_of), free(pos), free(alb);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory uploading the scene");
  }
  for (size_t v = 0; v < p->nv; v++) new_of[v] = UINT32_MAX;
  uint32_t next = 0;
  for (size_t i = 0; i < 3 * nt; i++) {
    if (new_of[idx[i]] == UINT32_MAX) {
      old_of[next] = idx[i];
      new_of[idx[i]] = next++;
    }
    idx[i] = new_of[idx[i]];
  }
  for (size_t v = 0; v < p->nv; v++)
    if (new_of[v] == UINT32_MAX) {
      old_of[next] = (uint32_t)v;
      new_of[v] = next++;
    }
  for (size_t v = 0; v < p->nv; v++)
    for (int j = 0; j < 3; j++) {
      pos[3 * v + j] = p->pos[3 * old_of[v] + j];
      alb[3 * v + j] = p->albedo[3 * old_of[v] + j];
    }
  for (size_t nvx = 0; nvx < p->nv; nvx++) {
    const size_t v = old_of[nvx];
    float *o = tf + 4 * nvx * (size_t)(nc + 1);
    for (int i = 0; i < nc; i++) {
      o[4 * i] = p->td[v * nc + i];
      for (int c = 0; c < 3; c++) o[4 * i + 1 + c] = p->ti ? p->ti[(v * 3 + c) * nc + i] : 0.0f;
    }
    for (int c = 0; c < 3; c++) o[4 * nc + c] = p->albedo[3 * v + c];
    o[4 * nc + 3] = 0;
  }
  if (th)
    for (size_t i = 0; i < 4 * texels; i++) th[i] = cv_float_to_half(tf[i]);
  r->tex_transfer = th ? make_tbo(&r->buf_transfer, GL_RGBA16F, th, 4 * texels * sizeof *th)
                       : make_tbo(&r->buf_transfer, GL_RGBA32F, tf, 4 * texels * sizeof *tf);
  glGenVertexArrays(1, &r->vao_empty);
  glGenVertexArrays(1, &r->vao_geom);
  glBindVertexArray(r->vao_geom);
  glGenBuffers(1, &r->buf_pos);
  glBindBuffer(GL_ARRAY_BUFFER, r->buf_pos);
  glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(3 * p->nv * sizeof(float)), pos, GL_STATIC_DRAW);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 0, 0);
  glEnableVertexAttribArray(0);
  glGenBuffers(1, &r->buf_rad);
  glBindBuffer(GL_ARRAY_BUFFER, r->buf_rad);
  glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(4 * p->nv * sizeof(float)), NULL, GL_DYNAMIC_COPY);
  glVertexAttribPointer(1, 4, GL_FLOAT, GL_FALSE, 0, 0);
  glEnableVertexAttribArray(1);
  glGenBuffers(1, &r->buf_alb);
  glBindBuffer(GL_ARRAY_BUFFER, r->buf_alb);
  glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(3 * p->nv * sizeof(float)), alb, GL_STATIC_DRAW);
  glVertexAttribPointer(2, 3, GL_FLOAT, GL_FALSE, 0, 0);
  glEnableVertexAttribArray(2);
  glGenBuffers(1, &r->buf_idx);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->buf_idx);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(3 * nt * sizeof *idx + 4), idx, GL_STATIC_DRAW);
  glBindVertexArray(0);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  free(tf), free(th), free(old_of), free(new_of), free(alb);
  r->idx_cpu = idx, r->pos_cpu = pos; /* kept for the sun split */
  r->chunk_nf = malloc(r->nchunks * sizeof *r->chunk_nf + 4);
  r->md_count = malloc(r->nchunks * sizeof *r->md_count + 4);
  r->md_off = malloc(r->nchunks * sizeof *r->md_off + 8);
  if (!r->chunk_nf || !r->md_count || !r->md_off)
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory uploading the scene");
  return gl_check("scene upload", err);
}

int cv_renderer_create(const cv_prt *prt, const cv_render_opts *opts, cv_renderer **out,
                       cv_err *err) {
  *out = NULL;
  if (!prt || prt->bands < 1 || prt->bands > CV_PRT_MAX_BANDS || !prt->nv || !prt->nt)
    return cv_err_set(err, CV_ERR_INVALID, "renderer: empty or invalid PRT");
  cv_renderer *r = calloc(1, sizeof *r);
  if (!r) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  if (opts) r->o = *opts;
  else cv_render_default_opts(&r->o);
  if (r->o.shadow_res < 16) r->o.shadow_res = 2048;
  cv_egl_request rq = {r->o.gpu, NULL, r->o.window};
  int st = CV_OK;
  if (r->o.window) st = cv_window_connect(r->o.window->display, &r->win, err);
  rq.window = r->win;
  if (!st) st = cv_egl_open(&rq, &r->egl, err);
  if (st) {
    cv_window_destroy(r->win);
    free(r);
    return st;
  }
  snprintf(r->gl_name, sizeof r->gl_name, "%s | %s (EGL %s)", (const char *)glGetString(GL_RENDERER),
           (const char *)glGetString(GL_VERSION), r->egl.platform);
  glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &r->max_rb);
  GLint tex_max = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &tex_max);
  if (tex_max < r->max_rb) r->max_rb = tex_max;
  r->nc = (int)(prt->bands * prt->bands);
  r->nv = prt->nv;
  char defs[64];
  snprintf(defs, sizeof defs, "#define NC %d\n", r->nc);
  if ((st = upload_scene(r, prt, err)) ||
      (st = build("relight.vert", NULL, defs, "v_out", &r->prog_relight, err)) ||
      (st = build("geom.vert", "depth.frag", "#define DEPTH_ONLY\n", NULL, &r->prog_depth, err)) ||
      (st = build("geom.vert", "unlit.frag", "", NULL, &r->prog_unlit, err)) ||
      (st = build("fullscreen.vert", "downsample.frag", "", NULL, &r->prog_down, err)) ||
      (r->win && (st = build("present.vert", "present.frag", "", NULL, &r->prog_present, err))) ||
      (st = upload_background(r, 1, 1, (const float[3]){0, 0, 0}, err))) {
    cv_renderer_destroy(r);
    return st;
  }
  r->rb_tiny = make_rb(GL_R8, 1, 1);
  glGenFramebuffers(1, &r->fbo_tiny);
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_tiny);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, r->rb_tiny);
  if ((st = fbo_complete("1x1", 1, 1, err)) || (st = gl_check("renderer setup", err))) {
    cv_renderer_destroy(r);
    return st;
  }
  *out = r;
  return CV_OK;
}

void cv_renderer_destroy(cv_renderer *r) {
  if (!r) return;
  if (r->egl.dpy && cv_egl_make_current(&r->egl) == CV_OK) {
    GLuint bufs[] = {r->buf_pos, r->buf_rad, r->buf_idx, r->buf_transfer, r->buf_alb,
                     r->buf_idx_sun};
    glDeleteBuffers(6, bufs);
    GLuint tex[] = {r->tex_transfer, r->tex_bg, r->tex_shadow, r->tex_disp, r->tex_hdr,
                    r->tex_panel};
    glDeleteTextures(6, tex);
    GLuint rbs[] = {r->rb_lum, r->rb_lum_depth, r->rb_depth, r->rb_res_disp, r->rb_res_hdr,
                    r->rb_tiny};
    glDeleteRenderbuffers(6, rbs);
    GLuint fbos[] = {r->fbo_shadow, r->fbo_lum, r->fbo_main, r->fbo_res, r->fbo_tiny};
    glDeleteFramebuffers(5, fbos);
    GLuint vaos[] = {r->vao_geom, r->vao_empty};
    glDeleteVertexArrays(2, vaos);
    glDeleteProgram(r->prog_relight);
    glDeleteProgram(r->prog_depth);
    glDeleteProgram(r->prog_unlit);
    glDeleteProgram(r->prog_down);
    glDeleteProgram(r->prog_present);
    glDeleteTextures(1, &r->tex_present);
    for (int k = 0; k < 2; k++)
      for (int f = 0; f < NVARIANT; f++) glDeleteProgram(r->prog_var[k][f]);
    glDeleteBuffers(1, &r->buf_tone);
    glDeleteTextures(1, &r->tex_tone);
  }
  cv_egl_close(&r->egl);
  cv_window_destroy(r->win);
  free(r->chunk_box);
  free(r->idx_cpu);
  free(r->pos_cpu);
  free(r->chunk_nf);
  free(r->md_count);
  free(r->md_off);
  free(r->run);
  free(r->rgba8);
  free(r);
}

/* ---------------------------------------------------------------- lighting */

/* Orthographic sun view over the scene bounds: clip matrix for rendering
 * the shadow map, and for the lookup (prt.frag) the texel-space matrix
 * shadow_q, its axis scales shadow_k and the sign of its determinant. */
static void sun_matrices(cv_renderer *r, const double s[3], float clip[16], float *texel) {
  double up[3] = {0, 1, 0};
  if (fabs(s[1]) > 0.99) up[0] = 1, up[1] = 0;
  double x[3] = {up[1] * s[2] - up[2] * s[1], up[2] * s[0] - up[0] * s[2],
                 up[0] * s[1] - up[1] * s[0]};
  double xl = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
  for (int j = 0; j < 3; j++) x[j] /= xl;
  double y[3] = {s[1] * x[2] - s[2] * x[1], s[2] * x[0] - s[0] * x[2], s[0] * x[1] - s[1] * x[0]};
  /* Axes: x, y across the beam; depth = distance along -s (away from the sun). */
  double axis[3][3] = {{x[0], x[1], x[2]}, {y[0], y[1], y[2]}, {-s[0], -s[1], -s[2]}};
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int c = 0; c < 8; c++) {
    double p[3] = {c & 1 ? r->hi[0] : r->lo[0], c & 2 ? r->hi[1] : r->lo[1],
                   c & 4 ? r->hi[2] : r->lo[2]};
    for (int a = 0; a < 3; a++) {
      double d = axis[a][0] * p[0] + axis[a][1] * p[1] + axis[a][2] * p[2];
      if (d < lo[a]) lo[a] = d;
      if (d > hi[a]) hi[a] = d;
    }
  }
  for (int a = 0; a < 3; a++) {
    double pad = 0.01 * (hi[a] - lo[a]) + 1e-3;
    lo[a] -= pad, hi[a] += pad;
  }
  /* clip_a = 2 (axis_a . p - lo_a)/(hi_a - lo_a) - 1; the lookup in texel
   * space (prt.frag): x, y = [0,1] coordinate * res - 0.5 (texel centres at
   * integers), z = the [0,1] depth.  Its linear part is A = D R, R the
   * rotation with rows axis_a, D = diag(res sc_x/2, res sc_y/2, sc_z/2). */
  const double res = r->o.shadow_res;
  float *q = r->shadow_q;
  memset(clip, 0, 16 * sizeof *clip);
  memset(q, 0, 16 * sizeof *q);
  double D[3];
  for (int a = 0; a < 3; a++) {
    double sc = 2.0 / (hi[a] - lo[a]), ts = a < 2 ? res : 1.0;
    D[a] = 0.5 * sc * ts;
    for (int j = 0; j < 3; j++) {
      clip[4 * j + a] = (float)(sc * axis[a][j]);
      q[4 * j + a] = (float)(D[a] * axis[a][j]);
    }
    clip[12 + a] = (float)(-sc * lo[a] - 1);
    q[12 + a] = (float)((0.5 * (-sc * lo[a] - 1) + 0.5) * ts - (a < 2 ? 0.5 : 0.0));
  }
  clip[15] = q[15] = 1;
  for (int a = 0; a < 3; a++) r->shadow_k[a] = (float)(D[a] * D[a]);
  r->shadow_k[3] = (float)-D[2];
  const double det = axis[0][0] * (axis[1][1] * axis[2][2] - axis[1][2] * axis[2][1]) -
                     axis[0][1] * (axis[1][0] * axis[2][2] - axis[1][2] * axis[2][0]) +
                     axis[0][2] * (axis[1][0] * axis[2][1] - axis[1][1] * axis[2][0]);
  r->shadow_detsign = det < 0 ? -1 : 1;
  double ext = fmax(hi[0] - lo[0], hi[1] - lo[1]);
  *texel = (float)(ext / r->o.shadow_res);
}

static int render_shadow(cv_renderer *r, const double s[3], cv_err *err) {
  const int n = r->o.shadow_res;
  if (!r->fbo_shadow || r->shadow_res != n) {
    if (!r->fbo_shadow) glGenFramebuffers(1, &r->fbo_shadow);
    if (!r->tex_shadow) glGenTextures(1, &r->tex_shadow);
    glBindTexture(GL_TEXTURE_2D, r->tex_shadow);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT32F, n, n, 0, GL_DEPTH_COMPONENT, GL_FLOAT,
                 NULL);
    /* read by texelFetch, compared and filtered in prt.frag */
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_MODE, GL_NONE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_shadow);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, r->tex_shadow, 0);
    glDrawBuffer(GL_NONE);
    glReadBuffer(GL_NONE);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      return cv_err_set(err, CV_ERR_BACKEND, "shadow map framebuffer incomplete (%d texels)", n);
    r->shadow_res = n;
  }
  float clip[16], texel;
  sun_matrices(r, s, clip, &texel);
  /* Against self-shadowing acne the lookup point moves 1.5 texels along the
   * triangle's normal (a slope-scaled polygon offset on top changed neither
   * the sun test's figures nor the time). */
  r->shadow_bias = 1.5f * texel;
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_shadow);
  glViewport(0, 0, n, n);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDepthMask(GL_TRUE);
  glClear(GL_DEPTH_BUFFER_BIT);
  set_cull(r, 0);
  glUseProgram(r->prog_depth);
  uni_mat(r->prog_depth, "u_mvp", clip);
  draw_mesh(r, NULL, DRAW_ALL);
  return gl_check("shadow map", err);
}

/* The sun split (see the struct): reorders each chunk of buf_idx into
 * buf_idx_sun, the triangles whose winding normal (that of cv_sun_direct
 * and prt.frag's n_t) has n . s > 0 first.  The others get no direct sun,
 * so the shading pass draws them with the variant without it: on llvmpipe,
 * which pays for every instruction of a shader on every pixel, the sun's
 * normal, shadow-map fetches and filter are about half the shading pass.
 * Same triangles, vertex order and positions: same depths (depth EQUAL). */
static int sun_split(cv_renderer *r, const double s[3], cv_err *err) {
  uint32_t *out = malloc(3 * r->nt * sizeof *out + 4);
  unsigned char *facing = malloc(CHUNK);
  if (!out || !facing) {
    free(out), free(facing);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory splitting the mesh for the sun");
  }
  for (size_t c = 0; c < r->nchunks; c++) {
    const size_t first = c * CHUNK, end = first + CHUNK > r->nt ? r->nt : first + CHUNK;
    size_t nf = 0;
    for (size_t t = first; t < end; t++) {
      const uint32_t *v = r->idx_cpu + 3 * t;
      const float *a = r->pos_cpu + 3 * v[0], *b = r->pos_cpu + 3 * v[1], *d = r->pos_cpu + 3 * v[2];
      double e1[3], e2[3];
      for (int j = 0; j < 3; j++) e1[j] = (double)b[j] - a[j], e2[j] = (double)d[j] - a[j];
      const double ns = (e1[1] * e2[2] - e1[2] * e2[1]) * s[0] +
                        (e1[2] * e2[0] - e1[0] * e2[2]) * s[1] +
                        (e1[0] * e2[1] - e1[1] * e2[0]) * s[2];
      facing[t - first] = ns > 0;
      nf += ns > 0;
    }
    size_t kf = first, ko = first + nf;
    for (size_t t = first; t < end; t++)
      memcpy(out + 3 * (facing[t - first] ? kf++ : ko++), r->idx_cpu + 3 * t, 3 * sizeof *out);
    r->chunk_nf[c] = (uint32_t)nf;
  }
  free(facing);
  glBindVertexArray(0);
  if (!r->buf_idx_sun) glGenBuffers(1, &r->buf_idx_sun);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->buf_idx_sun);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(3 * r->nt * sizeof *out + 4), out,
               GL_STATIC_DRAW);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, 0);
  free(out);
  r->sun_split = 1;
  return gl_check("sun split", err);
}

int cv_renderer_set_lighting(cv_renderer *r, const cv_lighting *l, cv_render_light_stats *stats,
                             cv_frame_timing *t, cv_err *err) {
  if (!r || !l) return cv_err_set(err, CV_ERR_INVALID, "renderer: NULL lighting");
  if (l->bands < 1 || l->bands > CV_PRT_MAX_BANDS || l->bands * l->bands < r->nc)
    return cv_err_set(err, CV_ERR_RANGE, "lighting has %d bands, the scene needs %d", l->bands,
                      (int)lround(sqrt(r->nc)));
  for (int i = 0; i < 3 * r->nc; i++)
    if (!isfinite(l->sh[i])) return cv_err_set(err, CV_ERR_NONFINITE, "lighting SH[%d] is not finite", i);
  double sd[3] = {0, 0, 0};
  int sun = 0;
  if (l->has_sun) {
    double n = sqrt(l->sun_dir[0] * l->sun_dir[0] + l->sun_dir[1] * l->sun_dir[1] +
                    l->sun_dir[2] * l->sun_dir[2]);
    for (int c = 0; c < 3; c++)
      if (!isfinite(l->sun_E[c]) || l->sun_E[c] < 0)
        return cv_err_set(err, CV_ERR_NONFINITE, "sun irradiance[%d] is %g", c, l->sun_E[c]);
    if (!(n > 0) || !isfinite(n)) return cv_err_set(err, CV_ERR_INVALID, "sun direction has no length");
    for (int c = 0; c < 3; c++) sd[c] = l->sun_dir[c] / n;
    sun = 1;
  }
  if (cv_egl_make_current(&r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  gl_check("(before set_lighting)", NULL);
  double t0 = tick(r);
  /* Uniforms: lighting without the sun (with td) and with the sun's SH
   * projection E * y_i(s) (with ti), as relight.c. */
  float ul[4 * 64], uls[4 * 64];
  double y[CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS] = {0};
  if (sun) cv_sh_eval_d((int)lround(sqrt(r->nc)), l->sun_dir, y);
  for (int i = 0; i < r->nc; i++) {
    for (int c = 0; c < 3; c++) {
      ul[4 * i + c] = (float)l->sh[3 * i + c];
      uls[4 * i + c] = (float)(l->sh[3 * i + c] + (sun ? l->sun_E[c] * y[i] : 0.0));
    }
    ul[4 * i + 3] = uls[4 * i + 3] = 0;
  }
  GLuint p = r->prog_relight;
  glUseProgram(p);
  glUniform4fv(glGetUniformLocation(p, "u_l"), r->nc, ul);
  glUniform4fv(glGetUniformLocation(p, "u_ls"), r->nc, uls);
  glActiveTexture(GL_TEXTURE0 + U_TRANSFER);
  glBindTexture(GL_TEXTURE_BUFFER, r->tex_transfer);
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_tiny);
  glBindVertexArray(r->vao_empty);
  glEnable(GL_RASTERIZER_DISCARD);
  glBindBufferBase(GL_TRANSFORM_FEEDBACK_BUFFER, 0, r->buf_rad);
  glBeginTransformFeedback(GL_POINTS);
  glDrawArrays(GL_POINTS, 0, (GLsizei)r->nv);
  glEndTransformFeedback();
  glBindBufferBase(GL_TRANSFORM_FEEDBACK_BUFFER, 0, 0);
  glDisable(GL_RASTERIZER_DISCARD);
  glBindVertexArray(0);
  /* Clamp count: sum of the captured w (exact in double). */
  uint64_t clamped = 0;
  glBindBuffer(GL_ARRAY_BUFFER, r->buf_rad);
  const float *m = glMapBufferRange(GL_ARRAY_BUFFER, 0, (GLsizeiptr)(4 * r->nv * sizeof(float)),
                                    GL_MAP_READ_BIT);
  if (m) {
    for (size_t v = 0; v < r->nv; v++) clamped += (uint64_t)m[4 * v + 3];
    glUnmapBuffer(GL_ARRAY_BUFFER);
  }
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  int st = gl_check("relighting", err);
  if (st) return st;
  if (!m) return cv_err_set(err, CV_ERR_BACKEND, "cannot map the relit vertex buffer");
  double t1 = tick(r);
  r->has_sun = sun;
  if (sun) {
    for (int c = 0; c < 3; c++) {
      r->sun_e[c] = (float)(l->sun_E[c] / M_PI);
    }
    if ((st = render_shadow(r, sd, err))) return st;
    r->sun_split = 0;
    if (r->o.sun_split && (st = sun_split(r, sd, err))) return st;
  }
  double t2 = tick(r);
  r->lit = 1;
  if (stats) stats->clamped = clamped;
  if (t) {
    t->relight_ms = t1 - t0;
    t->shadow_ms = t2 - t1;
  }
  return CV_OK;
}

int cv_renderer_set_background(cv_renderer *r, const cv_image *img, cv_err *err) {
  if (!r) return cv_err_set(err, CV_ERR_INVALID, "renderer: NULL");
  if (cv_egl_make_current(&r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  if (!img) return upload_background(r, 1, 1, (const float[3]){0, 0, 0}, err);
  if (img->w < 1 || img->h < 1 || img->c < 3 || !img->px)
    return cv_err_set(err, CV_ERR_INVALID, "background: expected an RGB image, got %dx%dx%d", img->w,
                      img->h, img->c);
  if (img->w > r->max_rb || img->h > r->max_rb)
    return cv_err_set(err, CV_ERR_RANGE, "background %dx%d exceeds the GL texture limit %d", img->w,
                      img->h, (int)r->max_rb);
  size_t n = (size_t)img->w * img->h;
  float *rgb = malloc(3 * n * sizeof *rgb);
  if (!rgb) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  for (size_t i = 0; i < n; i++)
    for (int c = 0; c < 3; c++) {
      float v = img->px[i * img->c + c];
      rgb[3 * i + c] = isfinite(v) && v > 0 ? v : 0.0f;
    }
  int st = upload_background(r, img->w, img->h, rgb, err);
  free(rgb);
  return st;
}

int cv_renderer_set_panel(cv_renderer *r, const float center[3], const float u[3],
                          const float v[3], const float size[2], const cv_image *img, cv_err *err) {
  if (!r) return cv_err_set(err, CV_ERR_INVALID, "renderer: NULL");
  if (cv_egl_make_current(&r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  if (!img) {
    r->panel_on = 0;
    return CV_OK;
  }
  if (!center || !u || !v || !size || img->w < 1 || img->h < 1 || img->c < 3 || !img->px ||
      !(size[0] > 0) || !(size[1] > 0))
    return cv_err_set(err, CV_ERR_INVALID, "panel: expected a frame, sizes > 0 and an RGB image");
  if (img->w > r->max_rb || img->h > r->max_rb)
    return cv_err_set(err, CV_ERR_RANGE, "panel image %dx%d exceeds the GL texture limit %d", img->w,
                      img->h, (int)r->max_rb);
  double lu = 0, lv = 0;
  for (int a = 0; a < 3; a++) {
    lu += (double)u[a] * u[a];
    lv += (double)v[a] * v[a];
  }
  if (!(lu > 0) || !(lv > 0)) return cv_err_set(err, CV_ERR_INVALID, "panel: zero axis");
  for (int a = 0; a < 3; a++) {
    r->panel_c[a] = center[a];
    r->panel_u[a] = (float)(u[a] / sqrt(lu));
    r->panel_v[a] = (float)(v[a] / sqrt(lv));
  }
  r->panel_n[0] = r->panel_u[1] * r->panel_v[2] - r->panel_u[2] * r->panel_v[1];
  r->panel_n[1] = r->panel_u[2] * r->panel_v[0] - r->panel_u[0] * r->panel_v[2];
  r->panel_n[2] = r->panel_u[0] * r->panel_v[1] - r->panel_u[1] * r->panel_v[0];
  r->panel_half[0] = 0.5f * size[0];
  r->panel_half[1] = 0.5f * size[1];
  size_t n = (size_t)img->w * img->h;
  float *rgb = malloc(3 * n * sizeof *rgb);
  if (!rgb) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  uint64_t bad = 0;
  for (size_t i = 0; i < n; i++)
    for (int c = 0; c < 3; c++) {
      float x = img->px[i * img->c + c];
      if (!(isfinite(x) && x >= 0)) bad++;
      rgb[3 * i + c] = isfinite(x) && x > 0 ? x : 0.0f; /* NaN/Inf/negative: black, counted */
    }
  if (!r->tex_panel) glGenTextures(1, &r->tex_panel);
  glBindTexture(GL_TEXTURE_2D, r->tex_panel);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, img->w, img->h, 0, GL_RGB, GL_FLOAT, rgb);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glBindTexture(GL_TEXTURE_2D, 0);
  free(rgb);
  r->panel_on = 1;
  r->panel_bad = bad;
  return gl_check("panel upload", err);
}

uint64_t cv_renderer_panel_invalid(const cv_renderer *r) { return r ? r->panel_bad : 0; }

int cv_renderer_tone_table(const cv_renderer *r, double *drago_err) {
  if (drago_err) *drago_err = r && r->tone_built ? r->tone_err : NAN;
  return r && r->tone_built && r->tone_ok;
}

int cv_render_background_image(const cv_scene_light *sl, int w, cv_image **out) {
  *out = NULL;
  if (!sl || w < 2) return CV_ERR_INVALID;
  int h = w / 2;
  cv_image *img;
  int st = cv_image_create(w, h, 3, &img);
  if (st) return st;
#pragma omp parallel for schedule(static)
  for (int y = 0; y < h; y++) {
    double th = M_PI * (y + 0.5) / h;
    for (int x = 0; x < w; x++) {
      double a = 2 * M_PI * ((x + 0.5) / w - 0.5);
      float d[3] = {(float)(sin(th) * sin(a)), (float)cos(th), (float)(-sin(th) * cos(a))};
      cv_scene_light_background(sl, d, cv_image_at(img, x, y));
    }
  }
  *out = img;
  return CV_OK;
}

/* ---------------------------------------------------------------- targets */

static GLuint make_rb(GLenum fmt, int w, int h) {
  GLuint rb;
  glGenRenderbuffers(1, &rb);
  glBindRenderbuffer(GL_RENDERBUFFER, rb);
  glRenderbufferStorage(GL_RENDERBUFFER, fmt, w, h);
  glBindRenderbuffer(GL_RENDERBUFFER, 0);
  return rb;
}

static GLuint make_tex(GLenum fmt, int w, int h) {
  GLuint t;
  glGenTextures(1, &t);
  glBindTexture(GL_TEXTURE_2D, t);
  glTexImage2D(GL_TEXTURE_2D, 0, fmt, w, h, 0, GL_RGBA, GL_FLOAT, NULL);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glBindTexture(GL_TEXTURE_2D, 0);
  return t;
}

static int fbo_complete(const char *what, int w, int h, cv_err *err) {
  GLenum s = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (s == GL_FRAMEBUFFER_COMPLETE) return CV_OK;
  return cv_err_set(err, CV_ERR_BACKEND, "%s framebuffer %dx%d incomplete (0x%04x)", what, w, h,
                    (unsigned)s);
}

static int ensure_lum(cv_renderer *r, int w, int h, cv_err *err) {
  if (r->fbo_lum && r->lum_w == w && r->lum_h == h) return CV_OK;
  GLuint old[2] = {r->rb_lum, r->rb_lum_depth};
  glDeleteRenderbuffers(2, old);
  if (!r->fbo_lum) glGenFramebuffers(1, &r->fbo_lum);
  r->rb_lum = make_rb(GL_R32F, w, h);
  r->rb_lum_depth = make_rb(GL_DEPTH_COMPONENT32F, w, h);
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_lum);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, r->rb_lum);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, r->rb_lum_depth);
  r->lum_w = w, r->lum_h = h;
  return fbo_complete("luminance", w, h, err);
}

/* Display target format: 8-bit unless opts.display_float; float while
 * supersampling (the resolve averages before quantising). */
static GLenum disp_fmt(const cv_renderer *r, int resolve_target, int ss) {
  return r->o.display_float || (!resolve_target && ss > 1) ? GL_RGBA32F : GL_RGBA8;
}

static int ensure_main(cv_renderer *r, int w, int h, GLenum dfmt, cv_err *err) {
  if (r->fbo_main && r->main_w == w && r->main_h == h && r->main_fmt == dfmt) return CV_OK;
  r->main_fmt = dfmt;
  GLuint old[2] = {r->tex_disp, r->tex_hdr};
  glDeleteTextures(2, old);
  glDeleteRenderbuffers(1, &r->rb_depth);
  if (!r->fbo_main) glGenFramebuffers(1, &r->fbo_main);
  r->tex_disp = make_tex(dfmt, w, h);
  r->tex_hdr = make_tex(GL_RGBA32F, w, h);
  r->rb_depth = make_rb(GL_DEPTH_COMPONENT32F, w, h);
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_main);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, r->tex_disp, 0);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_TEXTURE_2D, r->tex_hdr, 0);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, r->rb_depth);
  r->main_w = w, r->main_h = h;
  return fbo_complete("shading", w, h, err);
}

static int ensure_res(cv_renderer *r, int w, int h, cv_err *err) {
  if (r->fbo_res && r->res_w == w && r->res_h == h) return CV_OK;
  GLuint old[2] = {r->rb_res_disp, r->rb_res_hdr};
  glDeleteRenderbuffers(2, old);
  if (!r->fbo_res) glGenFramebuffers(1, &r->fbo_res);
  r->rb_res_disp = make_rb(disp_fmt(r, 1, 1), w, h);
  r->rb_res_hdr = make_rb(GL_RGBA32F, w, h);
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_res);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, r->rb_res_disp);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_RENDERBUFFER, r->rb_res_hdr);
  r->res_w = w, r->res_h = h;
  return fbo_complete("resolve", w, h, err);
}

/* Reads attachment `att` of the bound read framebuffer into img (c = 1 or
 * 3), flipping GL's bottom-up rows to the image's top-down order.  An 8-bit
 * target (is8) is read as bytes and converted (k/255). */
static int read_image(cv_renderer *r, GLenum att, int is8, cv_image *img) {
  glReadBuffer(att);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  const size_t row = (size_t)img->w * img->c;
  if (is8) {
    size_t need = (size_t)img->w * img->h * 4;
    if (need > r->rgba8_cap) {
      uint8_t *b = realloc(r->rgba8, need);
      if (!b) return CV_ERR_NOMEM;
      r->rgba8 = b, r->rgba8_cap = need;
    }
    glReadPixels(0, 0, img->w, img->h, GL_RGBA, GL_UNSIGNED_BYTE, r->rgba8);
    for (int y = 0; y < img->h; y++) {
      const uint8_t *src = r->rgba8 + (size_t)(img->h - 1 - y) * img->w * 4;
      float *dst = img->px + (size_t)y * row;
      for (int x = 0; x < img->w; x++)
        for (int c = 0; c < 3; c++) dst[3 * x + c] = src[4 * x + c] * (1.0f / 255.0f);
    }
    return CV_OK;
  }
  glReadPixels(0, 0, img->w, img->h, img->c == 1 ? GL_RED : GL_RGB, GL_FLOAT, img->px);
  for (int y = 0; y < img->h / 2; y++) {
    float *a = img->px + (size_t)y * row, *b = img->px + (size_t)(img->h - 1 - y) * row;
    for (size_t i = 0; i < row; i++) {
      float t = a[i];
      a[i] = b[i];
      b[i] = t;
    }
  }
  return CV_OK;
}

/* ---------------------------------------------------------------- passes */

/* Face culling of the view passes (opts.cull_back); the shadow map draws
 * both sides. */
static void set_cull(const cv_renderer *r, int on) {
  if (on && r->o.cull_back) {
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
  } else {
    glDisable(GL_CULL_FACE);
  }
}

static int check_view(const cv_renderer *r, const cv_render_view *v, cv_err *err) {
  if (!r || !v) return cv_err_set(err, CV_ERR_INVALID, "renderer: NULL view");
  if (!r->lit) return cv_err_set(err, CV_ERR_INVALID, "renderer: no lighting set");
  if (v->supersample != 1 && v->supersample != 2)
    return cv_err_set(err, CV_ERR_INVALID, "supersample must be 1 or 2, got %d", v->supersample);
  if (v->w < 1 || v->h < 1 || v->w * v->supersample > r->max_rb || v->h * v->supersample > r->max_rb)
    return cv_err_set(err, CV_ERR_RANGE, "view %dx%d (x%d) outside 1..%d pixels", v->w, v->h,
                      v->supersample, (int)r->max_rb);
  return CV_OK;
}

/* Binds the textures and sets the uniforms a prt.frag / background.frag
 * variant reads. */
static void bind_shading(const cv_renderer *r, GLuint p, const float mvp[16], const float inv[16],
                         float facing, const cv_drago_consts *dc) {
  glUseProgram(p);
  uni_mat(p, "u_mvp", mvp);
  uni_mat(p, "u_inv_mvp", inv);
  if (dc) {
    uni_f(p, "lwa", dc->lwa);
    uni_f(p, "lwmax_a", dc->lwmax_a);
    uni_f(p, "scale", dc->scale);
    uni_f(p, "p_exp", dc->p_exp);
    uni_f(p, "ld_top", dc->ld_top);
  }
  if (dc) {
    uni_f(p, "u_lut_k", r->lut_k);
    uni_f(p, "u_lut_tail", r->lut_tail);
    glActiveTexture(GL_TEXTURE0 + U_TONE);
    glBindTexture(GL_TEXTURE_BUFFER, r->tex_tone);
  }
  if (r->panel_on) {
    uni_v3(p, "u_panel_c", r->panel_c);
    uni_v3(p, "u_panel_u", r->panel_u);
    uni_v3(p, "u_panel_v", r->panel_v);
    uni_v3(p, "u_panel_n", r->panel_n);
    GLint loc = glGetUniformLocation(p, "u_panel_half");
    if (loc >= 0) glUniform2f(loc, r->panel_half[0], r->panel_half[1]);
    glActiveTexture(GL_TEXTURE0 + U_PANEL);
    glBindTexture(GL_TEXTURE_2D, r->tex_panel);
  }
  if (r->has_sun) {
    uni_mat(p, "u_shadow_q", r->shadow_q);
    GLint loc = glGetUniformLocation(p, "u_shadow_k");
    if (loc >= 0) glUniform4fv(loc, 1, r->shadow_k);
    loc = glGetUniformLocation(p, "u_shadow_res");
    if (loc >= 0) glUniform1i(loc, r->shadow_res);
    uni_v3(p, "u_sun_e", r->sun_e);
    uni_f(p, "u_shadow_bias", r->shadow_bias);
    uni_f(p, "u_sigma", facing * (float)r->shadow_detsign);
  }
  glActiveTexture(GL_TEXTURE0 + U_SHADOW);
  glBindTexture(GL_TEXTURE_2D, r->tex_shadow);
  glActiveTexture(GL_TEXTURE0 + U_BG);
  glBindTexture(GL_TEXTURE_2D, r->tex_bg);
}

/* ------------------------------------------------------- tone tables */

/* Drago's raw curve (cv_drago_map below Lwmax, before the clamp) at
 * y = x / Lwmax', in double from the float constants as the CPU does. */
static double drago_raw(const cv_drago_consts *c, double y) {
  double x = y * (double)c->lwmax_a;
  return (double)c->scale * log1p(x) / log(2.0 + 8.0 * pow(y, (double)c->p_exp));
}

/* Fills nseg texels (4 floats each) with the cubic through the curve at
 * f = 0, 1/3, 2/3, 1 of each segment (arguments 2^(e0 + j/16 - 127) * (1 +
 * (j%16 + f)/16)); continuous across segments.  Returns the largest error
 * at f = 1/6, 1/2, 5/6 of the float cubic evaluated as the shader does,
 * |p - curve| / max(|curve|, floor).  (Cubic interpolation error ~ h^4: a
 * 1/16 octave keeps it near float rounding, ~1e-7.) */
static double fit_table(double (*fn)(const cv_drago_consts *, double), const cv_drago_consts *c,
                        int e0, int nseg, double floor, float *out) {
  double worst = 0, prev = NAN;
  for (int j = 0; j < nseg; j++) {
    const int e = e0 + j / LUT_PER_OCT - 127, sub = j % LUT_PER_OCT;
    double v[4];
    for (int k = 0; k < 4; k++)
      v[k] = k == 0 && !isnan(prev) ? prev : fn(c, ldexp(1.0 + (sub + k / 3.0) / LUT_PER_OCT, e));
    prev = v[3];
    /* monomial coefficients of the cubic through (0, 1/3, 2/3, 1) */
    float *q = out + 4 * j;
    q[0] = (float)v[0];
    q[1] = (float)((-11 * v[0] + 18 * v[1] - 9 * v[2] + 2 * v[3]) / 2);
    q[2] = (float)((18 * v[0] - 45 * v[1] + 36 * v[2] - 9 * v[3]) / 2);
    q[3] = (float)((-9 * v[0] + 27 * v[1] - 27 * v[2] + 9 * v[3]) / 2);
    for (int k = 1; k <= 5; k += 2) {
      const float f = (float)(k / 6.0);
      const float p = q[0] + f * (q[1] + f * (q[2] + f * q[3]));
      const double want = fn(c, ldexp(1.0 + (sub + (double)f) / LUT_PER_OCT, e));
      const double d = fabs(p - want) / fmax(fabs(want), floor);
      if (!(d <= worst)) worst = d; /* NaN wins */
    }
  }
  return worst;
}

/* Makes the Drago table match dc (rebuilt only when the constants change:
 * 2016 segments, ~12K evaluations of the curve in double).  tone_ok says
 * whether it met LUT_TOL (opts.tone_exact forces the shader's own math). */
static void tone_table(cv_renderer *r, const cv_drago_consts *dc) {
  if (r->tone_built && !memcmp(&r->tone_dc, dc, sizeof *dc)) return;
  float *buf = malloc(4 * LUT_DRAGO_SEGS * sizeof *buf);
  if (!buf) {
    r->tone_ok = 0; /* the exact variant needs no table */
    return;
  }
  r->tone_err = fit_table(drago_raw, dc, LUT_DRAGO_E0, LUT_DRAGO_SEGS, 1e-4, buf);
  const double ylo = ldexp(1.0, -126);
  r->lut_tail = (float)(drago_raw(dc, ylo) / ylo);
  r->lut_k = (float)(1.0 / ((double)dc->lwa * (double)dc->lwmax_a));
  r->tone_ok = !r->o.tone_exact && r->tone_err <= LUT_TOL && isfinite(r->lut_tail) &&
               isfinite(r->lut_k);
  if (!r->buf_tone) {
    r->tex_tone = make_tbo(&r->buf_tone, GL_RGBA32F, buf, 4 * LUT_DRAGO_SEGS * sizeof *buf);
  } else {
    glBindBuffer(GL_TEXTURE_BUFFER, r->buf_tone);
    glBufferSubData(GL_TEXTURE_BUFFER, 0, 4 * LUT_DRAGO_SEGS * sizeof *buf, buf);
    glBindBuffer(GL_TEXTURE_BUFFER, 0);
  }
  free(buf);
  r->tone_dc = *dc;
  r->tone_built = 1;
}

/* 1 when the box (lo, hi) lies entirely outside one clip plane of mvp. */
static int box_outside(const float mvp[16], const float *lo, const float *hi) {
  int out[6] = {1, 1, 1, 1, 1, 1};
  for (int c = 0; c < 8; c++) {
    const float p[3] = {c & 1 ? hi[0] : lo[0], c & 2 ? hi[1] : lo[1], c & 4 ? hi[2] : lo[2]};
    float q[4];
    for (int i = 0; i < 4; i++)
      q[i] = mvp[i] * p[0] + mvp[4 + i] * p[1] + mvp[8 + i] * p[2] + mvp[12 + i];
    for (int a = 0; a < 3; a++) {
      out[2 * a] &= q[a] < -q[3];
      out[2 * a + 1] &= q[a] > q[3];
    }
  }
  return out[0] | out[1] | out[2] | out[3] | out[4] | out[5];
}

/* Draws the opaque triangles whose chunk intersects the frustum of mvp
 * (all of them when mvp is NULL or culling is off): part DRAW_ALL as runs
 * of consecutive chunks of buf_idx; DRAW_SUNLIT / DRAW_UNSUNLIT the
 * sun-facing / other triangles of those chunks from buf_idx_sun (the sun
 * split), in one glMultiDrawElements.  Every pass of a view submits the same
 * triangles, which the depth-EQUAL pass relies on.  Returns the triangles
 * submitted. */
static size_t draw_mesh(cv_renderer *r, const float *mvp, int part) {
  size_t nrun = 0, ntri = 0;
  for (size_t c = 0; c < r->nchunks; c++) {
    if (mvp && r->o.cull_frustum && box_outside(mvp, r->chunk_box + 6 * c, r->chunk_box + 6 * c + 3))
      continue;
    uint32_t first = (uint32_t)(c * CHUNK), n = (uint32_t)((c + 1) * CHUNK > r->nt ? r->nt - c * CHUNK : CHUNK);
    if (part == DRAW_SUNLIT) {
      n = r->chunk_nf[c];
    } else if (part == DRAW_UNSUNLIT) {
      first += r->chunk_nf[c];
      n -= r->chunk_nf[c];
    }
    if (!n) continue;
    if (nrun && r->run[2 * (nrun - 1)] + r->run[2 * (nrun - 1) + 1] == first) {
      r->run[2 * (nrun - 1) + 1] += n;
    } else {
      r->run[2 * nrun] = first, r->run[2 * nrun + 1] = n;
      nrun++;
    }
    ntri += n;
  }
  glBindVertexArray(r->vao_geom);
  if (part == DRAW_ALL) {
    for (size_t i = 0; i < nrun; i++) {
      glDrawElements(GL_TRIANGLES, (GLsizei)(3 * r->run[2 * i + 1]), GL_UNSIGNED_INT,
                     (const void *)(uintptr_t)(3 * sizeof(uint32_t) * r->run[2 * i]));
    }
  } else if (nrun) {
    for (size_t i = 0; i < nrun; i++) {
      r->md_count[i] = (GLsizei)(3 * r->run[2 * i + 1]);
      r->md_off[i] = (const void *)(uintptr_t)(3 * sizeof(uint32_t) * r->run[2 * i]);
    }
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->buf_idx_sun); /* VAO state: restored below */
    glMultiDrawElements(GL_TRIANGLES, r->md_count, GL_UNSIGNED_INT, r->md_off, (GLsizei)nrun);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->buf_idx);
  }
  glBindVertexArray(0);
  return ntri;
}

static void draw_fullscreen(const cv_renderer *r) {
  glBindVertexArray(r->vao_empty);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glBindVertexArray(0);
}

int cv_renderer_luminance(cv_renderer *r, const cv_render_view *v, cv_image *out,
                          cv_frame_timing *t, cv_err *err) {
  int st = check_view(r, v, err);
  if (st) return st;
  if (!out || out->c != 1 || out->w < 1 || out->h < 1 || out->w > r->max_rb || out->h > r->max_rb)
    return cv_err_set(err, CV_ERR_INVALID, "luminance image: expected 1 channel, 1..%d pixels",
                      (int)r->max_rb);
  float mvp[16], inv[16], eye[3], facing;
  if (view_matrices(v, mvp, inv, eye, &facing))
    return cv_err_set(err, CV_ERR_INVALID, "view: singular projection");
  if (cv_egl_make_current(&r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  gl_check("(before luminance)", NULL);
  set_cull(r, 1);
  double t0 = tick(r);
  if ((st = ensure_lum(r, out->w, out->h, err))) return st;
  GLuint pg, pb, pn = 0;
  const int split = r->has_sun && r->sun_split, panel = r->panel_on ? F_PANEL : 0;
  if ((st = variant(r, K_PRT, F_LUM | (r->has_sun ? F_SUN : 0) | panel, &pg, err)) ||
      (split && (st = variant(r, K_PRT, F_LUM | panel, &pn, err))) ||
      (st = variant(r, K_BG, F_LUM, &pb, err)))
    return st;
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_lum);
  glDrawBuffer(GL_COLOR_ATTACHMENT0);
  glViewport(0, 0, out->w, out->h);
  glEnable(GL_DEPTH_TEST);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_LESS);
  glClear(GL_DEPTH_BUFFER_BIT);
  bind_shading(r, pg, mvp, inv, facing, NULL);
  if (split) {
    draw_mesh(r, mvp, DRAW_SUNLIT);
    bind_shading(r, pn, mvp, inv, facing, NULL);
    draw_mesh(r, mvp, DRAW_UNSUNLIT);
  } else {
    draw_mesh(r, mvp, DRAW_ALL);
  }
  glDepthMask(GL_FALSE);
  glDepthFunc(GL_LEQUAL);
  bind_shading(r, pb, mvp, inv, facing, NULL);
  draw_fullscreen(r);
  double t1 = tick(r);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, r->fbo_lum);
  read_image(r, GL_COLOR_ATTACHMENT0, 0, out);
  double t2 = tick(r);
  if ((st = gl_check("luminance pass", err))) return st;
  if (t) {
    t->lum_ms = t1 - t0;
    t->lum_read_ms = t2 - t1;
  }
  return CV_OK;
}

/* Depth pre-pass into fbo_main (W x H). */
static void depth_pass(cv_renderer *r, const float mvp[16], int W, int H) {
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_main);
  glViewport(0, 0, W, H);
  glEnable(GL_DEPTH_TEST);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_LESS);
  glClear(GL_DEPTH_BUFFER_BIT);
  if (r->o.depth_less) return;
  glDrawBuffer(GL_NONE);
  glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  glUseProgram(r->prog_depth);
  uni_mat(r->prog_depth, "u_mvp", mvp);
  draw_mesh(r, mvp, DRAW_ALL);
  glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
}

/* Depth state of the pass after the pre-pass: EQUAL without writes, or the
 * single-pass reference (opts.depth_less). */
static void shading_depth_state(const cv_renderer *r) {
  glDepthFunc(r->o.depth_less ? GL_LESS : GL_EQUAL);

  glDepthMask(r->o.depth_less ? GL_TRUE : GL_FALSE);
}

int cv_renderer_shade(cv_renderer *r, const cv_render_view *v, const cv_drago_consts *dc,
                      int transfer, cv_image *out_display, cv_image *out_hdr, cv_frame_timing *t,
                      cv_err *err) {
  int st = check_view(r, v, err);
  if (st) return st;
  if (!out_display && !out_hdr) return cv_err_set(err, CV_ERR_INVALID, "shade: no output image");
  if (out_display && !dc) return cv_err_set(err, CV_ERR_INVALID, "shade: display output needs Drago constants");
  cv_image *outs[2] = {out_display, out_hdr};
  for (int k = 0; k < 2; k++)
    if (outs[k] && (outs[k]->c != 3 || outs[k]->w != v->w || outs[k]->h != v->h || !outs[k]->px))
      return cv_err_set(err, CV_ERR_INVALID, "shade: %s image must be %dx%d RGB",
                        k ? "HDR" : "display", v->w, v->h);
  float mvp[16], inv[16], eye[3], facing;
  if (view_matrices(v, mvp, inv, eye, &facing))
    return cv_err_set(err, CV_ERR_INVALID, "view: singular projection");
  if (cv_egl_make_current(&r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  gl_check("(before shade)", NULL);
  set_cull(r, 1);
  const int ss = v->supersample, W = v->w * ss, H = v->h * ss;
  int flags = (out_display ? F_DISP : 0) | (out_hdr ? F_HDR : 0) |
              (out_display && transfer ? F_TRANSFER : 0);
  if (out_display) {
    tone_table(r, dc);
    if (!r->tone_ok) flags |= F_EXACT;
  }
  GLuint pg, pb, pn = 0;
  const int split = r->has_sun && r->sun_split, panel = r->panel_on ? F_PANEL : 0;
  if ((st = ensure_main(r, W, H, disp_fmt(r, 0, ss), err)) || (ss > 1 && (st = ensure_res(r, v->w, v->h, err))) ||
      (st = variant(r, K_PRT, flags | (r->has_sun ? F_SUN : 0) | panel, &pg, err)) ||
      (split && (st = variant(r, K_PRT, flags | panel, &pn, err))) ||
      (st = variant(r, K_BG, flags, &pb, err)))
    return st;
  double t0 = tick(r);
  depth_pass(r, mvp, W, H);
  double t1 = tick(r);
  const GLenum bufs[2] = {out_display ? GL_COLOR_ATTACHMENT0 : GL_NONE,
                          out_hdr ? GL_COLOR_ATTACHMENT1 : GL_NONE};
  glDrawBuffers(2, bufs);
  if (r->o.debug_clear) {
    const float sentinel[4] = {-1, -1, -1, -1};
    for (int k = 0; k < 2; k++)
      if (outs[k]) glClearBufferfv(GL_COLOR, k, sentinel);
  }
  shading_depth_state(r);
  bind_shading(r, pg, mvp, inv, facing, dc);
  if (split) {
    draw_mesh(r, mvp, DRAW_SUNLIT);
    bind_shading(r, pn, mvp, inv, facing, dc);
    draw_mesh(r, mvp, DRAW_UNSUNLIT);
  } else {
    draw_mesh(r, mvp, DRAW_ALL);
  }
  double t2 = tick(r);
  glDepthFunc(GL_LEQUAL);
  glDepthMask(GL_FALSE);
  bind_shading(r, pb, mvp, inv, facing, dc);
  draw_fullscreen(r);
  double t3 = tick(r);
  GLuint read_fbo = r->fbo_main;
  if (ss > 1) {
    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_res);
    glViewport(0, 0, v->w, v->h);
    glDisable(GL_DEPTH_TEST);
    glUseProgram(r->prog_down);
    glActiveTexture(GL_TEXTURE0 + U_SRC);
    for (int k = 0; k < 2; k++) {
      if (!outs[k]) continue;
      glDrawBuffer(GL_COLOR_ATTACHMENT0 + k);
      glBindTexture(GL_TEXTURE_2D, k ? r->tex_hdr : r->tex_disp);
      draw_fullscreen(r);
    }
    glEnable(GL_DEPTH_TEST);
    read_fbo = r->fbo_res;
  }
  double t4 = tick(r);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, read_fbo);
  for (int k = 0; k < 2; k++)
    if (outs[k] && read_image(r, GL_COLOR_ATTACHMENT0 + k, k == 0 && !r->o.display_float, outs[k]))
      return cv_err_set(err, CV_ERR_NOMEM, "out of memory reading back");
  double t5 = tick(r);
  if ((st = gl_check("shading pass", err))) return st;
  if (t) {
    t->depth_ms = t1 - t0;
    t->shade_ms = t2 - t1;
    t->background_ms = t3 - t2;
    t->resolve_ms = t4 - t3;
    t->read_ms = t5 - t4;
  }
  return CV_OK;
}

int cv_renderer_frame(cv_renderer *r, const cv_render_view *v, const cv_drago_consts *dc,
                      int transfer, cv_image *out_display, cv_image *out_hdr, cv_image *out_lum,
                      cv_frame_timing *t, cv_err *err) {
  int st;
  if (out_lum && (st = cv_renderer_luminance(r, v, out_lum, t, err))) return st;
  return cv_renderer_shade(r, v, dc, transfer, out_display, out_hdr, t, err);
}

int cv_renderer_unlit(cv_renderer *r, const cv_render_view *v, cv_image *out, cv_frame_timing *t,
                      cv_err *err) {
  int st = check_view(r, v, err);
  if (st) return st;
  if (out && (out->c != 3 || out->w != v->w || out->h != v->h || v->supersample != 1))
    return cv_err_set(err, CV_ERR_INVALID, "unlit: image must be %dx%d RGB, no supersampling", v->w,
                      v->h);
  float mvp[16], inv[16], eye[3], facing;
  if (view_matrices(v, mvp, inv, eye, &facing))
    return cv_err_set(err, CV_ERR_INVALID, "view: singular projection");
  if (cv_egl_make_current(&r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  gl_check("(before unlit)", NULL);
  set_cull(r, 1);
  const int W = v->w * v->supersample, H = v->h * v->supersample;
  if ((st = ensure_main(r, W, H, disp_fmt(r, 0, v->supersample), err))) return st;
  double t0 = tick(r);
  depth_pass(r, mvp, W, H);
  double t1 = tick(r);
  glDrawBuffer(GL_COLOR_ATTACHMENT0);
  shading_depth_state(r);
  glUseProgram(r->prog_unlit);
  uni_mat(r->prog_unlit, "u_mvp", mvp);
  draw_mesh(r, mvp, DRAW_ALL);
  double t2 = tick(r);
  if (out) {
    glBindFramebuffer(GL_READ_FRAMEBUFFER, r->fbo_main);
    if (read_image(r, GL_COLOR_ATTACHMENT0, !r->o.display_float, out))
      return cv_err_set(err, CV_ERR_NOMEM, "out of memory reading back");
  }
  double t3 = tick(r);
  if ((st = gl_check("unlit pass", err))) return st;
  if (t) {
    t->depth_ms = t1 - t0;
    t->unlit_ms = t2 - t1;
    t->read_ms = t3 - t2;
  }
  return CV_OK;
}

/* ---------------------------------------------------------------- present */

int cv_renderer_present(cv_renderer *r, const uint8_t *left, const uint8_t *right, int w, int h,
                        int layout, cv_err *err) {
  if (!r->win) return cv_err_set(err, CV_ERR_INVALID, "renderer: no window to present on");
  const int packed = layout == CV_STEREO_SIDE_BY_SIDE || layout == CV_STEREO_TOP_BOTTOM;
  if (!left || w < 1 || h < 1 || (packed && !right))
    return cv_err_set(err, CV_ERR_INVALID, "renderer: present: no image or bad size");
  if (cv_egl_make_current(&r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  int ww, wh;
  cv_window_size(r->win, &ww, &wh);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glViewport(0, 0, ww, wh);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  glClearColor(0, 0, 0, 1);
  glClear(GL_COLOR_BUFFER_BIT);
  glUseProgram(r->prog_present);
  glActiveTexture(GL_TEXTURE0 + U_SRC);
  if (!r->tex_present) glGenTextures(1, &r->tex_present);
  glBindTexture(GL_TEXTURE_2D, r->tex_present);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  const int eyes = packed ? 2 : 1;
  /* 1:1 pixels copy exactly; another window size is filtered. */
  const int exact = layout == CV_STEREO_SIDE_BY_SIDE ? (2 * w == ww && h == wh)
                    : layout == CV_STEREO_TOP_BOTTOM ? (w == ww && 2 * h == wh)
                                                     : (w == ww && h == wh);
  const GLint filt = exact ? GL_NEAREST : GL_LINEAR;
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, filt);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, filt);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  const GLint loc = glGetUniformLocation(r->prog_present, "u_rect");
  glBindVertexArray(r->vao_empty);
  for (int e = 0; e < eyes; e++) {
    if (r->present_w != w || r->present_h != h) {
      glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB8, w, h, 0, GL_RGB, GL_UNSIGNED_BYTE, e ? right : left);
      r->present_w = w, r->present_h = h;
    } else {
      glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE, e ? right : left);
    }
    float rect[4] = {-1, -1, 1, 1};
    if (layout == CV_STEREO_SIDE_BY_SIDE) rect[0] = e ? 0.0f : -1.0f, rect[2] = e ? 1.0f : 0.0f;
    if (layout == CV_STEREO_TOP_BOTTOM) rect[1] = e ? -1.0f : 0.0f, rect[3] = e ? 0.0f : 1.0f;
    glUniform4fv(loc, 1, rect);
    glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
    if (e == 0 && eyes == 2) glFlush();
  }
  glBindVertexArray(0);
  glFinish();
  return gl_check("present", err);
}

int cv_renderer_swap(cv_renderer *r, cv_err *err) {
  if (!r->win) return CV_OK;
  if (cv_window_poll(r->win) == CV_WIN_LOST || cv_egl_swap(&r->egl))
    return cv_err_set(err, CV_ERR_BACKEND, "eglSwapBuffers on X display '%s' failed (%s)",
                      cv_window_display_name(r->win), cv_window_event_name(cv_window_poll(r->win)));
  return CV_OK;
}

int cv_renderer_window_poll(cv_renderer *r) { return r->win ? cv_window_poll(r->win) : CV_WIN_OK; }

void cv_renderer_window_size(const cv_renderer *r, int *w, int *h) {
  *w = *h = 0;
  if (r->win) cv_window_size(r->win, w, h);
}
