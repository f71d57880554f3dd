/* Window presentation of the renderer: the projector image drawn into the
 * window's back buffer, glFinish, swap (see renderer.h). */
#include "render/render_present.h"

#include "view/cave.h"

/* ---------------------------------------------------------------- present */

/* Draws textures tex[0] (and tex[1] for a packed stereo layout), each
 * w x h, into the window's back buffer, then glFinish; gl_rows: their row 0
 * is the image's bottom (drawn by GL) instead of its top (uploaded). */
static int draw_eyes(const cvr_ctx *c, const cvr_present *r, cv_window *win, const GLuint tex[2], int w,
                     int h, int layout, int gl_rows, cv_err *err) {
  const int packed = layout == CV_STEREO_SIDE_BY_SIDE || layout == CV_STEREO_TOP_BOTTOM;
  int ww, wh;
  cv_window_size(win, &ww, &wh);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glViewport(0, 0, ww, wh);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  glClearColor(0, 0, 0, 1);
  glClear(GL_COLOR_BUFFER_BIT);
  glUseProgram(r->prog);
  glActiveTexture(GL_TEXTURE0 + U_SRC);
  /* 1:1 pixels copy exactly; another window size is filtered. */
  const int exact = layout == CV_STEREO_SIDE_BY_SIDE ? (2 * w == ww && h == wh)
                    : layout == CV_STEREO_TOP_BOTTOM ? (w == ww && 2 * h == wh)
                                                     : (w == ww && h == wh);
  const GLint filt = exact ? GL_NEAREST : GL_LINEAR;
  const GLint loc = glGetUniformLocation(r->prog, "u_rect");
  glUniform1i(glGetUniformLocation(r->prog, "u_gl_rows"), gl_rows);
  glBindVertexArray(c->vao_empty);
  for (int e = 0; e < (packed ? 2 : 1); e++) {
    glBindTexture(GL_TEXTURE_2D, tex[e]);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, filt);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, filt);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    float rect[4] = {-1, -1, 1, 1};
    if (layout == CV_STEREO_SIDE_BY_SIDE) rect[0] = e ? 0.0f : -1.0f, rect[2] = e ? 1.0f : 0.0f;
    if (layout == CV_STEREO_TOP_BOTTOM) rect[1] = e ? -1.0f : 0.0f, rect[3] = e ? 0.0f : 1.0f;
    glUniform4fv(loc, 1, rect);
    glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
  }
  glBindVertexArray(0);
  glEnable(GL_DEPTH_TEST);
  glFinish();
  return cvr_gl_check("present", err);
}

int cvr_present_init(cvr_present *pr, cv_err *err) {
  return cvr_build("present.vert", "present.frag", "", NULL, &pr->prog, err);
}

void cvr_present_free(cvr_present *pr) {
  glDeleteProgram(pr->prog);
  glDeleteTextures(2, pr->tex);
  pr->prog = pr->tex[0] = pr->tex[1] = 0;
}

int cvr_present_codes(cvr_ctx *c, cvr_present *r, cv_window *win, const uint8_t *left,
                      const uint8_t *right, int w, int h, int layout, cv_err *err) {
  const int packed = layout == CV_STEREO_SIDE_BY_SIDE || layout == CV_STEREO_TOP_BOTTOM;
  if (!left || w < 1 || h < 1 || (packed && !right))
    return cv_err_set(err, CV_ERR_INVALID, "renderer: present: no image or bad size");
  if (cv_egl_make_current(c->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  /* the uploaded codes: one texture per eye (the first draw must not read a
   * texture the second upload rewrites) */
  const int eyes = packed ? 2 : 1;
  if (!r->tex[0]) glGenTextures(2, r->tex);
  if (r->w != w || r->h != h) {
    r->made[0] = r->made[1] = 0;
    r->w = w, r->h = h;
  }
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  for (int e = 0; e < eyes; e++) {
    glBindTexture(GL_TEXTURE_2D, r->tex[e]);
    if (!r->made[e])
      glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB8, w, h, 0, GL_RGB, GL_UNSIGNED_BYTE, e ? right : left);
    else
      glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE, e ? right : left);
    r->made[e] = 1;
    c->io_up += 3 * (size_t)w * h;
  }
  return draw_eyes(c, r, win, r->tex, w, h, layout, 0, err);
}

int cvr_present_textures(const cvr_ctx *c, const cvr_present *pr, cv_window *win, const GLuint tex[2],
                         int w, int h, int layout, cv_err *err) {
  if (cv_egl_make_current(c->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  return draw_eyes(c, pr, win, tex, w, h, layout, 1, err); /* the post pass's images */
}
