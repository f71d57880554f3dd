/* LCD rounds summed by allreduce (design card: "LCD sample aggregation via
 * allreduce").  The master and the gather-only ranks form a communicator
 * (cv_comm_lcd_group) and run the same epoch machine, each rank on its own
 * clock, never waiting:
 *
 *   header  MPI_Iallreduce (sum) of a small int64 vector: the master's LCD
 *           key for the next epoch and its quit flag, each contributor's
 *           LCD key and clamp in its own slot, and per round of the budget
 *           how many contributors bring it;
 *   data    only when the header counted rounds: MPI_Iallreduce (sum) of the
 *           fixed-point LCD buffers (cv_lcd_accum words; zeros from ranks
 *           that bring nothing).
 *
 * A contributor brings the rounds it finished for the key the master asked
 * for in the previous header (its pool), so every sum is of one key.  The
 * master tests the request once per poll (each frame and in its waiting
 * loops) and starts the next epoch at most every min_period seconds; the
 * gather ranks join at once.  A late gather rank delays the epoch (the sum
 * completes when it joins), never a frame.  The sum is of integers, so the
 * master's image is the same bits as the per-round messages gave, for any
 * rank count. */
#include "lcdreduce.h"

#include <stdlib.h>
#include <string.h>

#include "comm.h"
#include "service_internal.h"

enum { PH_IDLE, PH_HEADER, PH_DATA, PH_DONE };
enum { H_KEY = 0, H_QUIT = 1, H_SLOTS = 2, SLOT_WORDS = 6 }; /* slot: flag, key (4), clamp */
_Static_assert(sizeof(cv_lcd_key) == 4 * sizeof(int64_t), "an LCD key is 4 words");

struct cv_lcd_reduce {
  int w, h, budget, members, me;
  size_t words, hdr_n;
  int64_t *hdr, *data;
  int phase;
  double t_start;
  uint64_t next_key;  /* asked for by the last header's result */
  uint64_t epoch_key; /* asked for in the epoch in flight */
  int quit_epoch;
  /* master */
  uint64_t announce;
  int announce_quit;
  /* contributor: rounds not yet brought, and those in the epoch in flight */
  cv_lcd_accum *pool, *sent;
  cv_lcd_key pool_key;
  uint8_t *pool_rounds;
  uint32_t pool_n;
  /* totals */
  uint64_t epochs, data_epochs, rounds;
  double ms_sum;
};

int cv_lcd_reduce_create(int w, int h, int budget, int members, int me, cv_lcd_reduce **out) {
  *out = NULL;
  if (w < 1 || h < 1 || budget < 1 || members < 2 || me < 0 || me >= members) return CV_ERR_INVALID;
  cv_lcd_reduce *r = calloc(1, sizeof *r);
  if (!r) return CV_ERR_NOMEM;
  r->w = w;
  r->h = h;
  r->budget = budget;
  r->members = members;
  r->me = me;
  r->words = cv_lcd_accum_words(w, h);
  r->hdr_n = H_SLOTS + (size_t)SLOT_WORDS * (size_t)members + (size_t)budget;
  r->hdr = calloc(r->hdr_n, sizeof *r->hdr);
  r->data = calloc(r->words, sizeof *r->data);
  r->pool_rounds = calloc((size_t)budget, 1);
  if (!r->hdr || !r->data || !r->pool_rounds) {
    cv_lcd_reduce_destroy(r);
    return CV_ERR_NOMEM;
  }
  r->phase = PH_IDLE;
  *out = r;
  return CV_OK;
}

void cv_lcd_reduce_destroy(cv_lcd_reduce *r) {
  if (!r) return;
  cv_lcd_accum_destroy(r->pool);
  cv_lcd_accum_destroy(r->sent);
  free(r->hdr);
  free(r->data);
  free(r->pool_rounds);
  free(r);
}

static void pool_clear(cv_lcd_reduce *r) {
  cv_lcd_accum_destroy(r->pool);
  r->pool = NULL;
  r->pool_n = 0;
  memset(r->pool_rounds, 0, (size_t)r->budget);
}

int cv_lcd_reduce_add_round(cv_lcd_reduce *r, const uint8_t *msg, size_t len) {
  cv_lcd_msg h;
  if (len < sizeof h) return -1;
  memcpy(&h, msg, sizeof h);
  if (h.w != r->w || h.h != r->h || h.n != r->words || len != sizeof h + h.n * sizeof(int64_t) ||
      h.round >= (uint32_t)r->budget || !(h.clamp > 0))
    return -1;
  cv_lcd_accum view = {.w = h.w, .h = h.h, .clamp = h.clamp, .unit = cv_lcd_unit_for_clamp(h.clamp),
                       .n = h.n, .data = (int64_t *)(void *)(uintptr_t)(msg + sizeof h)};
  if (r->pool && cv_lcd_key_equal(&r->pool_key, &h.key) && r->pool->clamp == h.clamp) {
    if (r->pool_rounds[h.round]) return 0;
    if (cv_lcd_accum_add(r->pool, &view) != CV_OK) return 0; /* full: dropped */
  } else {
    pool_clear(r);
    if (cv_lcd_accum_clone(&view, &r->pool) != CV_OK) return -1;
    r->pool_key = h.key;
  }
  r->pool_rounds[h.round] = 1;
  r->pool_n++;
  return 0;
}

void cv_lcd_reduce_announce(cv_lcd_reduce *r, uint64_t key, int quit) {
  r->announce = key;
  if (quit) r->announce_quit = 1;
}

static int64_t *slot(int64_t *hdr, int member) { return hdr + H_SLOTS + (size_t)SLOT_WORDS * member; }
static int64_t *counts(const cv_lcd_reduce *r) { return r->hdr + H_SLOTS + (size_t)SLOT_WORDS * r->members; }

static void start_header(cv_lcd_reduce *r, double now) {
  memset(r->hdr, 0, r->hdr_n * sizeof *r->hdr);
  r->epoch_key = r->next_key;
  if (r->me == 0) {
    memcpy(&r->hdr[H_KEY], &r->announce, sizeof r->announce);
    r->hdr[H_QUIT] = r->announce_quit;
  } else if (r->pool && r->pool_n > 0 && r->epoch_key != 0 &&
             cv_service_lcd_key(r->pool_key.eye_q, r->pool_key.light_hash) == r->epoch_key) {
    int64_t *s = slot(r->hdr, r->me);
    s[0] = 1;
    memcpy(s + 1, &r->pool_key, sizeof r->pool_key);
    memcpy(s + 5, &r->pool->clamp, sizeof r->pool->clamp);
    int64_t *c = counts(r);
    for (int i = 0; i < r->budget; i++) c[i] = r->pool_rounds[i];
    r->sent = r->pool; /* brought in this epoch */
    r->pool = NULL;
    r->pool_n = 0;
    memset(r->pool_rounds, 0, (size_t)r->budget);
  }
  r->t_start = now;
  r->phase = cv_comm_lcd_iallreduce(r->hdr, r->hdr_n) ? PH_IDLE : PH_HEADER;
  if (r->phase == PH_IDLE) { /* MPI refused: the rounds are lost, try later */
    cv_lcd_accum_destroy(r->sent);
    r->sent = NULL;
  }
}

static void finish_epoch(cv_lcd_reduce *r, double now) {
  r->epochs++;
  r->ms_sum += (now - r->t_start) * 1e3;
  cv_lcd_accum_destroy(r->sent);
  r->sent = NULL;
  r->phase = r->quit_epoch ? PH_DONE : PH_IDLE;
}

static void header_done(cv_lcd_reduce *r, double now) {
  memcpy(&r->next_key, &r->hdr[H_KEY], sizeof r->next_key);
  r->quit_epoch = r->hdr[H_QUIT] != 0;
  const int64_t *c = counts(r);
  int64_t n = 0;
  for (int i = 0; i < r->budget; i++) n += c[i];
  if (n <= 0) {
    finish_epoch(r, now);
    return;
  }
  if (r->sent) memcpy(r->data, r->sent->data, r->words * sizeof *r->data);
  else memset(r->data, 0, r->words * sizeof *r->data);
  if (cv_comm_lcd_iallreduce(r->data, r->words)) {
    finish_epoch(r, now);
    return;
  }
  r->phase = PH_DATA;
}

static void data_done(cv_lcd_reduce *r, double now, cv_lcd_reduce_fn fn, void *user) {
  const int64_t *c = counts(r);
  uint32_t n = 0;
  for (int i = 0; i < r->budget; i++) n += (uint32_t)c[i];
  r->data_epochs++;
  r->rounds += n;
  if (r->me == 0 && fn) {
    cv_lcd_reduce_sum sum;
    memset(&sum, 0, sizeof sum);
    sum.asked_key = r->epoch_key;
    sum.counts = c;
    sum.rounds = n;
    sum.consistent = 1;
    double clamp = 0;
    int first = 1;
    for (int m = 1; m < r->members; m++) {
      const int64_t *s = slot(r->hdr, m);
      if (s[0] == 0) continue;
      cv_lcd_key k;
      double cl;
      memcpy(&k, s + 1, sizeof k);
      memcpy(&cl, s + 5, sizeof cl);
      if (s[0] != 1) sum.consistent = 0;
      if (first) {
        sum.key = k;
        clamp = cl;
        first = 0;
      } else if (!cv_lcd_key_equal(&k, &sum.key) || cl != clamp) {
        sum.consistent = 0;
      }
    }
    if (first || !(clamp > 0)) sum.consistent = 0;
    cv_lcd_accum view = {.w = r->w, .h = r->h, .clamp = clamp,
                         .unit = clamp > 0 ? cv_lcd_unit_for_clamp(clamp) : 0, .n = r->words,
                         .data = r->data};
    sum.acc = &view;
    fn(&sum, user);
  }
  finish_epoch(r, now);
}

int cv_lcd_reduce_poll(cv_lcd_reduce *r, double now, double min_period, cv_lcd_reduce_fn fn,
                       void *user) {
  for (;;) {
    switch (r->phase) {
    case PH_DONE:
      return 1;
    case PH_HEADER:
      if (!cv_comm_lcd_test()) return 0;
      header_done(r, now);
      break;
    case PH_DATA:
      if (!cv_comm_lcd_test()) return 0;
      data_done(r, now, fn, user);
      break;
    default: /* idle */
      if (r->me == 0 && !r->announce_quit && r->epochs > 0 && now - r->t_start < min_period) return 0;
      start_header(r, now);
      return r->phase == PH_DONE;
    }
  }
}

void cv_lcd_reduce_get_stats(const cv_lcd_reduce *r, cv_lcd_reduce_stats *st) {
  st->epochs = r->epochs;
  st->data_epochs = r->data_epochs;
  st->rounds = r->rounds;
  st->mean_ms = r->epochs ? r->ms_sum / (double)r->epochs : 0;
}
