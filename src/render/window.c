/* X11 windows of the wall-eye renderer (see window.h), on Xlib. */
#include "render/window.h"

#include <X11/Xatom.h>
#include <X11/Xlib.h>
#include <X11/Xutil.h>
#include <X11/keysym.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

struct cv_window {
  Display *dpy;
  Window win;
  Colormap cmap;
  Cursor blank;
  Atom wm_delete;
  int state; /* CV_WIN_* (sticky) */
  int w, h;
  char name[64];
};

const char *cv_window_event_name(int ev) {
  switch (ev) {
  case CV_WIN_OK: return "ok";
  case CV_WIN_CLOSED: return "window closed";
  case CV_WIN_ESCAPE: return "Escape pressed";
  case CV_WIN_LOST: return "X connection lost";
  default: return "?";
  }
}

/* Xlib's IO-error handler is process-wide and has no user pointer; it only
 * keeps Xlib's default "XIO: fatal IO error" line from being the last word
 * (the exit handler below, per display, records the loss). */
static int quiet_io_error(Display *d) {
  (void)d;
  return 0;
}

/* Per display, with a user pointer: instead of exit(1), mark the window
 * lost; Xlib then refuses every further request on this display. */
static void io_exit(Display *d, void *user) {
  (void)d;
  ((cv_window *)user)->state = CV_WIN_LOST;
}

static void set_state(cv_window *w, int s) {
  if (s > w->state) w->state = s;
}

int cv_window_connect(const char *display, cv_window **out, cv_err *err) {
  *out = NULL;
  const char *name = display && display[0] ? display : getenv("DISPLAY");
  if (!name || !name[0])
    return cv_err_set(err, CV_ERR_BACKEND,
                      "no X display: the output names none and DISPLAY is not set");
  cv_window *w = calloc(1, sizeof *w);
  if (!w) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  XSetIOErrorHandler(quiet_io_error);
  w->dpy = XOpenDisplay(name);
  if (!w->dpy) {
    free(w);
    return cv_err_set(err, CV_ERR_BACKEND,
                      "cannot open X display '%s' (is an X server running there, and "
                      "XAUTHORITY set?)", name);
  }
  XSetIOErrorExitHandler(w->dpy, io_exit, w);
  snprintf(w->name, sizeof w->name, "%s", DisplayString(w->dpy));
  *out = w;
  return CV_OK;
}

void *cv_window_xdisplay(const cv_window *w) { return w ? w->dpy : NULL; }
const char *cv_window_display_name(const cv_window *w) { return w ? w->name : ""; }
unsigned long cv_window_native(const cv_window *w) { return w ? w->win : 0; }

void cv_window_size(const cv_window *w, int *width, int *height) {
  *width = w->w;
  *height = w->h;
}

/* No decorations: the Motif hint every window manager honours. */
static void borderless(cv_window *w) {
  struct {
    unsigned long flags, functions, decorations;
    long input_mode;
    unsigned long status;
  } hints = {2, 0, 0, 0, 0};
  Atom a = XInternAtom(w->dpy, "_MOTIF_WM_HINTS", False);
  XChangeProperty(w->dpy, w->win, a, a, 32, PropModeReplace, (unsigned char *)&hints, 5);
}

static int wm_running(Display *d, int screen) {
  Atom check = XInternAtom(d, "_NET_SUPPORTING_WM_CHECK", True);
  if (check == None) return 0;
  Atom type;
  int fmt;
  unsigned long n, after;
  unsigned char *data = NULL;
  int ok = XGetWindowProperty(d, RootWindow(d, screen), check, 0, 1, False, XA_WINDOW, &type, &fmt,
                              &n, &after, &data) == Success && data && n == 1;
  if (data) XFree(data);
  return ok;
}

static Cursor blank_cursor(Display *d, Window win) {
  static const char zero[8] = {0};
  Pixmap p = XCreateBitmapFromData(d, win, zero, 8, 8);
  XColor black;
  memset(&black, 0, sizeof black);
  Cursor c = XCreatePixmapCursor(d, p, p, &black, &black, 0, 0);
  XFreePixmap(d, p);
  return c;
}

int cv_window_create(cv_window *w, unsigned long visual_id, const cv_window_spec *spec, cv_err *err) {
  Display *d = w->dpy;
  XVisualInfo tmpl;
  memset(&tmpl, 0, sizeof tmpl);
  tmpl.visualid = visual_id;
  int nvi = 0;
  XVisualInfo *vi = XGetVisualInfo(d, VisualIDMask, &tmpl, &nvi);
  if (!vi || nvi < 1) {
    if (vi) XFree(vi);
    return cv_err_set(err, CV_ERR_BACKEND, "X display '%s' has no visual 0x%lx for the EGL config",
                      w->name, visual_id);
  }
  const int sw = DisplayWidth(d, vi->screen), sh = DisplayHeight(d, vi->screen);
  int x = spec->x, y = spec->y, ww = spec->w, hh = spec->h;
  const int fs = spec->fullscreen, wm = wm_running(d, vi->screen);
  if (fs) x = 0, y = 0, ww = sw, hh = sh;
  if (ww < 1 || hh < 1 || x >= sw || y >= sh || x + ww <= 0 || y + hh <= 0) {
    XFree(vi);
    return cv_err_set(err, CV_ERR_BACKEND,
                      "window %dx%d+%d+%d lies outside X display '%s' (%dx%d)", ww, hh, x, y,
                      w->name, sw, sh);
  }
  XSetWindowAttributes a;
  memset(&a, 0, sizeof a);
  w->cmap = XCreateColormap(d, RootWindow(d, vi->screen), vi->visual, AllocNone);
  a.colormap = w->cmap;
  a.background_pixel = 0;
  a.border_pixel = 0;
  a.event_mask = KeyPressMask | StructureNotifyMask | ExposureMask;
  /* Without a window manager nobody would honour the hints: place the
   * window ourselves (override-redirect keeps it where we put it). */
  a.override_redirect = fs && !wm;
  w->win = XCreateWindow(d, RootWindow(d, vi->screen), x, y, (unsigned)ww, (unsigned)hh, 0, vi->depth,
                         InputOutput, vi->visual,
                         CWColormap | CWBackPixel | CWBorderPixel | CWEventMask | CWOverrideRedirect, &a);
  XFree(vi);
  w->w = ww;
  w->h = hh;
  XStoreName(d, w->win, spec->title ? spec->title : "cave");
  XSizeHints sz;
  memset(&sz, 0, sizeof sz);
  sz.flags = USPosition | USSize | PMinSize | PMaxSize;
  sz.x = x, sz.y = y, sz.width = sz.min_width = sz.max_width = ww;
  sz.height = sz.min_height = sz.max_height = hh;
  XSetWMNormalHints(d, w->win, &sz);
  borderless(w);
  w->wm_delete = XInternAtom(d, "WM_DELETE_WINDOW", False);
  XSetWMProtocols(d, w->win, &w->wm_delete, 1);
  if (fs && wm) {
    Atom st = XInternAtom(d, "_NET_WM_STATE", False), full = XInternAtom(d, "_NET_WM_STATE_FULLSCREEN", False);
    XChangeProperty(d, w->win, st, XA_ATOM, 32, PropModeReplace, (unsigned char *)&full, 1);
  }
  w->blank = blank_cursor(d, w->win);
  XDefineCursor(d, w->win, w->blank);
  XMapRaised(d, w->win);
  XMoveWindow(d, w->win, x, y); /* some window managers move windows on map */
  /* Wait (at most 2 s) for the MapNotify so the first frame lands. */
  for (int i = 0; i < 2000 && w->state != CV_WIN_LOST; i++) {
    XEvent ev;
    if (XCheckTypedWindowEvent(d, w->win, MapNotify, &ev)) break;
    struct timespec ts = {0, 1000000};
    nanosleep(&ts, NULL);
  }
  XSync(d, False);
  if (w->state == CV_WIN_LOST)
    return cv_err_set(err, CV_ERR_BACKEND, "X display '%s': connection lost while creating the window", w->name);
  return CV_OK;
}

int cv_window_poll(cv_window *w) {
  if (!w || w->state == CV_WIN_LOST) return w ? w->state : CV_WIN_OK;
  while (w->state != CV_WIN_LOST && XPending(w->dpy) > 0) {
    XEvent ev;
    XNextEvent(w->dpy, &ev);
    switch (ev.type) {
    case KeyPress:
      if (XLookupKeysym(&ev.xkey, 0) == XK_Escape) set_state(w, CV_WIN_ESCAPE);
      break;
    case ClientMessage:
      if ((Atom)ev.xclient.data.l[0] == w->wm_delete) set_state(w, CV_WIN_CLOSED);
      break;
    case DestroyNotify:
      if (ev.xdestroywindow.window == w->win) {
        set_state(w, CV_WIN_CLOSED);
        w->win = 0;
      }
      break;
    case UnmapNotify:
      if (ev.xunmap.window == w->win) set_state(w, CV_WIN_CLOSED);
      break;
    default:
      break;
    }
  }
  return w->state;
}

void cv_window_destroy(cv_window *w) {
  if (!w) return;
  if (w->state != CV_WIN_LOST) {
    if (w->blank) XFreeCursor(w->dpy, w->blank);
    if (w->win) XDestroyWindow(w->dpy, w->win);
    if (w->cmap) XFreeColormap(w->dpy, w->cmap);
    XSync(w->dpy, False);
  }
  XCloseDisplay(w->dpy);
  free(w);
}
