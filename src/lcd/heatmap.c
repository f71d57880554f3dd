/* The readable CR heat map (heatmap.h). */
#include "lcd/heatmap.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* 5 x 7 glyphs: seven rows, the low five bits of each, the leftmost pixel
 * in bit 4. */
typedef struct glyph {
  char c;
  uint8_t row[7];
} glyph;

static const glyph k_font[] = {
    {'0', {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E}}, {'1', {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E}},
    {'2', {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F}}, {'3', {0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E}},
    {'4', {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02}}, {'5', {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E}},
    {'6', {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E}}, {'7', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08}},
    {'8', {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E}}, {'9', {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C}},
    {'A', {0x0E, 0x11, 0x11, 0x11, 0x1F, 0x11, 0x11}}, {'B', {0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E}},
    {'C', {0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E}}, {'D', {0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C}},
    {'E', {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F}}, {'F', {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10}},
    {'G', {0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F}}, {'H', {0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11}},
    {'I', {0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E}}, {'J', {0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C}},
    {'K', {0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11}}, {'L', {0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F}},
    {'M', {0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11}}, {'N', {0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11}},
    {'O', {0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E}}, {'P', {0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10}},
    {'Q', {0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D}}, {'R', {0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11}},
    {'S', {0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E}}, {'T', {0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04}},
    {'U', {0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E}}, {'V', {0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04}},
    {'W', {0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A}}, {'X', {0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11}},
    {'Y', {0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04}}, {'Z', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F}},
    {' ', {0, 0, 0, 0, 0, 0, 0}},                      {'.', {0, 0, 0, 0, 0, 0x0C, 0x0C}},
    {',', {0, 0, 0, 0, 0x0C, 0x04, 0x08}},             {':', {0, 0x0C, 0x0C, 0, 0x0C, 0x0C, 0}},
    {'%', {0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03}}, {'+', {0, 0x04, 0x04, 0x1F, 0x04, 0x04, 0}},
    {'-', {0, 0, 0, 0x1F, 0, 0, 0}},                   {'/', {0, 0x01, 0x02, 0x04, 0x08, 0x10, 0}},
    {'(', {0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02}}, {')', {0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08}},
    {'=', {0, 0, 0x1F, 0, 0x1F, 0, 0}},                {'<', {0x02, 0x04, 0x08, 0x10, 0x08, 0x04, 0x02}},
    {'>', {0x08, 0x04, 0x02, 0x01, 0x02, 0x04, 0x08}}, {'_', {0, 0, 0, 0, 0, 0, 0x1F}},
    {'\'', {0x0C, 0x04, 0x08, 0, 0, 0, 0}},            {'"', {0x0A, 0x0A, 0, 0, 0, 0, 0}},
    {'?', {0x0E, 0x11, 0x01, 0x02, 0x04, 0, 0x04}},    {';', {0, 0x0C, 0x0C, 0, 0x0C, 0x04, 0x08}},
};

static const glyph *find_glyph(char c) {
  c = (char)toupper((unsigned char)c);
  for (size_t i = 0; i < sizeof k_font / sizeof k_font[0]; i++)
    if (k_font[i].c == c) return &k_font[i];
  return find_glyph('?');
}

static void put(uint8_t *px, int w, int h, int x, int y, const uint8_t rgb[3]) {
  if (x < 0 || y < 0 || x >= w || y >= h) return;
  memcpy(px + 3 * ((size_t)y * (size_t)w + (size_t)x), rgb, 3);
}

int cv_lcd_draw_text(uint8_t *px, int w, int h, int x, int y, int scale, const char *s,
                     const uint8_t rgb[3]) {
  int x0 = x;
  for (; *s; s++, x += 6 * scale) {
    const glyph *g = find_glyph(*s);
    for (int r = 0; r < 7; r++)
      for (int c = 0; c < 5; c++)
        if (g->row[r] & (0x10 >> c))
          for (int dy = 0; dy < scale; dy++)
            for (int dx = 0; dx < scale; dx++) put(px, w, h, x + c * scale + dx, y + r * scale + dy, rgb);
  }
  return x - x0;
}

#define TS 2        /* text scale */
#define LINE_H (7 * TS)
#define MARGIN 12
#define BAR_H 28

/* Text with a dark outline (for numbers on the colours). */
static void outlined(uint8_t *px, int w, int h, int x, int y, const char *s) {
  static const uint8_t k[3] = {0, 0, 0}, wt[3] = {255, 255, 255};
  for (int dy = -1; dy <= 1; dy++)
    for (int dx = -1; dx <= 1; dx++)
      if (dx || dy) cv_lcd_draw_text(px, w, h, x + dx, y + dy, TS, s, k);
  cv_lcd_draw_text(px, w, h, x, y, TS, s, wt);
}

/* The mean CR of each of gx x gy regions, written at their centres. */
static void region_numbers(const cv_lcd_readability *r, int s, uint8_t *px, int W, int H, int x0,
                           int y0) {
  const int gx = r->w >= 8 ? 4 : 1, gy = r->h >= 6 ? 3 : 1;
  for (int j = 0; j < gy; j++)
    for (int i = 0; i < gx; i++) {
      const int xa = r->w * i / gx, xb = r->w * (i + 1) / gx, ya = r->h * j / gy, yb = r->h * (j + 1) / gy;
      double sum = 0;
      int n = 0;
      for (int y = ya; y < yb; y++)
        for (int x = xa; x < xb; x++)
          if (isfinite(r->lr[(size_t)y * r->w + x])) sum += r->lr[(size_t)y * r->w + x], n++;
      if (!n) continue;
      /* the CR of the region's mean reflection, as the panel's figure (a
       * mean of texel CRs would be biased upwards by the noise) */
      const double den = r->black + sum / n + r->L_v.value;
      const double m = den > 0 ? (r->white + sum / n + r->L_v.value) / den : 1e6;
      char t[32];
      snprintf(t, sizeof t, m < 100 ? "%.1f" : "%.0f", m);
      const int tw = (int)strlen(t) * 6 * TS - TS;
      outlined(px, W, H, x0 + (xa + xb) * s / 2 - tw / 2, y0 + (ya + yb) * s / 2 - LINE_H / 2, t);
    }
}

int cv_lcd_heatmap_figure(const cv_lcd_readability *r, const char *const *lines, int n,
                          uint8_t **px, int *W, int *H) {
  *px = NULL;
  if (!r || !r->cr || r->w < 1 || r->h < 1 || n < 0 || n > CV_LCD_HEATMAP_LINES) return CV_ERR_INVALID;
  uint8_t *raw = malloc((size_t)r->w * (size_t)r->h * 3);
  if (!raw) return CV_ERR_NOMEM;
  cv_lcd_heatmap_rgb(r, 0, raw); /* the panel's texels, contour included */
  const int s = r->w >= 480 ? 1 : (480 + r->w - 1) / r->w; /* pixels per texel */
  const int pw = r->w * s, ph = r->h * s;
  char cap[120];
  snprintf(cap, sizeof cap, "CR (LOG SCALE); WHITE: THE REQUIRED %g:1; NUMBERS: MEAN CR PER REGION",
           r->cr_min);
  int text_w = (int)strlen(cap) * 6 * TS;
  for (int i = 0; i < n; i++) {
    const int len = lines[i] ? (int)strnlen(lines[i], 120) : 0;
    if (len * 6 * TS > text_w) text_w = len * 6 * TS;
  }
  const int w = (pw + 4 > text_w ? pw + 4 : text_w) + 2 * MARGIN;
  const int top = MARGIN + n * (LINE_H + 6) + 6;
  const int h = top + ph + 4 + 8 + BAR_H + 6 + LINE_H + 8 + LINE_H + MARGIN;
  uint8_t *o = malloc((size_t)w * (size_t)h * 3);
  if (!o) {
    free(raw);
    return CV_ERR_NOMEM;
  }
  memset(o, 255, (size_t)w * (size_t)h * 3);
  static const uint8_t black[3] = {0, 0, 0};
  for (int i = 0; i < n; i++) {
    char buf[121];
    snprintf(buf, sizeof buf, "%s", lines[i] ? lines[i] : "");
    cv_lcd_draw_text(o, w, h, MARGIN, MARGIN + i * (LINE_H + 6), TS, buf, black);
  }
  const int x0 = (w - pw) / 2, y0 = top + 2; /* the panel, inside a 2-pixel outline */
  for (int y = y0 - 2; y < y0 + ph + 2; y++)
    for (int x = x0 - 2; x < x0 + pw + 2; x++)
      if (y < y0 || y >= y0 + ph || x < x0 || x >= x0 + pw) put(o, w, h, x, y, black);
  for (int y = 0; y < ph; y++)
    for (int x = 0; x < pw; x++) put(o, w, h, x0 + x, y0 + y, raw + 3 * ((size_t)(y / s) * r->w + x / s));
  region_numbers(r, s, o, w, h, x0, y0);
  /* the colour bar across the panel's width: CR 1..10 on a log scale, black
   * ticks at 1, 2, ..., 10 with their numbers, the requirement white */
  const int yb = y0 + ph + 2 + 8;
  const double req = r->cr_min > 1 ? log10(r->cr_min) : 0;
  for (int x = 0; x < pw; x++) {
    uint8_t c[3];
    const double t = pw > 1 ? (double)x / (pw - 1) : 0;
    cv_lcd_viridis(t, c);
    if (req <= 1 && fabs(t - req) * (pw - 1) <= 1.5) c[0] = c[1] = c[2] = 255;
    for (int y = 0; y < BAR_H; y++) put(o, w, h, x0 + x, yb + y, c);
  }
  int tx[11], lx[11], tw[11];
  char t[11][8];
  for (int c = 1; c <= 10; c++) {
    snprintf(t[c], sizeof t[c], "%d", c);
    tx[c] = x0 + (int)lrint(log10((double)c) * (pw - 1));
    tw[c] = (int)strlen(t[c]) * 6 * TS - TS;
    lx[c] = c == 10 ? tx[c] - tw[c] : (c == 1 ? tx[c] : tx[c] - tw[c] / 2);
    for (int y = 0; y < BAR_H / 3; y++)
      for (int d = -1; d <= 0; d++) put(o, w, h, tx[c] + d, yb + y, black);
    for (int y = 0; y < 6; y++) put(o, w, h, tx[c], yb + BAR_H + y, black);
  }
  /* the numbers where they do not overlap (10 always, then from the left) */
  cv_lcd_draw_text(o, w, h, lx[10], yb + BAR_H + 6, TS, t[10], black);
  for (int c = 1, free_x = 0; c <= 9; c++) {
    if (lx[c] < free_x || lx[c] + tw[c] + 2 * TS > lx[10]) continue;
    cv_lcd_draw_text(o, w, h, lx[c], yb + BAR_H + 6, TS, t[c], black);
    free_x = lx[c] + tw[c] + 2 * TS;
  }
  cv_lcd_draw_text(o, w, h, MARGIN, yb + BAR_H + 6 + LINE_H + 8, TS, cap, black);
  free(raw);
  *px = o;
  *W = w;
  *H = h;
  return CV_OK;
}
