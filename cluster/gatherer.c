/* Gather-only ranks (render farm): LCD final-gather rounds, nothing else.
 * The MPI thread takes frame states (the newest wins), posts them to the
 * worker thread and pools its finished rounds for the LCD allreduce with the
 * master and the other gather ranks (lcdreduce.c).  A gather rank is never
 * waited for by a frame: a slow or stopped one only delays the sums. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "comm.h"
#include "lcdreduce.h"
#include "lcdwork.h"
#include "service_internal.h"

static int pool_round(const uint8_t *buf, size_t len, void *user) {
  return cv_lcd_reduce_add_round(user, buf, len);
}

/* After the allreduce was given up: each round straight to the master. */
static int send_round(const uint8_t *buf, size_t len, void *user) {
  (void)user;
  return cv_comm_send(buf, len, 0, CV_TAG_LCD);
}

/* Gives the allreduce up (a member died, docs/dead-rank.md): when the master
 * says so (a death notice, or dead gather ranks in the frame state: told),
 * or when an epoch has waited --gather-timeout s while states came in (the
 * master or another member is gone).  The rounds then go point-to-point;
 * those the allreduce had not carried yet are rendered again. */
static void maybe_abandon(cv_service *s, cv_lcd_reduce **red, cv_lcd_worker *w, double first_state,
                          int told) {
  if (!*red) return;
  const double waited = first_state > 0 ? cv_lcd_reduce_waiting(*red, cv_service_now(), first_state) : 0;
  if (!told && waited <= s->o.gather_timeout_s) return;
  if (told) fprintf(stderr, "cave run: rank %d: told a gather rank died: LCD rounds point-to-point\n", s->rank);
  else fprintf(stderr, "cave run: rank %d: LCD sum waited %.1f s: LCD rounds point-to-point\n", s->rank, waited);
  for (int which = 0; w && which < 4; which++) {
    cv_lcd_key key;
    uint32_t first, n;
    if (cv_lcd_reduce_unsent(*red, which, &key, &first, &n) == 0) cv_lcd_worker_redo(w, &key, first, n);
  }
  cv_lcd_reduce_abandon(*red);
  cv_lcd_reduce_destroy(*red);
  *red = NULL;
}

/* This (the MPI) thread's CPU time, ms. */
static double thread_cpu_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

/* Reports set-up success ('O') or failure ('F'), the .prt's hash and the
 * message to the master. */
void cv_service_ready(int ok, uint64_t prt_hash, const char *msg) {
  char buf[2048];
  buf[0] = ok ? 'O' : 'F';
  memcpy(buf + 1, &prt_hash, 8);
  size_t n = 9;
  if (msg) {
    size_t l = strlen(msg);
    if (l > sizeof buf - 10) l = sizeof buf - 10;
    memcpy(buf + 9, msg, l);
    n += l;
  }
  cv_comm_send(buf, n, 0, CV_TAG_READY);
}

void cv_service_test_load_delay(int rank) {
  const char *e = getenv("CAVE_TEST_LOAD_DELAY");
  if (!e) return;
  char *end;
  const long ms = strtol(e, &end, 10);
  if (*end != ':' || ms <= 0) return;
  for (const char *p = end + 1; *p;) {
    const long r = strtol(p, &end, 10);
    if (end == p) return;
    if (r == rank) {
      struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
      nanosleep(&ts, NULL);
      return;
    }
    p = *end == ',' ? end + 1 : end;
  }
}

int cv_gather_run(cv_service *s) {
  cv_err err;
  cv_err_clear(&err);
  cv_prt *prt = NULL;
  cv_lcd_worker *w = NULL;
  const int index = cv_service_contributor(s, s->rank);
  cv_service_test_load_delay(s->rank);
  int st = cv_prt_read(s->o.scene_path, &prt, &err);
  if (!st && index >= 0) st = cv_lcd_worker_create(s, prt, index, 0, &w, &err);
  {
    char host[128], msg[800];
    cv_comm_host(host, sizeof host);
    if (st == CV_OK) snprintf(msg, sizeof msg, "rank %d on %s: gather-only (LCD path tracing)", s->rank, host);
    else snprintf(msg, sizeof msg, "rank %d on %s (gather): %s", s->rank, host, err.msg);
    cv_service_ready(st == CV_OK, prt ? prt->meta.file_hash : 0, msg);
  }
  cv_lcd_reduce *red = NULL;
  if (s->lcd_me > 0 && cv_lcd_reduce_create(s->o.lcd_w, s->o.lcd_h, s->o.lcd_budget, s->n_contributors, s->lcd_members,
                                            s->lcd_me, &red) != CV_OK)
    fprintf(stderr, "cave run: rank %d: LCD reduction: out of memory\n", s->rank);
  cv_mailbox *mb = cv_mailbox_open(0, CV_TAG_STATE, CV_FRAME_STATE_BYTES);
  cv_mailbox *alive_mb = cv_mailbox_open(0, CV_TAG_ALIVE, 16);
  double stop_since = 0, quit_since = 0, first_state = 0, beat_t = 0;
  const double comm_cpu0 = thread_cpu_ms();
  uint32_t beats = 0;
  int rc = st ? 1 : 0;
  for (;;) {
    const uint8_t *data;
    long len;
    int quit = 0, got = 0;
    cv_frame_state fs;
    while (mb && (len = cv_mailbox_take(mb, &data, NULL)) >= 0) {
      if (cv_frame_state_unpack(data, (size_t)len, &fs, &err)) {
        fprintf(stderr, "cave run: rank %d: %s (state dropped)\n", s->rank, err.msg);
        continue;
      }
      if (fs.flags & CV_FS_QUIT) quit = 1;
      got = 1;
    }
    if (quit && quit_since == 0) quit_since = cv_service_now();
    if (got && first_state == 0) first_state = cv_service_now();
    /* the worker shares a dead gather rank's rounds only once the allreduce
     * (which wants each worker's rounds in stride) is given up */
    if (got && fs.lcd_dead && !quit_since) maybe_abandon(s, &red, w, first_state, 1);
    if (got && w && !quit_since && !(fs.flags & CV_FS_MEASURE)) cv_lcd_worker_post(w, &fs);
    if (cv_service_now() - beat_t >= 0.25) { /* heartbeat (master_health.c) */
      beats++;
      cv_comm_send(&beats, sizeof beats, 0, CV_TAG_ALIVE);
      beat_t = cv_service_now();
    }
    /* the master's death notices: another gather rank (the allreduce is
     * given up), or this one (it was stalled: it leaves at once) */
    int told = 0;
    while (alive_mb && (len = cv_mailbox_take(alive_mb, &data, NULL)) >= 0) {
      int32_t dead;
      if (cv_comm_dead_notice(data, len) && (memcpy(&dead, data + 1, sizeof dead), dead > s->n_render))
        told = 1; /* a gather rank ('D' + int32 rank): the allreduce would wait for it */
    }
    if (cv_comm_declared_dead()) break;
    if (!quit_since) maybe_abandon(s, &red, w, first_state, told);
    if (w && red) {
      cv_lcd_worker_send_ready(w, pool_round, red, NULL, NULL);
      uint64_t rounds;
      double ms, cpu_ms;
      cv_lcd_worker_totals(w, &rounds, &ms, &cpu_ms);
      cv_lcd_reduce_set_work(red, rounds, ms, cpu_ms, thread_cpu_ms() - comm_cpu0);
    }
    else if (w && s->lcd_me > 0) cv_lcd_worker_send_ready(w, send_round, NULL, NULL, NULL);
    /* After the quit, the epochs go on until the master's last one (it
     * brings the last pooled rounds), but not for ever: longer than the
     * master waits for it (10 s, lcd_reduce_finish), so it gives up first. */
    const int red_done = red ? cv_lcd_reduce_poll(red, cv_service_now(), 0, NULL, NULL) : 1;
    if (quit_since && (red_done || cv_service_now() - quit_since > 15)) break;
    cv_comm_progress();
    if (*s->stop) { /* wait for the master's quit, but not for ever */
      if (stop_since == 0) stop_since = cv_service_now();
      else if (cv_service_now() - stop_since > 5) break;
    }
    struct timespec ts = {0, 1000000};
    nanosleep(&ts, NULL);
  }
  if (red && cv_lcd_reduce_in_flight(red)) { /* its buffers stay MPI's; no MPI_Finalize */
    fprintf(stderr, "cave run: rank %d: LCD sum still in flight at the end: given up\n", s->rank);
    cv_lcd_reduce_abandon(red);
  }
  cv_lcd_worker_destroy(w);
  cv_lcd_reduce_destroy(red);
  cv_mailbox_close(mb);
  cv_mailbox_close(alive_mb);
  cv_prt_destroy(prt);
  cv_comm_flush(2);
  return rc;
}
