/* The renderer's targets and passes: luminance, depth, PRT shading with
 * Drago tables, resolve, read-back, and the unlit reference (see renderer.h). */
#include "render/render_passes.h"

#include "tonemap/foveal.h"

/* ---------------------------------------------------------------- targets */

static int ensure_lum(cvr_targets *r, int w, int h, cv_err *err) {
  if (r->fbo_lum && r->lum_w == w && r->lum_h == h) return CV_OK;
  GLuint old[2] = {r->rb_lum, r->rb_lum_depth};
  glDeleteRenderbuffers(2, old);
  if (!r->fbo_lum) glGenFramebuffers(1, &r->fbo_lum);
  r->rb_lum = cvr_make_rb(GL_R32F, w, h);
  r->rb_lum_depth = cvr_make_rb(GL_DEPTH_COMPONENT32F, w, h);
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_lum);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, r->rb_lum);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, r->rb_lum_depth);
  r->lum_w = w, r->lum_h = h;
  return cvr_fbo_complete("luminance", w, h, err);
}

/* Display target format: 8-bit unless opts.display_float; float while
 * supersampling (the resolve averages before quantising). */
static GLenum disp_fmt(const cvr_ctx *c, int resolve_target, int ss) {
  return c->o->display_float || (!resolve_target && ss > 1) ? GL_RGBA32F : GL_RGBA8;
}

static int ensure_main(cvr_targets *r, int w, int h, GLenum dfmt, cv_err *err) {
  if (r->fbo_main && r->main_w == w && r->main_h == h && r->main_fmt == dfmt) return CV_OK;
  r->main_fmt = dfmt;
  GLuint old[2] = {r->tex_disp, r->tex_hdr};
  glDeleteTextures(2, old);
  glDeleteRenderbuffers(1, &r->rb_depth);
  if (!r->fbo_main) glGenFramebuffers(1, &r->fbo_main);
  r->tex_disp = cvr_make_tex(dfmt, w, h);
  r->tex_hdr = cvr_make_tex(GL_RGBA32F, w, h);
  r->rb_depth = cvr_make_rb(GL_DEPTH_COMPONENT32F, w, h);
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_main);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, r->tex_disp, 0);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_TEXTURE_2D, r->tex_hdr, 0);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, r->rb_depth);
  r->main_w = w, r->main_h = h;
  return cvr_fbo_complete("shading", w, h, err);
}

/* The supersampling resolve's targets: the display image as a texture (the
 * GPU post pass reads it), the HDR image as a renderbuffer. */
static int ensure_res(const cvr_ctx *c, cvr_targets *r, int w, int h, cv_err *err) {
  const GLenum fmt = disp_fmt(c, 1, 1);
  if (r->fbo_res && r->res_w == w && r->res_h == h && r->res_fmt == fmt) return CV_OK;
  glDeleteTextures(1, &r->tex_res_disp);
  glDeleteRenderbuffers(1, &r->rb_res_hdr);
  if (!r->fbo_res) glGenFramebuffers(1, &r->fbo_res);
  r->tex_res_disp = cvr_make_tex(fmt, w, h);
  r->res_fmt = fmt;
  r->rb_res_hdr = cvr_make_rb(GL_RGBA32F, w, h);
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_res);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, r->tex_res_disp, 0);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_RENDERBUFFER, r->rb_res_hdr);
  r->res_w = w, r->res_h = h;
  return cvr_fbo_complete("resolve", w, h, err);
}

/* ---------------------------------------------------------------- passes */

static int check_view(const cvr_ctx *c, const cvr_light *lt, const cv_render_view *v, cv_err *err) {
  if (!v) return cv_err_set(err, CV_ERR_INVALID, "renderer: NULL view");
  if (!lt->lit) return cv_err_set(err, CV_ERR_INVALID, "renderer: no lighting set");
  if (v->supersample != 1 && v->supersample != 2)
    return cv_err_set(err, CV_ERR_INVALID, "supersample must be 1 or 2, got %d", v->supersample);
  if (v->w < 1 || v->h < 1 || v->w * v->supersample > c->max_rb || v->h * v->supersample > c->max_rb)
    return cv_err_set(err, CV_ERR_RANGE, "view %dx%d (x%d) outside 1..%d pixels", v->w, v->h,
                      v->supersample, (int)c->max_rb);
  return CV_OK;
}

/* The prt.frag (K_PRT) or background.frag (K_BG) program for flags F_*,
 * compiled on first use. */
static int variant(cvr_passes *r, int kind, int flags, GLuint *out, cv_err *err) {
  if (!r->prog_var[kind][flags]) {
    char defs[320];
    snprintf(defs, sizeof defs, "%s%s%s%s%s%s%s%s#define LUT_DRAGO_SEGS %d\n",
             flags & F_SUN ? "#define SUN\n" : "",
             flags & F_TRANSFER ? "#define TRANSFER\n" : "",
             flags & F_DISP ? "#define OUT_DISPLAY\n" : "", flags & F_HDR ? "#define OUT_HDR\n" : "",
             flags & F_LUM ? "#define OUT_LUM\n" : "", flags & F_PANEL ? "#define PANEL\n" : "",
             flags & F_EXACT ? "#define DRAGO_EXACT\n" : "",
             flags & F_TEX ? "#define TEXTURE\n" : "", LUT_DRAGO_SEGS);
    int st = kind == K_PRT ? cvr_build("geom.vert", "prt.frag", defs, NULL, &r->prog_var[kind][flags], err)
                           : cvr_build("fullscreen.vert", "background.frag", defs, NULL,
                                   &r->prog_var[kind][flags], err);
    if (st) return st;
  }
  *out = r->prog_var[kind][flags];
  return CV_OK;
}

/* Binds the textures and sets the uniforms a prt.frag / background.frag
 * variant reads. */
static void bind_shading(const cvr_passes *ps, const cvr_inputs *in, GLuint p, const float mvp[16],
                         const float inv[16], float facing, const cv_drago_consts *dc) {
  glUseProgram(p);
  cvr_uni_mat(p, "u_mvp", mvp);
  cvr_uni_mat(p, "u_inv_mvp", inv);
  if (dc) {
    cvr_uni_f(p, "lwa", dc->lwa);
    cvr_uni_f(p, "lwmax_a", dc->lwmax_a);
    cvr_uni_f(p, "scale", dc->scale);
    cvr_uni_f(p, "p_exp", dc->p_exp);
    cvr_uni_f(p, "ld_top", dc->ld_top);
  }
  if (dc) {
    cvr_uni_f(p, "u_lut_k", ps->tone.lut_k);
    cvr_uni_f(p, "u_lut_tail", ps->tone.lut_tail);
    glActiveTexture(GL_TEXTURE0 + U_TONE);
    glBindTexture(GL_TEXTURE_BUFFER, ps->tone.tex);
  }
  if (in->lt->panel.on) {
    cvr_uni_v3(p, "u_panel_c", in->lt->panel.c);
    cvr_uni_v3(p, "u_panel_u", in->lt->panel.u);
    cvr_uni_v3(p, "u_panel_v", in->lt->panel.v);
    cvr_uni_v3(p, "u_panel_n", in->lt->panel.n);
    GLint loc = glGetUniformLocation(p, "u_panel_half");
    if (loc >= 0) glUniform2f(loc, in->lt->panel.half[0], in->lt->panel.half[1]);
    glActiveTexture(GL_TEXTURE0 + U_PANEL);
    glBindTexture(GL_TEXTURE_2D, in->lt->panel.tex);
  }
  if (in->lt->has_sun) {
    cvr_uni_mat(p, "u_shadow_q", in->lt->shadow.q);
    GLint loc = glGetUniformLocation(p, "u_shadow_k");
    if (loc >= 0) glUniform4fv(loc, 1, in->lt->shadow.k);
    loc = glGetUniformLocation(p, "u_shadow_size");
    if (loc >= 0) glUniform2i(loc, in->lt->shadow.w, in->lt->shadow.h);
    cvr_uni_v3(p, "u_sun_e", in->lt->sun_e);
    cvr_uni_f(p, "u_shadow_bias", in->lt->shadow.bias);
    cvr_uni_f(p, "u_sigma", facing * (float)in->lt->shadow.detsign);
  }
  if (in->tx->tex) {
    glActiveTexture(GL_TEXTURE0 + U_ALBEDO);
    glBindTexture(GL_TEXTURE_2D_ARRAY, in->tx->tex);
  }
  glActiveTexture(GL_TEXTURE0 + U_SHADOW);
  glBindTexture(GL_TEXTURE_2D, in->lt->shadow.from_import ? in->lt->shadow.tex_imp : in->lt->shadow.tex);
  glActiveTexture(GL_TEXTURE0 + U_BG);
  glBindTexture(GL_TEXTURE_2D, in->lt->tex_bg);
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
static void tone_table(const cvr_ctx *c, cvr_tone *r, const cv_drago_consts *dc) {
  if (r->built && !memcmp(&r->dc, dc, sizeof *dc)) return;
  float *buf = malloc(4 * LUT_DRAGO_SEGS * sizeof *buf);
  if (!buf) {
    r->ok = 0; /* the exact variant needs no table */
    return;
  }
  r->err = fit_table(drago_raw, dc, LUT_DRAGO_E0, LUT_DRAGO_SEGS, 1e-4, buf);
  const double ylo = ldexp(1.0, -126);
  r->lut_tail = (float)(drago_raw(dc, ylo) / ylo);
  r->lut_k = (float)(1.0 / ((double)dc->lwa * (double)dc->lwmax_a));
  r->ok = !c->o->tone_exact && r->err <= LUT_TOL && isfinite(r->lut_tail) &&
               isfinite(r->lut_k);
  if (!r->buf) {
    r->tex = cvr_make_tbo(&r->buf, GL_RGBA32F, buf, 4 * LUT_DRAGO_SEGS * sizeof *buf);
  } else {
    glBindBuffer(GL_TEXTURE_BUFFER, r->buf);
    glBufferSubData(GL_TEXTURE_BUFFER, 0, 4 * LUT_DRAGO_SEGS * sizeof *buf, buf);
    glBindBuffer(GL_TEXTURE_BUFFER, 0);
  }
  free(buf);
  r->dc = *dc;
  r->built = 1;
}

int cvr_passes_luminance(cvr_ctx *c, cvr_passes *ps, const cvr_inputs *in, const cv_render_view *v,
                         cv_image *out, cv_frame_timing *t, cv_err *err) {
  int st = check_view(c, in->lt, v, err);
  if (st) return st;
  if (!out || out->c != 1 || out->w < 1 || out->h < 1 || out->w > c->max_rb || out->h > c->max_rb)
    return cv_err_set(err, CV_ERR_INVALID, "luminance image: expected 1 channel, 1..%d pixels",
                      (int)c->max_rb);
  float mvp[16], inv[16], eye[3], facing;
  if (cvr_view_matrices(v, mvp, inv, eye, &facing))
    return cv_err_set(err, CV_ERR_INVALID, "view: singular projection");
  if (cv_egl_make_current(c->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  cvr_gl_check("(before luminance)", NULL);
  cvr_scene_cull(c, in->sc, 1);
  double t0 = cvr_tick(c);
  if ((st = ensure_lum(&ps->targets, out->w, out->h, err))) return st;
  GLuint pg, pb, pn = 0;
  const int split = in->lt->has_sun && in->lt->sun_split,
            panel = (in->lt->panel.on ? F_PANEL : 0) | (in->tx->tex ? F_TEX : 0);
  if ((st = variant(ps, K_PRT, F_LUM | (in->lt->has_sun ? F_SUN : 0) | panel, &pg, err)) ||
      (split && (st = variant(ps, K_PRT, F_LUM | panel, &pn, err))) ||
      (st = variant(ps, K_BG, F_LUM, &pb, err)))
    return st;
  glBindFramebuffer(GL_FRAMEBUFFER, ps->targets.fbo_lum);
  glDrawBuffer(GL_COLOR_ATTACHMENT0);
  glViewport(0, 0, out->w, out->h);
  glEnable(GL_DEPTH_TEST);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_LESS);
  glClear(GL_DEPTH_BUFFER_BIT);
  bind_shading(ps, in, pg, mvp, inv, facing, NULL);
  if (split) {
    cvr_scene_draw(c, in->sc, mvp, DRAW_SUNLIT);
    bind_shading(ps, in, pn, mvp, inv, facing, NULL);
    cvr_scene_draw(c, in->sc, mvp, DRAW_UNSUNLIT);
  } else {
    cvr_scene_draw(c, in->sc, mvp, DRAW_ALL);
  }
  glDepthMask(GL_FALSE);
  glDepthFunc(GL_LEQUAL);
  bind_shading(ps, in, pb, mvp, inv, facing, NULL);
  cvr_draw_fullscreen(c);
  double t1 = cvr_tick(c);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, ps->targets.fbo_lum);
  cvr_read_image(c, GL_COLOR_ATTACHMENT0, 0, out);
  double t2 = cvr_tick(c);
  if ((st = cvr_gl_check("luminance pass", err))) return st;
  if (t) {
    t->lum_ms = t1 - t0;
    t->lum_read_ms = t2 - t1;
  }
  return CV_OK;
}

/* Depth pre-pass into fbo_main (W x H). */
static void depth_pass(const cvr_ctx *c, cvr_passes *ps, cvr_scene *sc, const float mvp[16], int W, int H) {
  glBindFramebuffer(GL_FRAMEBUFFER, ps->targets.fbo_main);
  glViewport(0, 0, W, H);
  glEnable(GL_DEPTH_TEST);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_LESS);
  glClear(GL_DEPTH_BUFFER_BIT);
  if (c->o->depth_less) return;
  glDrawBuffer(GL_NONE);
  glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  glUseProgram(sc->prog_depth);
  cvr_uni_mat(sc->prog_depth, "u_mvp", mvp);
  cvr_scene_draw(c, sc, mvp, DRAW_ALL);
  glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
}

/* Depth state of the pass after the pre-pass: EQUAL without writes, or the
 * single-pass reference (opts.depth_less). */
static void depth_state(const cvr_ctx *c) {
  glDepthFunc(c->o->depth_less ? GL_LESS : GL_EQUAL);

  glDepthMask(c->o->depth_less ? GL_TRUE : GL_FALSE);
}

/* Targets of the luminance statistics for a w x h luminance image: the
 * image (R32F) and the (max, invalid) pairs (RG32F texture), then those
 * pairs in blocks of LUM_BLOCK^2. */
#define LUM_BLOCK 8
static int ensure_reduce(cvr_targets *r, int w, int h, cv_err *err) {
  if (r->fbo_red && r->red_w == w && r->red_h == h) return CV_OK;
  const int bw = (w + LUM_BLOCK - 1) / LUM_BLOCK, bh = (h + LUM_BLOCK - 1) / LUM_BLOCK;
  float *buf = realloc(r->red_cpu, 2 * (size_t)bw * bh * sizeof *buf);
  if (!buf) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  r->red_cpu = buf;
  glDeleteRenderbuffers(1, &r->rb_red);
  glDeleteRenderbuffers(1, &r->rb_blk);
  glDeleteTextures(1, &r->tex_red_mb);
  if (!r->fbo_red) glGenFramebuffers(1, &r->fbo_red);
  if (!r->fbo_blk) glGenFramebuffers(1, &r->fbo_blk);
  r->rb_red = cvr_make_rb(GL_R32F, w, h);
  r->tex_red_mb = cvr_make_tex(GL_RG32F, w, h);
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_red);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, r->rb_red);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_TEXTURE_2D, r->tex_red_mb, 0);
  int st = cvr_fbo_complete("luminance statistics", w, h, err);
  if (st) return st;
  r->rb_blk = cvr_make_rb(GL_RG32F, bw, bh);
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_blk);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, r->rb_blk);
  if ((st = cvr_fbo_complete("luminance blocks", bw, bh, err))) return st;
  r->red_w = w, r->red_h = h;
  return CV_OK;
}

/* The luminance statistics of the HDR target just drawn (W x H pixels of
 * ss x ss texels; targets.tex_hdr) into lum (lum_reduce.frag, then
 * lum_block.frag): the luminance image and the (max, invalid) pairs of
 * LUM_BLOCK^2 blocks come back (4 bytes a luminance pixel + 8 a block), the
 * max and the count finished on the CPU. */
int cvr_reduce_luminance(cvr_ctx *c, cvr_passes *ps, int W, int H, int ss, cv_image *lum, double *max_y,
                         uint64_t *n_invalid, cv_err *err) {
  const int w = lum->w, h = lum->h;
  int st = ensure_reduce(&ps->targets, w, h, err);
  if (st) return st;
  static const GLenum bufs[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
  glBindFramebuffer(GL_FRAMEBUFFER, ps->targets.fbo_red);
  glDrawBuffers(2, bufs);
  glViewport(0, 0, w, h);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_CULL_FACE);
  GLuint p = ps->prog_lumred;
  glUseProgram(p);
  glUniform2i(glGetUniformLocation(p, "u_size"), W, H);
  glUniform2i(glGetUniformLocation(p, "u_out"), w, h);
  glUniform1i(glGetUniformLocation(p, "u_ss"), ss);
  glActiveTexture(GL_TEXTURE0 + U_SRC);
  glBindTexture(GL_TEXTURE_2D, ps->targets.tex_hdr);
  cvr_draw_fullscreen(c);
  const int bw = (w + LUM_BLOCK - 1) / LUM_BLOCK, bh = (h + LUM_BLOCK - 1) / LUM_BLOCK;
  glBindFramebuffer(GL_FRAMEBUFFER, ps->targets.fbo_blk);
  glDrawBuffer(GL_COLOR_ATTACHMENT0);
  glViewport(0, 0, bw, bh);
  p = ps->prog_lumblk;
  glUseProgram(p);
  glUniform2i(glGetUniformLocation(p, "u_size"), w, h);
  glUniform1i(glGetUniformLocation(p, "u_block"), LUM_BLOCK);
  glBindTexture(GL_TEXTURE_2D, ps->targets.tex_red_mb);
  cvr_draw_fullscreen(c);
  glEnable(GL_DEPTH_TEST);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, ps->targets.fbo_red);
  cvr_read_image(c, GL_COLOR_ATTACHMENT0, 0, lum);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, ps->targets.fbo_blk);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glReadPixels(0, 0, bw, bh, GL_RG, GL_FLOAT, ps->targets.red_cpu);
  c->io_read += 2 * (size_t)bw * bh * sizeof(float);
  double mx = 0, bad = 0;
  for (size_t i = 0; i < (size_t)bw * bh; i++) {
    if (ps->targets.red_cpu[2 * i] > mx) mx = ps->targets.red_cpu[2 * i];
    bad += ps->targets.red_cpu[2 * i + 1];
  }
  if (max_y) *max_y = mx;
  if (n_invalid) *n_invalid = (uint64_t)bad;
  return cvr_gl_check("luminance statistics", err);
}


/* cv_renderer_shade_stats, and with `keep` the display image drawn and
 * left on the GPU (cv_renderer_shade_gpu) instead of read back. */
int cvr_passes_shade(cvr_ctx *c, cvr_passes *ps, const cvr_inputs *in, const cv_render_view *v,
                     const cv_drago_consts *dc, int transfer, cv_image *out_display, int keep, cv_image *out_hdr, cv_image *out_lum, double *max_y,
                 uint64_t *n_invalid, cv_frame_timing *t, cv_err *err) {
  int st = check_view(c, in->lt, v, err);
  if (st) return st;
  if (keep && !c->o->display_float)
    return cv_err_set(err, CV_ERR_INVALID, "shade: a display image kept on the GPU needs opts.display_float");
  const int want_disp = out_display || keep;
  const int gpu_stats = out_lum && (keep || cvr_lum_stats_gpu(c));
  if (out_lum && !gpu_stats && !out_hdr) {
    /* statistics on the CPU: the HDR image is read back into scratch */
    if (!ps->targets.hdr_scratch || ps->targets.hdr_scratch->w != v->w || ps->targets.hdr_scratch->h != v->h) {
      cv_image_destroy(ps->targets.hdr_scratch);
      ps->targets.hdr_scratch = NULL;
      if (cv_image_create(v->w, v->h, 3, &ps->targets.hdr_scratch))
        return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
    }
    out_hdr = ps->targets.hdr_scratch;
  }
  if (!want_disp && !out_hdr && !out_lum)
    return cv_err_set(err, CV_ERR_INVALID, "shade: no output image");
  if (out_lum && (out_lum->c != 1 || out_lum->w < 1 || out_lum->h < 1 || !out_lum->px ||
                  out_lum->w > c->max_rb || out_lum->h > c->max_rb))
    return cv_err_set(err, CV_ERR_INVALID, "shade: the luminance image must be 1 channel, 1..%d pixels a side",
                      (int)c->max_rb);
  if (want_disp && !dc) return cv_err_set(err, CV_ERR_INVALID, "shade: display output needs Drago constants");
  cv_image *outs[2] = {out_display, out_hdr};
  for (int k = 0; k < 2; k++)
    if (outs[k] && (outs[k]->c != 3 || outs[k]->w != v->w || outs[k]->h != v->h || !outs[k]->px))
      return cv_err_set(err, CV_ERR_INVALID, "shade: %s image must be %dx%d RGB",
                        k ? "HDR" : "display", v->w, v->h);
  float mvp[16], inv[16], eye[3], facing;
  if (cvr_view_matrices(v, mvp, inv, eye, &facing))
    return cv_err_set(err, CV_ERR_INVALID, "view: singular projection");
  if (cv_egl_make_current(c->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  cvr_gl_check("(before shade)", NULL);
  cvr_scene_cull(c, in->sc, 1);
  const int ss = v->supersample, W = v->w * ss, H = v->h * ss;
  const int draw_hdr = out_hdr || out_lum;
  int flags = (want_disp ? F_DISP : 0) | (draw_hdr ? F_HDR : 0) |
              (want_disp && transfer ? F_TRANSFER : 0);
  if (want_disp) {
    tone_table(c, &ps->tone, dc);
    if (!ps->tone.ok) flags |= F_EXACT;
  }
  GLuint pg, pb, pn = 0;
  const int split = in->lt->has_sun && in->lt->sun_split,
            panel = (in->lt->panel.on ? F_PANEL : 0) | (in->tx->tex ? F_TEX : 0);
  if ((st = ensure_main(&ps->targets, W, H, disp_fmt(c, 0, ss), err)) || (ss > 1 && (st = ensure_res(c, &ps->targets, v->w, v->h, err))) ||
      (st = variant(ps, K_PRT, flags | (in->lt->has_sun ? F_SUN : 0) | panel, &pg, err)) ||
      (split && (st = variant(ps, K_PRT, flags | panel, &pn, err))) ||
      (st = variant(ps, K_BG, flags, &pb, err)))
    return st;
  double t0 = cvr_tick(c);
  depth_pass(c, ps, in->sc, mvp, W, H);
  double t1 = cvr_tick(c);
  const GLenum bufs[2] = {want_disp ? GL_COLOR_ATTACHMENT0 : GL_NONE,
                          draw_hdr ? GL_COLOR_ATTACHMENT1 : GL_NONE};
  glDrawBuffers(2, bufs);
  if (c->o->debug_clear) {
    const float sentinel[4] = {-1, -1, -1, -1};
    for (int k = 0; k < 2; k++)
      if (bufs[k] != GL_NONE) glClearBufferfv(GL_COLOR, k, sentinel);
  }
  depth_state(c);
  bind_shading(ps, in, pg, mvp, inv, facing, dc);
  if (split) {
    cvr_scene_draw(c, in->sc, mvp, DRAW_SUNLIT);
    bind_shading(ps, in, pn, mvp, inv, facing, dc);
    cvr_scene_draw(c, in->sc, mvp, DRAW_UNSUNLIT);
  } else {
    cvr_scene_draw(c, in->sc, mvp, DRAW_ALL);
  }
  double t2 = cvr_tick(c);
  glDepthFunc(GL_LEQUAL);
  glDepthMask(GL_FALSE);
  bind_shading(ps, in, pb, mvp, inv, facing, dc);
  cvr_draw_fullscreen(c);
  double t3 = cvr_tick(c);
  GLuint read_fbo = ps->targets.fbo_main;
  if (ss > 1) {
    glBindFramebuffer(GL_FRAMEBUFFER, ps->targets.fbo_res);
    glViewport(0, 0, v->w, v->h);
    glDisable(GL_DEPTH_TEST);
    glUseProgram(ps->prog_down);
    glActiveTexture(GL_TEXTURE0 + U_SRC);
    for (int k = 0; k < 2; k++) {
      if (!outs[k] && !(k == 0 && keep)) continue;
      glDrawBuffer(GL_COLOR_ATTACHMENT0 + k);
      glBindTexture(GL_TEXTURE_2D, k ? ps->targets.tex_hdr : ps->targets.tex_disp);
      cvr_draw_fullscreen(c);
    }
    glEnable(GL_DEPTH_TEST);
    read_fbo = ps->targets.fbo_res;
  }
  double t4 = cvr_tick(c);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, read_fbo);
  for (int k = 0; k < 2; k++)
    if (outs[k] && cvr_read_image(c, GL_COLOR_ATTACHMENT0 + k, k == 0 && !c->o->display_float, outs[k]))
      return cv_err_set(err, CV_ERR_NOMEM, "out of memory reading back");
  double t5 = cvr_tick(c);
  if ((st = cvr_gl_check("shading pass", err))) return st;
  if (want_disp) { /* where the display image now is (render_post.c reads it) */
    ps->disp.tex = ss > 1 ? ps->targets.tex_res_disp : ps->targets.tex_disp;
    ps->disp.fbo = read_fbo;
    ps->disp.w = v->w, ps->disp.h = v->h;
    ps->disp.is_float = (ss > 1 ? ps->targets.res_fmt : ps->targets.main_fmt) == GL_RGBA32F;
  }
  double t6 = t5;
  if (gpu_stats) {
    if ((st = cvr_reduce_luminance(c, ps, v->w, v->h, ss, out_lum, max_y, n_invalid, err))) return st;
    t6 = cvr_tick(c);
  } else if (out_lum) {
    const double c0 = cvr_now_ms();
    double mx = 0;
    uint64_t bad = 0;
    cv_lum_downsample(out_hdr, out_lum, &mx, &bad);
    if (max_y) *max_y = mx;
    if (n_invalid) *n_invalid = bad;
    t6 = t5 + (c->o->timing ? cvr_now_ms() - c0 : 0); /* wall ms of the CPU's work */
  }
  if (t) {
    t->depth_ms = t1 - t0;
    t->shade_ms = t2 - t1;
    t->background_ms = t3 - t2;
    t->resolve_ms = t4 - t3;
    t->read_ms = t5 - t4;
    if (out_lum) t->lum_ms = t6 - t5, t->lum_read_ms = 0;
  }
  return CV_OK;
}




int cvr_passes_unlit(cvr_ctx *c, cvr_passes *ps, const cvr_inputs *in, const cv_render_view *v, cv_image *out,
                     cv_frame_timing *t, cv_err *err) {
  int st = check_view(c, in->lt, v, err);
  if (st) return st;
  if (out && (out->c != 3 || out->w != v->w || out->h != v->h || v->supersample != 1))
    return cv_err_set(err, CV_ERR_INVALID, "unlit: image must be %dx%d RGB, no supersampling", v->w,
                      v->h);
  float mvp[16], inv[16], eye[3], facing;
  if (cvr_view_matrices(v, mvp, inv, eye, &facing))
    return cv_err_set(err, CV_ERR_INVALID, "view: singular projection");
  if (cv_egl_make_current(c->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  cvr_gl_check("(before unlit)", NULL);
  cvr_scene_cull(c, in->sc, 1);
  const int W = v->w * v->supersample, H = v->h * v->supersample;
  if ((st = ensure_main(&ps->targets, W, H, disp_fmt(c, 0, v->supersample), err))) return st;
  double t0 = cvr_tick(c);
  depth_pass(c, ps, in->sc, mvp, W, H);
  double t1 = cvr_tick(c);
  glDrawBuffer(GL_COLOR_ATTACHMENT0);
  depth_state(c);
  glUseProgram(ps->prog_unlit);
  cvr_uni_mat(ps->prog_unlit, "u_mvp", mvp);
  cvr_scene_draw(c, in->sc, mvp, DRAW_ALL);
  double t2 = cvr_tick(c);
  if (out) {
    glBindFramebuffer(GL_READ_FRAMEBUFFER, ps->targets.fbo_main);
    if (cvr_read_image(c, GL_COLOR_ATTACHMENT0, !c->o->display_float, out))
      return cv_err_set(err, CV_ERR_NOMEM, "out of memory reading back");
  }
  double t3 = cvr_tick(c);
  if ((st = cvr_gl_check("unlit pass", err))) return st;
  if (t) {
    t->depth_ms = t1 - t0;
    t->unlit_ms = t2 - t1;
    t->read_ms = t3 - t2;
  }
  return CV_OK;
}


int cvr_lum_stats_gpu(const cvr_ctx *c) {
  return c->o->lum_stats_gpu < 0 ? !c->egl->software : c->o->lum_stats_gpu != 0;
}

int cvr_passes_init(cvr_passes *ps, cv_err *err) {
  int st;
  if ((st = cvr_build("geom.vert", "unlit.frag", "", NULL, &ps->prog_unlit, err)) ||
      (st = cvr_build("fullscreen.vert", "downsample.frag", "", NULL, &ps->prog_down, err)) ||
      (st = cvr_build("fullscreen.vert", "lum_reduce.frag", "", NULL, &ps->prog_lumred, err)) ||
      (st = cvr_build("fullscreen.vert", "lum_block.frag", "", NULL, &ps->prog_lumblk, err)))
    return st;
  return CV_OK;
}

void cvr_passes_free(cvr_passes *ps) {
  cvr_targets *r = &ps->targets;
  GLuint tex[] = {r->tex_disp, r->tex_hdr, r->tex_res_disp, r->tex_red_mb, ps->tone.tex};
  glDeleteTextures(5, tex);
  GLuint rbs[] = {r->rb_lum, r->rb_lum_depth, r->rb_depth, r->rb_res_hdr, r->rb_red, r->rb_blk};
  glDeleteRenderbuffers(6, rbs);
  GLuint fbos[] = {r->fbo_lum, r->fbo_main, r->fbo_res, r->fbo_red, r->fbo_blk};
  glDeleteFramebuffers(5, fbos);
  glDeleteBuffers(1, &ps->tone.buf);
  GLuint progs[] = {ps->prog_unlit, ps->prog_down, ps->prog_lumred, ps->prog_lumblk};
  for (int i = 0; i < 4; i++) glDeleteProgram(progs[i]);
  for (int k = 0; k < 2; k++)
    for (int f = 0; f < NVARIANT; f++) glDeleteProgram(ps->prog_var[k][f]);
}

void cvr_passes_free_cpu(cvr_passes *ps) {
  free(ps->targets.red_cpu);
  ps->targets.red_cpu = NULL;
  cv_image_destroy(ps->targets.hdr_scratch);
  ps->targets.hdr_scratch = NULL;
}
