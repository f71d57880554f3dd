/* The renderer's bottom layer (render_gl.h): GL helpers with no knowledge
 * of any feature: programs from the embedded GLSL, uniforms, GL objects,
 * read-back, timing, matrices and keys. */
#include "render/render_gl.h"

/* ---------------------------------------------------------------- timing */

double cvr_now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/* Time stamp after the GL queue has drained (opts.timing), else 0: wall
 * clock, or with opts.timing == 2 the CPU time of the whole process (every
 * llvmpipe thread's work, insensitive to other load on the machine). */
double cvr_tick(const cvr_ctx *c) {
  if (!c->o->timing) return 0;
  glFinish();
  if (c->o->timing == 2) {
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
  }
  return cvr_now_ms();
}

/* GPU time of the commands between begin and end (GL_TIME_ELAPSED); the
 * caller makes the context current. */
void cvr_timer_begin(cvr_ctx *r) {
  if (!r->gpu_query) glGenQueries(1, &r->gpu_query);
  glBeginQuery(GL_TIME_ELAPSED, r->gpu_query);
  r->gpu_query_on = 1;
  r->gpu_query_t0 = cvr_now_ms();
}

void cvr_timer_end(cvr_ctx *r) {
  if (r->gpu_query_on != 1) return;
  glEndQuery(GL_TIME_ELAPSED);
  r->gpu_query_on = 2;
}

double cvr_timer_result(cvr_ctx *r) {
  if (r->gpu_query_on != 2) return NAN;
  GLuint64 ns = 0;
  glGetQueryObjectui64v(r->gpu_query, GL_QUERY_RESULT, &ns);
  r->gpu_query_on = 0;
  /* the GPU time cannot exceed the wall time since the begin: a result that
   * does (seen on llvmpipe: 926 s for a 50 ms frame) is not a measurement */
  const double ms = (double)ns * 1e-6;
  return ms <= cvr_now_ms() - r->gpu_query_t0 + 1.0 ? ms : NAN;
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

int cvr_has_extension(const char *name) {
  GLint n = 0;
  glGetIntegerv(GL_NUM_EXTENSIONS, &n);
  for (GLint i = 0; i < n; i++) {
    const char *e = (const char *)glGetStringi(GL_EXTENSIONS, (GLuint)i);
    if (e && !strcmp(e, name)) return 1;
  }
  return 0;
}

/* ---------------------------------------------------------------- objects */

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

void cvr_draw_fullscreen(const cvr_ctx *c) {
  glBindVertexArray(c->vao_empty);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glBindVertexArray(0);
}

/* Reads attachment `att` of the bound read framebuffer into img (c = 1 or
 * 3), flipping GL's bottom-up rows to the image's top-down order.  An 8-bit
 * target (is8) is read as bytes and converted (k/255). */
int cvr_read_image(cvr_ctx *r, GLenum att, int is8, cv_image *img) {
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

/* ---------------------------------------------------------------- matrices */

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

/* ---------------------------------------------------------------- keys */

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

uint64_t cvr_hash64(uint64_t k) {
  k ^= k >> 33;
  k *= 0xff51afd7ed558ccdull;
  k ^= k >> 33;
  return k;
}


void cvr_ctx_free(cvr_ctx *c) {
  glDeleteQueries(1, &c->gpu_query);
  glDeleteVertexArrays(1, &c->vao_empty);
  c->gpu_query = c->vao_empty = 0;
  free(c->rgba8);
  c->rgba8 = NULL, c->rgba8_cap = 0;
}
