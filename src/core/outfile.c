/* Whole-or-nothing output files (see outfile.h). */
#include "core/outfile.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

int cv_outfile_open(cv_outfile *o, const char *path, int with_stdio, cv_err *err) {
  memset(o, 0, sizeof *o);
  o->fd = -1;
  o->path = path;
  size_t n = strlen(path) + 16;
  o->tmp = malloc(n);
  if (!o->tmp) return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  snprintf(o->tmp, n, "%s.tmp.XXXXXX", path);
  o->fd = mkstemp(o->tmp);
  if (o->fd < 0) {
    int e = errno;
    free(o->tmp);
    o->tmp = NULL;
    return cv_err_set(err, CV_ERR_IO, "%s: cannot create a file there: %s", path, strerror(e));
  }
  /* mkstemp creates 0600; give the result what open(2) would have. */
  mode_t mask = umask(0);
  umask(mask);
  if (fchmod(o->fd, 0666 & ~mask) != 0) { /* not fatal: the data is what matters */
  }
  if (with_stdio && !(o->f = fdopen(o->fd, "wb"))) {
    int e = errno;
    cv_outfile_abort(o);
    return cv_err_set(err, CV_ERR_IO, "%s: cannot open: %s", path, strerror(e));
  }
  return CV_OK;
}

void cv_outfile_abort(cv_outfile *o) {
  if (o->f) fclose(o->f);
  else if (o->fd >= 0) close(o->fd);
  if (o->tmp) {
    unlink(o->tmp);
    free(o->tmp);
  }
  o->f = NULL;
  o->fd = -1;
  o->tmp = NULL;
}

int cv_outfile_commit(cv_outfile *o, cv_err *err) {
  int ok = 1, e = 0;
  if (o->f) {
    ok = fflush(o->f) == 0 && !ferror(o->f);
    if (!ok) e = errno;
    if (fclose(o->f) != 0 && ok) {
      ok = 0;
      e = errno;
    }
  } else if (o->fd >= 0 && close(o->fd) != 0) {
    ok = 0;
    e = errno;
  }
  o->f = NULL;
  o->fd = -1;
  if (ok && rename(o->tmp, o->path) != 0) {
    ok = 0;
    e = errno;
  }
  if (!ok) {
    unlink(o->tmp);
    free(o->tmp);
    o->tmp = NULL;
    return cv_err_set(err, CV_ERR_IO, "%s: write failed: %s", o->path, strerror(e ? e : EIO));
  }
  free(o->tmp);
  o->tmp = NULL;
  return CV_OK;
}
