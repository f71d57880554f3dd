/* Allowed-key checks for JSON objects (see json_keys.h). */
#include "io/json_keys.h"

#include <string.h>

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
