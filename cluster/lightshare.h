/* Shared lighting (`cave run --share-lighting host`, docs/service.md,
 * "Shared lighting"): the wall-eyes of one host that render the same scene
 * on the same kind of GL compute each lighting change once.  Their first
 * rank (the leader) computes it (cv_renderer_set_lighting and the
 * background image) and writes the products into one shared-memory segment
 * (comm.h, cv_comm_host_share); the others (importers) upload them from
 * there (cv_renderer_lighting_import) instead of computing.
 *
 * The segment: a slot header (a sequence counter, the light key and the
 * count of lighting changes it holds), then the renderer's export
 * (render_share.c), then the background image.  The sequence counter is a
 * seqlock: odd while the leader writes, even when the products are whole;
 * an importer takes them when the counter is even and names its own light
 * key and change count (every rank sees the same frame states, so the n-th
 * change is the same on all), and checks after the upload that the counter
 * did not move (else its upload may be torn: it computes itself).  It waits
 * for the leader at most --timeout-ms / 4; a late leader, one the master
 * declared dead, or a torn upload make it compute itself, counted in the
 * metrics (never silently).  C11 atomics (acquire/release) order the
 * counter against the products in the shared memory. */
#ifndef CV_CLUSTER_LIGHTSHARE_H
#define CV_CLUSTER_LIGHTSHARE_H

#include <stdint.h>

#include "comm.h"
#include "render/renderer.h"
#include "service.h"

struct cv_lightmix;

/* --share-lighting */
enum { CV_SHARE_OFF = 0, CV_SHARE_HOST = 1, CV_SHARE_HOST_NOW = 2 /* host without the prefetch */,
       CV_SHARE_BACKGROUND = 3, /* only the CPU-only part (the background image from the maps or the
                                   sky) is shared; each wall-eye relights, splits and draws its
                                   shadow map on its own GL */
       CV_SHARE_AUTO = 4 /* the default: background on a hardware GL; host on a software GL
                            with fewer than 4 cores per wall-eye on the host, else off */ };
/* "host", "host-now", "off", "background", "auto" */
const char *cv_share_lighting_name(int mode);

/* What a rank did for one lighting change. */
enum {
  CV_LIGHT_COMPUTED = 0, /* computed, no sharing (off, or alone on its host / scene / GL) */
  CV_LIGHT_LED = 1,      /* the leader: computed and exported */
  CV_LIGHT_IMPORTED = 2, /* an importer: uploaded the leader's products */
  CV_LIGHT_LATE = 3,     /* an importer that computed itself: the leader was late */
  CV_LIGHT_DEAD = 4,     /* ... the leader was declared dead */
  CV_LIGHT_TORN = 5      /* ... the leader overwrote the products during the upload */
};

/* Render rank -> master (CV_TAG_LIGHT) after each lighting change: this
 * rank's cumulative counts per CV_LIGHT_* and the last change's times. */
typedef struct cv_light_msg {
  uint32_t frame;      /* the frame whose state changed the lighting */
  uint32_t what;       /* CV_LIGHT_* of that change */
  uint32_t prefetched; /* the leader: this change was computed ahead (cv_lightshare_prefetch) */
  uint32_t pad;
  uint64_t count[6];   /* changes so far per CV_LIGHT_* */
  uint64_t prefetch[2];/* the leader's prefetches so far: came true, did not (restored) */
  double ms;           /* wall ms of the lighting step (renderer + background) */
  double cpu_ms;       /* process CPU ms of it (the renderer's GL threads included; a
                          prefetched change: the prefetch's CPU) */
  double wait_ms;      /* importers: of ms, waiting for the leader */
  double cpu_s;        /* the rank's process CPU seconds so far (all its threads) */
} cv_light_msg;

typedef struct cv_lightshare {
  int mode;           /* CV_SHARE_* (auto resolved at set-up) */
  int bg_only;        /* CV_SHARE_BACKGROUND: only the background image is shared */
  char why[160];      /* auto: what it picked and why */
  cv_host_share hs;   /* the segment (hs.base NULL: not sharing) */
  size_t render_bytes;/* the renderer's export part */
  int bg_w, bg_h;     /* background image part */
  uint64_t changes;   /* lighting changes this rank has made */
  uint64_t count[6];
  double wait_s;      /* how long an importer waits for the leader */
  /* the segment holds two slots; active: the published one (-1: none) */
  int active;
  /* the leader's prefetch: on, one pending (r holds it, slot pend_slot
   * written, unpublished), its key, lighting and CPU ms; came true / not */
  int prefetch_on, pending, pend_slot;
  uint64_t pend_key;
  cv_lighting pend_l;
  double pend_cpu_ms;
  uint64_t count_prefetch[2];
} cv_lightshare;

/* Collective over the render ranks (mode != off): joins the host group of
 * the ranks with the same scene and GL, whose leader is the rank of the
 * smallest cost (the triangles its views draw at the config's head: its
 * frame is the cheapest, so the lighting lengthens the shortest one; ties:
 * the lowest rank).  r NULL (set-up failed): takes no part.  Returns 0, or -1 when MPI failed (then not sharing). */
int cv_lightshare_setup(cv_lightshare *ls, const cv_service *s, cv_renderer *r, size_t cost, int bg_w, int bg_h);

/* "leader of 10 wall-eyes on this host", "importer (leader rank 1, 10 on this host)", "off", ... */
void cv_lightshare_describe(const cv_lightshare *ls, char *buf, size_t cap);

/* One lighting change: computes (set_lighting + the background image) or
 * imports, as the rank's role says.  idle(user) runs while an importer
 * waits.  Fills msg (what, counts, times).  Non-zero on an error (err). */
int cv_lightshare_relight(cv_lightshare *ls, const cv_service *s, cv_renderer *r, const struct cv_lightmix *mix,
                          const cv_lighting *l, const cv_drive_state *drive, uint64_t key, cv_frame_timing *tm,
                          void (*idle)(void *), void *user, cv_light_msg *msg, cv_err *err);

/* 1 while the leader's renderer holds a prefetched lighting not yet
 * confirmed by a frame state. */
int cv_lightshare_pending(const cv_lightshare *ls);
/* A frame state whose light key did not change while a prefetch is
 * pending: the renderer back to the published lighting (exactly: imported
 * from the leader's own slot).  0, or non-zero (err). */
int cv_lightshare_restore(cv_lightshare *ls, cv_renderer *r, cv_err *err);

/* The leader, after rendering frame fs (lighting key key_now): predicts the
 * next frame's drive state as the master will make it (sim clock: frame + 1
 * steps of --dt; wall clock: the last step again), and when its light key
 * differs, computes that lighting now (while the other wall-eyes still
 * render) and writes it to the unpublished slot.  cv_lightshare_relight
 * publishes it at once when the next state's key and lighting are
 * bit-equal to the prediction, else restores and computes.  1 when
 * prefetched. */
int cv_lightshare_prefetch(cv_lightshare *ls, const cv_service *s, cv_renderer *r, const struct cv_lightmix *mix,
                           const cv_frame_state *fs, uint64_t key_now);

#endif
