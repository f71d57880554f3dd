/* EGL + desktop OpenGL context of the renderer (internal to src/render):
 * headless on a chosen EGL device, or on an X11 window.
 *
 * GPU choice (docs/deploy.md): EGL_EXT_device_enumeration lists the devices;
 * a device whose extensions include EGL_MESA_device_software is Mesa's
 * software renderer (llvmpipe), every other one is hardware (DRM, CUDA).
 *   gpu >= 0          the gpu-th HARDWARE device (software devices are not
 *                     counted); none there is an error, never a fallback;
 *   CV_GPU_AUTO       the first hardware device; when hardware devices exist
 *                     but none gives a context, an error; with none at all,
 *                     the software device, and e->software says so;
 *   CV_GPU_SOFTWARE   the software device.
 * Headless contexts use EGL_PLATFORM_DEVICE_EXT on the chosen device (Mesa
 * surfaceless only when the EGL has no device enumeration).
 *
 * Windows: eglGetPlatformDisplay(EGL_PLATFORM_X11_KHR, Display*), a config
 * with EGL_WINDOW_BIT whose EGL_NATIVE_VISUAL_ID the X window is created
 * with, a window surface, eglSwapInterval(1).  The X server decides which
 * GPU draws; the renderer's GL_RENDERER is checked against the request (a
 * software renderer where hardware was asked for is an error).
 *
 * Each attempt's failure is kept for the error message.  GL 3.3 core. */
#ifndef CV_RENDER_EGL_CONTEXT_H
#define CV_RENDER_EGL_CONTEXT_H

#include <EGL/egl.h>

#include "core/status.h"
#include "render/window.h"

typedef struct cv_egl_request {
  int gpu;                     /* CV_GPU_AUTO, CV_GPU_SOFTWARE (view/cave.h) or a hardware index */
  cv_window *window;           /* connected, not yet created; NULL = headless */
  const cv_window_spec *spec;  /* the window's geometry (with window) */
} cv_egl_request;

typedef struct cv_egl {
  EGLDisplay dpy;
  EGLContext ctx;
  EGLSurface surf;     /* EGL_NO_SURFACE, a 1x1 pbuffer, or the window surface */
  int window;          /* 1: surf is a window surface (swap with cv_egl_swap) */
  int software;        /* 1: the renderer is a software rasteriser */
  int hw_devices;      /* hardware EGL devices this process sees */
  char platform[96];   /* "device 0 (hardware, /dev/dri/renderD128)", "software device", "x11 :99" */
} cv_egl;

/* Opens a display and a current context as requested; rq NULL = headless,
 * auto.  Errors: CV_ERR_BACKEND with what each attempt answered, or why the
 * request cannot be met ("--gpu 0: no hardware EGL device 0; this machine
 * has 0 (use --gpu software for llvmpipe)"). */
int cv_egl_open(const cv_egl_request *rq, cv_egl *e, cv_err *err);
/* Makes e's context current on this thread (no-op when it is). */
int cv_egl_make_current(const cv_egl *e);
/* Swaps the window surface (no-op headless).  CV_ERR_BACKEND on failure. */
int cv_egl_swap(const cv_egl *e);
/* Destroys the context and surface.  The display stays initialised for
 * the life of the process: EGL displays are process-wide singletons, so
 * eglTerminate would destroy the contexts of other renderers on it, and
 * Mesa unloads its driver on eglTerminate (reloading it costs ~100 ms and
 * leaves LeakSanitizer reports in an unloaded module). */
void cv_egl_close(cv_egl *e);

/* 1 when a GL_RENDERER string names a software rasteriser (llvmpipe,
 * softpipe, swrast, SwiftShader). */
int cv_gl_renderer_is_software(const char *renderer);

#endif
