/* Status message table and error-detail helpers (see status.h). */
#include "core/status.h"

#include <stdio.h>
#include <string.h>

const char *cv_status_str(int status) {
  switch (status) {
#define CV_STATUS_CASE_(name, val, msg) \
  case (val):                           \
    return (msg);
    CV_STATUS_MAP(CV_STATUS_CASE_)
#undef CV_STATUS_CASE_
  default:
    return "unknown status";
  }
}

int cv_err_set(cv_err *err, int status, const char *fmt, ...) {
  if (err) {
    va_list ap;
    va_start(ap, fmt);
    err->status = status;
    vsnprintf(err->msg, sizeof err->msg, fmt, ap);
    va_end(ap);
  }
  return status;
}

int cv_err_prefix(cv_err *err, const char *fmt, ...) {
  if (!err) return CV_OK;
  char prefix[256];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(prefix, sizeof prefix, fmt, ap);
  va_end(ap);
  char old[sizeof err->msg];
  memcpy(old, err->msg, sizeof old);
  const char *rest = old[0] ? old : cv_status_str(err->status);
  size_t np = strlen(prefix);
  if (np > sizeof err->msg - 3) np = sizeof err->msg - 3;
  memcpy(err->msg, prefix, np);
  memcpy(err->msg + np, ": ", 2);
  size_t room = sizeof err->msg - np - 3, nr = strlen(rest);
  if (nr > room) nr = room;
  memcpy(err->msg + np + 2, rest, nr);
  err->msg[np + 2 + nr] = '\0';
  return err->status;
}

void cv_err_clear(cv_err *err) {
  if (!err) return;
  err->status = CV_OK;
  err->msg[0] = '\0';
}
