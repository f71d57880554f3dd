/* Problem collector: see problems.h. */
#include "io/problems.h"

#include <stdarg.h>
#include <stdio.h>

#include <cjson/cJSON.h>

#include "io/json_keys.h"

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

void cv_problems_only_keys(cv_problems *x, const cJSON *obj, const char *path,
                           const char *const *allowed) {
  const cJSON *it;
  cJSON_ArrayForEach(it, obj) {
    if (!cv_json_key_allowed(it->string, allowed)) {
      char field[256], list[320], kbuf[128];
      snprintf(field, sizeof field, "%s%s%s", path, path[0] ? "." : "",
               cv_json_key_show(it->string, kbuf, sizeof kbuf));
      cv_json_key_list(allowed, list, sizeof list);
      cv_problem(x, CV_ERR_CONFIG, field, "unknown field (expected one of: %s)", list);
    }
  }
}

int cv_problems_finish(const cv_problems *x, cv_err *err) {
  if (x->count == 0) return CV_OK;
  const int st = x->first_status ? x->first_status : CV_ERR_CONFIG;
  if (x->count > 1)
    cv_err_set(err, st, "%s [+%d more problem%s]", x->first, x->count - 1, x->count > 2 ? "s" : "");
  else
    cv_err_set(err, st, "%s", x->first);
  return st;
}
