/* Fuzz harness: drives (JSON text) through cv_drive_parse, then evaluated. */
#include "fuzz_util.h"
#include "service/drive.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  char *t = fuzz_text(data, size);
  cv_drive *d = NULL;
  cv_err err;
  if (cv_drive_parse(t, "fuzz.json", CAVE_BLENDER_WORLD_DIR, &d, &err) == CV_OK) {
    cv_drive_state s;
    const double ts[4] = {-1, 0, 0.5 * cv_drive_duration(d), 1e9};
    for (int i = 0; i < 4; i++) cv_drive_eval(d, ts[i], &s);
    cv_drive_destroy(d);
  }
  free(t);
  return 0;
}
