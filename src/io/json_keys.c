/* Allowed-key checks for JSON objects (see json_keys.h). */
#include "io/json_keys.h"

#include <ctype.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

int cv_json_key_allowed(const char *key, const char *const *allowed) {
  for (const char *const *a = allowed; *a; a++)
    if (strcmp(key, *a) == 0) return 1;
  return 0;
}

void cv_json_key_list(const char *const *allowed, char *buf, size_t n) {
  if (!n) return;
  buf[0] = '\0';
  for (const char *const *a = allowed; *a; a++) {
    size_t l = strlen(buf);
    if (l + 3 >= n) break;
    strncat(buf, *a, n - l - 3);
    if (a[1]) strncat(buf, ", ", n - strlen(buf) - 1);
  }
}

const char *cv_json_key_show(const char *key, char *buf, size_t n) {
  if (!n) return buf;
  size_t o = 0;
  for (const unsigned char *k = (const unsigned char *)(key ? key : ""); *k && o + 5 < n; k++) {
    if (*k >= 0x20 && *k < 0x7f && *k != '\\')
      buf[o++] = (char)*k;
    else
      o += (size_t)snprintf(buf + o, n - o, "\\x%02x", *k);
  }
  buf[o] = '\0';
  return buf;
}

void cv_json_syntax_error(const char *text, const char *errpos, int *line, int *col, char *what,
                          size_t n) {
  *line = 1;
  *col = 1;
  if (!text) text = "";
  const char *e = errpos && errpos >= text ? errpos : text;
  while (*e && isspace((unsigned char)*e)) e++; /* point at the token, not the space before it */
  const char *p = text;
  for (; *p && p < e; p++) {
    if (*p == '\n') {
      (*line)++;
      *col = 1;
    } else {
      (*col)++;
    }
  }
  const char *q = text;
  while (*q && isspace((unsigned char)*q)) q++;
  if (!*q) {
    snprintf(what, n, "empty file (expected a JSON object)");
    return;
  }
  char near[16], shown[72];
  size_t k = 0;
  for (; p[k] && p[k] != '\n' && k + 1 < sizeof near; k++) near[k] = p[k];
  near[k] = '\0';
  cv_json_key_show(near, shown, sizeof shown);
  int nonnum = !strncasecmp(p, "nan", 3) || !strncasecmp(p, "inf", 3) ||
               !strncasecmp(p, "-nan", 4) || !strncasecmp(p, "-inf", 4);
  if (!k)
    snprintf(what, n, "JSON syntax error at the end of the text (an unclosed { or [?)");
  else
    snprintf(what, n, "JSON syntax error near '%s'%s", shown,
             nonnum ? " (NaN and Inf are not JSON numbers)" : "");
}

int cv_json_file_check(FILE *f, const char *path, cv_err *err) {
  struct stat st;
  if (fstat(fileno(f), &st) == 0 && S_ISDIR(st.st_mode))
    return cv_err_set(err, CV_ERR_IO, "%s: is a folder, expected a JSON file", path);
  return CV_OK;
}
