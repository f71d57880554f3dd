/* Text labels drawn into 8-bit RGB images (montages, the desktop preview):
 * a 5x7 bitmap font of the printable ASCII 32..95 (lower case drawn as
 * upper case), written for this project (public domain; no Debian library
 * draws text into a plain pixel buffer without a font stack: FreeType and
 * a font file for a few words of status was judged too much). */
#ifndef CV_VIEW_LABEL_H
#define CV_VIEW_LABEL_H

#include <stdint.h>

#include "core/image.h"

/* Pixels a line of text takes at a scale (each font pixel scale x scale). */
int cv_label_width(const char *s, int scale);
int cv_label_height(int scale);
/* Draws s with its top-left at (x, y) in px (W x H x 3, row-major), in fg
 * on a dark box one font pixel around it; '\n' starts a new line; clipped
 * at the image's edges.  Returns the y below the last line. */
int cv_label_draw(uint8_t *px, int W, int H, int x, int y, int scale, const char *s, const uint8_t fg[3]);
/* The same into a float image (c >= 3; fg / 255 into its first three
 * channels). */
int cv_label_draw_image(cv_image *im, int x, int y, int scale, const char *s, const uint8_t fg[3]);

#endif
