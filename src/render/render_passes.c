/* The renderer's targets and passes: luminance, depth, PRT shading with
 * Drago tables, resolve, read-back, and the unlit reference (see renderer.h). */
#include "render/renderer_internal.h"

/* ---------------------------------------------------------------- targets */

GLuint cvr_make_rb(GLenum fmt, int w, int h) {
  GLuint rb;
  glGenRenderbuffers(1, &rb);
  glBindRenderbuffer(GL_RENDERBUFFER, rb);
  glRenderbufferStorage(GL_RENDERBUFFER, fmt, w, h);
  glBindRenderbuffer(GL_RENDERBUFFER, 0);
  return rb;
}

GLuint cvr_make_tex(GLenum fmt, int w, int h) {
  GLuint t;
  glGenTextures(1, &t);
  glBindTexture(GL_TEXTURE_2D, t);
  glTexImage2D(GL_TEXTURE_2D, 0, fmt, w, h, 0, GL_RGBA, GL_FLOAT, NULL);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glBindTexture(GL_TEXTURE_2D, 0);
  return t;
}

int cvr_fbo_complete(const char *what, int w, int h, cv_err *err) {
  GLenum s = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (s == GL_FRAMEBUFFER_COMPLETE) return CV_OK;
  return cv_err_set(err, CV_ERR_BACKEND, "%s framebuffer %dx%d incomplete (0x%04x)", what, w, h,
                    (unsigned)s);
}

int cvr_ensure_lum(cv_renderer *r, int w, int h, cv_err *err) {
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
GLenum cvr_disp_fmt(const cv_renderer *r, int resolve_target, int ss) {
  return r->o.display_float || (!resolve_target && ss > 1) ? GL_RGBA32F : GL_RGBA8;
}

int cvr_ensure_main(cv_renderer *r, int w, int h, GLenum dfmt, cv_err *err) {
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
int cvr_ensure_res(cv_renderer *r, int w, int h, cv_err *err) {
  const GLenum fmt = cvr_disp_fmt(r, 1, 1);
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

/* Reads attachment `att` of the bound read framebuffer into img (c = 1 or
 * 3), flipping GL's bottom-up rows to the image's top-down order.  An 8-bit
 * target (is8) is read as bytes and converted (k/255). */
int cvr_read_image(cv_renderer *r, GLenum att, int is8, cv_image *img) {
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
    r->io_read += need;
    for (int y = 0; y < img->h; y++) {
      const uint8_t *src = r->rgba8 + (size_t)(img->h - 1 - y) * img->w * 4;
      float *dst = img->px + (size_t)y * row;
      for (int x = 0; x < img->w; x++)
        for (int c = 0; c < 3; c++) dst[3 * x + c] = src[4 * x + c] * (1.0f / 255.0f);
    }
    return CV_OK;
  }
  glReadPixels(0, 0, img->w, img->h, img->c == 1 ? GL_RED : GL_RGB, GL_FLOAT, img->px);
  r->io_read += (size_t)img->w * img->h * (img->c == 1 ? 1 : 3) * sizeof(float);
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

/* Face culling of the view passes (opts.cull_back; -1: on a closed mesh);
 * the shadow map draws both sides (or, culled, the part facing away from
 * the sun). */
void cvr_set_cull(const cv_renderer *r, int on) {
  if (on && (r->o.cull_back < 0 ? r->closed : r->o.cull_back)) {
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
  } else {
    glDisable(GL_CULL_FACE);
  }
}

int cvr_check_view(const cv_renderer *r, const cv_render_view *v, cv_err *err) {
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
void cvr_bind_shading(const cv_renderer *r, GLuint p, const float mvp[16], const float inv[16],
                         float facing, const cv_drago_consts *dc) {
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
    cvr_uni_f(p, "u_lut_k", r->lut_k);
    cvr_uni_f(p, "u_lut_tail", r->lut_tail);
    glActiveTexture(GL_TEXTURE0 + U_TONE);
    glBindTexture(GL_TEXTURE_BUFFER, r->tex_tone);
  }
  if (r->panel_on) {
    cvr_uni_v3(p, "u_panel_c", r->panel_c);
    cvr_uni_v3(p, "u_panel_u", r->panel_u);
    cvr_uni_v3(p, "u_panel_v", r->panel_v);
    cvr_uni_v3(p, "u_panel_n", r->panel_n);
    GLint loc = glGetUniformLocation(p, "u_panel_half");
    if (loc >= 0) glUniform2f(loc, r->panel_half[0], r->panel_half[1]);
    glActiveTexture(GL_TEXTURE0 + U_PANEL);
    glBindTexture(GL_TEXTURE_2D, r->tex_panel);
  }
  if (r->has_sun) {
    cvr_uni_mat(p, "u_shadow_q", r->shadow_q);
    GLint loc = glGetUniformLocation(p, "u_shadow_k");
    if (loc >= 0) glUniform4fv(loc, 1, r->shadow_k);
    loc = glGetUniformLocation(p, "u_shadow_size");
    if (loc >= 0) glUniform2i(loc, r->shadow_w, r->shadow_h);
    cvr_uni_v3(p, "u_sun_e", r->sun_e);
    cvr_uni_f(p, "u_shadow_bias", r->shadow_bias);
    cvr_uni_f(p, "u_sigma", facing * (float)r->shadow_detsign);
  }
  if (r->tex_albedo) {
    glActiveTexture(GL_TEXTURE0 + U_ALBEDO);
    glBindTexture(GL_TEXTURE_2D_ARRAY, r->tex_albedo);
  }
  glActiveTexture(GL_TEXTURE0 + U_SHADOW);
  glBindTexture(GL_TEXTURE_2D, r->shadow_from_import ? r->tex_shadow_imp : r->tex_shadow);
  glActiveTexture(GL_TEXTURE0 + U_BG);
  glBindTexture(GL_TEXTURE_2D, r->tex_bg);
}

/* ------------------------------------------------------- tone tables */

/* Drago's raw curve (cv_drago_map below Lwmax, before the clamp) at
 * y = x / Lwmax', in double from the float constants as the CPU does. */
double cvr_drago_raw(const cv_drago_consts *c, double y) {
  double x = y * (double)c->lwmax_a;
  return (double)c->scale * log1p(x) / log(2.0 + 8.0 * pow(y, (double)c->p_exp));
}

/* Fills nseg texels (4 floats each) with the cubic through the curve at
 * f = 0, 1/3, 2/3, 1 of each segment (arguments 2^(e0 + j/16 - 127) * (1 +
 * (j%16 + f)/16)); continuous across segments.  Returns the largest error
 * at f = 1/6, 1/2, 5/6 of the float cubic evaluated as the shader does,
 * |p - curve| / max(|curve|, floor).  (Cubic interpolation error ~ h^4: a
 * 1/16 octave keeps it near float rounding, ~1e-7.) */
double cvr_fit_table(double (*fn)(const cv_drago_consts *, double), const cv_drago_consts *c,
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
void cvr_tone_table(cv_renderer *r, const cv_drago_consts *dc) {
  if (r->tone_built && !memcmp(&r->tone_dc, dc, sizeof *dc)) return;
  float *buf = malloc(4 * LUT_DRAGO_SEGS * sizeof *buf);
  if (!buf) {
    r->tone_ok = 0; /* the exact variant needs no table */
    return;
  }
  r->tone_err = cvr_fit_table(cvr_drago_raw, dc, LUT_DRAGO_E0, LUT_DRAGO_SEGS, 1e-4, buf);
  const double ylo = ldexp(1.0, -126);
  r->lut_tail = (float)(cvr_drago_raw(dc, ylo) / ylo);
  r->lut_k = (float)(1.0 / ((double)dc->lwa * (double)dc->lwmax_a));
  r->tone_ok = !r->o.tone_exact && r->tone_err <= LUT_TOL && isfinite(r->lut_tail) &&
               isfinite(r->lut_k);
  if (!r->buf_tone) {
    r->tex_tone = cvr_make_tbo(&r->buf_tone, GL_RGBA32F, buf, 4 * LUT_DRAGO_SEGS * sizeof *buf);
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
int cvr_box_outside(const float mvp[16], const float *lo, const float *hi) {
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
 * split; DRAW_SHADOW those facing away or near grazing: the culled shadow
 * map), in one glMultiDrawElements.  Every pass of a view submits the same
 * triangles, which the depth-EQUAL pass relies on.  Returns the triangles
 * submitted. */
size_t cvr_draw_mesh(cv_renderer *r, const float *mvp, int part) {
  size_t nrun = 0, ntri = 0;
  for (size_t c = 0; c < r->nchunks; c++) {
    if (mvp && r->o.cull_frustum && cvr_box_outside(mvp, r->chunk_box + 6 * c, r->chunk_box + 6 * c + 3))
      continue;
    uint32_t first = (uint32_t)(c * CHUNK), n = (uint32_t)((c + 1) * CHUNK > r->nt ? r->nt - c * CHUNK : CHUNK);
    if (part == DRAW_SUNLIT) {
      n = r->chunk_nf[c];
    } else if (part == DRAW_UNSUNLIT) {
      first += r->chunk_nf[c];
      n -= r->chunk_nf[c];
    } else if (part == DRAW_SHADOW) {
      first += r->chunk_na[c];
      n -= r->chunk_na[c];
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

void cvr_draw_fullscreen(const cv_renderer *r) {
  glBindVertexArray(r->vao_empty);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glBindVertexArray(0);
}

int cv_renderer_luminance(cv_renderer *r, const cv_render_view *v, cv_image *out,
                          cv_frame_timing *t, cv_err *err) {
  int st = cvr_check_view(r, v, err);
  if (st) return st;
  if (!out || out->c != 1 || out->w < 1 || out->h < 1 || out->w > r->max_rb || out->h > r->max_rb)
    return cv_err_set(err, CV_ERR_INVALID, "luminance image: expected 1 channel, 1..%d pixels",
                      (int)r->max_rb);
  float mvp[16], inv[16], eye[3], facing;
  if (cvr_view_matrices(v, mvp, inv, eye, &facing))
    return cv_err_set(err, CV_ERR_INVALID, "view: singular projection");
  if (cv_egl_make_current(&r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  cvr_gl_check("(before luminance)", NULL);
  cvr_set_cull(r, 1);
  double t0 = cvr_tick(r);
  if ((st = cvr_ensure_lum(r, out->w, out->h, err))) return st;
  GLuint pg, pb, pn = 0;
  const int split = r->has_sun && r->sun_split,
            panel = (r->panel_on ? F_PANEL : 0) | (r->tex_albedo ? F_TEX : 0);
  if ((st = cvr_variant(r, K_PRT, F_LUM | (r->has_sun ? F_SUN : 0) | panel, &pg, err)) ||
      (split && (st = cvr_variant(r, K_PRT, F_LUM | panel, &pn, err))) ||
      (st = cvr_variant(r, K_BG, F_LUM, &pb, err)))
    return st;
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_lum);
  glDrawBuffer(GL_COLOR_ATTACHMENT0);
  glViewport(0, 0, out->w, out->h);
  glEnable(GL_DEPTH_TEST);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_LESS);
  glClear(GL_DEPTH_BUFFER_BIT);
  cvr_bind_shading(r, pg, mvp, inv, facing, NULL);
  if (split) {
    cvr_draw_mesh(r, mvp, DRAW_SUNLIT);
    cvr_bind_shading(r, pn, mvp, inv, facing, NULL);
    cvr_draw_mesh(r, mvp, DRAW_UNSUNLIT);
  } else {
    cvr_draw_mesh(r, mvp, DRAW_ALL);
  }
  glDepthMask(GL_FALSE);
  glDepthFunc(GL_LEQUAL);
  cvr_bind_shading(r, pb, mvp, inv, facing, NULL);
  cvr_draw_fullscreen(r);
  double t1 = cvr_tick(r);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, r->fbo_lum);
  cvr_read_image(r, GL_COLOR_ATTACHMENT0, 0, out);
  double t2 = cvr_tick(r);
  if ((st = cvr_gl_check("luminance pass", err))) return st;
  if (t) {
    t->lum_ms = t1 - t0;
    t->lum_read_ms = t2 - t1;
  }
  return CV_OK;
}

/* Depth pre-pass into fbo_main (W x H). */
void cvr_depth_pass(cv_renderer *r, const float mvp[16], int W, int H) {
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
  cvr_uni_mat(r->prog_depth, "u_mvp", mvp);
  cvr_draw_mesh(r, mvp, DRAW_ALL);
  glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
}

/* Depth state of the pass after the pre-pass: EQUAL without writes, or the
 * single-pass reference (opts.depth_less). */
void cvr_shading_depth_state(const cv_renderer *r) {
  glDepthFunc(r->o.depth_less ? GL_LESS : GL_EQUAL);

  glDepthMask(r->o.depth_less ? GL_TRUE : GL_FALSE);
}

/* Targets of the luminance statistics for a w x h luminance image: the
 * image (R32F) and the (max, invalid) pairs (RG32F texture), then those
 * pairs in blocks of LUM_BLOCK^2. */
#define LUM_BLOCK 8
static int ensure_reduce(cv_renderer *r, int w, int h, cv_err *err) {
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
 * ss x ss texels; r->tex_hdr) into lum (lum_reduce.frag, then
 * lum_block.frag): the luminance image and the (max, invalid) pairs of
 * LUM_BLOCK^2 blocks come back (4 bytes a luminance pixel + 8 a block), the
 * max and the count finished on the CPU. */
int cvr_reduce_luminance(cv_renderer *r, int W, int H, int ss, cv_image *lum, double *max_y,
                         uint64_t *n_invalid, cv_err *err) {
  const int w = lum->w, h = lum->h;
  int st = ensure_reduce(r, w, h, err);
  if (st) return st;
  static const GLenum bufs[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_red);
  glDrawBuffers(2, bufs);
  glViewport(0, 0, w, h);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_CULL_FACE);
  GLuint p = r->prog_lumred;
  glUseProgram(p);
  glUniform2i(glGetUniformLocation(p, "u_size"), W, H);
  glUniform2i(glGetUniformLocation(p, "u_out"), w, h);
  glUniform1i(glGetUniformLocation(p, "u_ss"), ss);
  glActiveTexture(GL_TEXTURE0 + U_SRC);
  glBindTexture(GL_TEXTURE_2D, r->tex_hdr);
  cvr_draw_fullscreen(r);
  const int bw = (w + LUM_BLOCK - 1) / LUM_BLOCK, bh = (h + LUM_BLOCK - 1) / LUM_BLOCK;
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_blk);
  glDrawBuffer(GL_COLOR_ATTACHMENT0);
  glViewport(0, 0, bw, bh);
  p = r->prog_lumblk;
  glUseProgram(p);
  glUniform2i(glGetUniformLocation(p, "u_size"), w, h);
  glUniform1i(glGetUniformLocation(p, "u_block"), LUM_BLOCK);
  glBindTexture(GL_TEXTURE_2D, r->tex_red_mb);
  cvr_draw_fullscreen(r);
  glEnable(GL_DEPTH_TEST);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, r->fbo_red);
  cvr_read_image(r, GL_COLOR_ATTACHMENT0, 0, lum);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, r->fbo_blk);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glReadPixels(0, 0, bw, bh, GL_RG, GL_FLOAT, r->red_cpu);
  r->io_read += 2 * (size_t)bw * bh * sizeof(float);
  double mx = 0, bad = 0;
  for (size_t i = 0; i < (size_t)bw * bh; i++) {
    if (r->red_cpu[2 * i] > mx) mx = r->red_cpu[2 * i];
    bad += r->red_cpu[2 * i + 1];
  }
  if (max_y) *max_y = mx;
  if (n_invalid) *n_invalid = (uint64_t)bad;
  return cvr_gl_check("luminance statistics", err);
}

int cv_renderer_shade(cv_renderer *r, const cv_render_view *v, const cv_drago_consts *dc,
                      int transfer, cv_image *out_display, cv_image *out_hdr, cv_frame_timing *t,
                      cv_err *err) {
  return cv_renderer_shade_stats(r, v, dc, transfer, out_display, out_hdr, NULL, NULL, NULL, t, err);
}

/* cv_renderer_shade_stats, and with `keep` the display image drawn and
 * left on the GPU (cv_renderer_shade_gpu) instead of read back. */
static int shade(cv_renderer *r, const cv_render_view *v, const cv_drago_consts *dc, int transfer,
                 cv_image *out_display, int keep, cv_image *out_hdr, cv_image *out_lum, double *max_y,
                 uint64_t *n_invalid, cv_frame_timing *t, cv_err *err) {
  int st = cvr_check_view(r, v, err);
  if (st) return st;
  if (keep && !r->o.display_float)
    return cv_err_set(err, CV_ERR_INVALID, "shade: a display image kept on the GPU needs opts.display_float");
  const int want_disp = out_display || keep;
  const int gpu_stats = out_lum && (keep || cv_renderer_lum_stats_on_gpu(r));
  if (out_lum && !gpu_stats && !out_hdr) {
    /* statistics on the CPU: the HDR image is read back into scratch */
    if (!r->hdr_scratch || r->hdr_scratch->w != v->w || r->hdr_scratch->h != v->h) {
      cv_image_destroy(r->hdr_scratch);
      r->hdr_scratch = NULL;
      if (cv_image_create(v->w, v->h, 3, &r->hdr_scratch))
        return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
    }
    out_hdr = r->hdr_scratch;
  }
  if (!want_disp && !out_hdr && !out_lum)
    return cv_err_set(err, CV_ERR_INVALID, "shade: no output image");
  if (out_lum && (out_lum->c != 1 || out_lum->w < 1 || out_lum->h < 1 || !out_lum->px ||
                  out_lum->w > r->max_rb || out_lum->h > r->max_rb))
    return cv_err_set(err, CV_ERR_INVALID, "shade: the luminance image must be 1 channel, 1..%d pixels a side",
                      (int)r->max_rb);
  if (want_disp && !dc) return cv_err_set(err, CV_ERR_INVALID, "shade: display output needs Drago constants");
  cv_image *outs[2] = {out_display, out_hdr};
  for (int k = 0; k < 2; k++)
    if (outs[k] && (outs[k]->c != 3 || outs[k]->w != v->w || outs[k]->h != v->h || !outs[k]->px))
      return cv_err_set(err, CV_ERR_INVALID, "shade: %s image must be %dx%d RGB",
                        k ? "HDR" : "display", v->w, v->h);
  float mvp[16], inv[16], eye[3], facing;
  if (cvr_view_matrices(v, mvp, inv, eye, &facing))
    return cv_err_set(err, CV_ERR_INVALID, "view: singular projection");
  if (cv_egl_make_current(&r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  cvr_gl_check("(before shade)", NULL);
  cvr_set_cull(r, 1);
  const int ss = v->supersample, W = v->w * ss, H = v->h * ss;
  const int draw_hdr = out_hdr || out_lum;
  int flags = (want_disp ? F_DISP : 0) | (draw_hdr ? F_HDR : 0) |
              (want_disp && transfer ? F_TRANSFER : 0);
  if (want_disp) {
    cvr_tone_table(r, dc);
    if (!r->tone_ok) flags |= F_EXACT;
  }
  GLuint pg, pb, pn = 0;
  const int split = r->has_sun && r->sun_split,
            panel = (r->panel_on ? F_PANEL : 0) | (r->tex_albedo ? F_TEX : 0);
  if ((st = cvr_ensure_main(r, W, H, cvr_disp_fmt(r, 0, ss), err)) || (ss > 1 && (st = cvr_ensure_res(r, v->w, v->h, err))) ||
      (st = cvr_variant(r, K_PRT, flags | (r->has_sun ? F_SUN : 0) | panel, &pg, err)) ||
      (split && (st = cvr_variant(r, K_PRT, flags | panel, &pn, err))) ||
      (st = cvr_variant(r, K_BG, flags, &pb, err)))
    return st;
  double t0 = cvr_tick(r);
  cvr_depth_pass(r, mvp, W, H);
  double t1 = cvr_tick(r);
  const GLenum bufs[2] = {want_disp ? GL_COLOR_ATTACHMENT0 : GL_NONE,
                          draw_hdr ? GL_COLOR_ATTACHMENT1 : GL_NONE};
  glDrawBuffers(2, bufs);
  if (r->o.debug_clear) {
    const float sentinel[4] = {-1, -1, -1, -1};
    for (int k = 0; k < 2; k++)
      if (bufs[k] != GL_NONE) glClearBufferfv(GL_COLOR, k, sentinel);
  }
  cvr_shading_depth_state(r);
  cvr_bind_shading(r, pg, mvp, inv, facing, dc);
  if (split) {
    cvr_draw_mesh(r, mvp, DRAW_SUNLIT);
    cvr_bind_shading(r, pn, mvp, inv, facing, dc);
    cvr_draw_mesh(r, mvp, DRAW_UNSUNLIT);
  } else {
    cvr_draw_mesh(r, mvp, DRAW_ALL);
  }
  double t2 = cvr_tick(r);
  glDepthFunc(GL_LEQUAL);
  glDepthMask(GL_FALSE);
  cvr_bind_shading(r, pb, mvp, inv, facing, dc);
  cvr_draw_fullscreen(r);
  double t3 = cvr_tick(r);
  GLuint read_fbo = r->fbo_main;
  if (ss > 1) {
    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_res);
    glViewport(0, 0, v->w, v->h);
    glDisable(GL_DEPTH_TEST);
    glUseProgram(r->prog_down);
    glActiveTexture(GL_TEXTURE0 + U_SRC);
    for (int k = 0; k < 2; k++) {
      if (!outs[k] && !(k == 0 && keep)) continue;
      glDrawBuffer(GL_COLOR_ATTACHMENT0 + k);
      glBindTexture(GL_TEXTURE_2D, k ? r->tex_hdr : r->tex_disp);
      cvr_draw_fullscreen(r);
    }
    glEnable(GL_DEPTH_TEST);
    read_fbo = r->fbo_res;
  }
  double t4 = cvr_tick(r);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, read_fbo);
  for (int k = 0; k < 2; k++)
    if (outs[k] && cvr_read_image(r, GL_COLOR_ATTACHMENT0 + k, k == 0 && !r->o.display_float, outs[k]))
      return cv_err_set(err, CV_ERR_NOMEM, "out of memory reading back");
  double t5 = cvr_tick(r);
  if ((st = cvr_gl_check("shading pass", err))) return st;
  if (want_disp) { /* where the display image now is (render_post.c reads it) */
    r->disp_src = ss > 1 ? r->tex_res_disp : r->tex_disp;
    r->disp_fbo = read_fbo;
    r->disp_w = v->w, r->disp_h = v->h;
    r->disp_float = (ss > 1 ? r->res_fmt : r->main_fmt) == GL_RGBA32F;
  }
  double t6 = t5;
  if (gpu_stats) {
    if ((st = cvr_reduce_luminance(r, v->w, v->h, ss, out_lum, max_y, n_invalid, err))) return st;
    t6 = cvr_tick(r);
  } else if (out_lum) {
    const double c0 = cvr_now_ms();
    double mx = 0;
    uint64_t bad = 0;
    cv_lum_downsample(out_hdr, out_lum, &mx, &bad);
    if (max_y) *max_y = mx;
    if (n_invalid) *n_invalid = bad;
    t6 = t5 + (r->o.timing ? cvr_now_ms() - c0 : 0); /* wall ms of the CPU's work */
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

int cv_renderer_shade_stats(cv_renderer *r, const cv_render_view *v, const cv_drago_consts *dc,
                            int transfer, cv_image *out_display, cv_image *out_hdr,
                            cv_image *out_lum, double *max_y, uint64_t *n_invalid,
                            cv_frame_timing *t, cv_err *err) {
  return shade(r, v, dc, transfer, out_display, 0, out_hdr, out_lum, max_y, n_invalid, t, err);
}

int cv_renderer_shade_gpu(cv_renderer *r, const cv_render_view *v, const cv_drago_consts *dc,
                          cv_image *out_hdr, cv_image *out_lum, double *max_y, uint64_t *n_invalid,
                          cv_frame_timing *t, cv_err *err) {
  return shade(r, v, dc, 0, NULL, 1, out_hdr, out_lum, max_y, n_invalid, t, err);
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
  int st = cvr_check_view(r, v, err);
  if (st) return st;
  if (out && (out->c != 3 || out->w != v->w || out->h != v->h || v->supersample != 1))
    return cv_err_set(err, CV_ERR_INVALID, "unlit: image must be %dx%d RGB, no supersampling", v->w,
                      v->h);
  float mvp[16], inv[16], eye[3], facing;
  if (cvr_view_matrices(v, mvp, inv, eye, &facing))
    return cv_err_set(err, CV_ERR_INVALID, "view: singular projection");
  if (cv_egl_make_current(&r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  cvr_gl_check("(before unlit)", NULL);
  cvr_set_cull(r, 1);
  const int W = v->w * v->supersample, H = v->h * v->supersample;
  if ((st = cvr_ensure_main(r, W, H, cvr_disp_fmt(r, 0, v->supersample), err))) return st;
  double t0 = cvr_tick(r);
  cvr_depth_pass(r, mvp, W, H);
  double t1 = cvr_tick(r);
  glDrawBuffer(GL_COLOR_ATTACHMENT0);
  cvr_shading_depth_state(r);
  glUseProgram(r->prog_unlit);
  cvr_uni_mat(r->prog_unlit, "u_mvp", mvp);
  cvr_draw_mesh(r, mvp, DRAW_ALL);
  double t2 = cvr_tick(r);
  if (out) {
    glBindFramebuffer(GL_READ_FRAMEBUFFER, r->fbo_main);
    if (cvr_read_image(r, GL_COLOR_ATTACHMENT0, !r->o.display_float, out))
      return cv_err_set(err, CV_ERR_NOMEM, "out of memory reading back");
  }
  double t3 = cvr_tick(r);
  if ((st = cvr_gl_check("unlit pass", err))) return st;
  if (t) {
    t->depth_ms = t1 - t0;
    t->unlit_ms = t2 - t1;
    t->read_ms = t3 - t2;
  }
  return CV_OK;
}

