/* JSON-lines metrics writer and percentiles (metrics.h).  The builder keeps
 * one growable char buffer; nested objects are tracked with a small stack of
 * "has a member yet" flags so commas land right without a JSON library. */
#include "service/metrics.h"

#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#define MAX_DEPTH 16

struct cv_metrics_line {
  char *buf;
  size_t len, cap;
  int depth;                 /* open objects, 1 = the top level */
  int has_member[MAX_DEPTH]; /* per open object */
  int failed;                /* sticky CV_ERR_NOMEM */
  uint64_t nonfinite;
  char *text;                /* cv_metrics_text's closed copy */
  size_t text_cap;
};

static int reserve(cv_metrics_line *m, size_t extra) {
  if (m->failed) return CV_ERR_NOMEM;
  if (m->len + extra + 1 <= m->cap) return CV_OK;
  size_t cap = m->cap ? m->cap : 256;
  while (cap < m->len + extra + 1) cap *= 2;
  char *b = realloc(m->buf, cap);
  if (!b) {
    m->failed = 1;
    return CV_ERR_NOMEM;
  }
  m->buf = b;
  m->cap = cap;
  return CV_OK;
}

static int append(cv_metrics_line *m, const char *s, size_t n) {
  int st = reserve(m, n);
  if (st) return st;
  memcpy(m->buf + m->len, s, n);
  m->len += n;
  m->buf[m->len] = '\0';
  return CV_OK;
}

static int appendf(cv_metrics_line *m, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
static int appendf(cv_metrics_line *m, const char *fmt, ...) {
  char tmp[64];
  va_list ap;
  va_start(ap, fmt);
  int n = vsnprintf(tmp, sizeof tmp, fmt, ap);
  va_end(ap);
  if (n < 0 || (size_t)n >= sizeof tmp) return append(m, "null", 4); /* cannot happen for numbers */
  return append(m, tmp, (size_t)n);
}

/* JSON string literal with the escapes RFC 8259 requires (", \, controls). */
static int append_string(cv_metrics_line *m, const char *s) {
  int st = append(m, "\"", 1);
  for (const unsigned char *p = (const unsigned char *)s; !st && *p; p++) {
    switch (*p) {
      case '"': st = append(m, "\\\"", 2); break;
      case '\\': st = append(m, "\\\\", 2); break;
      case '\n': st = append(m, "\\n", 2); break;
      case '\r': st = append(m, "\\r", 2); break;
      case '\t': st = append(m, "\\t", 2); break;
      case '\b': st = append(m, "\\b", 2); break;
      case '\f': st = append(m, "\\f", 2); break;
      default:
        if (*p < 0x20)
          st = appendf(m, "\\u%04x", (unsigned)*p);
        else
          st = append(m, (const char *)p, 1);
    }
  }
  return st ? st : append(m, "\"", 1);
}

static int append_double(cv_metrics_line *m, double v) {
  if (!isfinite(v)) {
    m->nonfinite++;
    return append(m, "null", 4);
  }
  return appendf(m, "%.9g", v);
}

/* Comma (when needed) and "key": */
static int key(cv_metrics_line *m, const char *k) {
  if (m->failed) return CV_ERR_NOMEM;
  int st = CV_OK;
  if (m->has_member[m->depth - 1]) st = append(m, ",", 1);
  m->has_member[m->depth - 1] = 1;
  if (!st) st = append_string(m, k ? k : "");
  if (!st) st = append(m, ":", 1);
  return st;
}

int cv_metrics_line_create(cv_metrics_line **out) {
  if (!out) return CV_ERR_INVALID;
  *out = NULL;
  cv_metrics_line *m = calloc(1, sizeof *m);
  if (!m) return CV_ERR_NOMEM;
  cv_metrics_begin(m);
  if (m->failed) {
    cv_metrics_line_destroy(m);
    return CV_ERR_NOMEM;
  }
  *out = m;
  return CV_OK;
}

void cv_metrics_line_destroy(cv_metrics_line *m) {
  if (!m) return;
  free(m->buf);
  free(m->text);
  free(m);
}

void cv_metrics_begin(cv_metrics_line *m) {
  m->len = 0;
  m->failed = 0;
  m->depth = 1;
  memset(m->has_member, 0, sizeof m->has_member);
  append(m, "{", 1);
}

int cv_metrics_int(cv_metrics_line *m, const char *k, int64_t v) {
  int st = key(m, k);
  return st ? st : appendf(m, "%" PRId64, v);
}

int cv_metrics_uint(cv_metrics_line *m, const char *k, uint64_t v) {
  int st = key(m, k);
  return st ? st : appendf(m, "%" PRIu64, v);
}

int cv_metrics_double(cv_metrics_line *m, const char *k, double v) {
  int st = key(m, k);
  return st ? st : append_double(m, v);
}

int cv_metrics_bool(cv_metrics_line *m, const char *k, int v) {
  int st = key(m, k);
  return st ? st : (v ? append(m, "true", 4) : append(m, "false", 5));
}

int cv_metrics_string(cv_metrics_line *m, const char *k, const char *v) {
  int st = key(m, k);
  if (st) return st;
  return v ? append_string(m, v) : append(m, "null", 4);
}

int cv_metrics_doubles(cv_metrics_line *m, const char *k, const double *v, size_t n) {
  int st = key(m, k);
  if (!st) st = append(m, "[", 1);
  for (size_t i = 0; !st && i < n; i++) {
    if (i) st = append(m, ",", 1);
    if (!st) st = append_double(m, v[i]);
  }
  return st ? st : append(m, "]", 1);
}

int cv_metrics_object_begin(cv_metrics_line *m, const char *k) {
  if (m->depth >= MAX_DEPTH) return CV_ERR_RANGE;
  int st = key(m, k);
  if (!st) st = append(m, "{", 1);
  if (st) return st;
  m->has_member[m->depth++] = 0;
  return CV_OK;
}

int cv_metrics_object_end(cv_metrics_line *m) {
  if (m->depth <= 1) return CV_ERR_INVALID;
  m->depth--;
  return append(m, "}", 1);
}

const char *cv_metrics_text(cv_metrics_line *m) {
  size_t need = m->len + (size_t)m->depth + 1;
  if (m->failed || !m->buf) return "";
  if (need > m->text_cap) {
    char *t = realloc(m->text, need);
    if (!t) return "";
    m->text = t;
    m->text_cap = need;
  }
  memcpy(m->text, m->buf, m->len);
  for (int i = 0; i < m->depth; i++) m->text[m->len + (size_t)i] = '}';
  m->text[m->len + (size_t)m->depth] = '\0';
  return m->text;
}

size_t cv_metrics_length(const cv_metrics_line *m) {
  return m && !m->failed ? m->len + (size_t)m->depth + 1 : 0;
}

int cv_metrics_write(cv_metrics_line *m, FILE *f) {
  if (!m || !f) return CV_ERR_INVALID;
  if (m->failed) {
    cv_metrics_begin(m);
    return CV_ERR_NOMEM;
  }
  while (m->depth > 1) cv_metrics_object_end(m);
  int st = append(m, "}\n", 2);
  if (st) {
    cv_metrics_begin(m);
    return st;
  }
  size_t w = fwrite(m->buf, 1, m->len, f);
  int ok = (w == m->len) && fflush(f) == 0;
  cv_metrics_begin(m);
  return ok ? CV_OK : CV_ERR_IO;
}

uint64_t cv_metrics_nonfinite(const cv_metrics_line *m) { return m ? m->nonfinite : 0; }

/* --- percentiles --------------------------------------------------------- */

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y); /* only finite values reach here: a total order */
}

int cv_percentiles(const double *v, size_t n, const double *ps, int np, double *out,
                   size_t *n_skipped) {
  if (n_skipped) *n_skipped = 0;
  if ((!v && n) || (!ps && np > 0) || (!out && np > 0) || np < 0) return CV_ERR_INVALID;
  for (int k = 0; k < np; k++)
    if (!(ps[k] >= 0.0 && ps[k] <= 100.0)) return CV_ERR_RANGE;
  double *x = malloc((n ? n : 1) * sizeof *x);
  if (!x) return CV_ERR_NOMEM;
  size_t m = 0;
  for (size_t i = 0; i < n; i++)
    if (isfinite(v[i])) x[m++] = v[i];
  if (n_skipped) *n_skipped = n - m;
  if (m == 0) {
    free(x);
    return CV_ERR_EMPTY;
  }
  qsort(x, m, sizeof *x, cmp_double);
  for (int k = 0; k < np; k++) {
    double r = ps[k] / 100.0 * (double)(m - 1);
    size_t lo = (size_t)floor(r);
    if (lo >= m - 1) {
      out[k] = x[m - 1];
      continue;
    }
    double f = r - (double)lo;
    out[k] = x[lo] + f * (x[lo + 1] - x[lo]);
  }
  free(x);
  return CV_OK;
}

int cv_percentile(const double *v, size_t n, double p, double *out, size_t *n_skipped) {
  return cv_percentiles(v, n, &p, 1, out, n_skipped);
}

void cv_metrics_percentiles(cv_metrics_line *ml, const char *stem, const double *v, size_t n) {
  const double ps[3] = {50, 99, 100};
  double q[3];
  if (!n || cv_percentiles(v, n, ps, 3, q, NULL) != CV_OK) return;
  char k[64];
  snprintf(k, sizeof k, "%s_p50", stem);
  cv_metrics_double(ml, k, q[0]);
  snprintf(k, sizeof k, "%s_p99", stem);
  cv_metrics_double(ml, k, q[1]);
  snprintf(k, sizeof k, "%s_max", stem);
  cv_metrics_double(ml, k, q[2]);
}
