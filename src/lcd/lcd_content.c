/* The LCD panel's content image (gather.h, cv_lcd_content_load). */
#include "lcd/gather_internal.h"
#include "io/exr.h"
#include "io/png.h"

static double srgb_decode(double v) {
  return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
}

static void builtin_pattern(cv_image *img) {
  const int w = img->w, h = img->h;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      float *px = cv_image_at(img, x, y);
      double fx = (x + 0.5) / w, fy = (y + 0.5) / h;
      double r = 0, g = 0, b = 0; /* black (the panel's black luminance) */
      /* six lines of "text": blocks of glyph-sized bars */
      int line = (int)(fy * 12);
      if (fx > 0.06 && fx < 0.55 && line >= 2 && line < 12 && line % 2 == 0) {
        double gx = fx * 60;
        if (gx - floor(gx) < 0.7 && ((int)gx * 7 + line) % 5 != 0) r = g = b = 1.0;
      }
      /* a gauge: a coloured ring on the right */
      double dx = (fx - 0.78) * w / h, dy = fy - 0.5, rr = sqrt(dx * dx + dy * dy);
      if (rr > 0.25 && rr < 0.32) {
        double a = atan2(dy, dx);
        if (a < 0.6) r = 0.9, g = 0.15, b = 0.1;
        else r = 0.1, g = 0.8, b = 0.3;
      }
      px[0] = (float)r, px[1] = (float)g, px[2] = (float)b;
    }
}

int cv_lcd_content_load(const char *path, int w, int h, double panel_aspect, double white,
                        double black, cv_image **out, cv_err *err) {
  *out = NULL;
  if (w < 1 || h < 1 || !(black >= 0) || !(white >= black) || !isfinite(white) ||
      !isfinite(panel_aspect))
    return cv_err_set(err, CV_ERR_INVALID, "content: size %dx%d, white %g, black %g", w, h, white,
                      black);
  cv_image *img;
  if (cv_image_create(w, h, 3, &img)) return cv_err_set(err, CV_ERR_NOMEM, "content: out of memory");
  if (!path || !path[0]) {
    builtin_pattern(img);
  } else {
    cv_image *src = NULL;
    int st, is_png = 0;
    size_t n = strlen(path);
    if (n >= 4 && (!strcmp(path + n - 4, ".png") || !strcmp(path + n - 4, ".PNG"))) {
      is_png = 1;
      st = cv_png_read(path, &src, err);
    } else {
      st = cv_exr_read(path, &src, err);
    }
    if (st) {
      cv_image_destroy(img);
      return st;
    }
    double scale = 1;
    if (!is_png) {
      double ymax = 0;
      for (size_t i = 0; i < (size_t)src->w * src->h; i++) {
        const float *q = src->px + i * src->c;
        ymax = fmax(ymax, 0.2126 * q[0] + 0.7152 * q[1] + 0.0722 * q[2]);
      }
      scale = ymax > 0 ? 1 / ymax : 1;
    }
    /* the content's rectangle on the panel: its own aspect, as large as
     * fits, centred (no stretch); black around it */
    double fw = 1, fh = 1;
    const double ca = (double)src->w / src->h;
    if (panel_aspect > 0 && ca > panel_aspect) fh = panel_aspect / ca;
    else if (panel_aspect > 0) fw = ca / panel_aspect;
    const double ox = 0.5 * (1 - fw), oy = 0.5 * (1 - fh);
    /* box filter: average of a grid of nearest source pixels per texel */
    int gx = (int)ceil(src->w / (fw * w)), gy = (int)ceil(src->h / (fh * h));
    for (int y = 0; y < h; y++)
      for (int x = 0; x < w; x++) {
        double acc[3] = {0, 0, 0};
        for (int j = 0; j < gy; j++)
          for (int i = 0; i < gx; i++) {
            const double cu = ((x + (i + 0.5) / gx) / w - ox) / fw;
            const double cv = ((y + (j + 0.5) / gy) / h - oy) / fh;
            if (cu < 0 || cu >= 1 || cv < 0 || cv >= 1) continue; /* outside: black */
            int sx = (int)(cu * src->w), sy = (int)(cv * src->h);
            if (sx >= src->w) sx = src->w - 1;
            if (sy >= src->h) sy = src->h - 1;
            const float *q = cv_image_at(src, sx, sy);
            for (int c = 0; c < 3; c++) {
              double v = src->c >= 3 ? q[c] : q[0];
              acc[c] += is_png ? srgb_decode(v) : v * scale;
            }
          }
        float *px = cv_image_at(img, x, y);
        for (int c = 0; c < 3; c++) px[c] = (float)(acc[c] / (gx * gy));
      }
    cv_image_destroy(src);
  }
  size_t n3 = (size_t)w * h * 3;
  for (size_t i = 0; i < n3; i++) img->px[i] = (float)(black + img->px[i] * (white - black));
  *out = img;
  return CV_OK;
}
