/* Strict number parsing for command lines (see parse.h). */
#include "core/parse.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

int cv_parse_double(const char *s, double *out) {
  if (!s || !*s) return -1;
  char *end;
  errno = 0;
  double v = strtod(s, &end);
  if (*end || errno || !isfinite(v)) return -1;
  *out = v;
  return 0;
}

int cv_parse_seconds(const char *s, double *out) {
  if (!s) return -1;
  const char *slash = strchr(s, '/');
  if (!slash) return cv_parse_double(s, out);
  char num[64];
  size_t n = (size_t)(slash - s);
  if (n == 0 || n >= sizeof num) return -1;
  memcpy(num, s, n);
  num[n] = '\0';
  double a, b;
  if (cv_parse_double(num, &a) || cv_parse_double(slash + 1, &b) || b == 0) return -1;
  double v = a / b;
  if (!isfinite(v)) return -1;
  *out = v;
  return 0;
}

int cv_parse_int(const char *s, int lo, int hi, int *out) {
  double v;
  if (cv_parse_double(s, &v) || v != floor(v) || v < lo || v > hi) return -1;
  *out = (int)v;
  return 0;
}

int cv_parse_vec(const char *s, int n, double *out) {
  char buf[256];
  if (!s || n < 1 || strlen(s) >= sizeof buf) return -1;
  /* field by field: an empty field ("5,,0", ",5,0", "5,0,") is an error,
   * not skipped (strtok would collapse it and shift the values) */
  const char *p = s;
  for (int i = 0; i < n; i++) {
    const char *comma = strchr(p, ',');
    size_t len = comma ? (size_t)(comma - p) : strlen(p);
    if (len == 0) return -1;
    memcpy(buf, p, len);
    buf[len] = '\0';
    if (cv_parse_double(buf, &out[i])) return -1;
    if (i + 1 < n) {
      if (!comma) return -1;
      p = comma + 1;
    } else if (comma) {
      return -1; /* more than n fields, or a trailing comma */
    }
  }
  return 0;
}
