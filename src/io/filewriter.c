/* The bounded-queue writer thread (see filewriter.h). */
#define _GNU_SOURCE 1 /* syscall */
#include "io/filewriter.h"

#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "io/png.h"

/* nice of an idle writer's thread: CFS weight 110 against 1024 for a busy
 * render thread, ~10% of a contended core; never starved (SCHED_IDLE
 * starved it on 2 cores with 12 busy ranks: 32 of 50 files dropped) */
#define CV_FILEWRITER_NICE 10

struct cv_filewriter {
  pthread_t th;
  pthread_mutex_t mu;
  pthread_cond_t cv;
  cv_write_job *q;        /* ring of cap jobs */
  int cap, head, n, quit, started, idle;
  cv_filewriter_stats st;
  int busy;               /* a job is running */
};

static void *writer_main(void *arg) {
  cv_filewriter *w = arg;
  if (w->idle) /* a low share of a busy core (Linux: nice is per thread) */
    setpriority(PRIO_PROCESS, (id_t)syscall(SYS_gettid), CV_FILEWRITER_NICE);
  pthread_mutex_lock(&w->mu);
  for (;;) {
    while (!w->n && !w->quit) pthread_cond_wait(&w->cv, &w->mu);
    if (!w->n) break; /* quit with an empty queue */
    cv_write_job j = w->q[w->head];
    w->head = (w->head + 1) % w->cap;
    w->n--;
    w->busy = 1;
    pthread_mutex_unlock(&w->mu);
    cv_err err;
    cv_err_clear(&err);
    const int rc = j.run(j.job, &err);
    if (j.done) j.done(j.job);
    pthread_mutex_lock(&w->mu);
    w->busy = 0;
    pthread_cond_broadcast(&w->cv);
    if (rc) {
      if (!w->st.failed) snprintf(w->st.first_error, sizeof w->st.first_error, "%s", err.msg);
      w->st.failed++;
    } else {
      w->st.written++;
    }
  }
  pthread_mutex_unlock(&w->mu);
  return NULL;
}

int cv_filewriter_create(int cap, int idle, cv_filewriter **out, cv_err *err) {
  *out = NULL;
  if (cap < 1) return cv_err_set(err, CV_ERR_INVALID, "file writer: queue of %d jobs", cap);
  cv_filewriter *w = calloc(1, sizeof *w);
  if (!w || !(w->q = calloc((size_t)cap, sizeof *w->q))) {
    free(w);
    return cv_err_set(err, CV_ERR_NOMEM, "file writer: out of memory");
  }
  w->cap = cap;
  w->idle = idle;
  pthread_mutex_init(&w->mu, NULL);
  pthread_cond_init(&w->cv, NULL);
  if (pthread_create(&w->th, NULL, writer_main, w)) {
    pthread_mutex_destroy(&w->mu);
    pthread_cond_destroy(&w->cv);
    free(w->q);
    free(w);
    return cv_err_set(err, CV_ERR_BACKEND, "file writer: cannot start its thread");
  }
  w->started = 1;
  *out = w;
  return CV_OK;
}

int cv_filewriter_submit(cv_filewriter *w, cv_write_job j) {
  pthread_mutex_lock(&w->mu);
  if (w->n >= w->cap) {
    w->st.dropped++;
    pthread_mutex_unlock(&w->mu);
    if (j.done) j.done(j.job);
    return -1;
  }
  w->q[(w->head + w->n) % w->cap] = j;
  w->n++;
  pthread_cond_broadcast(&w->cv);
  pthread_mutex_unlock(&w->mu);
  return 0;
}

void cv_filewriter_stats_get(cv_filewriter *w, cv_filewriter_stats *st) {
  memset(st, 0, sizeof *st);
  if (!w) return;
  pthread_mutex_lock(&w->mu);
  *st = w->st;
  st->queued = (uint64_t)w->n;
  pthread_mutex_unlock(&w->mu);
}

void cv_filewriter_drain(cv_filewriter *w, cv_filewriter_stats *st) {
  if (!w) {
    if (st) memset(st, 0, sizeof *st);
    return;
  }
  pthread_mutex_lock(&w->mu);
  while (w->n || w->busy) pthread_cond_wait(&w->cv, &w->mu);
  pthread_mutex_unlock(&w->mu);
  if (st) cv_filewriter_stats_get(w, st);
}

void cv_filewriter_destroy(cv_filewriter *w) {
  if (!w) return;
  pthread_mutex_lock(&w->mu);
  w->quit = 1;
  pthread_cond_broadcast(&w->cv);
  pthread_mutex_unlock(&w->mu);
  if (w->started) pthread_join(w->th, NULL);
  pthread_mutex_destroy(&w->mu);
  pthread_cond_destroy(&w->cv);
  free(w->q);
  free(w);
}

int cv_write_png_atomic(const char *path, int w, int h, int channels, const uint8_t *px, cv_err *err) {
  char tmp[4096];
  if (snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid()) >= (int)sizeof tmp)
    return cv_err_set(err, CV_ERR_INVALID, "%s: path too long", path);
  int st = cv_png_write(tmp, w, h, channels, px, err);
  if (!st && rename(tmp, path)) st = cv_err_set(err, CV_ERR_IO, "%s: cannot rename %s into place", path, tmp);
  if (st) remove(tmp);
  return st;
}
