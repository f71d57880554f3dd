/* Montage of one eye's walls: see montage.h. */
#include "view/montage.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "io/png.h"
#include "view/label.h"

static int cube_cell(const char *name, int *col, int *row) {
  static const struct {
    const char *name;
    int col, row;
  } tab[] = {{"front", 1, 1}, {"left", 0, 1}, {"right", 2, 1}, {"back", 3, 1},
             {"ceiling", 1, 0}, {"floor", 1, 2}};
  for (size_t i = 0; i < sizeof tab / sizeof tab[0]; i++)
    if (!strcmp(name, tab[i].name)) {
      *col = tab[i].col, *row = tab[i].row;
      return 0;
    }
  return -1;
}

int cv_montage_layout(const cv_cave *cave, const int *ws, const int *hs, int *x, int *y, int *W, int *H,
                      cv_err *err) {
  if (!cave || !ws || !hs || !x || !y || !W || !H || cave->n_walls < 1)
    return cv_err_set(err, CV_ERR_INVALID, "montage: no walls");
  int cube = 1, cw = 0, ch = 0, cols = 0;
  for (int i = 0; i < cave->n_walls; i++) {
    int c = 0, r = 0;
    if (ws[i] < 1 || hs[i] < 1) return cv_err_set(err, CV_ERR_INVALID, "montage: wall %d is %dx%d", i, ws[i], hs[i]);
    if (cube_cell(cave->walls[i].name, &c, &r)) cube = 0;
    if (i && (ws[i] != cw || hs[i] != ch)) cube = 0;
    if (ws[i] > cw) cw = ws[i];
    if (hs[i] > ch) ch = hs[i];
  }
  if (cube) {
    for (int i = 0; i < cave->n_walls; i++) {
      int c = 0, r = 0;
      cube_cell(cave->walls[i].name, &c, &r);
      if (c + 1 > cols) cols = c + 1;
      x[i] = c * cw, y[i] = r * ch;
    }
    /* three rows: the front stays on the middle row even without floor/ceiling */
    *W = cols * cw, *H = 3 * ch;
  } else {
    int x0 = 0;
    for (int i = 0; i < cave->n_walls; i++) {
      x[i] = x0, y[i] = 0;
      x0 += ws[i];
    }
    *W = x0, *H = ch;
  }
  return CV_OK;
}

int cv_montage_label_scale(int cell_w) { return cell_w >= 192 ? cell_w / 96 : 1; }

void cv_montage_label_walls(uint8_t *px, int W, int H, const cv_cave *cave, const int *x, const int *y, int scale) {
  static const uint8_t fg[3] = {255, 255, 160};
  for (int i = 0; i < cave->n_walls; i++) cv_label_draw(px, W, H, x[i] + scale, y[i] + scale, scale, cave->walls[i].name, fg);
}

int cv_montage_caption_lines(const char *caption) {
  int n = 1;
  for (const char *c = caption; *c; c++) n += *c == '\n';
  return n;
}

int cv_montage_write(const char *path, const cv_cave *cave, cv_image *const *disp, cv_err *err) {
  return cv_montage_write_labelled(path, cave, disp, NULL, err);
}

int cv_montage_write_labelled(const char *path, const cv_cave *cave, cv_image *const *disp, const char *caption,
                              cv_err *err) {
  if (!path || !cave || !disp || cave->n_walls < 1 || cave->n_walls > CV_CAVE_MAX_WALLS)
    return cv_err_set(err, CV_ERR_INVALID, "montage: no walls");
  /* a missing wall (NULL) takes the largest wall's size: a black cell */
  int ws[CV_CAVE_MAX_WALLS], hs[CV_CAVE_MAX_WALLS], xs[CV_CAVE_MAX_WALLS], ys[CV_CAVE_MAX_WALLS];
  int mw = 0, mh = 0;
  for (int i = 0; i < cave->n_walls; i++) {
    if (!disp[i]) continue;
    if (disp[i]->c < 3) return cv_err_set(err, CV_ERR_INVALID, "montage: wall %d has %d channels", i, disp[i]->c);
    if (disp[i]->w > mw) mw = disp[i]->w;
    if (disp[i]->h > mh) mh = disp[i]->h;
  }
  if (!mw) return cv_err_set(err, CV_ERR_INVALID, "montage: no wall image");
  for (int i = 0; i < cave->n_walls; i++) ws[i] = disp[i] ? disp[i]->w : mw, hs[i] = disp[i] ? disp[i]->h : mh;
  int W, H;
  int st = cv_montage_layout(cave, ws, hs, xs, ys, &W, &H, err);
  if (st) return st;
  const int scale = cv_montage_label_scale(mw);
  const int band = caption ? cv_montage_caption_lines(caption) * cv_label_height(scale) + 2 * scale : 0;
  uint8_t *px = calloc((size_t)W * (H + band) * 3, 1);
  if (!px) return cv_err_set(err, CV_ERR_NOMEM, "montage: out of memory");
  for (int i = 0; i < cave->n_walls; i++) {
    const cv_image *im = disp[i];
    if (!im) continue;
    for (int y = 0; y < im->h; y++)
      for (int x = 0; x < im->w; x++)
        for (int k = 0; k < 3; k++) {
          float v = cv_image_at(im, x, y)[k];
          v = v > 0 ? (v < 1 ? v : 1) : 0; /* NaN -> 0 */
          px[((size_t)(ys[i] + y) * W + xs[i] + x) * 3 + k] = (uint8_t)lrintf(v * 255.0f);
        }
  }
  if (caption) {
    static const uint8_t white[3] = {255, 255, 255};
    cv_montage_label_walls(px, W, H, cave, xs, ys, scale);
    cv_label_draw(px, W, H + band, scale, H + scale, scale, caption, white);
  }
  st = cv_png_write(path, W, H + band, 3, px, err);
  free(px);
  return st;
}
