/* A writer thread with a bounded queue (issue 33: writing files never stalls
 * a frame).  The caller hands over jobs, each a function that writes one or
 * more files from data it owns; the thread runs them in order.  When the
 * queue is full a job is refused at once (the caller counts it as dropped):
 * nothing waits for the disk on the caller's path.  Files are whole: jobs
 * write to a temporary name and rename (cv_write_png_atomic; cv_exr_write
 * already does).  No global state; one writer per caller. */
#ifndef CV_IO_FILEWRITER_H
#define CV_IO_FILEWRITER_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"

typedef struct cv_filewriter cv_filewriter;

/* A job: run(job, err) writes its files (0 or a status with err), then
 * done(job) frees it (also for a job never run: a refused one). */
typedef struct cv_write_job {
  int (*run)(void *job, cv_err *err);
  void (*done)(void *job);
  void *job;
} cv_write_job;

/* A writer whose queue holds at most cap jobs; idle: its thread runs at
 * SCHED_IDLE (Linux), only on cores the process's other threads and the
 * host's other processes leave idle, so its work does not lengthen frames
 * (the queue then fills sooner: drops are counted).  *out owned by the
 * caller (cv_filewriter_destroy).  Errors: CV_ERR_INVALID (cap < 1),
 * CV_ERR_NOMEM, CV_ERR_BACKEND (no thread). */
int cv_filewriter_create(int cap, int idle, cv_filewriter **out, cv_err *err);
/* Queues j: 0, or -1 when the queue is full (j.done called: dropped). */
int cv_filewriter_submit(cv_filewriter *w, cv_write_job j);
/* Counts so far: jobs written, failed (the first failure's message in
 * first_error, may be NULL), dropped (queue full), waiting in the queue. */
typedef struct cv_filewriter_stats {
  uint64_t written, failed, dropped, queued;
  char first_error[512];
} cv_filewriter_stats;
void cv_filewriter_stats_get(cv_filewriter *w, cv_filewriter_stats *st);
/* Waits until the queue is empty and the running job done; then *st (may
 * be NULL) gets the final counts. */
void cv_filewriter_drain(cv_filewriter *w, cv_filewriter_stats *st);
/* Runs what is queued, then ends the thread and frees; accepts NULL. */
void cv_filewriter_destroy(cv_filewriter *w);

/* cv_png_write to "path.tmp.<pid>" then rename(2): a reader never sees a
 * partial file, and a failed write leaves none (the temporary is removed). */
int cv_write_png_atomic(const char *path, int w, int h, int channels, const uint8_t *px, cv_err *err);

#endif
