/* Montage of one eye's tone-mapped walls for a quick look at a CAVE frame:
 * an unfolded cube (ceiling above the front, floor below, left / right /
 * back beside it) when every wall has a cube name (front, left, right, back,
 * ceiling, floor) and all have one size, else the walls side by side,
 * top-aligned. */
#ifndef CV_VIEW_MONTAGE_H
#define CV_VIEW_MONTAGE_H

#include <stdint.h>

#include "core/image.h"
#include "core/status.h"
#include "view/cave.h"

/* disp[i]: wall i's display image (c >= 3, values in [0, 1], clamped; NULL
 * leaves its cell black).  Writes an 8-bit PNG.  Errors: CV_ERR_INVALID,
 * CV_ERR_NOMEM, the PNG writer's. */
int cv_montage_write(const char *path, const cv_cave *cave, cv_image *const *disp, cv_err *err);
/* As cv_montage_write, labelled (caption non-NULL): every wall's name in
 * its cell's top-left corner (view/label.h), and the caption ('\n' between
 * lines: frame, time, variant) in a band below the walls, which makes the
 * image that band taller. */
int cv_montage_write_labelled(const char *path, const cv_cave *cave, cv_image *const *disp, const char *caption,
                              cv_err *err);
/* The label scale for cells w pixels wide (1 below 192, then w / 96), the
 * caption's line count, and the wall names drawn into an 8-bit RGB montage
 * of W x H (cells at x[i], y[i]): what the labelled montage and the desktop
 * preview draw. */
int cv_montage_label_scale(int cell_w);
int cv_montage_caption_lines(const char *caption);
void cv_montage_label_walls(uint8_t *px, int W, int H, const cv_cave *cave, const int *x, const int *y, int scale);

/* The layout cv_montage_write uses, for walls of ws[i] x hs[i] pixels
 * (n_walls entries each): the top-left corner (x[i], y[i]) of wall i's cell
 * and the montage's size *W x *H; cells no wall covers stay black.  The
 * cube layout needs every wall named after a cube face and one size for
 * all; else the walls sit side by side, top-aligned.  Errors:
 * CV_ERR_INVALID (no walls, a size < 1). */
int cv_montage_layout(const cv_cave *cave, const int *ws, const int *hs, int *x, int *y, int *W, int *H,
                      cv_err *err);

#endif
