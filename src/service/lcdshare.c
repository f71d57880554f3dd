/* LCD round ownership with dead gather ranks (lcdshare.h). */
#include "service/lcdshare.h"

int cv_lcd_contributor_dead(int c, int first_gather, uint64_t dead) {
  const int g = c - first_gather;
  return g >= 0 && g < 64 && ((dead >> g) & 1u);
}

int cv_lcd_round_owner(uint32_t round, int count, int first_gather, uint64_t dead) {
  if (count < 1) return -1;
  const int c = (int)(round % (uint32_t)count);
  if (!cv_lcd_contributor_dead(c, first_gather, dead)) return c;
  int live = 0;
  for (int i = 0; i < count; i++) live += !cv_lcd_contributor_dead(i, first_gather, dead);
  if (live == 0) return -1;
  int j = (int)((round / (uint32_t)count) % (uint32_t)live);
  for (int i = 0; i < count; i++)
    if (!cv_lcd_contributor_dead(i, first_gather, dead) && j-- == 0) return i;
  return -1; /* not reached */
}
