/* The GPU-resident end of a wall-eye frame (see renderer.h, "the frame on
 * the GPU"): the display image stays in its target; its patch means are
 * reduced on the GPU (shaders/patch_sum.frag, double sums with exact area
 * weights); equation 7's up-sampling, the clamp and the Rec.709 transfer run
 * in shaders/post.frag into an 8-bit target per eye ("slot"), which
 * cv_renderer_present_slots draws into the window.  Only the patch means
 * (and the luminance statistics, render_passes.c) come back each frame.
 *
 * This feature owns its state (struct cvr_post); the renderer holds a
 * pointer to it and calls cvr_post_free at destroy.  It uses only the GL
 * layer (render_gl.h): the display image it reads comes as a
 * cvr_image_ref from the caller (the passes' last shade). */
#include "render/render_post.h"

#include "core/overlaps.h"

enum { U_POST_SRC = U_SRC, U_POST_LO = 8, U_POST_ENT = 9, U_POST_FIRST = 10, U_POST_COLS = 11,
       U_POST_ROWS = 12, U_POST_DELTA = 13 };

struct cvr_post {
  int checked, fp64;     /* the GL was asked; it has GL_ARB_gpu_shader_fp64 */
  char why[160];         /* why not, when it has not */
  GLuint prog_cols, prog_rows, prog_post;
  /* the grid and the image size its tables were made for */
  int nu, nv, w, h;
  double *wu, *wv;       /* per patch column / row: the sum of its weights */
  GLuint buf_ent, tex_ent, buf_first, tex_first, buf_cols, tex_cols, buf_rows, tex_rows;
  GLuint fbo_a, tex_a[2];  /* nu x h: column sums, hi and lo */
  GLuint fbo_b, rb_b[2];   /* nu x nv: patch sums, hi and lo */
  float *b_cpu;            /* their read-back, 2 x 3 nu nv */
  GLuint tex_delta;
  /* per eye: the 8-bit projector image, and a kept copy of the display image */
  GLuint fbo_slot[2], tex_slot[2], fbo_keep[2], tex_keep[2];
  int keep_w[2], keep_h[2];
  uint8_t *rgba;           /* read-back scratch of a slot */
};

static void post_free_grid(cvr_post *p) {
  GLuint bufs[] = {p->buf_ent, p->buf_first, p->buf_cols, p->buf_rows};
  glDeleteBuffers(4, bufs);
  GLuint tex[] = {p->tex_ent, p->tex_first, p->tex_cols, p->tex_rows, p->tex_a[0], p->tex_a[1],
                  p->tex_delta, p->tex_slot[0], p->tex_slot[1]};
  glDeleteTextures(9, tex);
  glDeleteRenderbuffers(2, p->rb_b);
  GLuint fbos[] = {p->fbo_a, p->fbo_b, p->fbo_slot[0], p->fbo_slot[1]};
  glDeleteFramebuffers(4, fbos);
  p->buf_ent = p->buf_first = p->buf_cols = p->buf_rows = 0;
  p->tex_ent = p->tex_first = p->tex_cols = p->tex_rows = p->tex_delta = 0;
  p->tex_a[0] = p->tex_a[1] = p->rb_b[0] = p->rb_b[1] = 0;
  p->fbo_a = p->fbo_b = 0;
  for (int k = 0; k < 2; k++) p->fbo_slot[k] = p->tex_slot[k] = 0;
  free(p->wu), free(p->wv), free(p->b_cpu), free(p->rgba);
  p->wu = p->wv = NULL, p->b_cpu = NULL, p->rgba = NULL;
  p->nu = p->nv = p->w = p->h = 0;
}

void cvr_post_free(cvr_post **pp) {
  cvr_post *p = *pp;
  if (!p) return;
  post_free_grid(p);
  glDeleteTextures(2, p->tex_keep);
  glDeleteFramebuffers(2, p->fbo_keep);
  glDeleteProgram(p->prog_cols);
  glDeleteProgram(p->prog_rows);
  glDeleteProgram(p->prog_post);
  free(p);
  *pp = NULL;
}

static void set_units(GLuint prog) {
  static const struct {
    const char *name;
    int unit;
  } tab[] = {{"u_src_lo", U_POST_LO}, {"u_ent", U_POST_ENT}, {"u_first", U_POST_FIRST},
             {"u_cols", U_POST_COLS}, {"u_rows", U_POST_ROWS}, {"u_delta", U_POST_DELTA}};
  glUseProgram(prog);
  for (size_t i = 0; i < sizeof tab / sizeof tab[0]; i++) {
    GLint loc = glGetUniformLocation(prog, tab[i].name);
    if (loc >= 0) glUniform1i(loc, tab[i].unit);
  }
}

/* The feature's state and programs, made on first use. */
static int post_state(cvr_post **pp, cv_err *err) {
  if (*pp && (*pp)->prog_post) return CV_OK;
  if (!*pp && !(*pp = calloc(1, sizeof **pp))) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  cvr_post *p = *pp;
  if (!p->checked) {
    p->checked = 1;
    p->fp64 = cvr_has_extension("GL_ARB_gpu_shader_fp64");
    if (!p->fp64)
      snprintf(p->why, sizeof p->why, "the GL (%s) has no GL_ARB_gpu_shader_fp64 (double sums of the patch means)",
               (const char *)glGetString(GL_RENDERER));
  }
  if (!p->fp64) return cv_err_set(err, CV_ERR_BACKEND, "GPU post pass: %s", p->why);
  static const char fp64[] = "#extension GL_ARB_gpu_shader_fp64 : require\n";
  char defs[3][160];
  snprintf(defs[0], sizeof defs[0], "%s#define COLUMNS\n", fp64);
  snprintf(defs[1], sizeof defs[1], "%s#define ROWS\n", fp64);
  snprintf(defs[2], sizeof defs[2], "%s#define OUT_DISPLAY\n#define LUT_DRAGO_SEGS %d\n", fp64, LUT_DRAGO_SEGS);
  int st;
  if ((st = cvr_build("fullscreen.vert", "patch_sum.frag", defs[0], NULL, &p->prog_cols, err)) ||
      (st = cvr_build("fullscreen.vert", "patch_sum.frag", defs[1], NULL, &p->prog_rows, err)) ||
      (st = cvr_build("fullscreen.vert", "post.frag", defs[2], NULL, &p->prog_post, err)))
    return st;
  set_units(p->prog_cols);
  set_units(p->prog_rows);
  set_units(p->prog_post);
  return CV_OK;
}

int cvr_post_available(const cvr_ctx *c, cvr_post **pp, char *why, size_t cap) {
  cv_err err;
  if (cv_egl_make_current(c->egl)) {
    if (why && cap) snprintf(why, cap, "eglMakeCurrent failed");
    return 0;
  }
  if (post_state(pp, &err) == CV_OK) return 1;
  if (why && cap) snprintf(why, cap, "%s", err.msg);
  return 0;
}

/* ---- the grid's tables --------------------------------------------------- */

static const double *uniform_edges(const double *e, int n, double *tmp) {
  if (e) return e;
  for (int i = 0; i <= n; i++) tmp[i] = (double)i / n;
  return tmp;
}

/* Entries (pixel, weight bits) of each cell, cell-major, from the
 * pixel-major overlaps o of n pixels (flip: pixel i is n - 1 - i).  first[base + c] .. first[base + c + 1]: cell c's; wsum[c] the sum
 * of its weights.  Returns the entries written (the caller sized ent). */
static size_t cell_entries(const cv_overlaps *o, int n, int ncell, int flip, uint32_t *ent, size_t at,
                           int32_t *first, double *wsum) {
  for (int c = 0; c < ncell; c++) {
    first[c] = (int32_t)at;
    wsum[c] = 0;
    for (int i = 0; i < n; i++)
      for (int k = o->first[i]; k < o->first[i + 1]; k++) {
        if (o->cell[k] != c) continue;
        const int px = flip ? n - 1 - i : i; /* image row i is GL row n - 1 - i */
        uint64_t bits;
        memcpy(&bits, &o->len[k], sizeof bits);
        uint32_t *e = ent + 4 * at++;
        e[0] = (uint32_t)px, e[1] = (uint32_t)bits, e[2] = (uint32_t)(bits >> 32), e[3] = 0;
        wsum[c] += o->len[k];
      }
  }
  first[ncell] = (int32_t)at;
  return at;
}

/* The bracketing patch centres of each pixel centre (as resample.c's
 * bracket), 4 floats per pixel: i0, i1, f, 0; rows bottom up. */
static void brackets(const double *e, int n, int npx, int flip, float *out) {
  const double c0 = 0.5 * (e[0] + e[1]), cn = 0.5 * (e[n - 1] + e[n]);
  for (int i = 0; i < npx; i++) {
    const double t = ((flip ? npx - 1 - i : i) + 0.5) / npx;
    int i0 = 0, i1 = 0;
    double f = 0;
    if (n > 1 && t > c0 && t < cn) {
      const int k = cv_cell_of(e, n, t);
      const int a = 0.5 * (e[k] + e[k + 1]) <= t ? k : k - 1;
      const double ca = 0.5 * (e[a] + e[a + 1]), cb = 0.5 * (e[a + 1] + e[a + 2]);
      i0 = a, i1 = a + 1, f = (t - ca) / (cb - ca);
    } else if (n > 1 && t >= cn) {
      i0 = i1 = n - 1;
    }
    float *q = out + 4 * (size_t)i;
    q[0] = (float)i0, q[1] = (float)i1, q[2] = (float)f, q[3] = 0;
  }
}

static GLuint target_tex(GLenum fmt, int w, int h) {
  GLuint t = cvr_make_tex(fmt, w, h);
  return t;
}

static int grid_targets(cvr_post *p, cv_err *err) {
  glGenFramebuffers(1, &p->fbo_a);
  glBindFramebuffer(GL_FRAMEBUFFER, p->fbo_a);
  for (int k = 0; k < 2; k++) {
    p->tex_a[k] = target_tex(GL_RGBA32F, p->nu, p->h);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0 + k, GL_TEXTURE_2D, p->tex_a[k], 0);
  }
  int st = cvr_fbo_complete("patch columns", p->nu, p->h, err);
  if (st) return st;
  glGenFramebuffers(1, &p->fbo_b);
  glBindFramebuffer(GL_FRAMEBUFFER, p->fbo_b);
  for (int k = 0; k < 2; k++) {
    p->rb_b[k] = cvr_make_rb(GL_RGBA32F, p->nu, p->nv);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0 + k, GL_RENDERBUFFER, p->rb_b[k]);
  }
  if ((st = cvr_fbo_complete("patch means", p->nu, p->nv, err))) return st;
  for (int k = 0; k < 2; k++) {
    glGenFramebuffers(1, &p->fbo_slot[k]);
    glBindFramebuffer(GL_FRAMEBUFFER, p->fbo_slot[k]);
    p->tex_slot[k] = cvr_make_tex(GL_RGBA8, p->w, p->h);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, p->tex_slot[k], 0);
    if ((st = cvr_fbo_complete("projector image", p->w, p->h, err))) return st;
  }
  glGenTextures(1, &p->tex_delta);
  glBindTexture(GL_TEXTURE_2D, p->tex_delta);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, p->nu, p->nv, 0, GL_RGB, GL_FLOAT, NULL);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glBindTexture(GL_TEXTURE_2D, 0);
  return cvr_gl_check("post targets", err);
}

/* The tables of a grid: entries and their cells' firsts (columns, then
 * rows), the bracketing tables of equation 7's up-sampling. */
static int grid_tables(cvr_ctx *r, cvr_post *p, const double *U, const double *V, cv_err *err) {
  cv_overlaps ox = {0}, oy = {0};
  const int nu = p->nu, nv = p->nv, w = p->w, h = p->h;
  /* GL rows bottom up: row i covers [i / h, (i + 1) / h) of v (no flip) */
  int st = cv_overlaps_make(U, nu, w, 1.0, 0, &ox) || cv_overlaps_make(V, nv, h, 1.0, 0, &oy);
  const size_t nent = st ? 0 : (size_t)ox.first[w] + (size_t)oy.first[h];
  uint32_t *ent = st ? NULL : malloc(4 * nent * sizeof *ent);
  int32_t *first = malloc((size_t)(nu + nv + 2) * sizeof *first);
  float *cols = malloc(4 * (size_t)w * sizeof *cols), *rows = malloc(4 * (size_t)h * sizeof *rows);
  p->wu = malloc((size_t)nu * sizeof *p->wu);
  p->wv = malloc((size_t)nv * sizeof *p->wv);
  p->b_cpu = malloc(2 * 4 * (size_t)nu * nv * sizeof *p->b_cpu);
  if (st || !ent || !first || !cols || !rows || !p->wu || !p->wv || !p->b_cpu) {
    st = cv_err_set(err, CV_ERR_NOMEM, "out of memory making the patch tables");
  } else {
    size_t at = cell_entries(&ox, w, nu, 0, ent, 0, first, p->wu);
    cell_entries(&oy, h, nv, 0, ent, at, first + nu + 1, p->wv);
    brackets(U, nu, w, 0, cols);
    brackets(V, nv, h, 0, rows);
    p->tex_ent = cvr_make_tbo(&p->buf_ent, GL_RGBA32UI, ent, 4 * nent * sizeof *ent);
    p->tex_first = cvr_make_tbo(&p->buf_first, GL_R32I, first, (size_t)(nu + nv + 2) * sizeof *first);
    p->tex_cols = cvr_make_tbo(&p->buf_cols, GL_RGBA32F, cols, 4 * (size_t)w * sizeof *cols);
    p->tex_rows = cvr_make_tbo(&p->buf_rows, GL_RGBA32F, rows, 4 * (size_t)h * sizeof *rows);
    r->io_up += 4 * nent * sizeof *ent + (size_t)(nu + nv + 2) * sizeof *first + 16 * (size_t)(w + h);
  }
  free(ent), free(first), free(cols), free(rows);
  cv_overlaps_free(&ox), cv_overlaps_free(&oy);
  return st;
}

int cvr_post_grid(cvr_ctx *r, cvr_post **pp, int nu, int nv, const double *eu, const double *ev, int w,
                  int h, cv_err *err) {
  if (nu < 1 || nv < 1 || w < 1 || h < 1 || w > r->max_rb || h > r->max_rb || nu > w || nv > h)
    return cv_err_set(err, CV_ERR_INVALID, "post grid: %d x %d patches on %d x %d pixels (1..%d pixels, at "
                      "most one patch a pixel)", nu, nv, w, h, (int)r->max_rb);
  if (cv_egl_make_current(r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  int st = post_state(pp, err);
  if (st) return st;
  cvr_post *p = *pp;
  post_free_grid(p);
  p->nu = nu, p->nv = nv, p->w = w, p->h = h;
  double *tu = malloc((size_t)(nu + 1) * sizeof *tu), *tv = malloc((size_t)(nv + 1) * sizeof *tv);
  if (!tu || !tv) st = cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  if (!st) st = grid_tables(r, p, uniform_edges(eu, nu, tu), uniform_edges(ev, nv, tv), err);
  free(tu), free(tv);
  if (!st) st = grid_targets(p, err);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  if (st) post_free_grid(p);
  return st;
}

/* ---- per frame ------------------------------------------------------------ */

static int check_source(const cvr_image_ref *src, const cvr_post *p, cv_err *err) {
  if (!p || !p->nu) return cv_err_set(err, CV_ERR_INVALID, "post: no patch grid (cv_renderer_post_grid)");
  if (!src->tex || src->w != p->w || src->h != p->h || !src->is_float)
    return cv_err_set(err, CV_ERR_INVALID, "post: no %dx%d float display image on the GPU (shade with "
                      "cv_renderer_shade_gpu first)", p->w, p->h);
  return CV_OK;
}

static void bind_tables(const cvr_post *p) {
  glActiveTexture(GL_TEXTURE0 + U_POST_ENT);
  glBindTexture(GL_TEXTURE_BUFFER, p->tex_ent);
  glActiveTexture(GL_TEXTURE0 + U_POST_FIRST);
  glBindTexture(GL_TEXTURE_BUFFER, p->tex_first);
  glActiveTexture(GL_TEXTURE0 + U_POST_COLS);
  glBindTexture(GL_TEXTURE_BUFFER, p->tex_cols);
  glActiveTexture(GL_TEXTURE0 + U_POST_ROWS);
  glBindTexture(GL_TEXTURE_BUFFER, p->tex_rows);
}

static void draw_into(GLuint fbo, int nbuf, int w, int h) {
  static const GLenum bufs[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glDrawBuffers(nbuf, bufs);
  glViewport(0, 0, w, h);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
}

int cvr_post_patch_means(cvr_ctx *r, cvr_post *p, const cvr_image_ref *src, double *out, cv_err *err) {
  int st = check_source(src, p, err);
  if (st) return st;
  if (cv_egl_make_current(r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  bind_tables(p);
  /* columns: nu x h */
  draw_into(p->fbo_a, 2, p->nu, p->h);
  glUseProgram(p->prog_cols);
  glUniform1i(glGetUniformLocation(p->prog_cols, "u_base"), 0);
  glActiveTexture(GL_TEXTURE0 + U_POST_SRC);
  glBindTexture(GL_TEXTURE_2D, src->tex);
  cvr_draw_fullscreen(r);
  /* rows: nu x nv */
  draw_into(p->fbo_b, 2, p->nu, p->nv);
  glUseProgram(p->prog_rows);
  glUniform1i(glGetUniformLocation(p->prog_rows, "u_base"), p->nu + 1);
  glActiveTexture(GL_TEXTURE0 + U_POST_SRC);
  glBindTexture(GL_TEXTURE_2D, p->tex_a[0]);
  glActiveTexture(GL_TEXTURE0 + U_POST_LO);
  glBindTexture(GL_TEXTURE_2D, p->tex_a[1]);
  cvr_draw_fullscreen(r);
  glEnable(GL_DEPTH_TEST);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, p->fbo_b);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  const size_t np = (size_t)p->nu * p->nv;
  for (int k = 0; k < 2; k++) {
    glReadBuffer(GL_COLOR_ATTACHMENT0 + k);
    glReadPixels(0, 0, p->nu, p->nv, GL_RGB, GL_FLOAT, p->b_cpu + 3 * np * k);
  }
  r->io_read += 2 * 3 * np * sizeof(float);
  if ((st = cvr_gl_check("patch means", err))) return st;
  for (int v = 0; v < p->nv; v++)
    for (int u = 0; u < p->nu; u++) {
      const size_t i = (size_t)v * p->nu + u;
      const double wsum = p->wu[u] * p->wv[v];
      for (int c = 0; c < 3; c++) {
        const double s = (double)p->b_cpu[3 * i + c] + (double)p->b_cpu[3 * np + 3 * i + c];
        out[3 * i + c] = wsum > 0 ? s / wsum : 0.0;
      }
    }
  return CV_OK;
}

int cvr_post_keep(const cvr_ctx *r, cvr_post *p, const cvr_image_ref *src, int slot, cv_err *err) {
  int st = check_source(src, p, err);
  if (st) return st;
  if (cv_egl_make_current(r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  if (!p->tex_keep[slot] || p->keep_w[slot] != p->w || p->keep_h[slot] != p->h) {
    glDeleteTextures(1, &p->tex_keep[slot]);
    if (!p->fbo_keep[slot]) glGenFramebuffers(1, &p->fbo_keep[slot]);
    p->tex_keep[slot] = cvr_make_tex(GL_RGBA32F, p->w, p->h);
    glBindFramebuffer(GL_FRAMEBUFFER, p->fbo_keep[slot]);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, p->tex_keep[slot], 0);
    p->keep_w[slot] = p->w, p->keep_h[slot] = p->h;
    if ((st = cvr_fbo_complete("kept display image", p->w, p->h, err))) return st;
  }
  glBindFramebuffer(GL_READ_FRAMEBUFFER, src->fbo);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, p->fbo_keep[slot]);
  glDrawBuffer(GL_COLOR_ATTACHMENT0);
  glBlitFramebuffer(0, 0, p->w, p->h, 0, 0, p->w, p->h, GL_COLOR_BUFFER_BIT, GL_NEAREST);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  return cvr_gl_check("display keep", err);
}

int cvr_post_run(cvr_ctx *r, cvr_post *p, const cvr_image_ref *src, int slot, int kept, const float *delta,
                 cv_err *err) {
  int st = kept ? (p && p->nu && p->tex_keep[slot] && p->keep_w[slot] == p->w
                       ? CV_OK
                       : cv_err_set(err, CV_ERR_INVALID, "post: nothing kept in slot %d", slot))
                : check_source(src, p, err);
  if (st) return st;
  if (cv_egl_make_current(r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  if (delta) {
    glBindTexture(GL_TEXTURE_2D, p->tex_delta);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, p->nu, p->nv, GL_RGB, GL_FLOAT, delta);
    r->io_up += 3 * (size_t)p->nu * p->nv * sizeof(float);
  }
  bind_tables(p);
  draw_into(p->fbo_slot[slot], 1, p->w, p->h);
  glUseProgram(p->prog_post);
  glUniform1i(glGetUniformLocation(p->prog_post, "u_delta_on"), delta != NULL);
  glActiveTexture(GL_TEXTURE0 + U_POST_SRC);
  glBindTexture(GL_TEXTURE_2D, kept ? p->tex_keep[slot] : src->tex);
  glActiveTexture(GL_TEXTURE0 + U_POST_DELTA);
  glBindTexture(GL_TEXTURE_2D, p->tex_delta);
  cvr_draw_fullscreen(r);
  glEnable(GL_DEPTH_TEST);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  return cvr_gl_check("post pass", err);
}

int cvr_post_black(const cvr_ctx *r, cvr_post *p, int slot, cv_err *err) {
  if (!p || !p->nu || slot < 0 || slot > 1) return cv_err_set(err, CV_ERR_INVALID, "post: no grid, or slot not 0 or 1");
  if (cv_egl_make_current(r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  static const float black[4] = {0, 0, 0, 1};
  glBindFramebuffer(GL_FRAMEBUFFER, p->fbo_slot[slot]);
  glClearBufferfv(GL_COLOR, 0, black);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  return cvr_gl_check("post black", err);
}

int cvr_post_read(cvr_ctx *r, cvr_post *p, int slot, uint8_t *codes, cv_err *err) {
  if (!p || !p->nu || slot < 0 || slot > 1 || !codes)
    return cv_err_set(err, CV_ERR_INVALID, "post read: no grid, or slot not 0 or 1");
  if (cv_egl_make_current(r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  const size_t n = (size_t)p->w * p->h;
  if (!p->rgba && !(p->rgba = malloc(4 * n))) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  glBindFramebuffer(GL_READ_FRAMEBUFFER, p->fbo_slot[slot]);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glReadPixels(0, 0, p->w, p->h, GL_RGBA, GL_UNSIGNED_BYTE, p->rgba);
  r->io_read += 4 * n;
  for (int y = 0; y < p->h; y++) {
    const uint8_t *src = p->rgba + 4 * (size_t)(p->h - 1 - y) * p->w;
    uint8_t *dst = codes + 3 * (size_t)y * p->w;
    for (int x = 0; x < p->w; x++)
      for (int c = 0; c < 3; c++) dst[3 * x + c] = src[4 * x + c];
  }
  return cvr_gl_check("post read", err);
}

GLuint cvr_post_slot_texture(const cvr_post *p, int slot, int *w, int *h) {
  if (!p || !p->nu || slot < 0 || slot > 1) return 0;
  *w = p->w, *h = p->h;
  return p->tex_slot[slot];
}
