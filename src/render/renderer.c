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
 *   buf_uvl      textured scenes: (u, v, layer) per vertex, attribute 3;
 *                tex_albedo the texture array (render_texture.c)
 *   fbo_main     shading targets (display, HDR: RGBA32F textures) + depth
 *   fbo_res      the supersampling resolve targets; fbo_lum the luminance pass
 *   fbo_shadow   the sun's shadow map (depth texture with compare mode) */
#include "render/renderer_internal.h"


void cv_render_default_opts(cv_render_opts *o) {
  memset(o, 0, sizeof *o);
  o->shadow_res = 2048;
  o->timing = 1;
  o->cull_frustum = 1;
  o->sun_split = 1;
  o->gpu = CV_GPU_AUTO;
  o->shadow_cull = -1;
  o->shadow_reuse = 0.5;
  o->split_margin = 0.05;
  o->shadow_casters = 0.001;
  o->relight_cpu = -1;
  o->lum_stats_gpu = -1;
  o->half_transfer = -1;
}

int cv_render_transfer_parse(const char *s, int *half_transfer) {
  if (!s) return -1;
  if (!strcmp(s, "auto")) *half_transfer = -1;
  else if (!strcmp(s, "float")) *half_transfer = 0;
  else if (!strcmp(s, "half")) *half_transfer = 1;
  else return -1;
  return 0;
}

const char *cv_renderer_gl_name(const cv_renderer *r) { return r->gl_name; }
int cv_renderer_mesh_closed(const cv_renderer *r) { return r->closed; }
int cv_renderer_relight_on_cpu(const cv_renderer *r) { return r->relight_on_cpu; }
int cv_renderer_half_transfer(const cv_renderer *r) { return r->half_on; }
int cv_renderer_lum_stats_on_gpu(const cv_renderer *r) {
  return r->o.lum_stats_gpu < 0 ? !r->egl.software : r->o.lum_stats_gpu != 0;
}
int cv_renderer_is_software(const cv_renderer *r) { return r->egl.software; }
int cv_renderer_hw_devices(const cv_renderer *r) { return r->egl.hw_devices; }
const char *cv_renderer_platform(const cv_renderer *r) { return r->egl.platform; }

double cvr_now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/* Time stamp after the GL queue has drained (opts.timing), else 0: wall
 * clock, or with opts.timing == 2 the CPU time of the whole process (every
 * llvmpipe thread's work, insensitive to other load on the machine). */
double cvr_tick(const cv_renderer *r) {
  if (!r->o.timing) return 0;
  glFinish();
  if (r->o.timing == 2) {
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
  }
  return cvr_now_ms();
}

int cvr_gl_check(const char *where, cv_err *err) {
  GLenum e = glGetError(), first = e;
  while (e != GL_NO_ERROR) e = glGetError();
  if (first == GL_NO_ERROR) return CV_OK;
  return cv_err_set(err, CV_ERR_BACKEND, "OpenGL error 0x%04x in %s", (unsigned)first, where);
}


/* ---------------------------------------------------------------- programs */

GLuint cvr_compile(GLenum type, const char *name, const char *defines, cv_err *err) {
  const char *text = cv_shader_find(name);
  const char *common = cv_shader_find("common.glsl");
  if (!text || !common) {
    cv_err_set(err, CV_ERR_NOT_FOUND, "shader %s is not embedded in the binary", name);
    return 0;
  }
  const char *src[5] = {"#version 330 core\n#extension GL_ARB_texture_gather : enable\n", defines, "", "#line 1\n", text};
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

void cvr_set_samplers(GLuint p) {
  static const struct {
    const char *name;
    int unit;
  } tab[] = {{"u_transfer", U_TRANSFER}, {"u_shadow", U_SHADOW},
             {"u_bg", U_BG}, {"u_src", U_SRC}, {"u_panel", U_PANEL},
             {"u_tone", U_TONE}, {"u_albedo", U_ALBEDO}};
  glUseProgram(p);
  for (size_t i = 0; i < sizeof tab / sizeof tab[0]; i++) {
    GLint loc = glGetUniformLocation(p, tab[i].name);
    if (loc >= 0) glUniform1i(loc, tab[i].unit);
  }
}

int cvr_build(const char *vs_name, const char *fs_name, const char *defines, const char *tf,
                 GLuint *out, cv_err *err) {
  GLuint vs = cvr_compile(GL_VERTEX_SHADER, vs_name, defines, err);
  if (!vs) return CV_ERR_BACKEND;
  GLuint fs = 0;
  if (fs_name && !(fs = cvr_compile(GL_FRAGMENT_SHADER, fs_name, defines, err))) {
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
  cvr_set_samplers(p);
  *out = p;
  return CV_OK;
}

/* The prt.frag (K_PRT) or background.frag (K_BG) program for flags F_*,
 * compiled on first use. */
int cvr_variant(cv_renderer *r, int kind, int flags, GLuint *out, cv_err *err) {
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

void cvr_uni_mat(GLuint p, const char *name, const float m[16]) {
  GLint loc = glGetUniformLocation(p, name);
  if (loc >= 0) glUniformMatrix4fv(loc, 1, GL_FALSE, m);
}
void cvr_uni_f(GLuint p, const char *name, float v) {
  GLint loc = glGetUniformLocation(p, name);
  if (loc >= 0) glUniform1f(loc, v);
}
void cvr_uni_v3(GLuint p, const char *name, const float v[3]) {
  GLint loc = glGetUniformLocation(p, name);
  if (loc >= 0) glUniform3fv(loc, 1, v);
}

/* ------------------------------------------------------------ matrices */

/* Column-major 4x4 inverse (cofactors, double); 0 when singular. */
int cvr_invert4(const double m[16], double inv[16]) {
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
int cvr_view_matrices(const cv_render_view *v, float mvp[16], float inv[16], float eye[3],
                         float *facing) {
  double m[16], mi[16];
  const double *a = v->proj.viewproj_d;
  for (int i = 0; i < 12; i++) m[i] = a[i];
  for (int row = 0; row < 4; row++)
    m[12 + row] = a[12 + row] - (a[row] * v->scene_offset[0] + a[4 + row] * v->scene_offset[1] +
                                 a[8 + row] * v->scene_offset[2]);
  if (!cvr_invert4(m, mi)) return CV_ERR_INVALID;
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

GLuint cvr_make_tbo(GLuint *buf, GLenum fmt, const void *data, size_t bytes) {
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
uint64_t cvr_morton3(uint32_t x, uint32_t y, uint32_t z) {
  uint64_t m = 0;
  for (int b = 0; b < 10; b++)
    m |= (uint64_t)((x >> b) & 1) << (3 * b) | (uint64_t)((y >> b) & 1) << (3 * b + 1) |
         (uint64_t)((z >> b) & 1) << (3 * b + 2);
  return m;
}

int cvr_cmp_u64(const void *a, const void *b) {
  uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
  return x < y ? -1 : x > y;
}

int cvr_upload_background(cv_renderer *r, int w, int h, const float *rgb, cv_err *err) {
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

/* Per vertex the first vertex at exactly the same position (vertices split
 * at material boundaries are one point of the surface); NULL when out of
 * memory. */
static uint32_t *weld_positions(const cv_prt *p) {
  size_t cap = 1;
  while (cap < 2 * p->nv + 2) cap <<= 1;
  uint32_t *slot = malloc(cap * sizeof *slot), *id = malloc(p->nv * sizeof *id + 4);
  if (!slot || !id) {
    free(slot), free(id);
    return NULL;
  }
  memset(slot, 0xff, cap * sizeof *slot);
  for (size_t v = 0; v < p->nv; v++) {
    uint32_t b[3];
    memcpy(b, p->pos + 3 * v, sizeof b);
    size_t h = cvr_hash64(cvr_hash64((uint64_t)b[0] << 32 | b[1]) ^ b[2]) & (cap - 1);
    while (slot[h] != UINT32_MAX && memcmp(p->pos + 3 * (size_t)slot[h], p->pos + 3 * v, sizeof b))
      h = (h + 1) & (cap - 1);
    if (slot[h] == UINT32_MAX) slot[h] = (uint32_t)v;
    id[v] = slot[h];
  }
  free(slot);
  return id;
}

/* 1 when every directed edge of p's non-degenerate triangles, vertices
 * welded by position, occurs once and its reverse once (closed, consistently
 * wound); 0 otherwise or out of memory. */
static int mesh_closed(const cv_prt *p) {
  uint32_t *id = weld_positions(p), *tri = malloc(3 * p->nt * sizeof *tri + 4);
  cvr_edges e = {0};
  int closed = 0;
  if (id && tri) {
    for (size_t i = 0; i < 3 * p->nt; i++) tri[i] = id[p->tri[i]];
    if (cvr_edges_build(&e, tri, p->nt) == CV_OK)
      closed = e.dup == 0 && cvr_edges_border_unmatched(&e, NULL) == 0;
  }
  cvr_edges_free(&e);
  free(id), free(tri);
  return closed;
}

int cvr_upload_scene(cv_renderer *r, const cv_prt *p, cv_err *err) {
  r->closed = mesh_closed(p);
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
  r->relight_on_cpu = r->o.relight_cpu < 0 ? r->egl.software : r->o.relight_cpu != 0;
  r->half_on = r->o.half_transfer < 0 ? r->relight_on_cpu : r->o.half_transfer != 0;
  uint16_t *th = r->half_on ? malloc(4 * texels * sizeof *th + 4) : NULL;
  if (!idx || !tf || (r->half_on && !th)) {
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
    order[k++] = (cvr_morton3(q[0], q[1], q[2]) << 32) | (uint64_t)t;
  }
  qsort(order, nt, sizeof *order, cvr_cmp_u64);
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
  r->nv_used = next;
  for (size_t v = 0; v < p->nv; v++)
    if (new_of[v] == UINT32_MAX) {
      old_of[next] = (uint32_t)v;
      new_of[v] = next++;
    }
  /* Sampled textures (render_texture.c: p is then the split PRT, without
   * the texture flag, so the scale is 1) multiply the pixels; a textured
   * PRT drawn without them gets its mean albedo back. */
  float *usc = malloc(3 * p->nv * sizeof *usc + 4);
  if (!usc || cv_prt_untextured_scale(p, usc)) {
    free(idx), free(tf), free(th), free(old_of), free(new_of), free(pos), free(alb), free(usc);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory uploading the scene");
  }
  for (size_t v = 0; v < p->nv; v++)
    for (int j = 0; j < 3; j++) {
      pos[3 * v + j] = p->pos[3 * old_of[v] + j];
      alb[3 * v + j] = p->albedo[3 * old_of[v] + j] * usc[3 * old_of[v] + j];
    }
  for (size_t nvx = 0; nvx < p->nv; nvx++) {
    const size_t v = old_of[nvx];
    float *o = tf + 4 * nvx * (size_t)(nc + 1);
    for (int i = 0; i < nc; i++) {
      o[4 * i] = p->td[v * nc + i];
      for (int c = 0; c < 3; c++)
        o[4 * i + 1 + c] = p->ti ? p->ti[(v * 3 + c) * nc + i] * usc[3 * v + c] : 0.0f;
    }
    for (int c = 0; c < 3; c++) o[4 * nc + c] = p->albedo[3 * v + c] * usc[3 * v + c];
    o[4 * nc + 3] = 0;
  }
  /* The split window lights' direct light gets the same factors (by renderer vertex). */
  if ((p->flags & CV_PRT_TEXTURED) && (r->wl_usc = malloc(3 * p->nv * sizeof *r->wl_usc + 4)))
    for (size_t v = 0; v < p->nv; v++)
      for (int c = 0; c < 3; c++) r->wl_usc[3 * v + c] = usc[3 * old_of[v] + c];
  free(usc);
  if (th)
    for (size_t i = 0; i < 4 * texels; i++) th[i] = cv_float_to_half(tf[i]);
  if (r->relight_on_cpu) { /* the CPU reads what the texture buffer would hold */
    r->rad_cpu = malloc(4 * p->nv * sizeof *r->rad_cpu + 4);
    if (!r->rad_cpu) {
      free(idx), free(tf), free(th), free(old_of), free(new_of), free(pos), free(alb);
      return cv_err_set(err, CV_ERR_NOMEM, "out of memory uploading the scene");
    }
    if (th) r->th_cpu = th, th = NULL; /* kept: half the bytes to read per relight */
    else r->tf_cpu = tf, tf = NULL;
  } else {
    r->tex_transfer = th ? cvr_make_tbo(&r->buf_transfer, GL_RGBA16F, th, 4 * texels * sizeof *th)
                         : cvr_make_tbo(&r->buf_transfer, GL_RGBA32F, tf, 4 * texels * sizeof *tf);
  }
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
  if (r->tex_uvl) { /* (u, v, layer) in the renumbered order */
    float *uvl = malloc(3 * p->nv * sizeof *uvl + 4);
    if (!uvl) {
      free(idx), free(tf), free(th), free(old_of), free(new_of), free(alb), free(pos);
      return cv_err_set(err, CV_ERR_NOMEM, "out of memory uploading the scene");
    }
    for (size_t v = 0; v < p->nv; v++)
      for (int j = 0; j < 3; j++) uvl[3 * v + j] = r->tex_uvl[3 * old_of[v] + j];
    glGenBuffers(1, &r->buf_uvl);
    glBindBuffer(GL_ARRAY_BUFFER, r->buf_uvl);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(3 * p->nv * sizeof(float)), uvl, GL_STATIC_DRAW);
    glVertexAttribPointer(3, 3, GL_FLOAT, GL_FALSE, 0, 0);
    glEnableVertexAttribArray(3);
    free(uvl);
  }
  glGenBuffers(1, &r->buf_idx);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->buf_idx);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(3 * nt * sizeof *idx + 4), idx, GL_STATIC_DRAW);
  glBindVertexArray(0);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  /* Each renderer vertex's PRT vertex, for the split window lights. */
  r->wl_src = malloc(p->nv * sizeof *r->wl_src + 4);
  if (r->wl_src)
    for (size_t v = 0; v < p->nv; v++)
      r->wl_src[v] = r->tex_orig ? r->tex_orig[old_of[v]] : old_of[v];
  free(tf), free(th), free(old_of), free(new_of), free(alb);
  r->idx_cpu = idx, r->pos_cpu = pos; /* kept for the sun split */
  r->chunk_nf = malloc(r->nchunks * sizeof *r->chunk_nf + 4);
  r->chunk_na = malloc(r->nchunks * sizeof *r->chunk_na + 4);
  r->md_count = malloc(r->nchunks * sizeof *r->md_count + 4);
  r->md_off = malloc(r->nchunks * sizeof *r->md_off + 8);
  if (!r->chunk_nf || !r->chunk_na || !r->md_count || !r->md_off)
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory uploading the scene");
  return cvr_gl_check("scene upload", err);
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
  cv_prt *split = NULL; /* textured: vertices split at UV seams (render_texture.c) */
  if ((st = cvr_texture_prepare(r, prt, &split, err))) {
    cv_renderer_destroy(r);
    return st;
  }
  if (split) prt = split;
  r->nv = prt->nv;
  char defs[64];
  snprintf(defs, sizeof defs, "#define NC %d\n", r->nc);
  st = cvr_upload_scene(r, prt, err);
  cv_prt_destroy(split);
  free(r->tex_uvl);
  r->tex_uvl = NULL;
  free(r->tex_orig);
  r->tex_orig = NULL;
  if (st ||
      (st = cvr_build("relight.vert", NULL, defs, "v_out", &r->prog_relight, err)) ||
      (st = cvr_build("geom.vert", "depth.frag", "#define DEPTH_ONLY\n", NULL, &r->prog_depth, err)) ||
      (st = cvr_build("geom.vert", "unlit.frag", "", NULL, &r->prog_unlit, err)) ||
      (st = cvr_build("fullscreen.vert", "downsample.frag", "", NULL, &r->prog_down, err)) ||
      (st = cvr_build("fullscreen.vert", "lum_reduce.frag", "", NULL, &r->prog_lumred, err)) ||
      (st = cvr_build("fullscreen.vert", "lum_block.frag", "", NULL, &r->prog_lumblk, err)) ||
      (r->win && (st = cvr_build("present.vert", "present.frag", "", NULL, &r->prog_present, err))) ||
      (st = cvr_upload_background(r, 1, 1, (const float[3]){0, 0, 0}, err))) {
    cv_renderer_destroy(r);
    return st;
  }
  r->rb_tiny = cvr_make_rb(GL_R8, 1, 1);
  glGenFramebuffers(1, &r->fbo_tiny);
  glBindFramebuffer(GL_FRAMEBUFFER, r->fbo_tiny);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, r->rb_tiny);
  if ((st = cvr_fbo_complete("1x1", 1, 1, err)) || (st = cvr_gl_check("renderer setup", err))) {
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
                     r->buf_idx_sun, r->buf_uvl};
    glDeleteBuffers(7, bufs);
    GLuint tex[] = {r->tex_transfer, r->tex_bg, r->tex_shadow, r->tex_disp, r->tex_hdr,
                    r->tex_panel, r->tex_albedo, r->tex_shadow_imp, r->tex_res_disp, r->tex_red_mb};
    glDeleteTextures(10, tex);
    GLuint rbs[] = {r->rb_lum, r->rb_lum_depth, r->rb_depth, r->rb_res_hdr,
                    r->rb_tiny, r->rb_red, r->rb_blk};
    glDeleteRenderbuffers(7, rbs);
    GLuint fbos[] = {r->fbo_shadow, r->fbo_lum, r->fbo_main, r->fbo_res, r->fbo_tiny, r->fbo_red,
                     r->fbo_shadow_imp, r->fbo_blk};
    glDeleteFramebuffers(8, fbos);
    glDeleteQueries(1, &r->gpu_query);
    glDeleteProgram(r->prog_lumblk);
    cvr_post_free(r);
    GLuint vaos[] = {r->vao_geom, r->vao_empty};
    glDeleteVertexArrays(2, vaos);
    glDeleteProgram(r->prog_relight);
    glDeleteProgram(r->prog_depth);
    glDeleteProgram(r->prog_unlit);
    glDeleteProgram(r->prog_down);
    glDeleteProgram(r->prog_lumred);
    glDeleteProgram(r->prog_present);
    glDeleteTextures(2, r->tex_present);
    for (int k = 0; k < 2; k++)
      for (int f = 0; f < NVARIANT; f++) glDeleteProgram(r->prog_var[k][f]);
    glDeleteBuffers(1, &r->buf_tone);
    glDeleteTextures(1, &r->tex_tone);
    cvr_split_free(r);
    cvr_casters_free(r);
  }
  cv_egl_close(&r->egl);
  cv_window_destroy(r->win);
  free(r->chunk_box);
  free(r->red_cpu);
  cv_image_destroy(r->hdr_scratch);
  free(r->idx_cpu);
  free(r->pos_cpu);
  free(r->wl_src);
  free(r->wl_usc);
  free(r->tex_orig);
  free(r->chunk_nf);
  free(r->chunk_na);
  free(r->tri_n);
  free(r->md_count);
  free(r->md_off);
  free(r->run);
  free(r->rgba8);
  free(r->tex_uvl);
  free(r->cast_pos);
  free(r->cast_n);
  free(r->cast_idx);
  free(r->cast_draw);
  free(r->tf_cpu);
  free(r->th_cpu);
  free(r->wl_cpu);
  free(r->rad_cpu);
  free(r);
}

