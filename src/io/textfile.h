/* Whole-file reading of every text input the project reads whole: the JSON
 * configurations (scene, CAVE, display, LCD, drive, tracker calibration)
 * and the head paths.  One place that handles the size limit, a folder
 * given for a file, pipes (read to the end, no seeking), the NUL terminator
 * and the error line. */
#ifndef CV_IO_TEXTFILE_H
#define CV_IO_TEXTFILE_H

#include <stddef.h>

#include "core/status.h"

#define CV_TEXT_FILE_MAX ((size_t)64 << 20) /* 64 MiB: larger is surely not a config or a head path */

/* Reads path into a NUL-terminated heap buffer (*text owned by the caller,
 * free()); *len (may be NULL) gets the byte count without the NUL.  Errors
 * (err: "path: what"): CV_ERR_IO (cannot open or read, a folder),
 * CV_ERR_RANGE (larger than CV_TEXT_FILE_MAX), CV_ERR_NOMEM. */
int cv_read_text_file(const char *path, char **text, size_t *len, cv_err *err);
/* The same for a JSON configuration ("is a folder, expected a JSON file"). */
int cv_read_json_file(const char *path, char **text, cv_err *err);

/* The part of an error line after its leading "path: " (the whole line when
 * it does not start with it): for a caller that adds the file name itself. */
const char *cv_err_after_path(const char *msg, const char *path);

#endif
