/* Problem collector: see problems.h. */
#include "io/problems.h"

#include <stdarg.h>
#include <stdio.h>

void cv_problem(cv_problems *x, int status, const char *field, const char *fmt, ...) {
  char what[384], line[512];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(what, sizeof what, fmt, ap);
  va_end(ap);
  if (field && field[0])
    snprintf(line, sizeof line, "%s: %s: %s", x->file, field, what);
  else
    snprintf(line, sizeof line, "%s: %s", x->file, what);
  if (x->count++ == 0) {
    snprintf(x->first, sizeof x->first, "%s", line);
    x->first_status = status;
  }
  if (x->buf && x->cap > 0 && x->len + 1 < x->cap) {
    int w = snprintf(x->buf + x->len, x->cap - x->len, "%s\n", line);
    if (w > 0) x->len += (size_t)w;
    if (x->len >= x->cap) x->len = x->cap - 1;
  }
}
