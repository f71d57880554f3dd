/* Window presentation of the renderer: the projector image drawn into the
 * window's back buffer, glFinish, swap (see renderer.h). */
#include "render/renderer_internal.h"

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
  return cvr_gl_check("present", err);
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
