/* LCD rounds summed by a non-blocking allreduce among the master and the
 * gather-only ranks (see lcdreduce.c). */
#ifndef CV_CLUSTER_LCDREDUCE_H
#define CV_CLUSTER_LCDREDUCE_H

#include <stddef.h>
#include <stdint.h>

#include "lcd/accum.h"

typedef struct cv_lcd_reduce cv_lcd_reduce;

/* One epoch's sum as the master receives it: the LCD key of the rounds,
 * the earliest frame whose state that key was taken from, the rounds
 * (`rounds` entries, as the contributors declared them) and the summed
 * buffer (a view, valid during the call). */
typedef struct cv_lcd_reduce_sum {
  cv_lcd_key key;
  uint32_t frame;
  const uint32_t *round;
  uint32_t rounds;
  const cv_lcd_accum *acc;
} cv_lcd_reduce_sum;
typedef void (*cv_lcd_reduce_fn)(const cv_lcd_reduce_sum *sum, void *user);

/* members: the communicator's size (>= 2), me: this rank in it (0 = the
 * master); stride: the contributors' count (a worker's rounds of one key
 * are first, first + stride, ...).  *out owned by the caller.  Errors:
 * CV_ERR_INVALID, CV_ERR_NOMEM. */
int cv_lcd_reduce_create(int w, int h, int budget, int stride, int members, int me,
                         cv_lcd_reduce **out);
void cv_lcd_reduce_destroy(cv_lcd_reduce *r);

/* Contributor: adds a finished round (a cv_lcd_msg and its values) to the
 * pool it offers the next epochs; a round of another key (a newer snapshot)
 * replaces the pool.  Returns 0, or -1 for a malformed message. */
int cv_lcd_reduce_add_round(cv_lcd_reduce *r, const uint8_t *msg, size_t len);

/* Master: its current LCD key, preferred when contributors offer several
 * keys; quit = 1 makes the next epoch the last one for every member. */
void cv_lcd_reduce_announce(cv_lcd_reduce *r, uint64_t key, int quit);

/* Advances the epoch state machine without waiting: tests the sum in
 * flight (MPI_Test), hands a finished sum to fn (master; may be NULL),
 * starts the next epoch when the last one is over and, on the master, at
 * least min_period seconds have passed since it started.  Returns 1 once
 * the quit epoch has finished (nothing more will be started), else 0. */
int cv_lcd_reduce_poll(cv_lcd_reduce *r, double now, double min_period, cv_lcd_reduce_fn fn,
                       void *user);

/* Contributor: its totals so far (rounds rendered, their wall and CPU ms,
 * and the CPU ms of its MPI thread: pooling, the sum's share, polling),
 * sent in its header slot with every epoch (the master's per-rank figures). */
void cv_lcd_reduce_set_work(cv_lcd_reduce *r, uint64_t rounds, double ms, double cpu_ms, double comm_cpu_ms);

/* Seconds the epoch in flight has waited since max(its start, since); 0
 * when none is in flight. */
double cv_lcd_reduce_waiting(const cv_lcd_reduce *r, double now, double since);
/* 1 while a sum is in flight (its buffers belong to MPI). */
int cv_lcd_reduce_in_flight(const cv_lcd_reduce *r);
/* Gives the sum up for good (a member died, cv_comm_lcd_abandon): the
 * epoch in flight and the rounds it offered are dropped, poll returns 1
 * from now on; the totals stay.  With a sum in flight its buffers are never
 * freed (MPI may still write them). */
void cv_lcd_reduce_abandon(cv_lcd_reduce *r);

/* Contributor: the rounds no sum has carried yet, offered in the epoch in
 * flight (which = 0) or pooled since (which = 1), or carried by the last
 * (2) and the one before (3) sum here, which a member dying in the middle
 * of a sum may have kept from the master: key, first round, count (first,
 * first + stride, ...).  Returns 0, or -1 when there are none.  (Before
 * cv_lcd_reduce_abandon, which drops them: they are rendered again.) */
int cv_lcd_reduce_unsent(const cv_lcd_reduce *r, int which, cv_lcd_key *key, uint32_t *first,
                         uint32_t *n);

/* Totals: epochs finished, those that carried rounds, and the mean time
 * from an epoch's start to its sum on this rank (ms); calls of
 * cv_lcd_reduce_poll, their wall and thread-CPU time (total and largest
 * call, ms); on the master, the gather ranks' totals from the last header:
 * rounds rendered, their wall and CPU ms, their MPI threads' CPU ms (summed
 * over the ranks, and the largest). */
typedef struct cv_lcd_reduce_stats {
  uint64_t epochs, data_epochs, rounds;
  double mean_ms;
  uint64_t polls;
  double poll_ms, poll_cpu_ms, poll_ms_max, poll_cpu_ms_max;
  uint64_t gather_rounds;
  double gather_ms, gather_cpu_ms, gather_comm_cpu_ms, gather_comm_cpu_ms_max;
} cv_lcd_reduce_stats;
void cv_lcd_reduce_get_stats(const cv_lcd_reduce *r, cv_lcd_reduce_stats *st);

#endif
