/* Fuzz harness: recorded head paths through cv_head_path_load, then evaluated. */
#include "fuzz_util.h"
#include "service/tracker.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  cv_head_path *p = NULL;
  cv_err err;
  if (cv_head_path_load(fuzz_file(data, size, ".txt"), &p, &err) == CV_OK) {
    cv_head_pose pose;
    double d = cv_head_path_duration(p);
    const double ts[4] = {-1, 0, 0.5 * d, 3 * d + 1};
    for (int i = 0; i < 4; i++) {
      cv_head_path_eval(p, ts[i], 0, &pose);
      cv_head_path_eval(p, ts[i], 1, &pose);
    }
    cv_head_path_destroy(p);
  }
  return 0;
}
