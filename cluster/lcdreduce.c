/* LCD rounds summed by allreduce (design card: "LCD sample aggregation via
 * allreduce").  The master and the gather-only ranks form a communicator
 * (cv_comm_lcd_group) and run the same epoch machine, each rank on its own
 * clock, never waiting:
 *
 *   header  MPI_Iallreduce (sum) of a small int64 vector: the master's
 *           current LCD key and its quit flag; in its own slot, each
 *           contributor's offer: the rounds it finished for its newest key
 *           (the key, clamp, frame of the snapshot, first round, count);
 *   data    only when something was offered: every member picks the same
 *           offer from the header (the master's current key first, else the
 *           newest snapshot), and MPI_Iallreduce (sum) adds the fixed-point
 *           LCD buffers of the offers of that key (cv_lcd_accum words; zeros
 *           from the others, whose offers go back to their pools).  The
 *           master is a leaf of the sum's tree (cv_comm_lcd_group): the
 *           gather ranks do the adding.
 *
 * So every sum is of one key.  The master tests the request once per poll
 * (each frame and in its waiting loops) and starts the next epoch at most
 * every min_period seconds; the gather ranks join at once.  A late gather rank delays the epoch (the sum
 * completes when it joins), never a frame.  The sum is of integers, so the
 * master's image is the same bits as the per-round messages gave, for any
 * rank count. */
#include "lcdreduce.h"

#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "comm.h"
#include "service_internal.h"

enum { PH_IDLE, PH_HEADER, PH_DATA, PH_DONE };
/* header: master's key, quit flag, then one slot per member: offered (1),
 * LCD key (4 words), clamp (bits), frame of the key, first round, rounds;
 * and, offer or not, the member's totals (cv_lcd_reduce_set_work): rounds
 * rendered, their wall and CPU time, its MPI thread's CPU time (us) */
enum { H_KEY = 0, H_QUIT = 1, H_SLOTS = 2, SLOT_WORDS = 13 };
enum { S_OFFER = 0, S_KEY = 1, S_CLAMP = 5, S_FRAME = 6, S_FIRST = 7, S_N = 8, S_WROUNDS = 9,
       S_WUS = 10, S_WCPU_US = 11, S_WCOMM_US = 12 };
enum { WORK = 4 }; /* the words from S_WROUNDS */
_Static_assert(sizeof(cv_lcd_key) == 4 * sizeof(int64_t), "an LCD key is 4 words");

/* Rounds of one key from one worker: first, first + stride, ... (n). */
typedef struct pool {
  cv_lcd_accum *acc;
  cv_lcd_key key;
  uint32_t frame, first, n;
} pool;

struct cv_lcd_reduce {
  int w, h, budget, stride, members, me;
  size_t words, hdr_n;
  int64_t *hdr, *data;
  int phase;
  int leak; /* abandoned with a sum in flight: MPI may still write hdr, data */
  double t_start;
  int quit_epoch;
  /* master */
  uint64_t announce;
  int announce_quit;
  uint32_t *rounds; /* budget: the rounds of a sum */
  /* contributor: rounds since the offer, and the offer in flight */
  pool pool, offer;
  /* its offers in the last two sums (rounds only): a member that died in
   * the middle of a sum may have completed it here but not on the master */
  struct {
    cv_lcd_key key;
    uint32_t first, n;
  } carried[2];
  /* contributor: its work so far (sent in its header slot) */
  int64_t work[WORK];
  /* master: each member's work from the last header */
  int64_t *member_work; /* WORK per member */
  /* totals */
  uint64_t epochs, data_epochs, nrounds;
  double ms_sum;
  uint64_t polls;
  double poll_ms, poll_cpu_ms, poll_ms_max, poll_cpu_ms_max;
};

int cv_lcd_reduce_create(int w, int h, int budget, int stride, int members, int me,
                         cv_lcd_reduce **out) {
  *out = NULL;
  if (w < 1 || h < 1 || budget < 1 || stride < 1 || members < 2 || me < 0 || me >= members)
    return CV_ERR_INVALID;
  cv_lcd_reduce *r = calloc(1, sizeof *r);
  if (!r) return CV_ERR_NOMEM;
  r->w = w;
  r->h = h;
  r->budget = budget;
  r->stride = stride;
  r->members = members;
  r->me = me;
  r->words = cv_lcd_accum_words(w, h);
  r->hdr_n = H_SLOTS + (size_t)SLOT_WORDS * (size_t)members;
  r->hdr = calloc(r->hdr_n, sizeof *r->hdr);
  r->data = calloc(r->words, sizeof *r->data);
  r->rounds = calloc((size_t)budget, sizeof *r->rounds);
  r->member_work = calloc(WORK * (size_t)members, sizeof *r->member_work);
  if (!r->hdr || !r->data || !r->rounds || !r->member_work) {
    cv_lcd_reduce_destroy(r);
    return CV_ERR_NOMEM;
  }
  r->phase = PH_IDLE;
  *out = r;
  return CV_OK;
}

static void pool_clear(pool *p) {
  cv_lcd_accum_destroy(p->acc);
  memset(p, 0, sizeof *p);
}

void cv_lcd_reduce_destroy(cv_lcd_reduce *r) {
  if (!r) return;
  pool_clear(&r->pool);
  pool_clear(&r->offer);
  if (!r->leak) { /* else left to MPI: the sum in flight may still write them */
    free(r->hdr);
    free(r->data);
  }
  free(r->rounds);
  free(r->member_work);
  free(r);
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
  pool *p = &r->pool;
  if (p->acc && cv_lcd_key_equal(&p->key, &h.key) && p->acc->clamp == h.clamp &&
      h.round == p->first + p->n * (uint32_t)r->stride) {
    if (cv_lcd_accum_add(p->acc, &view) != CV_OK) return 0; /* full: dropped */
    p->n++;
    return 0;
  }
  /* a new key (or a gap): the newest snapshot starts over */
  pool_clear(p);
  if (cv_lcd_accum_clone(&view, &p->acc) != CV_OK) return -1;
  p->key = h.key;
  p->frame = h.frame;
  p->first = h.round;
  p->n = 1;
  return 0;
}

void cv_lcd_reduce_announce(cv_lcd_reduce *r, uint64_t key, int quit) {
  r->announce = key;
  if (quit) r->announce_quit = 1;
}

static int64_t *slot(const cv_lcd_reduce *r, int member) {
  return r->hdr + H_SLOTS + (size_t)SLOT_WORDS * (size_t)member;
}

static void start_header(cv_lcd_reduce *r, double now) {
  memset(r->hdr, 0, r->hdr_n * sizeof *r->hdr);
  if (r->me == 0) {
    memcpy(&r->hdr[H_KEY], &r->announce, sizeof r->announce);
    r->hdr[H_QUIT] = r->announce_quit;
  } else {
    memcpy(slot(r, r->me) + S_WROUNDS, r->work, sizeof r->work);
  }
  if (r->me > 0 && r->pool.acc && r->pool.n > 0) { /* offer the pool, frozen */
    r->offer = r->pool;
    memset(&r->pool, 0, sizeof r->pool);
    int64_t *s = slot(r, r->me);
    s[S_OFFER] = 1;
    memcpy(s + S_KEY, &r->offer.key, sizeof r->offer.key);
    memcpy(s + S_CLAMP, &r->offer.acc->clamp, sizeof(double));
    s[S_FRAME] = r->offer.frame;
    s[S_FIRST] = r->offer.first;
    s[S_N] = r->offer.n;
  }
  r->t_start = now;
  r->phase = cv_comm_lcd_iallreduce(r->hdr, r->hdr_n) ? PH_IDLE : PH_HEADER;
  if (r->phase == PH_IDLE) pool_clear(&r->offer); /* MPI refused: lost, try later */
}

/* The offer every member picks from the header (the same on all): one of
 * the master's current key, else the newest snapshot (latest frame), the
 * lowest member on ties.  -1: nothing offered. */
static int chosen(const cv_lcd_reduce *r) {
  uint64_t cur;
  memcpy(&cur, &r->hdr[H_KEY], sizeof cur);
  int best = -1, best_cur = 0;
  int64_t best_frame = -1;
  for (int m = 1; m < r->members; m++) {
    const int64_t *s = slot(r, m);
    if (s[S_OFFER] != 1) continue;
    cv_lcd_key k;
    memcpy(&k, s + S_KEY, sizeof k);
    const int is_cur = cv_service_lcd_key(k.eye_q, k.light_hash) == cur;
    if (best < 0 || is_cur > best_cur || (is_cur == best_cur && s[S_FRAME] > best_frame)) {
      best = m;
      best_cur = is_cur;
      best_frame = s[S_FRAME];
    }
  }
  return best;
}

/* Does member m's offer sum with the chosen one (same key and clamp)? */
static int matches(const cv_lcd_reduce *r, int m, int best) {
  const int64_t *s = slot(r, m), *b = slot(r, best);
  return s[S_OFFER] == 1 && memcmp(s + S_KEY, b + S_KEY, 5 * sizeof(int64_t)) == 0;
}

static void finish_epoch(cv_lcd_reduce *r, double now) {
  r->epochs++;
  r->ms_sum += (now - r->t_start) * 1e3;
  pool_clear(&r->offer);
  r->phase = r->quit_epoch ? PH_DONE : PH_IDLE;
}

/* An offer not chosen goes back to the pool: in front of the rounds of the
 * same key finished meanwhile; dropped when a newer key has started. */
static void offer_back(cv_lcd_reduce *r) {
  pool *o = &r->offer, *p = &r->pool;
  if (!o->acc) return;
  if (!p->acc) {
    *p = *o;
    memset(o, 0, sizeof *o);
  } else if (cv_lcd_key_equal(&p->key, &o->key) && p->acc->clamp == o->acc->clamp &&
             p->first == o->first + o->n * (uint32_t)r->stride &&
             cv_lcd_accum_add(o->acc, p->acc) == CV_OK) {
    o->n += p->n;
    pool_clear(p);
    *p = *o;
    memset(o, 0, sizeof *o);
  }
  pool_clear(o);
}

static void header_done(cv_lcd_reduce *r, double now) {
  r->quit_epoch = r->hdr[H_QUIT] != 0;
  if (r->me == 0)
    for (int m = 1; m < r->members; m++) {
      const int64_t *s = slot(r, m);
      if (s[S_WROUNDS] >= r->member_work[WORK * m]) /* totals only grow */
        memcpy(r->member_work + WORK * (size_t)m, s + S_WROUNDS, WORK * sizeof(int64_t));
    }
  const int best = chosen(r);
  if (r->me > 0 && r->offer.acc && (best < 0 || !matches(r, r->me, best))) offer_back(r);
  if (best < 0) {
    finish_epoch(r, now);
    return;
  }
  if (r->offer.acc) memcpy(r->data, r->offer.acc->data, r->words * sizeof *r->data);
  else memset(r->data, 0, r->words * sizeof *r->data);
  if (cv_comm_lcd_iallreduce(r->data, r->words)) {
    finish_epoch(r, now);
    return;
  }
  r->phase = PH_DATA;
}

static void data_done(cv_lcd_reduce *r, double now, cv_lcd_reduce_fn fn, void *user) {
  const int best = chosen(r);
  cv_lcd_reduce_sum sum;
  memset(&sum, 0, sizeof sum);
  memcpy(&sum.key, slot(r, best) + S_KEY, sizeof sum.key);
  double clamp;
  memcpy(&clamp, slot(r, best) + S_CLAMP, sizeof clamp);
  sum.frame = (uint32_t)slot(r, best)[S_FRAME];
  for (int m = 1; m < r->members; m++) {
    if (!matches(r, m, best)) continue;
    const int64_t *s = slot(r, m);
    if ((uint32_t)s[S_FRAME] < sum.frame) sum.frame = (uint32_t)s[S_FRAME];
    for (int64_t i = 0; i < s[S_N]; i++) {
      const int64_t round = s[S_FIRST] + i * r->stride;
      if (round >= 0 && round < r->budget && sum.rounds < (uint32_t)r->budget)
        r->rounds[sum.rounds++] = (uint32_t)round;
    }
  }
  if (r->me > 0 && r->offer.acc && matches(r, r->me, best)) {
    r->carried[1] = r->carried[0];
    r->carried[0].key = r->offer.key;
    r->carried[0].first = r->offer.first;
    r->carried[0].n = r->offer.n;
  }
  r->data_epochs++;
  r->nrounds += sum.rounds;
  if (r->me == 0 && fn && clamp > 0) {
    cv_lcd_accum view = {.w = r->w, .h = r->h, .clamp = clamp, .unit = cv_lcd_unit_for_clamp(clamp),
                         .n = r->words, .data = r->data};
    sum.round = r->rounds;
    sum.acc = &view;
    fn(&sum, user);
  }
  finish_epoch(r, now);
}

static int poll_step(cv_lcd_reduce *r, double now, double min_period, cv_lcd_reduce_fn fn,
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
      return 0;
    }
  }
}

static double clock_ms(clockid_t id) {
  struct timespec ts;
  clock_gettime(id, &ts);
  return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

/* poll_step, timed: wall and this thread's CPU time per call (the MPI_Test
 * that may run Open MPI's part of the sum, and fn). */
int cv_lcd_reduce_poll(cv_lcd_reduce *r, double now, double min_period, cv_lcd_reduce_fn fn,
                       void *user) {
  const double w0 = clock_ms(CLOCK_MONOTONIC), c0 = clock_ms(CLOCK_THREAD_CPUTIME_ID);
  const int done = poll_step(r, now, min_period, fn, user);
  const double dw = clock_ms(CLOCK_MONOTONIC) - w0, dc = clock_ms(CLOCK_THREAD_CPUTIME_ID) - c0;
  r->polls++;
  r->poll_ms += dw;
  r->poll_cpu_ms += dc;
  if (dw > r->poll_ms_max) r->poll_ms_max = dw;
  if (dc > r->poll_cpu_ms_max) r->poll_cpu_ms_max = dc;
  return done;
}

void cv_lcd_reduce_set_work(cv_lcd_reduce *r, uint64_t rounds, double ms, double cpu_ms, double comm_cpu_ms) {
  r->work[0] = (int64_t)rounds;
  r->work[1] = (int64_t)(ms * 1e3);
  r->work[2] = (int64_t)(cpu_ms * 1e3);
  r->work[3] = (int64_t)(comm_cpu_ms * 1e3);
}

int cv_lcd_reduce_in_flight(const cv_lcd_reduce *r) {
  return r->phase == PH_HEADER || r->phase == PH_DATA;
}

double cv_lcd_reduce_waiting(const cv_lcd_reduce *r, double now, double since) {
  if (r->phase != PH_HEADER && r->phase != PH_DATA) return 0;
  return now - (r->t_start > since ? r->t_start : since);
}

void cv_lcd_reduce_abandon(cv_lcd_reduce *r) {
  if (r->phase == PH_HEADER || r->phase == PH_DATA) r->leak = 1;
  cv_comm_lcd_abandon();
  pool_clear(&r->offer);
  r->phase = PH_DONE;
}

int cv_lcd_reduce_unsent(const cv_lcd_reduce *r, int which, cv_lcd_key *key, uint32_t *first,
                         uint32_t *n) {
  if (which == 2 || which == 3) {
    if (r->carried[which - 2].n == 0) return -1;
    *key = r->carried[which - 2].key;
    *first = r->carried[which - 2].first;
    *n = r->carried[which - 2].n;
    return 0;
  }
  const pool *p = which == 0 ? &r->offer : &r->pool;
  if (!p->acc || p->n == 0) return -1;
  *key = p->key;
  *first = p->first;
  *n = p->n;
  return 0;
}

void cv_lcd_reduce_get_stats(const cv_lcd_reduce *r, cv_lcd_reduce_stats *st) {
  st->epochs = r->epochs;
  st->data_epochs = r->data_epochs;
  st->rounds = r->nrounds;
  st->mean_ms = r->epochs ? r->ms_sum / (double)r->epochs : 0;
  st->polls = r->polls;
  st->poll_ms = r->poll_ms;
  st->poll_cpu_ms = r->poll_cpu_ms;
  st->poll_ms_max = r->poll_ms_max;
  st->poll_cpu_ms_max = r->poll_cpu_ms_max;
  st->gather_rounds = 0;
  st->gather_ms = st->gather_cpu_ms = st->gather_comm_cpu_ms = st->gather_comm_cpu_ms_max = 0;
  for (int m = 1; r->me == 0 && m < r->members; m++) {
    const int64_t *w = r->member_work + WORK * (size_t)m;
    st->gather_rounds += (uint64_t)w[0];
    st->gather_ms += (double)w[1] * 1e-3;
    st->gather_cpu_ms += (double)w[2] * 1e-3;
    st->gather_comm_cpu_ms += (double)w[3] * 1e-3;
    if ((double)w[3] * 1e-3 > st->gather_comm_cpu_ms_max) st->gather_comm_cpu_ms_max = (double)w[3] * 1e-3;
  }
}
