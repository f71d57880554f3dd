/* Whole-file reading (textfile.h). */
#include "io/textfile.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static int read_text(const char *path, const char *kind, char **text, size_t *len, cv_err *err) {
  *text = NULL;
  if (len) *len = 0;
  FILE *f = fopen(path, "rb");
  if (!f) return cv_err_set(err, CV_ERR_IO, "%s: cannot open (%s)", path, strerror(errno));
  struct stat sb;
  if (fstat(fileno(f), &sb) == 0 && S_ISDIR(sb.st_mode)) {
    fclose(f);
    return cv_err_set(err, CV_ERR_IO, "%s: is a folder, expected %s", path, kind);
  }
  size_t cap = 4096, n = 0;
  char *b = malloc(cap);
  if (!b) {
    fclose(f);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  }
  for (;;) {
    if (n + 1 >= cap) {
      if (cap >= CV_TEXT_FILE_MAX) {
        free(b);
        fclose(f);
        return cv_err_set(err, CV_ERR_RANGE, "%s: larger than %zu MiB: not a configuration or "
                          "head path file", path, (size_t)CV_TEXT_FILE_MAX >> 20);
      }
      char *nb = realloc(b, cap * 2);
      if (!nb) {
        free(b);
        fclose(f);
        return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
      }
      b = nb;
      cap *= 2;
    }
    size_t r = fread(b + n, 1, cap - 1 - n, f);
    n += r;
    if (r == 0) break;
  }
  int bad = ferror(f);
  fclose(f);
  if (bad) {
    free(b);
    return cv_err_set(err, CV_ERR_IO, "%s: read error", path);
  }
  b[n] = '\0';
  *text = b;
  if (len) *len = n;
  return CV_OK;
}

int cv_read_text_file(const char *path, char **text, size_t *len, cv_err *err) {
  return read_text(path, "a file", text, len, err);
}

int cv_read_json_file(const char *path, char **text, cv_err *err) {
  return read_text(path, "a JSON file", text, NULL, err);
}

const char *cv_err_after_path(const char *msg, const char *path) {
  const size_t n = strlen(path);
  return strncmp(msg, path, n) == 0 && msg[n] == ':' && msg[n + 1] == ' ' ? msg + n + 2 : msg;
}
