/* Fuzz harness: CAVE configs (JSON text) through cv_cave_parse. */
#include "fuzz_util.h"
#include "view/cave.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  char *t = fuzz_text(data, size);
  cv_cave c;
  cv_err err;
  if (cv_cave_parse(t, "fuzz.json", &c, &err) == CV_OK) {
    const double eye[3] = {0, 1.6, 0};
    cv_cave_check_eye(&c, eye, &err);
  }
  free(t);
  return 0;
}
