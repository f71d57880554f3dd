/* LCD final-gather contributor thread (see lcdwork.c). */
#ifndef CV_CLUSTER_LCDWORK_H
#define CV_CLUSTER_LCDWORK_H

#include <stddef.h>
#include <stdint.h>

#include "lcd/accum.h"
#include "prt/prt.h"
#include "service.h"

typedef struct cv_lcd_worker cv_lcd_worker;

/* Builds the tracer, BRDF and gather for prt (borrowed: must outlive the
 * worker) and starts the thread; index = cv_service_contributor of the rank;
 * idle = 1: the thread runs at SCHED_IDLE (a wall-eye's spare cycles).
 * *out owned by the caller. */
int cv_lcd_worker_create(const cv_service *s, const cv_prt *prt, int index, int idle,
                         cv_lcd_worker **out, cv_err *err);
/* Posts the newest frame state (copied). */
void cv_lcd_worker_post(cv_lcd_worker *w, const cv_frame_state *fs);
/* Hands every finished round to send(buf, len, user) (called on the calling
 * thread); returns how many.  rounds_done / ms_total (may be NULL): totals
 * so far. */
int cv_lcd_worker_send_ready(cv_lcd_worker *w, int (*send)(const uint8_t *, size_t, void *),
                             void *user, uint64_t *rounds_done, double *ms_total);
/* The rounds first, first + contributors, ... (n) of key were lost on the
 * way to the master (an abandoned LCD allreduce): rendered again when key
 * is still the worker's current key, else nothing. */
void cv_lcd_worker_redo(cv_lcd_worker *w, const cv_lcd_key *key, uint32_t first, uint32_t n);
/* Totals so far: rounds finished, their wall time and the worker thread's
 * CPU time in them (CLOCK_THREAD_CPUTIME_ID), ms. */
void cv_lcd_worker_totals(cv_lcd_worker *w, uint64_t *rounds_done, double *ms_total, double *cpu_ms_total);
/* Last error of the thread, or NULL. */
const char *cv_lcd_worker_error(cv_lcd_worker *w);
/* Stops the thread (after its current round) and frees everything. */
void cv_lcd_worker_destroy(cv_lcd_worker *w);

#endif
