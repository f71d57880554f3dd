/* Shared lighting among the wall-eyes of one host (lightshare.h). */
#include "lightshare.h"

#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "core/hash.h"
#include "service_internal.h"

static int join(cv_lightshare *ls, const cv_service *s, cv_renderer *r, size_t cost, int bg_w, int bg_h);

/* Each of the segment's two slots starts with this (64 bytes). */
typedef struct slot {
  _Atomic uint64_t seq;     /* seqlock: odd while the leader writes (or holds a prefetch) */
  _Atomic uint64_t key;     /* light key of the products (0: none) */
  _Atomic uint64_t changes; /* the leader's lighting change they are (1 = the first) */
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

static size_t slot_bytes(const cv_lightshare *ls) {
  return sizeof(slot) + pad64(ls->render_bytes) + BG_HDR + 3 * (size_t)ls->bg_w * ls->bg_h * sizeof(float);
}
static slot *slot_at(const cv_lightshare *ls, int i) {
  return (slot *)(void *)((uint8_t *)ls->hs.base + (size_t)i * slot_bytes(ls));
}
static uint8_t *render_part(const cv_lightshare *ls, int i) { return (uint8_t *)slot_at(ls, i) + sizeof(slot); }
static uint8_t *bg_part(const cv_lightshare *ls, int i) { return render_part(ls, i) + pad64(ls->render_bytes); }

const char *cv_share_lighting_name(int mode) {
  static const char *names[] = {"off", "host", "host-now", "background", "auto"};
  return mode >= 0 && mode <= CV_SHARE_AUTO ? names[mode] : "?";
}

/* --share-lighting auto, once the host's group is known: on a hardware GL
 * each wall-eye relights on its own GPU (6.8 ms on an H200, docs/
 * benchmarks.md) and only the background image (CPU work) is shared; on a
 * software GL the lighting is CPU work too, shared while the host has fewer
 * than 4 cores per wall-eye (on 2 cores sharing cut a lighting change's CPU
 * to about a tenth, docs/benchmarks.md, "Shared lighting"), else each rank
 * computes it (no wait for a leader). */
static void resolve_auto(cv_lightshare *ls, cv_renderer *r) {
  const long cores = sysconf(_SC_NPROCESSORS_ONLN);
  const int members = ls->hs.members > 0 ? ls->hs.members : 1;
  const double per = (double)(cores > 0 ? cores : 1) / members;
  if (r && !cv_renderer_is_software(r)) {
    ls->mode = CV_SHARE_BACKGROUND;
    snprintf(ls->why, sizeof ls->why, "auto: background (a hardware GL relights on its GPU)");
  } else if (per < 4) {
    ls->mode = CV_SHARE_HOST;
    snprintf(ls->why, sizeof ls->why, "auto: host (a software GL, %.2g cores per wall-eye)", per);
  } else {
    ls->mode = CV_SHARE_OFF;
    snprintf(ls->why, sizeof ls->why, "auto: off (a software GL, %.2g cores per wall-eye)", per);
  }
}

int cv_lightshare_setup(cv_lightshare *ls, const cv_service *s, cv_renderer *r, size_t cost, int bg_w, int bg_h) {
  memset(ls, 0, sizeof *ls);
  ls->mode = s->o.share_lighting;
  ls->hs.leader = -1;
  ls->active = -1;
  ls->wait_s = 0.25e-3 * s->o.timeout_ms;
  if (ls->mode == CV_SHARE_OFF) return 0;
  int st = join(ls, s, r, cost, bg_w, bg_h);
  if (ls->mode == CV_SHARE_AUTO) resolve_auto(ls, r);
  ls->bg_only = ls->mode == CV_SHARE_BACKGROUND;
  ls->prefetch_on = ls->mode == CV_SHARE_HOST;
  if (ls->mode == CV_SHARE_OFF) ls->hs.base = NULL; /* auto chose off: joined, shares nothing */
  return st;
}

/* Joins the host group of the ranks with the same scene and GL (collective). */
static int join(cv_lightshare *ls, const cv_service *s, cv_renderer *r, size_t cost, int bg_w, int bg_h) {
  (void)s;
  /* the same scene on the same kind of GL: the same products, bit for bit */
  int color = -1;
  size_t bytes = 0;
  if (r) {
    ls->render_bytes = cv_renderer_lighting_bytes(r);
    ls->bg_w = bg_w, ls->bg_h = bg_h;
    bytes = 2 * slot_bytes(ls);
    uint64_t h = cv_hash64_u64(cv_hash64_init(), cv_renderer_lighting_scene(r));
    h = cv_hash64_str(h, cv_renderer_gl_name(r));
    h = cv_hash64_str(h, cv_renderer_platform(r));
    h = cv_hash64_u64(h, (uint64_t)bytes);
    color = (int)(h & 0x3fffffff);
  }
  if (cv_comm_host_share(color, cost > INT32_MAX ? INT32_MAX : (int)cost, bytes, &ls->hs)) {
    memset(&ls->hs, 0, sizeof ls->hs);
    ls->hs.leader = -1;
    return -1;
  }
  if (ls->hs.base && ls->hs.members < 2) ls->hs.base = NULL; /* alone: nothing to share */
  return 0;
}

void cv_lightshare_describe(const cv_lightshare *ls, char *buf, size_t cap) {
  char role[160];
  const char *part = ls->bg_only ? " of the background image" : "";
  if (ls->mode == CV_SHARE_OFF) snprintf(role, sizeof role, "off");
  else if (!ls->hs.base) snprintf(role, sizeof role, "alone (no other wall-eye of this scene and GL on its host)");
  else if (ls->hs.index == 0) snprintf(role, sizeof role, "leader%s of %d wall-eyes on this host", part, ls->hs.members);
  else snprintf(role, sizeof role, "importer%s (leader rank %d, %d wall-eyes on this host)", part, ls->hs.leader,
                ls->hs.members);
  if (ls->why[0]) snprintf(buf, cap, "%s [%s]", role, ls->why);
  else snprintf(buf, cap, "%s", role);
}

/* Computes the lighting: the renderer's products and the background image
 * (*bg, owned by the caller; NULL on error). */
static int compute(const cv_service *s, cv_renderer *r, const struct cv_lightmix *mix, const cv_lighting *l,
                   const cv_drive_state *drive, cv_frame_timing *tm, cv_image **bg, cv_err *err) {
  *bg = NULL;
  int st = cv_renderer_set_lighting(r, l, NULL, tm, err);
  /* the background alone: the SH came with the frame state */
  if (!st) st = cv_service_lighting(s, mix, drive, l->bands, NULL, 512, bg, err);
  if (!st) st = cv_renderer_set_background(r, *bg, err);
  return st;
}

/* The leader: the products into slot i, its counter left odd (being
 * written; open_slot publishes them). */
static int write_slot(cv_lightshare *ls, int i, cv_renderer *r, const cv_image *bg, cv_err *err) {
  slot *h = slot_at(ls, i);
  const uint64_t q = atomic_load_explicit(&h->seq, memory_order_relaxed);
  if (!(q & 1)) atomic_store_explicit(&h->seq, q + 1, memory_order_relaxed);
  atomic_store_explicit(&h->key, 0, memory_order_relaxed);
  atomic_thread_fence(memory_order_release);
  int st = ls->bg_only ? CV_OK : cv_renderer_lighting_export(r, render_part(ls, i), ls->render_bytes, err);
  uint8_t *b = bg_part(ls, i);
  int32_t wh[2] = {0, 0};
  if (bg && bg->c == 3 && bg->w == ls->bg_w && bg->h == ls->bg_h) {
    wh[0] = bg->w, wh[1] = bg->h;
    memcpy(b + BG_HDR, bg->px, 3 * (size_t)bg->w * bg->h * sizeof(float));
  }
  memcpy(b, wh, sizeof wh);
  return st;
}

/* Publishes slot i (written by write_slot) as the lighting key, change c. */
static void open_slot(cv_lightshare *ls, int i, uint64_t key, uint64_t c) {
  slot *h = slot_at(ls, i);
  const uint64_t q = atomic_load_explicit(&h->seq, memory_order_relaxed);
  atomic_store_explicit(&h->key, key, memory_order_relaxed);
  atomic_store_explicit(&h->changes, c, memory_order_relaxed);
  atomic_store_explicit(&h->seq, (q | 1) + 1, memory_order_release);
  ls->active = i;
}

/* Uploads slot i into r.  0, or non-zero (err). */
static int import_slot(cv_lightshare *ls, int i, cv_renderer *r, const cv_lighting *l, cv_frame_timing *tm,
                       cv_err *err) {
  const uint8_t *b = bg_part(ls, i);
  int32_t wh[2];
  memcpy(wh, b, sizeof wh);
  cv_image bg = {.w = wh[0], .h = wh[1], .c = 3, .px = (float *)(void *)(uintptr_t)(b + BG_HDR)};
  int st = ls->bg_only ? cv_renderer_set_lighting(r, l, NULL, tm, err)
                       : cv_renderer_lighting_import(r, render_part(ls, i), ls->render_bytes, tm, err);
  if (!st) st = cv_renderer_set_background(r, wh[0] > 0 ? &bg : NULL, err);
  return st;
}

/* An importer: 1 imported, 0 not (yet), -1 torn or refused (r's lighting
 * forgotten). */
static int try_import(cv_lightshare *ls, const cv_service *s, cv_renderer *r, const cv_lighting *l, uint64_t key,
                      cv_frame_timing *tm, int *ahead) {
  for (int i = 0; i < 2; i++) {
    slot *h = slot_at(ls, i);
    const uint64_t q1 = atomic_load_explicit(&h->seq, memory_order_acquire);
    if (q1 & 1) continue;
    const uint64_t k = atomic_load_explicit(&h->key, memory_order_relaxed);
    const uint64_t c = atomic_load_explicit(&h->changes, memory_order_relaxed);
    if (k && c > ls->changes) *ahead = 1;
    if (!k || k != key || c != ls->changes) continue;
    cv_err err;
    const int st = import_slot(ls, i, r, l, tm, &err);
    atomic_thread_fence(memory_order_acquire);
    const uint64_t q2 = atomic_load_explicit(&h->seq, memory_order_relaxed);
    if (st || q1 != q2) {
      if (st) fprintf(stderr, "cave run: rank %d: shared lighting: %s (computing it)\n", s->rank, err.msg);
      cv_renderer_lighting_forget(r);
      return -1;
    }
    return 1;
  }
  return 0;
}

static void nap(void) {
  struct timespec ts = {0, 500000};
  nanosleep(&ts, NULL);
}

/* The frame state's lighting as cv_renderer_set_lighting takes it. */
static void lighting_of(const cv_lighting *src, cv_lighting *l) {
  memset(l, 0, sizeof *l);
  l->bands = src->bands;
  memcpy(l->sh, src->sh, sizeof l->sh);
  l->has_sun = src->has_sun;
  memcpy(l->sun_dir, src->sun_dir, sizeof l->sun_dir);
  memcpy(l->sun_E, src->sun_E, sizeof l->sun_E);
}

int cv_lightshare_pending(const cv_lightshare *ls) { return ls->pending; }

/* The leader after a prefetch that did not come true: its renderer back to
 * the published lighting (the active slot), exactly. */
static int restore(cv_lightshare *ls, cv_renderer *r, cv_err *err) {
  ls->pending = 0;
  ls->count_prefetch[1]++;
  if (ls->active < 0) { /* nothing published to return to: computed again by the caller */
    cv_renderer_lighting_forget(r);
    return cv_err_set(err, CV_ERR_INVALID, "shared lighting: no published lighting to return to");
  }
  return import_slot(ls, ls->active, r, NULL, NULL, err); /* host mode only (prefetch) */
}

int cv_lightshare_restore(cv_lightshare *ls, cv_renderer *r, cv_err *err) {
  return ls->pending ? restore(ls, r, err) : CV_OK;
}

int cv_lightshare_relight(cv_lightshare *ls, const cv_service *s, cv_renderer *r, const struct cv_lightmix *mix,
                          const cv_lighting *l, const cv_drive_state *drive, uint64_t key, cv_frame_timing *tm,
                          void (*idle)(void *), void *user, cv_light_msg *msg, cv_err *err) {
  const double w0 = clock_ms(CLOCK_MONOTONIC), c0 = clock_ms(CLOCK_PROCESS_CPUTIME_ID);
  ls->changes++;
  int what = CV_LIGHT_COMPUTED, st = CV_OK, prefetched = 0;
  double wait_ms = 0;
  cv_image *bg = NULL;
  if (!ls->hs.base) {
    st = compute(s, r, mix, l, drive, tm, &bg, err);
  } else if (ls->hs.index == 0) {
    what = CV_LIGHT_LED;
    cv_lighting lt;
    lighting_of(l, &lt);
    if (ls->pending && ls->pend_key == key && !memcmp(&lt, &ls->pend_l, sizeof lt)) {
      /* the prefetch came true: published at once */
      ls->pending = 0;
      ls->count_prefetch[0]++;
      prefetched = 1;
      open_slot(ls, ls->pend_slot, key, ls->changes);
    } else {
      if (ls->pending && (st = restore(ls, r, err))) {
        fprintf(stderr, "cave run: rank %d: shared lighting: %s (recomputing)\n", s->rank, err->msg);
        cv_renderer_lighting_forget(r);
      }
      st = compute(s, r, mix, l, drive, tm, &bg, err);
      const int i = ls->active < 0 ? 0 : 1 - ls->active;
      if (!st) {
        if (write_slot(ls, i, r, bg, err))
          fprintf(stderr, "cave run: rank %d: shared lighting: %s (the importers compute it)\n", s->rank, err->msg);
        else
          open_slot(ls, i, key, ls->changes);
      }
    }
  } else {
    const double deadline = w0 + 1e3 * ls->wait_s;
    int got = 0, ahead = 0;
    for (;;) {
      if (cv_comm_is_dead(ls->hs.leader)) {
        what = CV_LIGHT_DEAD;
        break;
      }
      got = try_import(ls, s, r, l, key, tm, &ahead);
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
    msg->prefetched = (uint32_t)prefetched;
    memcpy(msg->count, ls->count, sizeof msg->count);
    memcpy(msg->prefetch, ls->count_prefetch, sizeof msg->prefetch);
    msg->ms = clock_ms(CLOCK_MONOTONIC) - w0;
    msg->cpu_ms = clock_ms(CLOCK_PROCESS_CPUTIME_ID) - c0 + (prefetched ? ls->pend_cpu_ms : 0);
    msg->wait_ms = wait_ms;
    msg->cpu_s = clock_ms(CLOCK_PROCESS_CPUTIME_ID) * 1e-3;
  }
  return st;
}

int cv_lightshare_prefetch(cv_lightshare *ls, const cv_service *s, cv_renderer *r, const struct cv_lightmix *mix,
                           const cv_frame_state *fs, uint64_t key_now) {
  if (!ls->hs.base || ls->hs.index != 0 || ls->pending || !ls->prefetch_on) return 0;
  if (fs->flags & CV_FS_MEASURE) return 0;
  if (s->o.frames > 0 && fs->frame + 1 >= (uint32_t)s->o.frames) return 0; /* the quit, or held frames */
  /* the master's next frame time (cluster/master.c frame_clock): exact in
   * sim time, the last step again on the wall clock */
  const double t = s->o.clock == 0 ? (double)(fs->frame + 1) * s->o.dt : fs->time + fs->dt;
  cv_drive_state d;
  cv_drive_eval(s->drive, t, &d);
  cv_service_quantise_drive(&d);
  const uint64_t key = cv_service_light_key(&d);
  if (key == key_now) return 0;
  const double c0 = clock_ms(CLOCK_PROCESS_CPUTIME_ID);
  cv_lighting nl;
  cv_image *bg = NULL;
  cv_err err;
  int st = cv_service_lighting(s, mix, &d, fs->bands, &nl, 512, &bg, &err);
  if (st) {
    cv_image_destroy(bg);
    return 0;
  }
  lighting_of(&nl, &ls->pend_l);
  const int i = ls->active < 0 ? 0 : 1 - ls->active;
  ls->pending = 1; /* from here on r holds it: restore() if it does not come */
  ls->pend_slot = i;
  st = cv_renderer_set_lighting(r, &ls->pend_l, NULL, NULL, &err);
  if (!st) st = cv_renderer_set_background(r, bg, &err);
  if (!st) st = write_slot(ls, i, r, bg, &err);
  cv_image_destroy(bg);
  if (st) {
    fprintf(stderr, "cave run: rank %d: shared lighting: prefetch: %s\n", s->rank, err.msg);
    if (restore(ls, r, &err)) cv_renderer_lighting_forget(r);
    return 0;
  }
  ls->pend_key = key;
  ls->pend_cpu_ms = clock_ms(CLOCK_PROCESS_CPUTIME_ID) - c0;
  return 1;
}
