/* The bounded-queue writer thread (src/io/filewriter.c): jobs run in order
 * and are counted; a full queue refuses a job at once (dropped, its data
 * freed); a failing job is counted with its message; cv_write_png_atomic
 * leaves a whole PNG or nothing (no temporary); drain waits for the queue. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>

#include "io/filewriter.h"
#include "io/png.h"

typedef struct job {
  int id, fail, sleep_ms;
  int *order, *n_done, *freed;
} job;

static int run_job(void *p, cv_err *err) {
  job *j = p;
  if (j->sleep_ms) {
    struct timespec ts = {j->sleep_ms / 1000, (long)(j->sleep_ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
  }
  j->order[(*j->n_done)++] = j->id;
  return j->fail ? cv_err_set(err, CV_ERR_IO, "job %d failed on purpose", j->id) : CV_OK;
}

static void free_job(void *p) {
  job *j = p;
  (*j->freed)++;
  free(j);
}

static cv_write_job make(int id, int fail, int sleep_ms, int *order, int *n_done, int *freed) {
  job *j = calloc(1, sizeof *j);
  *j = (job){id, fail, sleep_ms, order, n_done, freed};
  return (cv_write_job){run_job, free_job, j};
}

static void test_order_drop_fail(void **state) {
  (void)state;
  cv_filewriter *w;
  cv_err err;
  assert_int_equal(cv_filewriter_create(0, 0, &w, &err), CV_ERR_INVALID);
  assert_int_equal(cv_filewriter_create(2, 1, &w, &err), CV_OK);
  int order[16], n_done = 0, freed = 0;
  /* the first job keeps the thread 1 s: the queue (2) fills, the next is dropped */
  assert_int_equal(cv_filewriter_submit(w, make(0, 0, 1000, order, &n_done, &freed)), 0);
  cv_filewriter_stats st;
  for (int i = 0; i < 20000; i++) { /* until the thread has taken job 0 (it then sleeps 1 s in it) */
    cv_filewriter_stats_get(w, &st);
    if (st.queued == 0) break;
    struct timespec ts = {0, 100000L};
    nanosleep(&ts, NULL);
  }
  assert_int_equal(st.queued, 0);
  assert_int_equal(cv_filewriter_submit(w, make(1, 1, 0, order, &n_done, &freed)), 0);
  assert_int_equal(cv_filewriter_submit(w, make(2, 0, 0, order, &n_done, &freed)), 0);
  assert_int_equal(cv_filewriter_submit(w, make(3, 0, 0, order, &n_done, &freed)), -1);
  assert_int_equal(freed, 1); /* the dropped job's data freed at once */
  cv_filewriter_drain(w, &st);
  assert_int_equal(n_done, 3);
  assert_int_equal(order[0], 0);
  assert_int_equal(order[1], 1);
  assert_int_equal(order[2], 2);
  assert_int_equal(st.written, 2);
  assert_int_equal(st.failed, 1);
  assert_int_equal(st.dropped, 1);
  assert_int_equal(st.queued, 0);
  assert_non_null(strstr(st.first_error, "job 1 failed on purpose"));
  assert_int_equal(freed, 4);
  cv_filewriter_destroy(w);
  cv_filewriter_destroy(NULL);
}

/* destroy runs what is still queued */
static void test_destroy_drains(void **state) {
  (void)state;
  cv_filewriter *w;
  cv_err err;
  assert_int_equal(cv_filewriter_create(8, 0, &w, &err), CV_OK);
  int order[16], n_done = 0, freed = 0;
  for (int i = 0; i < 8; i++) assert_int_equal(cv_filewriter_submit(w, make(i, 0, 5, order, &n_done, &freed)), 0);
  cv_filewriter_destroy(w);
  assert_int_equal(n_done, 8);
  assert_int_equal(freed, 8);
  for (int i = 0; i < 8; i++) assert_int_equal(order[i], i);
}

static void test_png_atomic(void **state) {
  (void)state;
  char path[512], tmp[600];
  snprintf(path, sizeof path, "%s/atomic.png", CV_TEST_TMP_DIR);
  snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid());
  remove(path);
  uint8_t px[3 * 4 * 3];
  for (int i = 0; i < 36; i++) px[i] = (uint8_t)(7 * i);
  cv_err err;
  assert_int_equal(cv_write_png_atomic(path, 4, 3, 3, px, &err), CV_OK);
  assert_int_equal(access(tmp, F_OK), -1); /* no temporary left */
  cv_image *img;
  assert_int_equal(cv_png_read(path, &img, &err), CV_OK);
  assert_int_equal(img->w, 4);
  assert_int_equal(img->h, 3);
  cv_image_destroy(img);
  /* a folder that does not exist: an error naming the file, nothing left */
  snprintf(path, sizeof path, "%s/no/such/folder/x.png", CV_TEST_TMP_DIR);
  assert_int_not_equal(cv_write_png_atomic(path, 4, 3, 3, px, &err), CV_OK);
  assert_non_null(strstr(err.msg, "x.png"));
  assert_int_equal(access(path, F_OK), -1);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_order_drop_fail),
      cmocka_unit_test(test_destroy_drains),
      cmocka_unit_test(test_png_atomic),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
