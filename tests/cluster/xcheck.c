/* A small X client for the window tests (tests/cluster/test_present.sh,
 * test_desktop.sh):
 *   xcheck find TITLE              prints "id x y w h" of the window whose
 *                                  title starts with TITLE (root coordinates)
 *   xcheck compare TITLE FILE.png [K [ROWS]]
 *                                  compares the window's pixels with a PNG of
 *                                  the same size: prints "max N differing M of T"
 *                                  (channel codes), exit 0 when compared; with K,
 *                                  the window shows the PNG's first ROWS rows
 *                                  (default all) K times enlarged at its top-left:
 *                                  window pixel (x, y) against PNG pixel (x/K, y/K)
 *   xcheck close TITLE             asks the window to close as a window
 *                                  manager does (WM_DELETE_WINDOW)
 *   xcheck grab TITLE|root OUT.png screenshot
 *   xcheck cells TITLE NX NY [W H] splits the window (or its top-left W x H)
 *                                  into NX x NY cells and prints "col row mean
 *                                  max" per cell (mean and max of the channel
 *                                  codes)
 *   xcheck diff A.png B.png X Y W H  prints the mean absolute difference of
 *                                  the channel codes of two PNGs in a rectangle
 *                                  (no X display needed)
 * Exit 1 with a message when the window is missing or the PNG unreadable. */
#include <X11/Xlib.h>
#include <X11/Xutil.h>
#include <math.h>
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
static int cells(Display *d, Window w, int nx, int ny, int rw, int rh) {
  int W, H, GW, GH;
  unsigned char *rgb;
  if (nx < 1 || ny < 1 || grab(d, w, &GW, &GH, &rgb)) {
    fprintf(stderr, "xcheck: cannot read the window's pixels (or a bad grid)\n");
    return 1;
  }
  W = rw > 0 && rw < GW ? rw : GW;
  H = rh > 0 && rh < GH ? rh : GH;
  for (int cy = 0; cy < ny; cy++)
    for (int cx = 0; cx < nx; cx++) {
      const int x0 = cx * W / nx, x1 = (cx + 1) * W / nx, y0 = cy * H / ny, y1 = (cy + 1) * H / ny;
      double sum = 0;
      int mx = 0;
      long n = 0;
      for (int y = y0; y < y1; y++)
        for (int x = x0; x < x1; x++)
          for (int c = 0; c < 3; c++, n++) {
            const int v = rgb[3 * ((size_t)y * GW + x) + c];
            sum += v;
            if (v > mx) mx = v;
          }
      printf("%d %d %.2f %d\n", cx, cy, n ? sum / n : 0.0, mx);
    }
  free(rgb);
  return 0;
}

/* Mean absolute difference of two PNGs' codes in a rectangle. */
static int diff(char **argv) {
  cv_image *a = NULL, *b = NULL;
  cv_err err;
  const int x0 = atoi(argv[4]), y0 = atoi(argv[5]), w = atoi(argv[6]), h = atoi(argv[7]);
  int rc = 1;
  if (cv_png_read(argv[2], &a, &err) || cv_png_read(argv[3], &b, &err)) {
    fprintf(stderr, "xcheck: %s\n", err.msg);
  } else if (a->w != b->w || a->h != b->h || a->c < 3 || b->c < 3 || x0 < 0 || y0 < 0 || w < 1 || h < 1 ||
             x0 + w > a->w || y0 + h > a->h) {
    fprintf(stderr, "xcheck: %dx%d and %dx%d, rectangle %d %d %d %d\n", a->w, a->h, b->w, b->h, x0, y0, w, h);
  } else {
    double s = 0;
    for (int y = y0; y < y0 + h; y++)
      for (int x = x0; x < x0 + w; x++)
        for (int c = 0; c < 3; c++)
          s += 255.0 * fabs((double)a->px[((size_t)y * a->w + x) * a->c + c] - b->px[((size_t)y * b->w + x) * b->c + c]);
    printf("%.3f\n", s / (3.0 * w * h));
    rc = 0;
  }
  cv_image_destroy(a);
  cv_image_destroy(b);
  return rc;
}

int main(int argc, char **argv) {
  if (argc == 8 && !strcmp(argv[1], "diff")) return diff(argv);
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
      } else {
        const int k = argc > 4 ? atoi(argv[4]) : 1;
        const int rows = argc > 5 ? atoi(argv[5]) : ref->h;
        const int cw = k * ref->w, ch = k * rows;
        if (k < 1 || rows < 1 || rows > ref->h || ref->c < 3 || (k == 1 && argc <= 4 && (ref->w != W || ref->h != H)) ||
            cw > W || ch > H) {
          fprintf(stderr, "xcheck: window %dx%d, PNG %dx%d (x%d, %d rows)\n", W, H, ref->w, ref->h, k, rows);
          rc = 1;
        } else {
          int mx = 0;
          long differing = 0;
          for (int y = 0; y < ch; y++)
            for (int x = 0; x < cw; x++)
              for (int c = 0; c < 3; c++) {
                const long i = (long)y * W + x, j = (long)(y / k) * ref->w + x / k;
                int a = rgb[3 * i + c], b = (int)(ref->px[j * ref->c + c] * 255.0f + 0.5f);
                int df = a > b ? a - b : b - a;
                if (df > mx) mx = df;
                differing += df != 0;
              }
          printf("max %d differing %ld of %ld\n", mx, differing, 3L * cw * ch);
        }
      }
      cv_image_destroy(ref);
    }
    free(rgb);
  } else if (!strcmp(cmd, "cells") && argc > 4) {
    rc = cells(d, w, atoi(argv[3]), atoi(argv[4]), argc > 6 ? atoi(argv[5]) : 0, argc > 6 ? atoi(argv[6]) : 0);
  } else {
    fprintf(stderr, "usage: xcheck find|compare|close|grab|cells TITLE [FILE | NX NY]\n");
    rc = 2;
  }
  XCloseDisplay(d);
  return rc;
}
