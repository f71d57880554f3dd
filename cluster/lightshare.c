/* Shared lighting among the wall-eyes of one host (lightshare.h). */
#include "lightshare.h"

#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "core/hash.h"
#include "service_internal.h"

/* The segment's first 64 bytes. */
typedef struct slot {
  _Atomic uint64_t seq;     /* seqlock: odd while the leader writes */
  _Atomic uint64_t key;     /* light key of the products */
  _Atomic uint64_t changes; /* the leader's lighting changes when it wrote them (1 = the first) */
  uint64_t pad[5];
} slot;
_Static_assert(sizeof(slot) == 64, "slot header");

#define BG_HDR 64 /* int32 w, h, then padding: the floats start 64-aligned */

static size_t pad64(size_t n) { return (n + 63) & ~(size_t)63; }

static double clock_ms(clockid_t c) {
  struct timespec ts;
  clock_gettime(c, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

static uint8_t *render_part(const cv_lightshare *ls) { return (uint8_t *)ls->hs.base + sizeof(slot); }
static uint8_t *bg_part(const cv_lightshare *ls) { return render_part(ls) + pad64(ls->render_bytes); }

int cv_lightshare_setup(cv_lightshare *ls, const cv_service *s, cv_renderer *r, int bg_w, int bg_h) {
  memset(ls, 0, sizeof *ls);
  ls->mode = s->o.share_lighting;
  ls->hs.leader = -1;
  ls->wait_s = 0.25e-3 * s->o.timeout_ms;
  if (ls->mode == CV_SHARE_OFF) return 0;
  /* the same scene on the same kind of GL: the same products, bit for bit */
  int color = -1;
  size_t bytes = 0;
  if (r) {
    ls->render_bytes = cv_renderer_lighting_bytes(r);
    ls->bg_w = bg_w, ls->bg_h = bg_h;
    bytes = sizeof(slot) + pad64(ls->render_bytes) + BG_HDR + 3 * (size_t)bg_w * bg_h * sizeof(float);
    uint64_t h = cv_hash64_u64(cv_hash64_init(), cv_renderer_lighting_scene(r));
    h = cv_hash64_str(h, cv_renderer_gl_name(r));
    h = cv_hash64_str(h, cv_renderer_platform(r));
    h = cv_hash64_u64(h, (uint64_t)bytes);
    color = (int)(h & 0x3fffffff);
  }
  if (cv_comm_host_share(color, bytes, &ls->hs)) {
    memset(&ls->hs, 0, sizeof ls->hs);
    ls->hs.leader = -1;
    return -1;
  }
  if (ls->hs.base && ls->hs.members < 2) ls->hs.base = NULL; /* alone: nothing to share */
  return 0;
}

void cv_lightshare_describe(const cv_lightshare *ls, char *buf, size_t cap) {
  if (ls->mode == CV_SHARE_OFF) snprintf(buf, cap, "off");
  else if (!ls->hs.base) snprintf(buf, cap, "alone (no other wall-eye of this scene and GL on its host)");
  else if (ls->hs.index == 0) snprintf(buf, cap, "leader of %d wall-eyes on this host", ls->hs.members);
  else snprintf(buf, cap, "importer (leader rank %d, %d wall-eyes on this host)", ls->hs.leader, ls->hs.members);
}

/* Computes the lighting: the renderer's products and the background image
 * (*bg, owned by the caller; NULL on error). */
static int compute(const cv_service *s, cv_renderer *r, const struct cv_lightmix *mix, const cv_lighting *l,
                   const cv_drive_state *drive, cv_frame_timing *tm, cv_image **bg, cv_err *err) {
  cv_lighting unused;
  *bg = NULL;
  int st = cv_renderer_set_lighting(r, l, NULL, tm, err);
  if (!st) st = cv_service_lighting(s, mix, drive, l->bands, &unused, 512, bg, err);
  if (!st) st = cv_renderer_set_background(r, *bg, err);
  return st;
}

/* The leader: the products into the segment, under the seqlock. */
static int publish(cv_lightshare *ls, cv_renderer *r, const cv_image *bg, uint64_t key, cv_err *err) {
  slot *h = ls->hs.base;
  const uint64_t q = atomic_load_explicit(&h->seq, memory_order_relaxed) & ~(uint64_t)1;
  atomic_store_explicit(&h->seq, q + 1, memory_order_relaxed);
  atomic_thread_fence(memory_order_release);
  int st = cv_renderer_lighting_export(r, render_part(ls), ls->render_bytes, err);
  uint8_t *b = bg_part(ls);
  int32_t wh[2] = {0, 0};
  if (bg && bg->c == 3 && bg->w == ls->bg_w && bg->h == ls->bg_h) {
    wh[0] = bg->w, wh[1] = bg->h;
    memcpy(b + BG_HDR, bg->px, 3 * (size_t)bg->w * bg->h * sizeof(float));
  }
  memcpy(b, wh, sizeof wh);
  atomic_store_explicit(&h->key, st ? 0 : key, memory_order_relaxed);
  atomic_store_explicit(&h->changes, st ? 0 : ls->changes, memory_order_relaxed);
  atomic_store_explicit(&h->seq, q + 2, memory_order_release);
  return st;
}

/* An importer: 1 imported, 0 not (yet), -1 torn (r's lighting forgotten). */
static int try_import(cv_lightshare *ls, const cv_service *s, cv_renderer *r, uint64_t key, cv_frame_timing *tm,
                      int *ahead) {
  slot *h = ls->hs.base;
  const uint64_t q1 = atomic_load_explicit(&h->seq, memory_order_acquire);
  if (q1 & 1) return 0;
  const uint64_t k = atomic_load_explicit(&h->key, memory_order_relaxed);
  const uint64_t c = atomic_load_explicit(&h->changes, memory_order_relaxed);
  if (c > ls->changes) *ahead = 1;
  if (k != key || c != ls->changes) return 0;
  cv_err err;
  const uint8_t *b = bg_part(ls);
  int32_t wh[2];
  memcpy(wh, b, sizeof wh);
  cv_image bg = {.w = wh[0], .h = wh[1], .c = 3, .px = (float *)(void *)(uintptr_t)(b + BG_HDR)};
  int st = cv_renderer_lighting_import(r, render_part(ls), ls->render_bytes, tm, &err);
  if (!st) st = cv_renderer_set_background(r, wh[0] > 0 ? &bg : NULL, &err);
  atomic_thread_fence(memory_order_acquire);
  const uint64_t q2 = atomic_load_explicit(&h->seq, memory_order_relaxed);
  if (st || q1 != q2) {
    if (st) fprintf(stderr, "cave run: rank %d: shared lighting: %s (computing it)\n", s->rank, err.msg);
    cv_renderer_lighting_forget(r);
    return -1;
  }
  return 1;
}

static void nap(void) {
  struct timespec ts = {0, 500000};
  nanosleep(&ts, NULL);
}

int cv_lightshare_relight(cv_lightshare *ls, const cv_service *s, cv_renderer *r, const struct cv_lightmix *mix,
                          const cv_lighting *l, const cv_drive_state *drive, uint64_t key, cv_frame_timing *tm,
                          void (*idle)(void *), void *user, cv_light_msg *msg, cv_err *err) {
  const double w0 = clock_ms(CLOCK_MONOTONIC), c0 = clock_ms(CLOCK_PROCESS_CPUTIME_ID);
  ls->changes++;
  int what = CV_LIGHT_COMPUTED, st = CV_OK;
  double wait_ms = 0;
  cv_image *bg = NULL;
  if (!ls->hs.base) {
    st = compute(s, r, mix, l, drive, tm, &bg, err);
  } else if (ls->hs.index == 0) {
    what = CV_LIGHT_LED;
    st = compute(s, r, mix, l, drive, tm, &bg, err);
    if (!st && publish(ls, r, bg, key, err))
      fprintf(stderr, "cave run: rank %d: shared lighting: %s (the importers compute it)\n", s->rank, err->msg);
  } else {
    const double deadline = w0 + 1e3 * ls->wait_s;
    int got = 0, ahead = 0;
    for (;;) {
      if (cv_comm_is_dead(ls->hs.leader)) {
        what = CV_LIGHT_DEAD;
        break;
      }
      got = try_import(ls, s, r, key, tm, &ahead);
      if (got) break;
      if (ahead || clock_ms(CLOCK_MONOTONIC) > deadline) {
        what = CV_LIGHT_LATE;
        break;
      }
      if (idle) idle(user);
      nap();
    }
    wait_ms = clock_ms(CLOCK_MONOTONIC) - w0;
    if (got == 1) what = CV_LIGHT_IMPORTED;
    else {
      if (got < 0) what = CV_LIGHT_TORN;
      st = compute(s, r, mix, l, drive, tm, &bg, err);
    }
  }
  cv_image_destroy(bg);
  ls->count[what]++;
  if (msg) {
    memset(msg, 0, sizeof *msg);
    msg->what = (uint32_t)what;
    memcpy(msg->count, ls->count, sizeof msg->count);
    msg->ms = clock_ms(CLOCK_MONOTONIC) - w0;
    msg->cpu_ms = clock_ms(CLOCK_PROCESS_CPUTIME_ID) - c0;
    msg->wait_ms = wait_ms;
    msg->cpu_s = clock_ms(CLOCK_PROCESS_CPUTIME_ID) * 1e-3;
  }
  return st;
}
