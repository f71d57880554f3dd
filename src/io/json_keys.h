/* Checking JSON objects against the keys a format allows, shared by every
 * config parser (scene configs, display descriptions), so a misspelt field
 * is always an error that lists what was expected. */
#ifndef CV_IO_JSON_KEYS_H
#define CV_IO_JSON_KEYS_H

#include <stddef.h>

/* 1 when key is in the NULL-terminated list allowed. */
int cv_json_key_allowed(const char *key, const char *const *allowed);
/* "a, b, c" from the NULL-terminated list, truncated to n bytes. */
void cv_json_key_list(const char *const *allowed, char *buf, size_t n);

#endif
