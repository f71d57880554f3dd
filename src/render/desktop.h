/* The desktop preview window (`cave run --present desktop`): one ordinary
 * X11 window on a desktop (plain Xlib, no GL) that shows an 8-bit RGB
 * image with XPutImage, scaled to the window (nearest neighbour, aspect
 * kept, black bars; 1:1 when the window has the image's size), and turns
 * the keyboard and mouse into head-steering input:
 *   Right/D, Left/A        step right / left        (input.right +-1)
 *   Up/W, Down/S           step forward / back      (input.forward +-1)
 *   Page_Up/Q, Page_Down/E step up / down           (input.up +-1)
 *   left-button drag       turn the gaze            (input.drag_x/y, pixels)
 *   R                      back to the home pose    (input.reset)
 *   Escape, the window manager's close, a lost X connection: the window's
 *   state (CV_WIN_* of render/window.h), sticky.
 * A lost connection does not end the process: as in window.c, an IO-error
 * exit handler marks the window lost and every later call returns at once.
 * No MPI and no service knowledge here: the caller decides what the input
 * means and what the image is. */
#ifndef CV_RENDER_DESKTOP_H
#define CV_RENDER_DESKTOP_H

#include <stdint.h>

#include "core/status.h"
#include "render/window.h"

typedef struct cv_desktop cv_desktop;

/* Input since the last poll (summed over the events taken). */
typedef struct cv_desktop_input {
  int right, forward, up; /* key presses, signed */
  double drag_x, drag_y;  /* left-button drag in pixels (+x right, +y down) */
  int reset;              /* R pressed */
  int events;             /* key and button events taken */
} cv_desktop_input;

/* Opens the X display (display NULL or "" = $DISPLAY) and maps a titled,
 * resizable window of w x h pixels (shrunk, aspect kept, to fit the
 * screen).  Errors: CV_ERR_BACKEND naming the display ("DISPLAY is not set",
 * "cannot open X display ':5' ...", no 24/32-bit TrueColor visual),
 * CV_ERR_INVALID (w or h < 1), CV_ERR_NOMEM.  *out owned by the caller
 * (cv_desktop_destroy). */
int cv_desktop_open(const char *display, const char *title, int w, int h, cv_desktop **out, cv_err *err);
/* As cv_desktop_open, at k times w x h: k the largest whole number that
 * keeps the window within frac of the screen's width and height (1 at
 * least; frac <= 0: 1), into *k_out (may be NULL). */
int cv_desktop_open_scaled(const char *display, const char *title, int w, int h, double frac, int *k_out,
                           cv_desktop **out, cv_err *err);
/* The display's name as Xlib reports it (":99"). */
const char *cv_desktop_display_name(const cv_desktop *d);
/* The window's current size in pixels. */
void cv_desktop_size(const cv_desktop *d, int *w, int *h);
/* Shows rgb (3 w h bytes, rows top to bottom; copied: the caller keeps
 * it) scaled to the window, and flushes.  Errors: CV_ERR_INVALID (size < 1),
 * CV_ERR_NOMEM, CV_ERR_BACKEND (the connection is lost). */
int cv_desktop_show(cv_desktop *d, const uint8_t *rgb, int w, int h, cv_err *err);
/* Takes the pending events without blocking: adds the input to *in (may be
 * NULL: input dropped), redraws on expose and resize, and returns the
 * strongest CV_WIN_* seen so far (sticky). */
int cv_desktop_poll(cv_desktop *d, cv_desktop_input *in);
/* Destroys the window and closes the connection; accepts NULL. */
void cv_desktop_destroy(cv_desktop *d);

#endif
