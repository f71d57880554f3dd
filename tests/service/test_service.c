/* Runs every group of the service module's tests; fails if any test does. */
#include "test_service.h"

int main(void) {
  int failed = 0;
  failed += run_drive_tests();
  failed += run_tracker_tests();
  failed += run_framestate_tests();
  failed += run_metrics_tests();
  failed += run_clocksync_tests();
  failed += run_lcdshare_tests();
  return failed ? 1 : 0;
}
