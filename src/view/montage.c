/* Montage of one eye's walls: see montage.h. */
#include "view/montage.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "io/png.h"

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

int cv_montage_write(const char *path, const cv_cave *cave, cv_image *const *disp, cv_err *err) {
  if (!path || !cave || !disp || cave->n_walls < 1)
    return cv_err_set(err, CV_ERR_INVALID, "montage: no walls");
  int cube = 1, cw = 0, ch = 0, cols = 0, rows = 0, first = 1;
  for (int i = 0; i < cave->n_walls; i++) {
    int c = 0, r = 0;
    if (cube_cell(cave->walls[i].name, &c, &r)) cube = 0;
    if (!disp[i]) continue;
    if (disp[i]->c < 3) return cv_err_set(err, CV_ERR_INVALID, "montage: wall %d has %d channels", i, disp[i]->c);
    if (!first && (disp[i]->w != cw || disp[i]->h != ch)) cube = 0;
    if (disp[i]->w > cw) cw = disp[i]->w;
    if (disp[i]->h > ch) ch = disp[i]->h;
    first = 0;
  }
  if (first) return cv_err_set(err, CV_ERR_INVALID, "montage: no wall image");
  int W, H;
  if (cube) {
    for (int i = 0; i < cave->n_walls; i++) {
      int c = 0, r = 0;
      cube_cell(cave->walls[i].name, &c, &r);
      if (c + 1 > cols) cols = c + 1;
      if (r + 1 > rows) rows = r + 1;
    }
    rows = 3; /* keep the front on the middle row even without floor/ceiling */
    W = cols * cw, H = rows * ch;
  } else {
    W = 0, H = ch;
    for (int i = 0; i < cave->n_walls; i++) W += disp[i] ? disp[i]->w : cw;
  }
  uint8_t *px = calloc((size_t)W * H * 3, 1);
  if (!px) return cv_err_set(err, CV_ERR_NOMEM, "montage: out of memory");
  int x0 = 0;
  for (int i = 0; i < cave->n_walls; i++) {
    const cv_image *im = disp[i];
    int ox = x0, oy = 0;
    if (cube) {
      int c = 0, r = 0;
      cube_cell(cave->walls[i].name, &c, &r);
      ox = c * cw, oy = r * ch;
    }
    x0 += im ? im->w : cw;
    if (!im) continue;
    for (int y = 0; y < im->h; y++)
      for (int x = 0; x < im->w; x++)
        for (int k = 0; k < 3; k++) {
          float v = cv_image_at(im, x, y)[k];
          v = v > 0 ? (v < 1 ? v : 1) : 0; /* NaN -> 0 */
          px[((size_t)(oy + y) * W + ox + x) * 3 + k] = (uint8_t)lrintf(v * 255.0f);
        }
  }
  int st = cv_png_write(path, W, H, 3, px, err);
  free(px);
  return st;
}
