/* Headless EGL + desktop OpenGL context for the renderer (internal).
 *
 * Order of attempts: EGL_PLATFORM_SURFACELESS_MESA (Mesa: llvmpipe, or a
 * GPU through its Mesa driver), then every device of EGL_EXT_platform_device
 * (NVIDIA's EGL, which has no surfaceless platform), then the default
 * display.  On each: bind EGL_OPENGL_API, a 3.3 core context (drivers give
 * their highest compatible core version), no config where
 * EGL_KHR_no_config_context exists, made current without a surface
 * (EGL_KHR_surfaceless_context) or else on a 1x1 pbuffer; rendering goes to
 * FBOs anyway. */
#ifndef CV_RENDER_EGL_CONTEXT_H
#define CV_RENDER_EGL_CONTEXT_H

#include <EGL/egl.h>

#include "core/status.h"

typedef struct cv_egl {
  EGLDisplay dpy;
  EGLContext ctx;
  EGLSurface surf; /* EGL_NO_SURFACE, or the 1x1 pbuffer */
  char platform[32]; /* "surfaceless", "device 0", "default" */
} cv_egl;

/* Opens a display and a current context.  Errors: CV_ERR_BACKEND, the
 * message listing what each attempt answered. */
int cv_egl_open(cv_egl *e, cv_err *err);
/* Makes e's context current on this thread (no-op when it is). */
int cv_egl_make_current(const cv_egl *e);
/* Destroys the context (and pbuffer).  The display stays initialised for
 * the life of the process: EGL displays are process-wide singletons, so
 * eglTerminate would destroy the contexts of other renderers on it, and
 * Mesa unloads its driver on eglTerminate (reloading it costs ~100 ms and
 * leaves LeakSanitizer reports in an unloaded module).  Re-initialising an
 * initialised display is a no-op. */
void cv_egl_close(cv_egl *e);

#endif
