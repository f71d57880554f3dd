/* EGL context: GPU choice by device enumeration, headless or on an X11
 * window (see egl_context.h). */
#include "render/egl_context.h"

#include <EGL/eglext.h>
#include <GL/gl.h>
#include <stdio.h>
#include <string.h>

#include "view/cave.h"

static int has_ext(const char *list, const char *name) {
  if (!list) return 0;
  size_t n = strlen(name);
  for (const char *p = list; (p = strstr(p, name)); p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == 0)) return 1;
  return 0;
}

static void note(char *log, size_t cap, const char *what, const char *why, EGLint code) {
  size_t len = strlen(log);
  if (len + 1 < cap) snprintf(log + len, cap - len, "%s: %s (0x%x); ", what, why, (unsigned)code);
}

int cv_gl_renderer_is_software(const char *r) {
  return r && (strstr(r, "llvmpipe") || strstr(r, "softpipe") || strstr(r, "swrast") ||
               strstr(r, "SwiftShader"));
}

static const EGLint k_ctx_attr[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_CONTEXT_MINOR_VERSION, 3,
                                    EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                    EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};

/* Initialises dpy and creates a current GL 3.3 core context without a
 * window (surfaceless, or a 1x1 pbuffer). */
static int headless_context(EGLDisplay dpy, const char *what, cv_egl *e, char *log, size_t cap) {
  if (dpy == EGL_NO_DISPLAY) {
    note(log, cap, what, "no display", eglGetError());
    return 0;
  }
  EGLint maj, min;
  if (!eglInitialize(dpy, &maj, &min)) {
    note(log, cap, what, "eglInitialize failed", eglGetError());
    return 0;
  }
  if (!eglBindAPI(EGL_OPENGL_API)) {
    note(log, cap, what, "no desktop OpenGL API", eglGetError());
    return 0;
  }
  const char *ext = eglQueryString(dpy, EGL_EXTENSIONS);
  EGLConfig cfg = EGL_NO_CONFIG_KHR;
  int need_pbuffer = !has_ext(ext, "EGL_KHR_surfaceless_context");
  if (!has_ext(ext, "EGL_KHR_no_config_context") || need_pbuffer) {
    const EGLint attr[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_NONE};
    EGLint n = 0;
    if (!eglChooseConfig(dpy, attr, &cfg, 1, &n) || n < 1) {
      note(log, cap, what, "no OpenGL config", eglGetError());
      return 0;
    }
  }
  EGLContext ctx = eglCreateContext(dpy, cfg, EGL_NO_CONTEXT, k_ctx_attr);
  if (ctx == EGL_NO_CONTEXT) {
    note(log, cap, what, "cannot create a GL 3.3 core context", eglGetError());
    return 0;
  }
  EGLSurface surf = EGL_NO_SURFACE;
  if (need_pbuffer) {
    const EGLint pa[] = {EGL_WIDTH, 1, EGL_HEIGHT, 1, EGL_NONE};
    surf = eglCreatePbufferSurface(dpy, cfg, pa);
  }
  if (!eglMakeCurrent(dpy, surf, surf, ctx)) {
    note(log, cap, what, "eglMakeCurrent failed", eglGetError());
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

typedef struct devices {
  EGLDeviceEXT dev[16];
  int soft[16];
  int n, n_hw;
} devices;

static PFNEGLGETPLATFORMDISPLAYEXTPROC get_platform_display(void) {
  return (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
}

static void list_devices(devices *d) {
  memset(d, 0, sizeof *d);
  const char *cext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!has_ext(cext, "EGL_EXT_device_enumeration") && !has_ext(cext, "EGL_EXT_device_base")) return;
  PFNEGLQUERYDEVICESEXTPROC qd = (PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
  PFNEGLQUERYDEVICESTRINGEXTPROC qs =
      (PFNEGLQUERYDEVICESTRINGEXTPROC)eglGetProcAddress("eglQueryDeviceStringEXT");
  EGLint n = 0;
  if (!qd || !qs || !qd(16, d->dev, &n)) return;
  d->n = n;
  for (int i = 0; i < n; i++) {
    d->soft[i] = has_ext(qs(d->dev[i], EGL_EXTENSIONS), "EGL_MESA_device_software");
    d->n_hw += !d->soft[i];
  }
}

static const char *device_file(EGLDeviceEXT dev) {
  PFNEGLQUERYDEVICESTRINGEXTPROC qs =
      (PFNEGLQUERYDEVICESTRINGEXTPROC)eglGetProcAddress("eglQueryDeviceStringEXT");
  const char *f = qs ? qs(dev, EGL_DRM_DEVICE_FILE_EXT) : NULL;
  return f ? f : "no DRM file";
}

static int try_device(const devices *d, int i, int hw_index, cv_egl *e, char *log, size_t cap) {
  PFNEGLGETPLATFORMDISPLAYEXTPROC gpd = get_platform_display();
  char what[96];
  if (d->soft[i]) snprintf(what, sizeof what, "software device (EGL device %d)", i);
  else snprintf(what, sizeof what, "hardware device %d (%s)", hw_index, device_file(d->dev[i]));
  return gpd && headless_context(gpd(EGL_PLATFORM_DEVICE_EXT, d->dev[i], NULL), what, e, log, cap);
}

static int open_headless(int gpu, const devices *d, cv_egl *e, cv_err *err) {
  char log[600] = "";
  if (gpu >= 0 || (gpu == CV_GPU_AUTO && d->n_hw > 0)) {
    int hw = -1;
    for (int i = 0; i < d->n; i++) {
      if (d->soft[i]) continue;
      hw++;
      if (gpu >= 0 && hw != gpu) continue;
      if (try_device(d, i, hw, e, log, sizeof log)) return CV_OK;
    }
    size_t len = strlen(log);
    if (len >= 2) log[len - 2] = 0;
    if (gpu >= 0 && gpu >= d->n_hw)
      return cv_err_set(err, CV_ERR_BACKEND,
                        "GPU %d: no hardware EGL device %d; this machine has %d (use gpu \"software\" "
                        "for Mesa's llvmpipe)", gpu, gpu, d->n_hw);
    return cv_err_set(err, CV_ERR_BACKEND, "no context on the requested hardware EGL device: %s", log);
  }
  /* software, or auto without hardware devices */
  for (int i = 0; i < d->n; i++)
    if (d->soft[i] && try_device(d, i, -1, e, log, sizeof log)) {
      e->software = 1;
      return CV_OK;
    }
  PFNEGLGETPLATFORMDISPLAYEXTPROC gpd = get_platform_display();
  const char *cext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (d->n == 0 && gpd && has_ext(cext, "EGL_MESA_platform_surfaceless") &&
      headless_context(gpd(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL),
                       "Mesa surfaceless (no EGL device enumeration)", e, log, sizeof log)) {
    e->software = cv_gl_renderer_is_software((const char *)glGetString(GL_RENDERER));
    if (e->software || gpu == CV_GPU_AUTO) return CV_OK;
    cv_egl_close(e);
    return cv_err_set(err, CV_ERR_BACKEND, "software renderer requested, but Mesa surfaceless renders on %s",
                      (const char *)glGetString(GL_RENDERER));
  }
  size_t len = strlen(log);
  if (len >= 2) log[len - 2] = 0;
  return cv_err_set(err, CV_ERR_BACKEND, "no software EGL device (Mesa's EGL_MESA_device_software)%s%s",
                    log[0] ? ": " : "", log);
}

static int open_window(const cv_egl_request *rq, const devices *d, cv_egl *e, cv_err *err) {
  if (rq->gpu >= 0 && rq->gpu >= d->n_hw)
    return cv_err_set(err, CV_ERR_BACKEND,
                      "GPU %d: no hardware EGL device %d; this machine has %d (use gpu \"software\" "
                      "for Mesa's llvmpipe)", rq->gpu, rq->gpu, d->n_hw);
  const char *xname = cv_window_display_name(rq->window);
  PFNEGLGETPLATFORMDISPLAYEXTPROC gpd = get_platform_display();
  const char *cext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!gpd || !(has_ext(cext, "EGL_KHR_platform_x11") || has_ext(cext, "EGL_EXT_platform_x11")))
    return cv_err_set(err, CV_ERR_BACKEND, "this EGL has no X11 platform (EGL_KHR_platform_x11)");
  EGLDisplay dpy = gpd(EGL_PLATFORM_X11_KHR, cv_window_xdisplay(rq->window), NULL);
  EGLint maj, min;
  if (dpy == EGL_NO_DISPLAY || !eglInitialize(dpy, &maj, &min))
    return cv_err_set(err, CV_ERR_BACKEND, "X display '%s': no EGL display (0x%x)", xname, eglGetError());
  if (!eglBindAPI(EGL_OPENGL_API))
    return cv_err_set(err, CV_ERR_BACKEND, "X display '%s': EGL has no desktop OpenGL", xname);
  const EGLint attr[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, EGL_WINDOW_BIT,
                         EGL_RED_SIZE, 8, EGL_GREEN_SIZE, 8, EGL_BLUE_SIZE, 8, EGL_NONE};
  EGLConfig cfg;
  EGLint n = 0;
  if (!eglChooseConfig(dpy, attr, &cfg, 1, &n) || n < 1)
    return cv_err_set(err, CV_ERR_BACKEND, "X display '%s': no 8-bit RGB OpenGL window config", xname);
  EGLint vid = 0;
  eglGetConfigAttrib(dpy, cfg, EGL_NATIVE_VISUAL_ID, &vid);
  int st = cv_window_create(rq->window, (unsigned long)vid, rq->spec, err);
  if (st) return st;
  EGLContext ctx = eglCreateContext(dpy, cfg, EGL_NO_CONTEXT, k_ctx_attr);
  if (ctx == EGL_NO_CONTEXT)
    return cv_err_set(err, CV_ERR_BACKEND, "X display '%s': cannot create a GL 3.3 core context (0x%x)", xname,
                      eglGetError());
  EGLSurface surf = eglCreateWindowSurface(dpy, cfg, (EGLNativeWindowType)cv_window_native(rq->window), NULL);
  if (surf == EGL_NO_SURFACE || !eglMakeCurrent(dpy, surf, surf, ctx)) {
    EGLint code = eglGetError();
    if (surf != EGL_NO_SURFACE) eglDestroySurface(dpy, surf);
    eglDestroyContext(dpy, ctx);
    return cv_err_set(err, CV_ERR_BACKEND, "X display '%s': no window surface (0x%x)", xname, code);
  }
  eglSwapInterval(dpy, 1);
  e->dpy = dpy;
  e->ctx = ctx;
  e->surf = surf;
  e->window = 1;
  snprintf(e->platform, sizeof e->platform, "x11 %s", xname);
  const char *gl = (const char *)glGetString(GL_RENDERER);
  e->software = cv_gl_renderer_is_software(gl);
  if (e->software && (rq->gpu >= 0 || (rq->gpu == CV_GPU_AUTO && d->n_hw > 0))) {
    cv_egl_close(e);
    return cv_err_set(err, CV_ERR_BACKEND,
                      "X display '%s' renders with %s (software) although %s; run the X server of "
                      "this output on the GPU (docs/deploy.md)", xname, gl ? gl : "?",
                      rq->gpu >= 0 ? "a hardware GPU was requested" : "this host has a hardware GPU");
  }
  if (!e->software && rq->gpu == CV_GPU_SOFTWARE) {
    cv_egl_close(e);
    return cv_err_set(err, CV_ERR_BACKEND,
                      "X display '%s' renders with %s (hardware) although gpu \"software\" was requested",
                      xname, gl ? gl : "?");
  }
  return CV_OK;
}

int cv_egl_open(const cv_egl_request *rq, cv_egl *e, cv_err *err) {
  memset(e, 0, sizeof *e);
  cv_egl_request def = {CV_GPU_AUTO, NULL, NULL};
  if (!rq) rq = &def;
  devices d;
  list_devices(&d);
  e->hw_devices = d.n_hw;
  int st = rq->window ? open_window(rq, &d, e, err) : open_headless(rq->gpu, &d, e, err);
  e->hw_devices = d.n_hw;
  return st;
}

int cv_egl_make_current(const cv_egl *e) {
  if (eglGetCurrentContext() == e->ctx) return CV_OK;
  return eglMakeCurrent(e->dpy, e->surf, e->surf, e->ctx) ? CV_OK : CV_ERR_BACKEND;
}

int cv_egl_swap(const cv_egl *e) {
  if (!e->window) return CV_OK;
  return eglSwapBuffers(e->dpy, e->surf) ? CV_OK : CV_ERR_BACKEND;
}

void cv_egl_close(cv_egl *e) {
  if (!e || e->dpy == EGL_NO_DISPLAY || !e->dpy) return;
  if (eglGetCurrentContext() == e->ctx) eglMakeCurrent(e->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  if (e->surf != EGL_NO_SURFACE) eglDestroySurface(e->dpy, e->surf);
  eglDestroyContext(e->dpy, e->ctx);
  e->dpy = EGL_NO_DISPLAY;
}
