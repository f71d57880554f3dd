/* The live console's shared state, images and control queue (console.h). */
#include "service/console.h"

#include <math.h>
#include <pthread.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/png.h"

const double cv_console_buckets[CV_CONSOLE_BUCKETS] = {0.005, 0.01, 0.02, 0.0333, 0.05, 0.1,
                                                       0.2,   0.5,  1,    2,      5,    INFINITY};
const char *const cv_console_image_names[CV_IMG_COUNT] = {"projector", "uncompensated", "viewer", "heatmap"};

#define STAGE_CAP 64

typedef struct console_image {
  uint32_t frame;
  int w, h;
  uint8_t *rgb;
  uint64_t version;     /* raises with every set */
  uint8_t *png;         /* encoded from `png_version` */
  size_t png_n;
  uint64_t png_version;
} console_image;

struct cv_console {
  pthread_mutex_t mu;   /* state, ring, version */
  cv_console_state st;
  cv_console_sample ring[CV_CONSOLE_RING];
  size_t ring_head, ring_n; /* next slot, samples held */
  uint64_t version;
  /* the master's staging area (its thread only): samples that found the
   * lock taken (the state itself is replaced by the next publish's) */
  cv_console_sample stage_s[STAGE_CAP];
  size_t stage_n;
  /* images */
  pthread_mutex_t img_mu;
  console_image img[CV_IMG_COUNT];
  /* controls */
  pthread_mutex_t ctl_mu;
  cv_console_ctl q[CV_CONSOLE_QUEUE];
  size_t q_head, q_n;
};

int cv_console_create(cv_console **out) {
  cv_console *c = calloc(1, sizeof *c);
  if (!c) return CV_ERR_NOMEM;
  pthread_mutex_init(&c->mu, NULL);
  pthread_mutex_init(&c->img_mu, NULL);
  pthread_mutex_init(&c->ctl_mu, NULL);
  *out = c;
  return CV_OK;
}

void cv_console_destroy(cv_console *c) {
  if (!c) return;
  for (int i = 0; i < CV_IMG_COUNT; i++) {
    free(c->img[i].rgb);
    free(c->img[i].png);
  }
  pthread_mutex_destroy(&c->mu);
  pthread_mutex_destroy(&c->img_mu);
  pthread_mutex_destroy(&c->ctl_mu);
  free(c);
}

/* The bytes of a state that matter: the ranks in use only. */
static size_t state_bytes(const cv_console_state *st) {
  int n = st->n_ranks < 0 ? 0 : st->n_ranks > CV_CONSOLE_MAX_RANKS ? CV_CONSOLE_MAX_RANKS : st->n_ranks;
  return offsetof(cv_console_state, ranks) + (size_t)n * sizeof(cv_console_rank);
}

static void ring_add(cv_console *c, const cv_console_sample *s) {
  c->ring[c->ring_head] = *s;
  c->ring_head = (c->ring_head + 1) % CV_CONSOLE_RING;
  if (c->ring_n < CV_CONSOLE_RING) c->ring_n++;
}

int cv_console_publish(cv_console *c, const cv_console_state *st, const cv_console_sample *s) {
  if (pthread_mutex_trylock(&c->mu) != 0) {
    if (s) {
      if (c->stage_n == STAGE_CAP) { /* a reader held the lock for 64 frames: the oldest go */
        memmove(c->stage_s, c->stage_s + 1, (STAGE_CAP - 1) * sizeof *c->stage_s);
        c->stage_n--;
      }
      c->stage_s[c->stage_n++] = *s;
    }
    return 0;
  }
  for (size_t i = 0; i < c->stage_n; i++) ring_add(c, &c->stage_s[i]);
  c->stage_n = 0;
  if (s) ring_add(c, s);
  memcpy(&c->st, st, state_bytes(st));
  c->version++;
  pthread_mutex_unlock(&c->mu);
  return 1;
}

void cv_console_read(cv_console *c, cv_console_state *st, cv_console_sample *ring, size_t cap, size_t *n,
                     uint64_t *version) {
  pthread_mutex_lock(&c->mu);
  if (st) memcpy(st, &c->st, state_bytes(&c->st));
  size_t k = c->ring_n < cap ? c->ring_n : cap;
  size_t first = (c->ring_head + CV_CONSOLE_RING - k) % CV_CONSOLE_RING;
  for (size_t i = 0; ring && i < k; i++) ring[i] = c->ring[(first + i) % CV_CONSOLE_RING];
  if (n) *n = ring ? k : 0;
  if (version) *version = c->version;
  pthread_mutex_unlock(&c->mu);
}

uint64_t cv_console_version(cv_console *c) {
  pthread_mutex_lock(&c->mu);
  uint64_t v = c->version;
  pthread_mutex_unlock(&c->mu);
  return v;
}

int cv_console_set_image(cv_console *c, int which, uint32_t frame, int w, int h, const uint8_t *rgb,
                         int blocking) {
  if (which < 0 || which >= CV_IMG_COUNT || w < 1 || h < 1 || !rgb) return -1;
  if (blocking) pthread_mutex_lock(&c->img_mu);
  else if (pthread_mutex_trylock(&c->img_mu) != 0) return 1;
  console_image *im = &c->img[which];
  const size_t n = 3 * (size_t)w * (size_t)h;
  if (!im->rgb || (size_t)im->w * im->h != (size_t)w * h) {
    uint8_t *nb = realloc(im->rgb, n);
    if (!nb) {
      pthread_mutex_unlock(&c->img_mu);
      return -1;
    }
    im->rgb = nb;
  }
  memcpy(im->rgb, rgb, n);
  im->w = w;
  im->h = h;
  im->frame = frame;
  im->version++;
  pthread_mutex_unlock(&c->img_mu);
  return 0;
}

int cv_console_image_png(cv_console *c, int which, uint8_t **png, size_t *n, uint32_t *frame, cv_err *err) {
  if (which < 0 || which >= CV_IMG_COUNT) return cv_err_set(err, CV_ERR_INVALID, "no image %d", which);
  pthread_mutex_lock(&c->img_mu);
  console_image *im = &c->img[which];
  if (!im->rgb) {
    pthread_mutex_unlock(&c->img_mu);
    return cv_err_set(err, CV_ERR_NOT_FOUND, "%s: no image yet", cv_console_image_names[which]);
  }
  if (im->png && im->png_version == im->version) { /* encoded already */
    *png = malloc(im->png_n);
    if (*png) memcpy(*png, im->png, im->png_n);
    *n = im->png_n;
    *frame = im->frame;
    pthread_mutex_unlock(&c->img_mu);
    return *png ? CV_OK : cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  }
  const int w = im->w, h = im->h;
  const uint64_t ver = im->version;
  *frame = im->frame;
  uint8_t *copy = malloc(3 * (size_t)w * h);
  if (copy) memcpy(copy, im->rgb, 3 * (size_t)w * h);
  pthread_mutex_unlock(&c->img_mu);
  if (!copy) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  int st = cv_png_encode(w, h, 3, copy, 1, png, n, err); /* outside the lock */
  free(copy);
  if (st) return st;
  pthread_mutex_lock(&c->img_mu);
  if (im->version == ver) { /* keep it for the next reader */
    uint8_t *keep = malloc(*n);
    if (keep) {
      memcpy(keep, *png, *n);
      free(im->png);
      im->png = keep;
      im->png_n = *n;
      im->png_version = ver;
    }
  }
  pthread_mutex_unlock(&c->img_mu);
  return CV_OK;
}

int cv_console_push(cv_console *c, const cv_console_ctl *ctl) {
  pthread_mutex_lock(&c->ctl_mu);
  int rc = -1;
  if (c->q_n < CV_CONSOLE_QUEUE) {
    c->q[(c->q_head + c->q_n) % CV_CONSOLE_QUEUE] = *ctl;
    c->q_n++;
    rc = 0;
  }
  pthread_mutex_unlock(&c->ctl_mu);
  return rc;
}

int cv_console_take(cv_console *c, cv_console_ctl *out) {
  if (pthread_mutex_trylock(&c->ctl_mu) != 0) return 0;
  int got = 0;
  if (c->q_n > 0) {
    *out = c->q[c->q_head];
    c->q_head = (c->q_head + 1) % CV_CONSOLE_QUEUE;
    c->q_n--;
    got = 1;
  }
  pthread_mutex_unlock(&c->ctl_mu);
  return got;
}

void cv_console_hist_add(cv_console_state *st, double seconds) {
  if (!isfinite(seconds)) return;
  for (int b = 0; b < CV_CONSOLE_BUCKETS; b++)
    if (seconds <= cv_console_buckets[b]) st->frame_hist[b]++;
  st->frame_sum_s += seconds;
  st->frames_total++;
}
