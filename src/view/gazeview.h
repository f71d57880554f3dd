/* The view along the gaze, from the CAVE's wall images (the desktop
 * preview's "what you look at", issue 33): the wall images are rendered
 * for the eye position only (off-axis projections through fixed screens),
 * so turning the gaze changes none of them; what a viewer looking along
 * the gaze sees is the walls seen from the head in that direction.  Each
 * pixel of an n x n perspective view (fov_deg across, up = +Y, the gaze's
 * roll 0) is the wall pixel its ray from the head hits first (nearest
 * neighbour); a ray that hits no wall is black. */
#ifndef CV_VIEW_GAZEVIEW_H
#define CV_VIEW_GAZEVIEW_H

#include <stdint.h>

#include "view/cave.h"

/* The wall images: wall w's image (ws[w] x hs[w], 8-bit RGB, row 0 at the
 * wall's top edge pc) at (cell_x[w], cell_y[w]) in src (src_w pixels wide);
 * shown[w] 0: the wall is skipped (its rays pass through).  out: 3 n n
 * bytes.  Returns the number of pixels that hit a wall. */
long cv_gaze_view(const cv_cave *cave, const uint8_t *src, int src_w, const int *cell_x, const int *cell_y,
                  const int *ws, const int *hs, const uint8_t *shown, const double head[3], const double gaze[3],
                  double fov_deg, uint8_t *out, int n);

#endif
