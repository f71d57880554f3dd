/* Progress bar with ETA for long multi-threaded loops (bake, final gather).
 *
 * Worker threads call cv_progress_add() once per work item (e.g. a tile of
 * ~1000 rays); the call is one relaxed atomic add plus a cheap monotonic
 * clock read, and at most one thread at a time redraws (a try-lock, at most
 * ~5 redraws a second), so it can be called from OpenMP loops freely.
 *
 * Output goes to stderr (or the stream given to cv_progress_create_ex):
 *  - on a terminal one line is redrawn with '\r':
 *      "label [#####.....] 42% 12.3 s elapsed, ETA 17.0 s"
 *  - otherwise (CI logs, files) a plain line is printed at each 10% step.
 * cv_progress_finish() prints the closing line with elapsed time and items/s.
 *
 * Every function accepts a NULL progress and then does nothing, so callers
 * can pass NULL (or create with CV_PROGRESS_QUIET) to silence it. */
#ifndef CV_CORE_PROGRESS_H
#define CV_CORE_PROGRESS_H

#include <stdint.h>
#include <stdio.h>

typedef struct cv_progress cv_progress;

enum {
  CV_PROGRESS_QUIET = 1u << 0,      /* count, but never print */
  CV_PROGRESS_FORCE_TTY = 1u << 1,  /* redraw with '\r' even if not a TTY */
  CV_PROGRESS_FORCE_PLAIN = 1u << 2 /* 10% lines even on a TTY */
};

/* Seconds on the monotonic clock (CLOCK_MONOTONIC) since an arbitrary
 * origin; for measuring intervals only. */
double cv_now_seconds(void);

/* Creates a progress bar over `total` items (0 = unknown total: no bar,
 * percentage or ETA, only counts) printing to stderr.  label is copied
 * (truncated to 63 chars; NULL = "progress").  *out owned by the caller
 * (cv_progress_destroy).  Returns CV_ERR_NOMEM. */
int cv_progress_create(const char *label, uint64_t total, cv_progress **out);

/* As cv_progress_create with CV_PROGRESS_* flags and an output stream
 * (NULL = stderr; not closed by the progress). */
int cv_progress_create_ex(const char *label, uint64_t total, unsigned flags,
                          FILE *stream, cv_progress **out);

/* Adds n finished items.  Thread-safe; may redraw (one thread at a time,
 * throttled to ~5 Hz on a TTY, once per 10% step otherwise). */
void cv_progress_add(cv_progress *p, uint64_t n);

/* Items counted so far (exact once all adding threads have joined). */
uint64_t cv_progress_count(const cv_progress *p);

/* Prints the final line: count, total elapsed seconds and items per second.
 * Call once after the loop (later calls do nothing).  Not thread-safe with
 * concurrent cv_progress_add. */
void cv_progress_finish(cv_progress *p);

/* Seconds since creation. 0 for NULL. */
double cv_progress_elapsed(const cv_progress *p);

/* Frees the progress (does not print); accepts NULL. */
void cv_progress_destroy(cv_progress *p);

#endif
