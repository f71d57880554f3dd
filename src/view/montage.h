/* Montage of one eye's tone-mapped walls for a quick look at a CAVE frame:
 * an unfolded cube (ceiling above the front, floor below, left / right /
 * back beside it) when every wall has a cube name (front, left, right, back,
 * ceiling, floor) and all have one size, else the walls side by side,
 * top-aligned. */
#ifndef CV_VIEW_MONTAGE_H
#define CV_VIEW_MONTAGE_H

#include "core/image.h"
#include "core/status.h"
#include "view/cave.h"

/* disp[i]: wall i's display image (c >= 3, values in [0, 1], clamped; NULL
 * leaves its cell black).  Writes an 8-bit PNG.  Errors: CV_ERR_INVALID,
 * CV_ERR_NOMEM, the PNG writer's. */
int cv_montage_write(const char *path, const cv_cave *cave, cv_image *const *disp, cv_err *err);

#endif
