/* Fuzz harness: display descriptions (JSON text) through cv_display_parse. */
#include "compensate/display.h"
#include "fuzz_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  char *t = fuzz_text(data, size);
  cv_display *d = NULL;
  cv_err err;
  if (cv_display_parse(t, "fuzz.json", &d, &err) == CV_OK) cv_display_destroy(d);
  free(t);
  return 0;
}
