/* A small X client for the window tests (tests/cluster/test_present.sh,
 * test_desktop.sh):
 *   xcheck find TITLE              prints "id x y w h" of the window whose
 *                                  title starts with TITLE (root coordinates)
 *   xcheck compare TITLE FILE.png  compares the window's pixels with a PNG of
 *                                  the same size: prints "max N differing M of T"
 *                                  (channel codes), exit 0 when compared
 *   xcheck close TITLE             asks the window to close as a window
 *                                  manager does (WM_DELETE_WINDOW)
 *   xcheck grab TITLE|root OUT.png screenshot
 *   xcheck cells TITLE NX NY       splits the window into NX x NY cells and
 *                                  prints "col row mean max" per cell (mean
 *                                  and max of the channel codes)
 * Exit 1 with a message when the window is missing or the PNG unreadable. */
#include <X11/Xlib.h>
#include <X11/Xutil.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/png.h"

static Window find(Display *d, Window w, const char *title) {
  char *name = NULL;
  if (XFetchName(d, w, &name) && name) {
    int hit = !strncmp(name, title, strlen(title));
    XFree(name);
    if (hit) return w;
  }
  Window root, parent, *kids = NULL;
  unsigned n = 0;
  if (!XQueryTree(d, w, &root, &parent, &kids, &n)) return 0;
  Window found = 0;
  for (unsigned i = 0; i < n && !found; i++) found = find(d, kids[i], title);
  if (kids) XFree(kids);
  return found;
}

static int grab(Display *d, Window w, int *W, int *H, unsigned char **rgb) {
  XWindowAttributes a;
  if (!XGetWindowAttributes(d, w, &a)) return -1;
  XImage *img = XGetImage(d, w, 0, 0, (unsigned)a.width, (unsigned)a.height, AllPlanes, ZPixmap);
  if (!img) return -1;
  *W = a.width, *H = a.height;
  *rgb = malloc(3 * (size_t)a.width * a.height);
  for (int y = 0; y < a.height; y++)
    for (int x = 0; x < a.width; x++) {
      unsigned long p = XGetPixel(img, x, y);
      unsigned char *o = *rgb + 3 * ((size_t)y * a.width + x);
      o[0] = (unsigned char)((p & img->red_mask) >> __builtin_ctzl(img->red_mask));
      o[1] = (unsigned char)((p & img->green_mask) >> __builtin_ctzl(img->green_mask));
      o[2] = (unsigned char)((p & img->blue_mask) >> __builtin_ctzl(img->blue_mask));
    }
  XDestroyImage(img);
  return 0;
}

/* Mean and max code per cell of an nx x ny grid over the window. */
static int cells(Display *d, Window w, int nx, int ny) {
  int W, H;
  unsigned char *rgb;
  if (nx < 1 || ny < 1 || grab(d, w, &W, &H, &rgb)) {
    fprintf(stderr, "xcheck: cannot read the window's pixels (or a bad grid)\n");
    return 1;
  }
  for (int cy = 0; cy < ny; cy++)
    for (int cx = 0; cx < nx; cx++) {
      const int x0 = cx * W / nx, x1 = (cx + 1) * W / nx, y0 = cy * H / ny, y1 = (cy + 1) * H / ny;
      double sum = 0;
      int mx = 0;
      long n = 0;
      for (int y = y0; y < y1; y++)
        for (int x = x0; x < x1; x++)
          for (int c = 0; c < 3; c++, n++) {
            const int v = rgb[3 * ((size_t)y * W + x) + c];
            sum += v;
            if (v > mx) mx = v;
          }
      printf("%d %d %.2f %d\n", cx, cy, n ? sum / n : 0.0, mx);
    }
  free(rgb);
  return 0;
}

int main(int argc, char **argv) {
  if (argc < 3) {
    fprintf(stderr, "usage: xcheck find|compare|close|grab|cells TITLE [FILE | NX NY]\n");
    return 2;
  }
  Display *d = XOpenDisplay(NULL);
  if (!d) {
    fprintf(stderr, "xcheck: cannot open the X display\n");
    return 1;
  }
  const char *cmd = argv[1], *title = argv[2];
  Window w = !strcmp(title, "root") ? DefaultRootWindow(d) : find(d, DefaultRootWindow(d), title);
  if (!w) {
    fprintf(stderr, "xcheck: no window titled '%s...'\n", title);
    return 1;
  }
  int rc = 0;
  if (!strcmp(cmd, "find")) {
    XWindowAttributes a;
    Window child;
    int x, y;
    XGetWindowAttributes(d, w, &a);
    XTranslateCoordinates(d, w, DefaultRootWindow(d), 0, 0, &x, &y, &child);
    printf("0x%lx %d %d %d %d\n", (unsigned long)w, x, y, a.width, a.height);
  } else if (!strcmp(cmd, "close")) {
    XEvent ev;
    memset(&ev, 0, sizeof ev);
    ev.xclient.type = ClientMessage;
    ev.xclient.window = w;
    ev.xclient.message_type = XInternAtom(d, "WM_PROTOCOLS", False);
    ev.xclient.format = 32;
    ev.xclient.data.l[0] = (long)XInternAtom(d, "WM_DELETE_WINDOW", False);
    XSendEvent(d, w, False, NoEventMask, &ev);
    XSync(d, False);
  } else if ((!strcmp(cmd, "compare") || !strcmp(cmd, "grab")) && argc > 3) {
    int W, H;
    unsigned char *rgb;
    if (grab(d, w, &W, &H, &rgb)) {
      fprintf(stderr, "xcheck: cannot read the window's pixels\n");
      return 1;
    }
    cv_err err;
    if (!strcmp(cmd, "grab")) {
      if (cv_png_write(argv[3], W, H, 3, rgb, &err)) {
        fprintf(stderr, "xcheck: %s\n", err.msg);
        rc = 1;
      }
    } else {
      cv_image *ref;
      if (cv_png_read(argv[3], &ref, &err)) {
        fprintf(stderr, "xcheck: %s\n", err.msg);
        rc = 1;
      } else if (ref->w != W || ref->h != H || ref->c < 3) {
        fprintf(stderr, "xcheck: window %dx%d, PNG %dx%d\n", W, H, ref->w, ref->h);
        rc = 1;
      } else {
        int mx = 0;
        long differing = 0;
        for (long i = 0; i < (long)W * H; i++)
          for (int c = 0; c < 3; c++) {
            int a = rgb[3 * i + c], b = (int)(ref->px[i * ref->c + c] * 255.0f + 0.5f);
            int df = a > b ? a - b : b - a;
            if (df > mx) mx = df;
            differing += df != 0;
          }
        printf("max %d differing %ld of %ld\n", mx, differing, 3L * W * H);
      }
      cv_image_destroy(ref);
    }
    free(rgb);
  } else if (!strcmp(cmd, "cells") && argc > 4) {
    rc = cells(d, w, atoi(argv[3]), atoi(argv[4]));
  } else {
    fprintf(stderr, "usage: xcheck find|compare|close|grab|cells TITLE [FILE | NX NY]\n");
    rc = 2;
  }
  XCloseDisplay(d);
  return rc;
}
