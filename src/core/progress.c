/* Progress bar with ETA (see progress.h).
 *
 * Concurrency: `done` is a relaxed atomic counter.  Redrawing is guarded by
 * an atomic_flag used as a try-lock: a thread that fails to take it simply
 * skips drawing (another thread is drawing a fresher or equally fresh
 * state), so adders never block.  The time of the last redraw is an atomic
 * nanosecond count read before trying the lock, which keeps the common path
 * to one fetch_add, one clock read and one load. */
#include "core/progress.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "core/status.h"

#define CV_PROGRESS_REDRAW_NS 200000000ull /* 0.2 s: at most ~5 redraws/s */
#define CV_PROGRESS_BAR 30

struct cv_progress {
  char label[64];
  uint64_t total;
  FILE *stream;
  int tty;   /* redraw one line with '\r' */
  int quiet; /* print nothing */
  int finished;
  uint64_t t0_ns;
  atomic_uint_fast64_t done;
  atomic_uint_fast64_t last_draw_ns;
  atomic_int last_decile; /* plain mode: last 10% step printed */
  atomic_flag drawing;
};

static uint64_t now_ns(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

double cv_now_seconds(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int cv_progress_create_ex(const char *label, uint64_t total, unsigned flags,
                          FILE *stream, cv_progress **out) {
  *out = NULL;
  cv_progress *p = calloc(1, sizeof *p);
  if (!p) return CV_ERR_NOMEM;
  snprintf(p->label, sizeof p->label, "%s", label ? label : "progress");
  p->total = total;
  p->stream = stream ? stream : stderr;
  p->quiet = (flags & CV_PROGRESS_QUIET) != 0;
  if (flags & CV_PROGRESS_FORCE_TTY)
    p->tty = 1;
  else if (flags & CV_PROGRESS_FORCE_PLAIN)
    p->tty = 0;
  else
    p->tty = isatty(fileno(p->stream));
  p->t0_ns = now_ns();
  atomic_init(&p->done, 0);
  atomic_init(&p->last_draw_ns, 0);
  atomic_init(&p->last_decile, 0);
  atomic_flag_clear(&p->drawing);
  *out = p;
  return CV_OK;
}

int cv_progress_create(const char *label, uint64_t total, cv_progress **out) {
  return cv_progress_create_ex(label, total, 0, NULL, out);
}

/* Fraction done in [0, 1] (counts past total are shown as 100%). */
static double fraction(const cv_progress *p, uint64_t done) {
  if (p->total == 0) return 0.0;
  double f = (double)done / (double)p->total;
  return f > 1.0 ? 1.0 : f;
}

static void draw_tty(cv_progress *p, uint64_t done, double elapsed) {
  if (p->total == 0) {
    fprintf(p->stream, "\r%s %llu items %.1f s elapsed   ", p->label,
            (unsigned long long)done, elapsed);
    fflush(p->stream);
    return;
  }
  double f = fraction(p, done);
  char bar[CV_PROGRESS_BAR + 1];
  int full = (int)(f * CV_PROGRESS_BAR);
  for (int i = 0; i < CV_PROGRESS_BAR; ++i) bar[i] = i < full ? '#' : '.';
  bar[CV_PROGRESS_BAR] = '\0';
  /* ETA by linear extrapolation of the mean rate so far. */
  if (done > 0) {
    double eta = elapsed * (1.0 - f) / f;
    fprintf(p->stream, "\r%s [%s] %3d%% %.1f s elapsed, ETA %.1f s   ", p->label, bar,
            (int)(100.0 * f), elapsed, eta);
  } else {
    fprintf(p->stream, "\r%s [%s] %3d%% %.1f s elapsed, ETA ?   ", p->label, bar,
            (int)(100.0 * f), elapsed);
  }
  fflush(p->stream);
}

void cv_progress_add(cv_progress *p, uint64_t n) {
  if (!p) return;
  uint64_t done = atomic_fetch_add_explicit(&p->done, n, memory_order_relaxed) + n;
  if (p->quiet) return;
  if (p->tty) {
    uint64_t t = now_ns();
    uint64_t last = atomic_load_explicit(&p->last_draw_ns, memory_order_relaxed);
    if (t - p->t0_ns < CV_PROGRESS_REDRAW_NS || t - last < CV_PROGRESS_REDRAW_NS) return;
    if (atomic_flag_test_and_set_explicit(&p->drawing, memory_order_acquire)) return;
    atomic_store_explicit(&p->last_draw_ns, t, memory_order_relaxed);
    draw_tty(p, done, 1e-9 * (double)(t - p->t0_ns));
    atomic_flag_clear_explicit(&p->drawing, memory_order_release);
    return;
  }
  /* Plain mode: one line per 10% step, steps 1..9 (finish prints the end). */
  if (p->total == 0) return;
  int decile = (int)(10.0 * fraction(p, done));
  if (decile > 9) decile = 9;
  if (decile <= atomic_load_explicit(&p->last_decile, memory_order_relaxed)) return;
  if (atomic_flag_test_and_set_explicit(&p->drawing, memory_order_acquire)) return;
  /* Re-read under the lock: another thread may have printed this step. */
  int last = atomic_load_explicit(&p->last_decile, memory_order_relaxed);
  if (decile > last) {
    atomic_store_explicit(&p->last_decile, decile, memory_order_relaxed);
    double elapsed = 1e-9 * (double)(now_ns() - p->t0_ns);
    double f = fraction(p, done);
    fprintf(p->stream, "%s: %d%% (%llu/%llu) %.1f s elapsed, ETA %.1f s\n", p->label,
            10 * decile, (unsigned long long)done, (unsigned long long)p->total, elapsed,
            f > 0 ? elapsed * (1.0 - f) / f : 0.0);
    fflush(p->stream);
  }
  atomic_flag_clear_explicit(&p->drawing, memory_order_release);
}

uint64_t cv_progress_count(const cv_progress *p) {
  if (!p) return 0;
  return atomic_load_explicit(&((cv_progress *)p)->done, memory_order_relaxed);
}

double cv_progress_elapsed(const cv_progress *p) {
  if (!p) return 0.0;
  return 1e-9 * (double)(now_ns() - p->t0_ns);
}

void cv_progress_finish(cv_progress *p) {
  if (!p || p->finished) return;
  p->finished = 1;
  if (p->quiet) return;
  uint64_t done = cv_progress_count(p);
  double elapsed = cv_progress_elapsed(p);
  double rate = elapsed > 0 ? (double)done / elapsed : 0.0;
  if (p->tty) {
    if (p->total > 0) {
      char bar[CV_PROGRESS_BAR + 1];
      int full = (int)(fraction(p, done) * CV_PROGRESS_BAR);
      for (int i = 0; i < CV_PROGRESS_BAR; ++i) bar[i] = i < full ? '#' : '.';
      bar[CV_PROGRESS_BAR] = '\0';
      fprintf(p->stream, "\r%s [%s] %3d%% ", p->label, bar, (int)(100.0 * fraction(p, done)));
    } else {
      fprintf(p->stream, "\r%s ", p->label);
    }
    fprintf(p->stream, "%llu items in %.2f s (%.4g items/s)          \n",
            (unsigned long long)done, elapsed, rate);
  } else {
    fprintf(p->stream, "%s: done, %llu items in %.2f s (%.4g items/s)\n", p->label,
            (unsigned long long)done, elapsed, rate);
  }
  fflush(p->stream);
}

void cv_progress_destroy(cv_progress *p) { free(p); }
