/* The renderer's lighting (render_light.h): a lighting change (the relight
 * of render_relight.c, the sun split of the scene's chunks, the sun's
 * shadow map of the casters or the mesh), the background and the
 * dashboard LCD image (see renderer.h). */
#include "render/render_light.h"

#include "sh/sh.h"

/* ---------------------------------------------------------------- lighting */

/* a . p, for a vertex or a box corner (one expression: the same rounding) */
static double along(const double a[3], const float p[3]) { return a[0] * p[0] + a[1] * p[1] + a[2] * p[2]; }

/* The largest a . p over the vertices of chunk c's triangles. */
static double chunk_max(const cvr_scene *r, size_t c, const double a[3]) {
  const size_t first = c * CHUNK, end = first + CHUNK > r->nt ? r->nt : first + CHUNK;
  double m = -INFINITY;
  for (size_t i = 3 * first; i < 3 * end; i++) m = fmax(m, along(a, r->pos_cpu + 3 * r->idx_cpu[i]));
  return m;
}

/* An upper bound of a . p over chunk c's vertices: its box's corner on a's side. */
static double box_bound(const cvr_scene *r, size_t c, const double a[3]) {
  const float *b = r->chunk_box + 6 * c;
  const float corner[3] = {a[0] >= 0 ? b[3] : b[0], a[1] >= 0 ? b[4] : b[1], a[2] >= 0 ? b[5] : b[2]};
  return along(a, corner);
}

/* The largest a . p over the vertices of the opaque triangles (the first
 * nv_used), exactly, visiting only the chunks whose boxes could hold it:
 * a chunk's box bounds its vertices' a . p from above (its corner on a's
 * side), so after the chunk of the largest bound, only chunks whose bound
 * reaches the maximum so far are read (a few of the 500 on the cabin). */
static double extent_max(const cvr_scene *r, const double a[3]) {
  double best_bound = -INFINITY, m = -INFINITY;
  size_t best = 0;
  for (size_t c = 0; c < r->nchunks; c++) {
    const double u = box_bound(r, c, a);
    if (u > best_bound) best_bound = u, best = c;
  }
  if (r->nchunks) m = chunk_max(r, best, a);
  for (size_t c = 0; c < r->nchunks; c++)
    if (c != best && box_bound(r, c, a) >= m - 1e-9 * (1 + fabs(m))) m = fmax(m, chunk_max(r, c, a));
  return m;
}

/* The range of a . p over the opaque triangles' vertices (extent_max). */
static void vertex_extent(const cvr_scene *r, const double a[3], double *lo, double *hi) {
  const double na[3] = {-a[0], -a[1], -a[2]};
  *hi = extent_max(r, a);
  *lo = -extent_max(r, na);
}

/* Orthographic sun view over the scene bounds: clip matrix for rendering
 * the shadow map, and for the lookup (prt.frag) the texel-space matrix
 * shadow_q, its axis scales shadow_k and the sign of its determinant.  The
 * texels are square, the beam's longer side over opts.shadow_res; the map
 * takes size[0] x size[1] of them (the shorter side fewer: on llvmpipe the
 * clear and the fill cost by the texel). */
void cvr_sun_matrices(const cvr_ctx *c, cvr_shadow *sh, const cvr_scene *r, const double s[3],
                      float clip[16], float *texel, int size[2]) {
  double up[3] = {0, 1, 0};
  if (fabs(s[1]) > 0.99) up[0] = 1, up[1] = 0;
  double x[3] = {up[1] * s[2] - up[2] * s[1], up[2] * s[0] - up[0] * s[2],
                 up[0] * s[1] - up[1] * s[0]};
  double xl = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
  for (int j = 0; j < 3; j++) x[j] /= xl;
  double y[3] = {s[1] * x[2] - s[2] * x[1], s[2] * x[0] - s[0] * x[2], s[0] * x[1] - s[1] * x[0]};
  /* Axes: x, y across the beam; depth = distance along -s (away from the sun). */
  double axis[3][3] = {{x[0], x[1], x[2]}, {y[0], y[1], y[2]}, {-s[0], -s[1], -s[2]}};
  /* Fitted to the vertices of the opaque triangles, not to the corners of
   * their box: a box seen obliquely covers up to twice the area, so the
   * same texels then sample the cabin more finely (about 1 ms of CPU). */
  double lo[3], hi[3];
  for (int a = 0; a < 3; a++) {
    vertex_extent(r, axis[a], &lo[a], &hi[a]);
    if (!(hi[a] >= lo[a])) lo[a] = hi[a] = 0; /* no opaque triangle: a 1 mm map of nothing */
  }
  for (int a = 0; a < 3; a++) {
    double pad = 0.01 * (hi[a] - lo[a]) + 1e-3;
    lo[a] -= pad, hi[a] += pad;
  }
  /* Square texels: the longer side over res; the shorter side gets the
   * texels it needs and its range grows to a whole number of them. */
  const int res = c->o->shadow_res;
  const double tx = fmax(hi[0] - lo[0], hi[1] - lo[1]) / res;
  int n[2];
  for (int a = 0; a < 2; a++) {
    n[a] = (int)ceil((hi[a] - lo[a]) / tx - 1e-9);
    if (n[a] < 2) n[a] = 2;
    if (n[a] > res) n[a] = res;
    hi[a] = lo[a] + n[a] * tx;
    size[a] = n[a];
  }
  /* clip_a = 2 (axis_a . p - lo_a)/(hi_a - lo_a) - 1; the lookup in texel
   * space (prt.frag): x, y = [0,1] coordinate * n_a - 0.5 (texel centres at
   * integers), z = the [0,1] depth.  Its linear part is A = D R, R the
   * rotation with rows axis_a, D = diag(n_x sc_x/2, n_y sc_y/2, sc_z/2). */
  float *q = sh->q;
  memset(clip, 0, 16 * sizeof *clip);
  memset(q, 0, 16 * sizeof *q);
  double D[3];
  for (int a = 0; a < 3; a++) {
    double sc = 2.0 / (hi[a] - lo[a]), ts = a < 2 ? n[a] : 1.0;
    D[a] = 0.5 * sc * ts;
    for (int j = 0; j < 3; j++) {
      clip[4 * j + a] = (float)(sc * axis[a][j]);
      q[4 * j + a] = (float)(D[a] * axis[a][j]);
    }
    clip[12 + a] = (float)(-sc * lo[a] - 1);
    q[12 + a] = (float)((0.5 * (-sc * lo[a] - 1) + 0.5) * ts - (a < 2 ? 0.5 : 0.0));
  }
  clip[15] = q[15] = 1;
  for (int a = 0; a < 3; a++) sh->k[a] = (float)(D[a] * D[a]);
  sh->k[3] = (float)-D[2];
  const double det = axis[0][0] * (axis[1][1] * axis[2][2] - axis[1][2] * axis[2][1]) -
                     axis[0][1] * (axis[1][0] * axis[2][2] - axis[1][2] * axis[2][0]) +
                     axis[0][2] * (axis[1][0] * axis[2][1] - axis[1][1] * axis[2][0]);
  sh->detsign = det < 0 ? -1 : 1;
  *texel = (float)tx;
}

static int shadow_target(cvr_shadow *r, int n, cv_err *err) {
  if (!r->fbo || r->depth_res != n) {
    if (!r->fbo) glGenFramebuffers(1, &r->fbo);
    if (!r->tex) glGenTextures(1, &r->tex);
    glBindTexture(GL_TEXTURE_2D, r->tex);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT32F, n, n, 0, GL_DEPTH_COMPONENT, GL_FLOAT,
                 NULL);
    /* read by texelFetch, compared and filtered in prt.frag */
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_MODE, GL_NONE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, r->tex, 0);
    glDrawBuffer(GL_NONE);
    glReadBuffer(GL_NONE);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      return cv_err_set(err, CV_ERR_BACKEND, "shadow map framebuffer incomplete (%d texels)", n);
    r->depth_res = n;
  }
  r->res = n; /* the current map's (an imported one may differ) */
  return CV_OK;
}

static int render_shadow(const cvr_ctx *c, cvr_light *lt, cvr_scene *sc, cvr_casters *k,
                         const double s[3], cv_err *err) {
  cvr_shadow *r = &lt->shadow;
  const int n = c->o->shadow_res;
  int st = shadow_target(r, n, err);
  if (st) return st;
  float clip[16], texel;
  int size[2];
  cvr_sun_matrices(c, r, sc, s, clip, &texel, size);
  /* Against self-shadowing acne the lookup point moves 1.5 texels along the
   * triangle's normal (a slope-scaled polygon offset on top changed neither
   * the sun test's figures nor the time). */
  r->bias = 1.5f * texel;
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo);
  glViewport(0, 0, size[0], size[1]);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDepthMask(GL_TRUE);
  /* The whole texture: a scissored clear (only the map's texels) costs
   * more on llvmpipe (Mesa draws it as a quad). */
  glClear(GL_DEPTH_BUFFER_BIT);
  cvr_scene_cull(c, sc, 0);
  glUseProgram(sc->prog_depth);
  cvr_uni_mat(sc->prog_depth, "u_mvp", clip);
  if (c->o->shadow_casters > 0) {
    if ((st = cvr_casters_draw(c, k, sc, s, err))) return st;
  } else {
    cvr_scene_draw(c, sc, NULL, cvr_scene_shadow_culled(c, sc) && lt->split.valid ? DRAW_SHADOW : DRAW_ALL);
  }
  for (int j = 0; j < 3; j++) r->s[j] = s[j];
  r->w = size[0], r->h = size[1];
  r->texel = texel;
  r->valid = 1;
  r->from_import = 0;
  r->gen++, r->import = 0; /* drawn here (render_share.c) */
  return cvr_gl_check("shadow map", err);
}

/* Half the diagonal of the scene's box: how far a point can be from its
 * centre, so a sun turned by |s - s0| (radians, small) moves a point's
 * shadow-map position by at most this times |s - s0|. */
static double scene_radius(const cvr_scene *r) {
  double d = 0;
  for (int j = 0; j < 3; j++) d += (r->hi[j] - r->lo[j]) * (r->hi[j] - r->lo[j]);
  return 0.5 * sqrt(d);
}

static double dist3(const double a[3], const double b[3]) {
  return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
              (a[2] - b[2]) * (a[2] - b[2]));
}

/* 1 when the current shadow map may stand for the sun s (opts.shadow_reuse):
 * made for a sun that differs from s by less than shadow_reuse texels at the
 * scene's radius.  Its matrices are kept with it, so the image is that of
 * the old sun's shadow, within that many texels of the new one. */
static int shadow_reusable(const cvr_ctx *c, const cvr_shadow *r, const cvr_scene *sc, const double s[3]) {
  if (!r->valid || r->res != c->o->shadow_res || !(r->texel > 0)) return 0;
  const double moved = dist3(s, r->s) * scene_radius(sc) / r->texel;
  return moved < c->o->shadow_reuse || dist3(s, r->s) == 0;
}

/* One chunk of the sun split: its triangles into out (the chunk's own
 * range of buf_idx_sun) in the three parts, their counts into chunk_na,
 * chunk_nf. */
static void split_chunk(cvr_scene *r, size_t c, const float sf[3], double m, uint32_t *out) {
  unsigned char part[CHUNK];
  const size_t first = c * CHUNK, end = first + CHUNK > r->nt ? r->nt : first + CHUNK;
  size_t k[3] = {0, 0, 0};
  for (size_t t = first; t < end; t++) {
    const float *n = r->tri_n + 3 * t;
    const double ns = (double)(n[0] * sf[0] + n[1] * sf[1] + n[2] * sf[2]);
    const int q = ns > m ? 0 : (ns >= -m && (m > 0 || ns >= 0) ? 1 : 2);
    part[t - first] = (unsigned char)q;
    k[q]++;
  }
  size_t at[3] = {first, first + k[0], first + k[0] + k[1]};
  for (size_t t = first; t < end; t++)
    memcpy(out + 3 * at[part[t - first]]++, r->idx_cpu + 3 * t, 3 * sizeof *out);
  r->chunk_na[c] = (uint32_t)k[0];
  r->chunk_nf[c] = (uint32_t)(k[0] + k[1]);
}

/* The sun split (see the struct): reorders each chunk of buf_idx into
 * buf_idx_sun in three parts by c = n_t . s, m = opts.split_margin:
 * c > m, then |c| <= m, then c < -m.  The first two (chunk_nf) are drawn
 * with the sun's per-pixel code, the last alone without it: on llvmpipe,
 * which pays for every instruction of a shader on every pixel, the sun's
 * normal, shadow-map fetches and filter are about half the shading pass.
 * The culled shadow map (opts.shadow_cull) draws the last two.  While the
 * sun stays within m of s (|s' - s| <= m) every triangle with n_t . s' > 0
 * is in the first two parts and every one with n_t . s' <= 0 in the last
 * two, so the split is reused exactly.  Same triangles, vertex order and
 * positions: same depths (depth EQUAL).  The chunks are split in parallel
 * straight into the mapped buffer (no copy, no allocation per split). */
static int sun_split(const cvr_ctx *ctx, cvr_sunsplit *sp, cvr_scene *r, const double s[3], cv_err *err) {
  const double m = ctx->o->split_margin > 0 ? ctx->o->split_margin : 0.0;
  if (sp->valid && dist3(s, sp->s) <= m) return CV_OK;
  if (cvr_scene_tri_normals(r)) return cv_err_set(err, CV_ERR_NOMEM, "out of memory splitting the mesh for the sun");
  const float sf[3] = {(float)s[0], (float)s[1], (float)s[2]};
  cvr_scene_parts_bind(r);
  uint32_t *out = glMapBufferRange(GL_ELEMENT_ARRAY_BUFFER, 0, (GLsizeiptr)(3 * r->nt * sizeof *out),
                                   GL_MAP_WRITE_BIT | GL_MAP_INVALIDATE_BUFFER_BIT);
  if (!out) {
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, 0);
    sp->valid = 0;
    return cv_err_set(err, CV_ERR_BACKEND, "sun split: cannot map the index buffer (GL error 0x%04x)",
                      glGetError());
  }
  const long nchunks = (long)r->nchunks;
#pragma omp parallel for schedule(static)
  for (long c = 0; c < nchunks; c++) split_chunk(r, (size_t)c, sf, m, out);
  const GLboolean kept = glUnmapBuffer(GL_ELEMENT_ARRAY_BUFFER);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, 0);
  if (!kept) { /* the GL lost the contents (GL_FALSE): no split */
    sp->valid = 0;
    return cv_err_set(err, CV_ERR_BACKEND, "sun split: the index buffer's contents were lost on unmap");
  }
  for (int j = 0; j < 3; j++) sp->s[j] = s[j];
  sp->valid = 1;
  sp->gen++, sp->import = 0; /* made here (render_share.c) */
  return cvr_gl_check("sun split", err);
}

/* The relight's uniforms: lighting without the sun (with td) and with the
 * sun's SH projection E * y_i(s) and the split lights' (with ti), as
 * relight.c. */
static void relight_uniforms(const cv_lighting *l, int sun, int nc, const cvr_split *wl, float *ul,
                             float *uls) {
  double y[CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS] = {0};
  if (sun) cv_sh_eval_d((int)lround(sqrt(nc)), l->sun_dir, y);
  for (int i = 0; i < nc; i++) {
    for (int c = 0; c < 3; c++) {
      ul[4 * i + c] = (float)l->sh[3 * i + c];
      uls[4 * i + c] = (float)(l->sh[3 * i + c] + (sun ? l->sun_E[c] * y[i] : 0.0) +
                               (wl->n ? wl->sh[3 * i + c] : 0.0));
    }
    ul[4 * i + 3] = uls[4 * i + 3] = 0;
  }
}

int cvr_light_set(const cvr_ctx *c, cvr_light *r, cvr_scene *sc, cvr_relight *rl,
                  const cvr_split *wl, cvr_casters *k, const cv_lighting *l,
                  cv_render_light_stats *stats, cv_frame_timing *t, cv_err *err) {
  if (l->bands < 1 || l->bands > CV_PRT_MAX_BANDS || l->bands * l->bands < sc->nc)
    return cv_err_set(err, CV_ERR_RANGE, "lighting has %d bands, the scene needs %d", l->bands,
                      (int)lround(sqrt(sc->nc)));
  for (int i = 0; i < 3 * sc->nc; i++)
    if (!isfinite(l->sh[i])) return cv_err_set(err, CV_ERR_NONFINITE, "lighting SH[%d] is not finite", i);
  double sd[3] = {0, 0, 0};
  int sun = 0;
  if (l->has_sun) {
    double n = sqrt(l->sun_dir[0] * l->sun_dir[0] + l->sun_dir[1] * l->sun_dir[1] +
                    l->sun_dir[2] * l->sun_dir[2]);
    for (int ch = 0; ch < 3; ch++)
      if (!isfinite(l->sun_E[ch]) || l->sun_E[ch] < 0)
        return cv_err_set(err, CV_ERR_NONFINITE, "sun irradiance[%d] is %g", ch, l->sun_E[ch]);
    if (!(n > 0) || !isfinite(n)) return cv_err_set(err, CV_ERR_INVALID, "sun direction has no length");
    for (int ch = 0; ch < 3; ch++) sd[ch] = l->sun_dir[ch] / n;
    sun = 1;
  }
  if (cv_egl_make_current(c->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  cvr_gl_check("(before set_lighting)", NULL);
  double t0 = cvr_tick(c);
  float ul[4 * 64], uls[4 * 64];
  relight_uniforms(l, sun, sc->nc, wl, ul, uls);
  uint64_t clamped = 0;
  int st = cvr_relight_run(c, rl, sc, wl, ul, uls, stats != NULL, &clamped, err);
  if (st) return st;
  double t1 = cvr_tick(c), t2 = t1, t3 = t1;
  int reused = 0;
  r->has_sun = sun;
  if (sun) {
    for (int ch = 0; ch < 3; ch++) {
      r->sun_e[ch] = (float)(l->sun_E[ch] / M_PI);
    }
    /* the split first: the culled shadow map draws a part of it */
    r->sun_split = 0;
    if ((c->o->sun_split || cvr_scene_shadow_culled(c, sc)) && (st = sun_split(c, &r->split, sc, sd, err)))
      return st;
    r->sun_split = c->o->sun_split;
    t2 = cvr_tick(c);
    reused = shadow_reusable(c, &r->shadow, sc, sd);
    if (!reused && (st = render_shadow(c, r, sc, k, sd, err))) return st;
    t3 = cvr_tick(c);
  }
  r->lit = 1;
  if (stats) stats->clamped = clamped;
  if (t) {
    t->relight_ms = t1 - t0;
    t->split_ms = t2 - t1;
    t->shadow_ms = t3 - t2;
    t->shadow_reused = reused;
  }
  return CV_OK;
}

int cvr_light_upload_background(cvr_light *r, int w, int h, const float *rgb, cv_err *err) {
  if (!r->tex_bg) glGenTextures(1, &r->tex_bg);
  glBindTexture(GL_TEXTURE_2D, r->tex_bg);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, w, h, 0, GL_RGB, GL_FLOAT, rgb);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glBindTexture(GL_TEXTURE_2D, 0);
  return cvr_gl_check("background upload", err);
}

int cvr_light_background(const cvr_ctx *ctx, cvr_light *r, const cv_image *img, cv_err *err) {
  if (!img) return cvr_light_upload_background(r, 1, 1, (const float[3]){0, 0, 0}, err);
  if (img->w < 1 || img->h < 1 || img->c < 3 || !img->px)
    return cv_err_set(err, CV_ERR_INVALID, "background: expected an RGB image, got %dx%dx%d", img->w,
                      img->h, img->c);
  if (img->w > ctx->max_rb || img->h > ctx->max_rb)
    return cv_err_set(err, CV_ERR_RANGE, "background %dx%d exceeds the GL texture limit %d", img->w,
                      img->h, (int)ctx->max_rb);
  size_t n = (size_t)img->w * img->h;
  float *rgb = malloc(3 * n * sizeof *rgb);
  if (!rgb) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  for (size_t i = 0; i < n; i++)
    for (int c = 0; c < 3; c++) {
      float v = img->px[i * img->c + c];
      rgb[3 * i + c] = isfinite(v) && v > 0 ? v : 0.0f;
    }
  int st = cvr_light_upload_background(r, img->w, img->h, rgb, err);
  free(rgb);
  return st;
}

int cvr_light_panel(const cvr_ctx *ctx, cvr_light *lt, const float center[3], const float u[3],
                    const float v[3], const float size[2], const cv_image *img, cv_err *err) {
  cvr_panel *r = &lt->panel;
  if (!img) {
    r->on = 0;
    return CV_OK;
  }
  if (!center || !u || !v || !size || img->w < 1 || img->h < 1 || img->c < 3 || !img->px ||
      !(size[0] > 0) || !(size[1] > 0))
    return cv_err_set(err, CV_ERR_INVALID, "panel: expected a frame, sizes > 0 and an RGB image");
  if (img->w > ctx->max_rb || img->h > ctx->max_rb)
    return cv_err_set(err, CV_ERR_RANGE, "panel image %dx%d exceeds the GL texture limit %d", img->w,
                      img->h, (int)ctx->max_rb);
  double lu = 0, lv = 0;
  for (int a = 0; a < 3; a++) {
    lu += (double)u[a] * u[a];
    lv += (double)v[a] * v[a];
  }
  if (!(lu > 0) || !(lv > 0)) return cv_err_set(err, CV_ERR_INVALID, "panel: zero axis");
  for (int a = 0; a < 3; a++) {
    r->c[a] = center[a];
    r->u[a] = (float)(u[a] / sqrt(lu));
    r->v[a] = (float)(v[a] / sqrt(lv));
  }
  r->n[0] = r->u[1] * r->v[2] - r->u[2] * r->v[1];
  r->n[1] = r->u[2] * r->v[0] - r->u[0] * r->v[2];
  r->n[2] = r->u[0] * r->v[1] - r->u[1] * r->v[0];
  r->half[0] = 0.5f * size[0];
  r->half[1] = 0.5f * size[1];
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
  if (!r->tex) glGenTextures(1, &r->tex);
  glBindTexture(GL_TEXTURE_2D, r->tex);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, img->w, img->h, 0, GL_RGB, GL_FLOAT, rgb);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glBindTexture(GL_TEXTURE_2D, 0);
  free(rgb);
  r->on = 1;
  r->bad = bad;
  return cvr_gl_check("panel upload", err);
}

void cvr_light_forget(cvr_light *r) {
  r->lit = 0;
  r->shadow.valid = r->split.valid = 0;
  r->shadow.import = r->split.import = 0;
}

void cvr_light_free(cvr_light *r) {
  GLuint tex[] = {r->shadow.tex, r->shadow.tex_imp, r->tex_bg, r->panel.tex};
  glDeleteTextures(4, tex);
  GLuint fbos[] = {r->shadow.fbo, r->shadow.fbo_imp};
  glDeleteFramebuffers(2, fbos);
  r->shadow.tex = r->shadow.tex_imp = r->tex_bg = r->panel.tex = r->shadow.fbo = r->shadow.fbo_imp = 0;
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

