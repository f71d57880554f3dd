/* Fuzz harness: OpenEXR files through our wrapper cv_exr_read. */
#include "core/image.h"
#include "fuzz_util.h"
#include "io/exr.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  cv_image *img = NULL;
  cv_err err;
  if (cv_exr_read(fuzz_file(data, size, ".exr"), &img, &err) == CV_OK) cv_image_destroy(img);
  return 0;
}
