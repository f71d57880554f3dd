/* Whole-file reading for the service module's text formats (drive files,
 * head paths): one place that handles the size, the NUL terminator and the
 * error line. */
#ifndef CV_SERVICE_TEXTFILE_H
#define CV_SERVICE_TEXTFILE_H

#include <stddef.h>

#include "core/status.h"

#define CV_TEXT_FILE_MAX ((size_t)256 << 20) /* 256 MiB: larger is surely not a config */

/* Reads path into a NUL-terminated heap buffer (*text owned by the caller,
 * free()); *len (may be NULL) gets the byte count without the NUL.  Errors
 * (err: "path: what"): CV_ERR_IO (cannot open or read), CV_ERR_RANGE (larger
 * than CV_TEXT_FILE_MAX), CV_ERR_NOMEM. */
int cv_service_read_text(const char *path, char **text, size_t *len, cv_err *err);

#endif
