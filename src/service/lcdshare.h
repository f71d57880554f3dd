/* Who renders which LCD round (docs/dead-rank.md).  The LCD contributors
 * (wall-eyes' idle threads, if on, then the gather-only ranks) share a key's
 * rounds round-robin: round r is contributor r % count's.  A dead gather
 * rank's rounds go to the live contributors in turn, so a key still reaches
 * its budget; a round's samples depend only on the round (and the key), so
 * the image is the same bits whoever renders it.  Pure, no MPI. */
#ifndef CV_SERVICE_LCDSHARE_H
#define CV_SERVICE_LCDSHARE_H

#include <stdint.h>

/* The contributor of `round` among contributors [0, count) when the gather
 * ranks are contributors first_gather, first_gather + 1, ... and bit g of
 * dead marks contributor first_gather + g dead (bits past count ignored):
 * round % count when that one is alive, else the j-th live contributor
 * (in index order), j = (round / count) % live.  -1 when count < 1 or no
 * contributor is alive. */
int cv_lcd_round_owner(uint32_t round, int count, int first_gather, uint64_t dead);

/* 1 when contributor c is marked dead in dead (as above), else 0. */
int cv_lcd_contributor_dead(int c, int first_gather, uint64_t dead);

#endif
