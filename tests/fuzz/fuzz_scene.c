/* Fuzz harness: scene configs (JSON) through cv_scene_config_load. */
#include <string.h>

#include "fuzz_util.h"
#include "io/scene_config.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  cv_scene_config c;
  memset(&c, 0, sizeof c);
  cv_err err;
  cv_scene_config_load(fuzz_file(data, size, ".json"), &c, &err);
  cv_scene_config_free(&c);
  return 0;
}
