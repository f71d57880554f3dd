/* The pre-flight's questions to this host's X server and EGL (probe.h). */
#include "render/probe.h"

#include <GL/gl.h>
#include <stdio.h>

#include "render/egl_context.h"
#include "render/window.h"

int cv_probe_display(const char *display, cv_err *err) {
  cv_window *w = NULL;
  int st = cv_window_connect(display, &w, err);
  if (st) return st;
  cv_window_destroy(w);
  return CV_OK;
}

int cv_probe_gpu(int gpu, char *renderer, size_t cap, int *software, cv_err *err) {
  cv_egl_request rq = {gpu, NULL, NULL};
  cv_egl e;
  int st = cv_egl_open(&rq, &e, err);
  if (st) return st;
  const char *r = (const char *)glGetString(GL_RENDERER);
  snprintf(renderer, cap, "%s (%s)", r ? r : "unknown renderer", e.platform);
  *software = e.software || (r && cv_gl_renderer_is_software(r));
  cv_egl_close(&e);
  return CV_OK;
}
