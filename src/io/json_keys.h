/* Checking JSON objects against the keys a format allows, shared by every
 * config parser (scene configs, display descriptions), so a misspelt field
 * is always an error that lists what was expected; and saying where a JSON
 * text stops being JSON (line and column). */
#ifndef CV_IO_JSON_KEYS_H
#define CV_IO_JSON_KEYS_H

#include <stddef.h>
#include <stdio.h>

#include "core/status.h"

/* 1 when key is in the NULL-terminated list allowed. */
int cv_json_key_allowed(const char *key, const char *const *allowed);
/* "a, b, c" from the NULL-terminated list, truncated to n bytes. */
void cv_json_key_list(const char *const *allowed, char *buf, size_t n);

/* key with every byte outside printable ASCII shown as \xNN (a mangled key
 * is never echoed raw to a terminal); truncated to n bytes; returns buf. */
const char *cv_json_key_show(const char *key, char *buf, size_t n);

/* Where and why cJSON stopped: errpos is cJSON_GetErrorPtr() or the parse
 * end of cJSON_ParseWithOpts (may be NULL: taken as the start).  Gives the
 * 1-based line and column (in bytes) and a short reason in what: "empty
 * file" for a file of only white space, else "JSON syntax error near
 * '<the next characters, escaped>'", with a hint when they spell NaN or Inf. */
void cv_json_syntax_error(const char *text, const char *errpos, int *line, int *col, char *what,
                          size_t n);

/* Right after fopen(path) of a file to be read whole (a config): CV_OK for
 * a file that can be read, else err "<path>: is a folder, expected a JSON
 * file" (a folder opens, but reads as nothing or as a huge size) and
 * CV_ERR_IO.  The caller still closes f. */
int cv_json_file_check(FILE *f, const char *path, cv_err *err);

#endif
