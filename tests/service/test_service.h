/* The service tests' groups, one per source file, run by test_service.c. */
#ifndef CV_TEST_SERVICE_H
#define CV_TEST_SERVICE_H

int run_drive_tests(void);
int run_tracker_tests(void);
int run_framestate_tests(void);
int run_metrics_tests(void);
int run_clocksync_tests(void);
int run_lcdshare_tests(void);

#endif
