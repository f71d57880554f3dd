/* Writing an output file so that it appears whole or not at all: data goes
 * to a temporary file next to the destination (same file system), which is
 * renamed over the destination only when everything was written.  A crash
 * or an error never leaves a partial file under the final name.  The file
 * gets the usual permissions (0666 minus the umask), not mkstemp's 0600. */
#ifndef CV_CORE_OUTFILE_H
#define CV_CORE_OUTFILE_H

#include <stdio.h>

#include "core/status.h"

typedef struct cv_outfile {
  const char *path; /* destination (borrowed) */
  char *tmp;        /* temporary path (owned) */
  int fd;           /* open descriptor of tmp, or -1 */
  FILE *f;          /* stdio stream on fd when opened with stdio, else NULL */
} cv_outfile;

/* Creates the temporary file.  with_stdio: also open a FILE* (o->f).
 * Errors (err names the path): CV_ERR_NOMEM, CV_ERR_IO. */
int cv_outfile_open(cv_outfile *o, const char *path, int with_stdio, cv_err *err);
/* Flushes, closes and renames into place.  On failure the temporary file is
 * removed and err names the path; o is released either way. */
int cv_outfile_commit(cv_outfile *o, cv_err *err);
/* Closes and removes the temporary file (after an error); accepts a
 * never-opened (zeroed) o. */
void cv_outfile_abort(cv_outfile *o);

#endif
