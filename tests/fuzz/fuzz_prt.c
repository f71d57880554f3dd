/* Fuzz harness: .prt files through cv_prt_read (the reader `cave shade`,
 * `cave lcd` and the service use). */
#include "fuzz_util.h"
#include "prt/prt.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  cv_prt *p = NULL;
  cv_err err;
  if (cv_prt_read(fuzz_file(data, size, ".prt"), &p, &err) == CV_OK) {
    cv_mesh *m = NULL;
    if (cv_prt_to_mesh(p, &m) == CV_OK) cv_mesh_destroy(m);
    cv_prt_destroy(p);
  }
  return 0;
}
