/* The CR heat map as a figure a person can read (`cave lcd`'s panel.cr.png,
 * docs/readability.md, "The heat map"): title lines (the panel's name, its
 * figures and verdict, the light level), the panel magnified to at least
 * 480 pixels wide inside a black outline, each texel coloured by its CR
 * (cv_lcd_heatmap_rgb: viridis over log10 CR 1..10, the white contour where
 * the smoothed CR crosses the requirement), the mean CR of each of up to
 * 4 x 3 regions written on the panel, and the colour bar below with its
 * numbers (CR 1..10) and the requirement marked.  Text is a built-in 5 x 7
 * pixel font (upper case, digits, common signs) drawn at twice its size.
 * Pure computation: no files. */
#ifndef CV_LCD_HEATMAP_H
#define CV_LCD_HEATMAP_H

#include <stdint.h>

#include "lcd/readability.h"

#define CV_LCD_HEATMAP_LINES 4 /* title lines at most */

/* *px (owned by the caller, free()): *W x *H x 3 bytes, row 0 at the top.
 * lines: n (0..CV_LCD_HEATMAP_LINES) title lines, each cut at 120
 * characters.  Errors: CV_ERR_INVALID (no map, n out of range),
 * CV_ERR_NOMEM. */
int cv_lcd_heatmap_figure(const cv_lcd_readability *r, const char *const *lines, int n,
                          uint8_t **px, int *W, int *H);

/* Draws s (upper-cased; unknown characters as '?') with its top-left
 * corner at (x, y) in an RGB image of width w, height h, at `scale` pixels
 * per font pixel; clipped.  Returns the width drawn, in pixels. */
int cv_lcd_draw_text(uint8_t *px, int w, int h, int x, int y, int scale, const char *s,
                     const uint8_t rgb[3]);

#endif
