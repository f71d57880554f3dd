/* X11 windows of the wall-eye renderer (internal to src/render): one
 * borderless window per output on an X display, fullscreen through the
 * window manager's _NET_WM_STATE_FULLSCREEN hint (or, without a window
 * manager, an override-redirect window at the screen's size) or placed at a
 * given geometry, cursor hidden, closable by Escape or the window manager.
 *
 * The connection is opened first (EGL needs the Display to choose a config
 * whose native visual the window then uses), the window second.  A lost
 * connection does not end the process (Xlib's default): an IO-error exit
 * handler (libX11 >= 1.7, XSetIOErrorExitHandler) marks the window lost and
 * every later call returns at once, so the service can stop cleanly. */
#ifndef CV_RENDER_WINDOW_H
#define CV_RENDER_WINDOW_H

#include "core/status.h"

typedef struct cv_window_spec {
  const char *display; /* X display name; NULL or "" = $DISPLAY */
  int x, y, w, h;      /* geometry in pixels (ignored when fullscreen) */
  int fullscreen;
  const char *title;   /* window title (operators and tests find windows by it) */
} cv_window_spec;

/* What the window was told since the last poll (highest wins). */
enum { CV_WIN_OK = 0, CV_WIN_CLOSED = 1, CV_WIN_ESCAPE = 2, CV_WIN_LOST = 3 };
/* "ok", "window closed", "Escape pressed", "X connection lost". */
const char *cv_window_event_name(int ev);

typedef struct cv_window cv_window;

/* Opens the connection to the X display.  Errors: CV_ERR_BACKEND naming
 * the display ("cannot open X display ':5' (is an X server running there,
 * and DISPLAY/XAUTHORITY set?)").  *out owned by the caller. */
int cv_window_connect(const char *display, cv_window **out, cv_err *err);
/* The Xlib Display* (for eglGetPlatformDisplay). */
void *cv_window_xdisplay(const cv_window *w);
/* The display's name as Xlib reports it (":99"). */
const char *cv_window_display_name(const cv_window *w);
/* Creates and maps the window with the X visual `visual_id` (from the EGL
 * config's EGL_NATIVE_VISUAL_ID) and waits until it is mapped.  Errors:
 * CV_ERR_BACKEND (no such visual, geometry off the screen). */
int cv_window_create(cv_window *w, unsigned long visual_id, const cv_window_spec *spec, cv_err *err);
/* The X window id (for eglCreateWindowSurface); 0 before create. */
unsigned long cv_window_native(const cv_window *w);
/* Current size in pixels. */
void cv_window_size(const cv_window *w, int *width, int *height);
/* Drains the event queue; returns the strongest CV_WIN_* seen (sticky:
 * once closed or lost, always that). */
int cv_window_poll(cv_window *w);
/* Destroys the window and closes the connection; accepts NULL. */
void cv_window_destroy(cv_window *w);

#endif
