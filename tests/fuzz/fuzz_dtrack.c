/* Fuzz harness: DTrack ASCII UDP packets through cv_dtrack_parse and the
 * head pose of bodies 1 and 2 (what cv_dtrack_receiver_poll does with a
 * datagram). */
#include "fuzz_util.h"
#include "service/tracker.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  cv_dtrack_frame f;
  cv_err err;
  if (cv_dtrack_parse((const char *)data, size, &f, &err) == CV_OK) {
    const double fwd[3] = {0, 0, -1};
    cv_head_pose pose;
    cv_dtrack_head_pose(&f, 1, fwd, &pose);
    cv_dtrack_head_pose(&f, 2, fwd, &pose);
  }
  return 0;
}
