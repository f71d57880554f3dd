/* Unit tests of the guarded child (src/io/child_guard.c): a child that
 * succeeds, one that runs past the time limit, one that allocates past the
 * memory limit (not under AddressSanitizer, which applies no memory limit),
 * one that crashes, one that fails; each gives its outcome and one clean
 * line of error, its output is captured, and no child is left behind. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "core/status.h"
#include "io/child_guard.h"

static const cv_child_labels k_lab = {"in.dat", "work (TEST)", "testlib", "TEST_TIMEOUT", "TEST_MEMORY_MB"};

/* No child of ours is left, reaped or not. */
static void assert_no_child(void) {
  errno = 0;
  assert_int_equal(waitpid(-1, NULL, WNOHANG), -1);
  assert_int_equal(errno, ECHILD);
}

/* One line: no newline in the message, and it starts with the file. */
static void assert_one_line(const cv_err *e) {
  assert_null(strchr(e->msg, '\n'));
  assert_int_equal(strncmp(e->msg, "in.dat: work (TEST) ", 20), 0);
}

static int child_hello(void *ctx, int fd) {
  (void)ctx;
  fprintf(stderr, "chatter on stderr\n");
  printf("chatter on stdout\n");
  return cv_child_write(fd, "hello", 5) ? CV_ERR_IO : CV_OK;
}

static void test_success(void **state) {
  (void)state;
  cv_child_limits lim = {10, 512};
  cv_child_result res;
  cv_err err;
  assert_int_equal(cv_child_run(child_hello, NULL, &lim, &res, &err), CV_OK);
  assert_int_equal(res.outcome, CV_CHILD_DONE);
  assert_int_equal(res.exit_code, 0);
  assert_int_equal(res.signal, 0);
  assert_int_equal(res.data_n, 5);
  assert_memory_equal(res.data, "hello", 5);
  assert_non_null(res.output);
  assert_non_null(strstr(res.output, "chatter on stderr"));
  assert_non_null(strstr(res.output, "chatter on stdout"));
  assert_int_equal(cv_child_error(&res, &lim, &k_lab, &err), CV_OK);
  cv_child_result_free(&res);
  assert_no_child();
}

static int child_sleep(void *ctx, int fd) {
  (void)ctx;
  (void)fd;
  sleep(60);
  return CV_OK;
}

static int child_spin(void *ctx, int fd) {
  (void)ctx;
  (void)fd;
  volatile unsigned long n = 0;
  for (;;) n++;
  return CV_OK;
}

static double wall_s(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void test_time_limit(void **state) {
  (void)state;
  cv_child_fn fns[2] = {child_sleep, child_spin};
  for (int i = 0; i < 2; i++) {
    cv_child_limits lim = {1, 0};
    cv_child_result res;
    cv_err err;
    double t0 = wall_s();
    assert_int_equal(cv_child_run(fns[i], NULL, &lim, &res, &err), CV_OK);
    double took = wall_s() - t0;
    assert_int_equal(res.outcome, CV_CHILD_TIMEOUT);
    assert_true(took >= 1.0 && took < 5.0);
    assert_int_equal(cv_child_error(&res, &lim, &k_lab, &err), CV_ERR_RANGE);
    print_message("%s\n", err.msg);
    assert_one_line(&err);
    assert_non_null(strstr(err.msg, "stopped after ")); /* 1.0 s, more on a loaded machine */
    assert_non_null(strstr(err.msg, " s: time limit 1 s hit (TEST_TIMEOUT sets it)"));
    cv_child_result_free(&res);
    assert_no_child();
  }
}

/* Allocates and touches 64 MB blocks up to 8 GB; CV_ERR_NOMEM when malloc
 * fails. */
static int child_hog(void *ctx, int fd) {
  (void)ctx;
  (void)fd;
  for (int i = 0; i < 128; i++) {
    char *p = malloc((size_t)64 << 20);
    if (!p) return CV_ERR_NOMEM;
    memset(p, i, (size_t)64 << 20);
  }
  return CV_OK;
}

/* Allocates and touches 128 MB; CV_ERR_NOMEM when malloc fails. */
static int child_128mb(void *ctx, int fd) {
  (void)ctx;
  char *p = malloc((size_t)128 << 20);
  if (!p) return CV_ERR_NOMEM;
  memset(p, 1, (size_t)128 << 20);
  free(p);
  return cv_child_write(fd, "ok", 2) ? CV_ERR_IO : CV_OK;
}

static void test_memory_limit(void **state) {
  (void)state;
  if (!cv_child_memory_limit_applies()) {
    print_message("AddressSanitizer build: no memory limit applies, test skipped\n");
    skip();
  }
  cv_child_limits lim = {60, 256};
  cv_child_result res;
  cv_err err;
  assert_int_equal(cv_child_run(child_hog, NULL, &lim, &res, &err), CV_OK);
  assert_int_equal(res.outcome, CV_CHILD_MEMORY);
  assert_true(res.memory_limited);
  assert_int_equal(cv_child_error(&res, &lim, &k_lab, &err), CV_ERR_NOMEM);
  print_message("%s\n", err.msg);
  assert_one_line(&err);
  assert_non_null(strstr(err.msg, "stopped: memory limit 256 MB hit (TEST_MEMORY_MB sets it)"));
  cv_child_result_free(&res);
  assert_no_child();

  /* The limit is on top of what the process has: 1 GB mapped here (not
   * touched) does not stop a child allowed 256 MB from using 128 MB. */
  void *big = mmap(NULL, (size_t)1 << 30, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  assert_true(big != MAP_FAILED);
  assert_int_equal(cv_child_run(child_128mb, NULL, &lim, &res, &err), CV_OK);
  assert_int_equal(res.outcome, CV_CHILD_DONE);
  assert_int_equal(res.data_n, 2);
  cv_child_result_free(&res);
  munmap(big, (size_t)1 << 30);
  assert_no_child();
}

static int child_segv(void *ctx, int fd) {
  (void)ctx;
  (void)fd;
  fprintf(stderr, "about to crash\n");
  raise(SIGSEGV);
  return CV_OK;
}

static int child_abort(void *ctx, int fd) {
  (void)ctx;
  (void)fd;
  abort();
}

static void test_crash(void **state) {
  (void)state;
  cv_child_limits lim = {30, 0};
  cv_child_result res;
  cv_err err;
  assert_int_equal(cv_child_run(child_segv, NULL, &lim, &res, &err), CV_OK);
  int st = cv_child_error(&res, &lim, &k_lab, &err);
  print_message("%s\n", err.msg);
  assert_int_equal(st, CV_ERR_BACKEND);
  assert_one_line(&err);
  if (cv_child_memory_limit_applies()) {
    assert_int_equal(res.outcome, CV_CHILD_SIGNAL);
    assert_int_equal(res.signal, SIGSEGV);
    assert_non_null(strstr(err.msg, "crashed: signal SIGSEGV ("));
    assert_non_null(strstr(err.msg, ") in testlib"));
  } else { /* AddressSanitizer's SEGV handler reports and exits */
    assert_true(res.outcome == CV_CHILD_FAILED || res.outcome == CV_CHILD_SIGNAL);
  }
  assert_non_null(strstr(res.output, "about to crash"));
  cv_child_result_free(&res);
  assert_no_child();

  assert_int_equal(cv_child_run(child_abort, NULL, &lim, &res, &err), CV_OK);
  assert_int_equal(res.outcome, CV_CHILD_SIGNAL);
  assert_int_equal(cv_child_error(&res, &lim, &k_lab, &err), CV_ERR_BACKEND);
  print_message("%s\n", err.msg);
  assert_one_line(&err);
  assert_non_null(strstr(err.msg, "crashed: signal SIGABRT ("));
  cv_child_result_free(&res);
  assert_no_child();
}

static int child_format_error(void *ctx, int fd) {
  (void)ctx;
  (void)fd;
  return CV_ERR_FORMAT;
}

static void test_child_error(void **state) {
  (void)state;
  cv_child_result res;
  cv_err err;
  assert_int_equal(cv_child_run(child_format_error, NULL, NULL, &res, &err), CV_OK);
  assert_int_equal(res.outcome, CV_CHILD_FAILED);
  assert_int_equal(res.status, CV_ERR_FORMAT);
  assert_int_equal(cv_child_error(&res, NULL, &k_lab, &err), CV_ERR_FORMAT);
  assert_string_equal(err.msg, "in.dat: work (TEST) failed: malformed file");
  cv_child_result_free(&res);
  assert_no_child();
  char b[24];
  assert_string_equal(cv_child_signal_name(SIGBUS, b, sizeof b), "SIGBUS");
  assert_string_equal(cv_child_signal_name(SIGRTMIN + 1, b, sizeof b), b);
  assert_int_equal(strncmp(b, "signal ", 7), 0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_success), cmocka_unit_test(test_time_limit),
      cmocka_unit_test(test_memory_limit), cmocka_unit_test(test_crash),
      cmocka_unit_test(test_child_error),
  };
  return cmocka_run_group_tests_name("child_guard", tests, NULL, NULL);
}
