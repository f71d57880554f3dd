/* Fuzz harness: BRDF tables and MERL files through cv_brdf_load, then evaluated. */
#include "fuzz_util.h"
#include "lcd/brdf.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  cv_brdf *b = NULL;
  cv_brdf_report rep;
  cv_err err;
  if (cv_brdf_load(fuzz_file(data, size, ".brdf"), &b, &rep, &err) == CV_OK) {
    float rgb[3];
    cv_brdf_eval(b, 0.3, 1.2, 2.0, rgb);
    cv_brdf_eval(b, -1, 9, -9, rgb);
    cv_brdf_destroy(b);
  }
  return 0;
}
