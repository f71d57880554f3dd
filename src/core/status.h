/* Status codes and error details shared by every module.
 *
 * Functions that can fail return a cv_status (0 = CV_OK, negative = error)
 * and write results to trailing out-parameters.  Where a user needs more than
 * the code (which file, which field or line, what was expected), the function
 * also takes a `cv_err *err` (may be NULL) and fills it with one line.
 * Library code never exits and never prints errors itself. */
#ifndef CV_CORE_STATUS_H
#define CV_CORE_STATUS_H

#include <stdarg.h>

/* X-macro: name, value, message.  Generates the enum and the message table. */
#define CV_STATUS_MAP(X)                                              \
  X(OK, 0, "ok")                                                      \
  X(ERR_NOMEM, -1, "out of memory")                                   \
  X(ERR_IO, -2, "input/output error")                                 \
  X(ERR_FORMAT, -3, "malformed file")                                 \
  X(ERR_INVALID, -4, "invalid argument")                              \
  X(ERR_UNSUPPORTED, -5, "unsupported feature")                       \
  X(ERR_RANGE, -6, "value out of range")                              \
  X(ERR_NONFINITE, -7, "non-finite value (NaN or Inf)")               \
  X(ERR_CONFIG, -8, "invalid configuration")                          \
  X(ERR_NOT_FOUND, -9, "not found")                                   \
  X(ERR_BACKEND, -10, "third-party library failure")                  \
  X(ERR_EMPTY, -11, "empty input")

typedef enum cv_status {
#define CV_STATUS_ENUM_(name, val, msg) CV_##name = (val),
  CV_STATUS_MAP(CV_STATUS_ENUM_)
#undef CV_STATUS_ENUM_
} cv_status;

/* Human-readable text of a status code; never NULL. */
const char *cv_status_str(int status);

/* One line of detail for the last error of a call. */
typedef struct cv_err {
  int status;
  char msg[512];
} cv_err;

/* Fills err (when non-NULL) with status and a printf-formatted message and
 * returns status, so callers can write `return cv_err_set(err, CV_ERR_IO, ...)`. */
int cv_err_set(cv_err *err, int status, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* Prefixes the message already in err with "prefix: " (for adding a file name
 * or a field path on the way up).  Returns err->status (or CV_OK if err NULL). */
int cv_err_prefix(cv_err *err, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

/* Clears err to CV_OK and an empty message. */
void cv_err_clear(cv_err *err);

#endif
