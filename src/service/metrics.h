/* JSON-lines metrics for the render service: one JSON object per line (one
 * per frame, plus a summary at exit), easy to grep, tail and load with any
 * JSON reader.
 *
 * A cv_metrics_line builds one object in a growable buffer: "key": value
 * pairs of integers, doubles (printed with %.9g, enough to round-trip a
 * float and readable; NaN/Inf are written as null and counted, since JSON
 * has no non-finite numbers), strings (escaped), booleans, arrays of doubles
 * and nested objects.  cv_metrics_write emits the line and flushes, so a
 * killed job leaves only whole lines behind (bar the last write itself).
 *
 * Also the percentile helper used for the p50/p99 timing summaries. */
#ifndef CV_SERVICE_METRICS_H
#define CV_SERVICE_METRICS_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "core/status.h"

typedef struct cv_metrics_line cv_metrics_line;

/* New empty line builder (already begun: "{").  *out owned by the caller
 * (cv_metrics_line_destroy).  Errors: CV_ERR_NOMEM. */
int cv_metrics_line_create(cv_metrics_line **out);
void cv_metrics_line_destroy(cv_metrics_line *m); /* accepts NULL */

/* Starts a new object, dropping any unwritten content (the non-finite count
 * is kept: it is a running total). */
void cv_metrics_begin(cv_metrics_line *m);

/* Appenders: add "key": value to the innermost open object.  key is escaped
 * like strings.  They return CV_OK or CV_ERR_NOMEM; a failure is sticky (the
 * line is then refused by cv_metrics_write) so callers may ignore the
 * returns of individual appends. */
int cv_metrics_int(cv_metrics_line *m, const char *key, int64_t v);
int cv_metrics_uint(cv_metrics_line *m, const char *key, uint64_t v);
int cv_metrics_double(cv_metrics_line *m, const char *key, double v); /* non-finite: null */
int cv_metrics_bool(cv_metrics_line *m, const char *key, int v);
int cv_metrics_string(cv_metrics_line *m, const char *key, const char *v); /* NULL: null */
/* Array of n doubles (non-finite entries null); v may be NULL when n is 0. */
int cv_metrics_doubles(cv_metrics_line *m, const char *key, const double *v, size_t n);
/* Nested object: "key": { ... }.  Up to 16 levels. CV_ERR_RANGE past that. */
int cv_metrics_object_begin(cv_metrics_line *m, const char *key);
/* Closes the innermost nested object; CV_ERR_INVALID when none is open. */
int cv_metrics_object_end(cv_metrics_line *m);

/* The object so far, closed with as many braces as are open (owned by m,
 * valid until the next call on m). */
const char *cv_metrics_text(cv_metrics_line *m);
/* Writes the object (closing any open nested objects) and "\n" to f,
 * flushes, and begins a new object.  Errors: CV_ERR_NOMEM (an append
 * failed; nothing written), CV_ERR_IO (write or flush failed),
 * CV_ERR_INVALID (NULL). */
int cv_metrics_write(cv_metrics_line *m, FILE *f);
/* Bytes cv_metrics_write would write for the object so far (its closing
 * braces and the newline included). */
size_t cv_metrics_length(const cv_metrics_line *m);
/* Non-finite doubles written as null since create (running total). */
uint64_t cv_metrics_nonfinite(const cv_metrics_line *m);

/* Percentile p (0..100) of the finite values of v[0..n) with linear
 * interpolation between order statistics: with the finite values sorted
 * ascending x[0..m), r = p/100 * (m - 1), result x[floor r] + (r - floor r) *
 * (x[floor r + 1] - x[floor r]) (NumPy's default "linear").  Deterministic:
 * independent of the input order.  Non-finite values are skipped and their
 * number written to *n_skipped (may be NULL).  Errors: CV_ERR_EMPTY (no
 * finite value), CV_ERR_RANGE (p outside [0, 100] or NaN), CV_ERR_NOMEM. */
int cv_percentile(const double *v, size_t n, double p, double *out, size_t *n_skipped);
/* Several percentiles with one sort: out[k] for ps[k], k < np.  Errors as
 * cv_percentile. */
int cv_percentiles(const double *v, size_t n, const double *ps, int np, double *out,
                   size_t *n_skipped);

/* Writes "<stem>_p50", "<stem>_p99" and "<stem>_max" of v[0..n) into the
 * line (nothing when n is 0). */
void cv_metrics_percentiles(cv_metrics_line *ml, const char *stem, const double *v, size_t n);

#endif
