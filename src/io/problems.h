/* Collecting every problem of a configuration file before failing, so a user
 * sees all of them at once (display descriptions, drives): each problem is
 * one line "file: field.path: what"; the first is kept with its status for
 * the one-line cv_err, and all of them go to an optional buffer. */
#ifndef CV_IO_PROBLEMS_H
#define CV_IO_PROBLEMS_H

#include <stddef.h>

#include "core/status.h"

typedef struct cv_problems {
  const char *file;
  int count;
  int first_status;
  char first[512]; /* the first problem, one line */
  char *buf;       /* all problems, one per line (may be NULL; not owned) */
  size_t cap, len;
} cv_problems;

/* Records one problem (field may be NULL or ""). */
void cv_problem(cv_problems *x, int status, const char *field, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

/* Records an "unknown field (expected one of: ...)" problem for every key of
 * obj not in the NULL-terminated allowed list; fields are named
 * "path.key" ("key" at the top, path ""). */
struct cJSON;
void cv_problems_only_keys(cv_problems *x, const struct cJSON *obj, const char *path,
                           const char *const *allowed);

/* The problems as the one-line error of a loader: the first, then
 * " [+N more problem(s)]"; returns its status (CV_ERR_CONFIG when it had
 * none), or CV_OK when there was no problem. */
int cv_problems_finish(const cv_problems *x, cv_err *err);

#endif
