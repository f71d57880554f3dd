/* Headless EGL context (see egl_context.h). */
#include "render/egl_context.h"

#include <EGL/eglext.h>
#include <stdio.h>
#include <string.h>

static int has_ext(const char *list, const char *name) {
  if (!list) return 0;
  size_t n = strlen(name);
  for (const char *p = list; (p = strstr(p, name)); p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == 0)) return 1;
  return 0;
}

static void note(char *log, size_t cap, const char *fmt, const char *what, EGLint code) {
  size_t len = strlen(log);
  if (len + 1 < cap) snprintf(log + len, cap - len, fmt, what, (unsigned)code);
}

/* Initialises dpy and creates a current GL 3.3 core context on it. */
static int try_display(EGLDisplay dpy, const char *what, cv_egl *e, char *log, size_t cap) {
  if (dpy == EGL_NO_DISPLAY) {
    note(log, cap, "%s: no display (0x%x); ", what, eglGetError());
    return 0;
  }
  EGLint maj, min;
  if (!eglInitialize(dpy, &maj, &min)) {
    note(log, cap, "%s: eglInitialize failed (0x%x); ", what, eglGetError());
    return 0;
  }
  if (!eglBindAPI(EGL_OPENGL_API)) {
    note(log, cap, "%s: no desktop OpenGL API (0x%x); ", what, eglGetError());
    return 0;
  }
  const char *ext = eglQueryString(dpy, EGL_EXTENSIONS);
  EGLConfig cfg = EGL_NO_CONFIG_KHR;
  int need_pbuffer = !has_ext(ext, "EGL_KHR_surfaceless_context");
  if (!has_ext(ext, "EGL_KHR_no_config_context") || need_pbuffer) {
    const EGLint attr[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE,
                           EGL_PBUFFER_BIT, EGL_NONE};
    EGLint n = 0;
    if (!eglChooseConfig(dpy, attr, &cfg, 1, &n) || n < 1) {
      note(log, cap, "%s: no OpenGL config (0x%x); ", what, eglGetError());
        return 0;
    }
  }
  const EGLint ca[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_CONTEXT_MINOR_VERSION, 3,
                       EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                       EGL_NONE};
  EGLContext ctx = eglCreateContext(dpy, cfg, EGL_NO_CONTEXT, ca);
  if (ctx == EGL_NO_CONTEXT) {
    note(log, cap, "%s: cannot create a GL 3.3 core context (0x%x); ", what, eglGetError());
    return 0;
  }
  EGLSurface surf = EGL_NO_SURFACE;
  if (need_pbuffer) {
    const EGLint pa[] = {EGL_WIDTH, 1, EGL_HEIGHT, 1, EGL_NONE};
    surf = eglCreatePbufferSurface(dpy, cfg, pa);
  }
  if (!eglMakeCurrent(dpy, surf, surf, ctx)) {
    note(log, cap, "%s: eglMakeCurrent failed (0x%x); ", what, eglGetError());
    if (surf != EGL_NO_SURFACE) eglDestroySurface(dpy, surf);
    eglDestroyContext(dpy, ctx);
    return 0;
  }
  e->dpy = dpy;
  e->ctx = ctx;
  e->surf = surf;
  snprintf(e->platform, sizeof e->platform, "%s", what);
  return 1;
}

int cv_egl_open(cv_egl *e, cv_err *err) {
  memset(e, 0, sizeof *e);
  char log[400] = "";
  const char *cext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  PFNEGLGETPLATFORMDISPLAYEXTPROC gpd =
      (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
  if (gpd && has_ext(cext, "EGL_MESA_platform_surfaceless") &&
      try_display(gpd(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL), "surfaceless",
                  e, log, sizeof log))
    return CV_OK;
  if (gpd && has_ext(cext, "EGL_EXT_platform_device")) {
    PFNEGLQUERYDEVICESEXTPROC qd = (PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
    EGLDeviceEXT dev[16];
    EGLint n = 0;
    if (qd && qd(16, dev, &n))
      for (EGLint i = 0; i < n; i++) {
        char what[32];
        snprintf(what, sizeof what, "device %d", (int)i);
        if (try_display(gpd(EGL_PLATFORM_DEVICE_EXT, dev[i], NULL), what, e, log, sizeof log))
          return CV_OK;
      }
  }
  if (try_display(eglGetDisplay(EGL_DEFAULT_DISPLAY), "default", e, log, sizeof log)) return CV_OK;
  size_t len = strlen(log);
  if (len >= 2) log[len - 2] = 0;
  return cv_err_set(err, CV_ERR_BACKEND, "no EGL display with a desktop GL 3.3 core context: %s",
                    log[0] ? log : "EGL reports nothing");
}

int cv_egl_make_current(const cv_egl *e) {
  if (eglGetCurrentContext() == e->ctx) return CV_OK;
  return eglMakeCurrent(e->dpy, e->surf, e->surf, e->ctx) ? CV_OK : CV_ERR_BACKEND;
}

void cv_egl_close(cv_egl *e) {
  if (!e || e->dpy == EGL_NO_DISPLAY || !e->dpy) return;
  if (eglGetCurrentContext() == e->ctx)
    eglMakeCurrent(e->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  if (e->surf != EGL_NO_SURFACE) eglDestroySurface(e->dpy, e->surf);
  eglDestroyContext(e->dpy, e->ctx);
  e->dpy = EGL_NO_DISPLAY;
}
