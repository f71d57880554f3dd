/* The desktop preview window (see desktop.h), on plain Xlib: the image is
 * scaled into an XImage of the window's size and put with XPutImage. */
#include "render/desktop.h"

#include <math.h>

#include <X11/Xlib.h>
#include <X11/Xutil.h>
#include <X11/keysym.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

struct cv_desktop {
  Display *dpy;
  Window win;
  Visual *visual;
  int depth;
  GC gc;
  Colormap cmap;
  Atom wm_delete;
  int state;             /* CV_WIN_* (sticky) */
  int w, h;              /* window size */
  XImage *img;           /* w x h, what the window shows */
  uint8_t *src;          /* the last image shown (3 sw sh), for redraws */
  int sw, sh;
  int dragging, drag_x, drag_y;
  unsigned long rmask, gmask, bmask;
  int rshift, gshift, bshift;
  char name[64];
};

static int quiet_io_error(Display *d) {
  (void)d;
  return 0;
}

static void io_exit(Display *d, void *user) {
  (void)d;
  ((cv_desktop *)user)->state = CV_WIN_LOST;
}

static void set_state(cv_desktop *d, int s) {
  if (s > d->state) d->state = s;
}

static int shift_of(unsigned long mask) {
  int s = 0;
  while (mask && !(mask & 1)) mask >>= 1, s++;
  return s;
}

const char *cv_desktop_display_name(const cv_desktop *d) { return d ? d->name : ""; }

void cv_desktop_size(const cv_desktop *d, int *w, int *h) {
  *w = d->w;
  *h = d->h;
}

/* The window size for an image of w x h: as is, or shrunk to fit 90% of
 * the screen with the aspect kept. */
static void fit_screen(Display *dpy, int screen, int *w, int *h) {
  const double sw = 0.9 * DisplayWidth(dpy, screen), sh = 0.9 * DisplayHeight(dpy, screen);
  if (*w <= sw && *h <= sh) return;
  const double k = sw / *w < sh / *h ? sw / *w : sh / *h;
  *w = (int)(*w * k) > 0 ? (int)(*w * k) : 1;
  *h = (int)(*h * k) > 0 ? (int)(*h * k) : 1;
}

static int make_window(cv_desktop *d, const char *title, int w, int h, cv_err *err) {
  Display *dpy = d->dpy;
  const int screen = DefaultScreen(dpy);
  XVisualInfo vi;
  if (!XMatchVisualInfo(dpy, screen, 24, TrueColor, &vi) && !XMatchVisualInfo(dpy, screen, 32, TrueColor, &vi))
    return cv_err_set(err, CV_ERR_BACKEND, "X display '%s' has no 24-bit TrueColor visual", d->name);
  d->visual = vi.visual;
  d->depth = vi.depth;
  d->rmask = vi.red_mask, d->gmask = vi.green_mask, d->bmask = vi.blue_mask;
  d->rshift = shift_of(d->rmask), d->gshift = shift_of(d->gmask), d->bshift = shift_of(d->bmask);
  fit_screen(dpy, screen, &w, &h);
  XSetWindowAttributes a;
  memset(&a, 0, sizeof a);
  d->cmap = XCreateColormap(dpy, RootWindow(dpy, screen), vi.visual, AllocNone);
  a.colormap = d->cmap;
  a.background_pixel = 0;
  a.border_pixel = 0;
  a.event_mask = KeyPressMask | ButtonPressMask | ButtonReleaseMask | Button1MotionMask | StructureNotifyMask |
                 ExposureMask;
  d->win = XCreateWindow(dpy, RootWindow(dpy, screen), 0, 0, (unsigned)w, (unsigned)h, 0, vi.depth, InputOutput,
                         vi.visual, CWColormap | CWBackPixel | CWBorderPixel | CWEventMask, &a);
  d->w = w, d->h = h;
  XStoreName(dpy, d->win, title && title[0] ? title : "cave desktop");
  XSizeHints sz;
  memset(&sz, 0, sizeof sz);
  sz.flags = PSize | PMinSize;
  sz.width = w, sz.height = h, sz.min_width = sz.min_height = 32;
  XSetWMNormalHints(dpy, d->win, &sz);
  d->wm_delete = XInternAtom(dpy, "WM_DELETE_WINDOW", False);
  XSetWMProtocols(dpy, d->win, &d->wm_delete, 1);
  d->gc = XCreateGC(dpy, d->win, 0, NULL);
  XMapRaised(dpy, d->win);
  /* Wait (at most 2 s) for the MapNotify so the first image lands. */
  for (int i = 0; i < 2000 && d->state != CV_WIN_LOST; i++) {
    XEvent ev;
    if (XCheckTypedWindowEvent(dpy, d->win, MapNotify, &ev)) break;
    struct timespec ts = {0, 1000000};
    nanosleep(&ts, NULL);
  }
  XSync(dpy, False);
  if (d->state == CV_WIN_LOST)
    return cv_err_set(err, CV_ERR_BACKEND, "X display '%s': connection lost while creating the window", d->name);
  return CV_OK;
}

int cv_desktop_open(const char *display, const char *title, int w, int h, cv_desktop **out, cv_err *err) {
  return cv_desktop_open_scaled(display, title, w, h, 0, NULL, out, err);
}

int cv_desktop_open_scaled(const char *display, const char *title, int w, int h, double frac, int *k_out,
                           cv_desktop **out, cv_err *err) {
  *out = NULL;
  if (w < 1 || h < 1) return cv_err_set(err, CV_ERR_INVALID, "desktop window: size %dx%d", w, h);
  const char *name = display && display[0] ? display : getenv("DISPLAY");
  if (!name || !name[0]) return cv_err_set(err, CV_ERR_BACKEND, "no X display: DISPLAY is not set");
  cv_desktop *d = calloc(1, sizeof *d);
  if (!d) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  XSetIOErrorHandler(quiet_io_error);
  d->dpy = XOpenDisplay(name);
  if (!d->dpy) {
    free(d);
    return cv_err_set(err, CV_ERR_BACKEND,
                      "cannot open X display '%s' (is an X server running there, and XAUTHORITY set?)", name);
  }
  XSetIOErrorExitHandler(d->dpy, io_exit, d);
  snprintf(d->name, sizeof d->name, "%s", DisplayString(d->dpy));
  int k = 1;
  if (frac > 0) { /* on this connection: a server without -noreset resets when its last client leaves */
    const int scr = DefaultScreen(d->dpy);
    const double kk = fmin(frac * DisplayWidth(d->dpy, scr) / w, frac * DisplayHeight(d->dpy, scr) / h);
    k = kk >= 2 ? (int)kk : 1;
  }
  if (k_out) *k_out = k;
  int st = make_window(d, title, k * w, k * h, err);
  if (st) {
    cv_desktop_destroy(d);
    return st;
  }
  *out = d;
  return CV_OK;
}

/* The XImage at the window's size (re)allocated; 0 on success. */
static int ensure_image(cv_desktop *d) {
  if (d->img && d->img->width == d->w && d->img->height == d->h) return 0;
  if (d->img) XDestroyImage(d->img); /* frees its data too */
  d->img = NULL;
  char *data = calloc((size_t)d->w * d->h, 4);
  if (!data) return -1;
  d->img = XCreateImage(d->dpy, d->visual, (unsigned)d->depth, ZPixmap, 0, data, (unsigned)d->w, (unsigned)d->h,
                        32, 0);
  if (!d->img) {
    free(data);
    return -1;
  }
  return 0;
}

/* d->src scaled into d->img (nearest neighbour, aspect kept, centred);
 * the source column of each window column is tabulated once. */
static void scale_into_image(cv_desktop *d) {
  XImage *im = d->img;
  const int W = d->w, H = d->h, sw = d->sw, sh = d->sh;
  /* destination rectangle: the largest sw:sh box in W x H */
  int dw = W, dh = (int)((long)W * sh / sw);
  if (dh > H) dh = H, dw = (int)((long)H * sw / sh);
  if (dw < 1) dw = 1;
  if (dh < 1) dh = 1;
  const int ox = (W - dw) / 2, oy = (H - dh) / 2;
  const int fast = im->bits_per_pixel == 32 && im->byte_order == LSBFirst;
  int *col = malloc((size_t)W * sizeof *col);
  if (!col) return;
  for (int x = 0; x < W; x++) col[x] = x >= ox && x < ox + dw ? (int)((long)(x - ox) * sw / dw) : -1;
  for (int y = 0; y < H; y++) {
    const int inside_y = y >= oy && y < oy + dh;
    const int sy = inside_y ? (int)((long)(y - oy) * sh / dh) : 0;
    const uint8_t *row = d->src + 3 * (size_t)sy * sw;
    for (int x = 0; x < W; x++) {
      unsigned long p = 0;
      if (inside_y && col[x] >= 0) {
        const uint8_t *s = row + 3 * (size_t)col[x];
        p = (((unsigned long)s[0] << d->rshift) & d->rmask) | (((unsigned long)s[1] << d->gshift) & d->gmask) |
            (((unsigned long)s[2] << d->bshift) & d->bmask);
      }
      if (fast) {
        uint8_t *o = (uint8_t *)im->data + (size_t)y * im->bytes_per_line + 4 * (size_t)x;
        o[0] = (uint8_t)p, o[1] = (uint8_t)(p >> 8), o[2] = (uint8_t)(p >> 16), o[3] = (uint8_t)(p >> 24);
      } else {
        XPutPixel(im, x, y, p);
      }
    }
  }
  free(col);
}

static void redraw(cv_desktop *d) {
  if (!d->img || d->state == CV_WIN_LOST || !d->win) return;
  XPutImage(d->dpy, d->win, d->gc, d->img, 0, 0, 0, 0, (unsigned)d->w, (unsigned)d->h);
  XFlush(d->dpy);
}

/* The last image again at the window's (new) size. */
static void rescale(cv_desktop *d) {
  if (!d->src || ensure_image(d)) return;
  scale_into_image(d);
  redraw(d);
}

int cv_desktop_show(cv_desktop *d, const uint8_t *rgb, int w, int h, cv_err *err) {
  if (w < 1 || h < 1 || !rgb) return cv_err_set(err, CV_ERR_INVALID, "desktop window: image %dx%d", w, h);
  if (d->state == CV_WIN_LOST)
    return cv_err_set(err, CV_ERR_BACKEND, "X display '%s': connection lost", d->name);
  const size_t n = 3 * (size_t)w * h;
  if (w != d->sw || h != d->sh) {
    free(d->src);
    d->src = malloc(n);
    d->sw = d->src ? w : 0, d->sh = d->src ? h : 0;
  }
  if (!d->src || ensure_image(d)) return cv_err_set(err, CV_ERR_NOMEM, "desktop window: out of memory");
  memcpy(d->src, rgb, n);
  scale_into_image(d);
  redraw(d);
  return CV_OK;
}

static void take_key(cv_desktop *d, XKeyEvent *k, cv_desktop_input *in) {
  const KeySym s = XLookupKeysym(k, 0);
  switch (s) {
  case XK_Escape: set_state(d, CV_WIN_ESCAPE); return;
  case XK_Right: case XK_d: in->right++; break;
  case XK_Left: case XK_a: in->right--; break;
  case XK_Up: case XK_w: in->forward++; break;
  case XK_Down: case XK_s: in->forward--; break;
  case XK_Page_Up: case XK_q: in->up++; break;
  case XK_Page_Down: case XK_e: in->up--; break;
  case XK_r: in->reset = 1; break;
  default: return;
  }
  in->events++;
}

static void take_event(cv_desktop *d, XEvent *ev, cv_desktop_input *in) {
  switch (ev->type) {
  case KeyPress: take_key(d, &ev->xkey, in); break;
  case ButtonPress:
    if (ev->xbutton.button == Button1) {
      d->dragging = 1, d->drag_x = ev->xbutton.x, d->drag_y = ev->xbutton.y;
      in->events++;
    }
    break;
  case ButtonRelease:
    if (ev->xbutton.button == Button1) d->dragging = 0;
    break;
  case MotionNotify:
    if (d->dragging) {
      in->drag_x += ev->xmotion.x - d->drag_x;
      in->drag_y += ev->xmotion.y - d->drag_y;
      d->drag_x = ev->xmotion.x, d->drag_y = ev->xmotion.y;
      in->events++;
    }
    break;
  case Expose:
    if (ev->xexpose.count == 0) redraw(d);
    break;
  case ConfigureNotify:
    if (ev->xconfigure.width != d->w || ev->xconfigure.height != d->h) {
      d->w = ev->xconfigure.width, d->h = ev->xconfigure.height;
      rescale(d);
    }
    break;
  case ClientMessage:
    if ((Atom)ev->xclient.data.l[0] == d->wm_delete) set_state(d, CV_WIN_CLOSED);
    break;
  case DestroyNotify:
    if (ev->xdestroywindow.window == d->win) {
      set_state(d, CV_WIN_CLOSED);
      d->win = 0;
    }
    break;
  case UnmapNotify:
    /* a desktop window may be minimised: only the close button stops */
    break;
  default:
    break;
  }
}

int cv_desktop_poll(cv_desktop *d, cv_desktop_input *in) {
  if (!d) return CV_WIN_OK;
  cv_desktop_input sink;
  memset(&sink, 0, sizeof sink);
  if (!in) in = &sink;
  while (d->state != CV_WIN_LOST && XPending(d->dpy) > 0) {
    XEvent ev;
    XNextEvent(d->dpy, &ev);
    take_event(d, &ev, in);
  }
  return d->state;
}

void cv_desktop_destroy(cv_desktop *d) {
  if (!d) return;
  if (d->img) XDestroyImage(d->img); /* client memory only */
  if (d->state != CV_WIN_LOST) {
    if (d->gc) XFreeGC(d->dpy, d->gc);
    if (d->win) XDestroyWindow(d->dpy, d->win);
    if (d->cmap) XFreeColormap(d->dpy, d->cmap);
    XSync(d->dpy, False);
  }
  XCloseDisplay(d->dpy);
  free(d->src);
  free(d);
}
