/* Window presentation of the renderer: the projector image drawn into the
 * window's back buffer, glFinish, swap (see renderer.h). */
#include "render/renderer_internal.h"

/* ---------------------------------------------------------------- present */

/* Draws textures tex[0] (and tex[1] for a packed stereo layout), each
 * w x h, into the window's back buffer, then glFinish; gl_rows: their row 0
 * is the image's bottom (drawn by GL) instead of its top (uploaded). */
static int draw_eyes(cv_renderer *r, const GLuint tex[2], int w, int h, int layout, int gl_rows, cv_err *err) {
  const int packed = layout == CV_STEREO_SIDE_BY_SIDE || layout == CV_STEREO_TOP_BOTTOM;
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
  /* 1:1 pixels copy exactly; another window size is filtered. */
  const int exact = layout == CV_STEREO_SIDE_BY_SIDE ? (2 * w == ww && h == wh)
                    : layout == CV_STEREO_TOP_BOTTOM ? (w == ww && 2 * h == wh)
                                                     : (w == ww && h == wh);
  const GLint filt = exact ? GL_NEAREST : GL_LINEAR;
  const GLint loc = glGetUniformLocation(r->prog_present, "u_rect");
  glUniform1i(glGetUniformLocation(r->prog_present, "u_gl_rows"), gl_rows);
  glBindVertexArray(r->vao_empty);
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

int cv_renderer_present(cv_renderer *r, const uint8_t *left, const uint8_t *right, int w, int h,
                        int layout, cv_err *err) {
  if (!r->win) return cv_err_set(err, CV_ERR_INVALID, "renderer: no window to present on");
  const int packed = layout == CV_STEREO_SIDE_BY_SIDE || layout == CV_STEREO_TOP_BOTTOM;
  if (!left || w < 1 || h < 1 || (packed && !right))
    return cv_err_set(err, CV_ERR_INVALID, "renderer: present: no image or bad size");
  if (cv_egl_make_current(&r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  /* the uploaded codes: one texture per eye (the first draw must not read a
   * texture the second upload rewrites) */
  const int eyes = packed ? 2 : 1;
  if (!r->tex_present[0]) glGenTextures(2, r->tex_present);
  if (r->present_w != w || r->present_h != h) {
    r->present_made[0] = r->present_made[1] = 0;
    r->present_w = w, r->present_h = h;
  }
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  for (int e = 0; e < eyes; e++) {
    glBindTexture(GL_TEXTURE_2D, r->tex_present[e]);
    if (!r->present_made[e])
      glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB8, w, h, 0, GL_RGB, GL_UNSIGNED_BYTE, e ? right : left);
    else
      glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE, e ? right : left);
    r->present_made[e] = 1;
    r->io_up += 3 * (size_t)w * h;
  }
  return draw_eyes(r, r->tex_present, w, h, layout, 0, err);
}

int cv_renderer_present_slots(cv_renderer *r, int layout, cv_err *err) {
  if (!r->win) return cv_err_set(err, CV_ERR_INVALID, "renderer: no window to present on");
  const int packed = layout == CV_STEREO_SIDE_BY_SIDE || layout == CV_STEREO_TOP_BOTTOM;
  int w = 0, h = 0, w1 = 0, h1 = 0;
  GLuint tex[2] = {cvr_post_slot_texture(r, 0, &w, &h), cvr_post_slot_texture(r, 1, &w1, &h1)};
  if (!tex[0] || (packed && !tex[1]))
    return cv_err_set(err, CV_ERR_INVALID, "renderer: present: no projector image (cv_renderer_post_grid)");
  if (cv_egl_make_current(&r->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  return draw_eyes(r, tex, w, h, layout, 1, err);
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
