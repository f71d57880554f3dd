/* Whole-file reading (textfile.h). */
#include "service/textfile.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

int cv_service_read_text(const char *path, char **text, size_t *len, cv_err *err) {
  *text = NULL;
  if (len) *len = 0;
  FILE *f = fopen(path, "rb");
  if (!f) return cv_err_set(err, CV_ERR_IO, "%s: cannot open (%s)", path, strerror(errno));
  struct stat sb;
  if (fstat(fileno(f), &sb) == 0 && S_ISDIR(sb.st_mode)) {
    fclose(f);
    return cv_err_set(err, CV_ERR_IO, "%s: is a folder, expected a file", path);
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
        return cv_err_set(err, CV_ERR_RANGE, "%s: larger than %zu bytes", path,
                          (size_t)CV_TEXT_FILE_MAX);
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
