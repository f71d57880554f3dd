/* JSON-lines metrics: the lines parse with cJSON (an independent reader),
 * strings survive escaping, non-finite doubles become null and are counted,
 * %.9g keeps doubles to 9 significant digits, and percentiles match values
 * worked out by hand (NumPy's "linear" rule). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include "cv_test_near.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "service/metrics.h"
#include "test_service.h"

static void test_line_parses(void **state) {
  (void)state;
  cv_metrics_line *m;
  assert_int_equal(cv_metrics_line_create(&m), CV_OK);
  const double arr[4] = {1.5, NAN, -2e-7, INFINITY};
  const char *nasty = "quote\" back\\ nl\n tab\t cr\r bell\x07 utf8 \xc3\xa9 end";
  cv_metrics_int(m, "frame", -12);
  cv_metrics_uint(m, "big", UINT64_MAX);
  cv_metrics_double(m, "pi", 3.14159265358979);
  cv_metrics_double(m, "nan", NAN);
  cv_metrics_double(m, "ninf", -INFINITY);
  cv_metrics_bool(m, "ok", 1);
  cv_metrics_string(m, "text", nasty);
  cv_metrics_string(m, "none", NULL);
  cv_metrics_doubles(m, "arr", arr, 4);
  cv_metrics_doubles(m, "empty", NULL, 0);
  assert_int_equal(cv_metrics_object_begin(m, "stage"), CV_OK);
  cv_metrics_double(m, "ms", 0.125);
  assert_int_equal(cv_metrics_object_begin(m, "deep"), CV_OK);
  assert_int_equal(cv_metrics_object_end(m), CV_OK);
  cv_metrics_int(m, "n", 3);
  assert_int_equal(cv_metrics_object_end(m), CV_OK);
  assert_int_equal(cv_metrics_object_end(m), CV_ERR_INVALID); /* no nested object open */
  cv_metrics_string(m, "k\"ey", "v");
  assert_int_equal(cv_metrics_nonfinite(m), 4);

  char path[1024];
  snprintf(path, sizeof path, "%s/metrics_test.jsonl", CV_TEST_TMP_DIR);
  FILE *f = fopen(path, "w+");
  assert_non_null(f);
  assert_int_equal(cv_metrics_write(m, f), CV_OK);
  cv_metrics_int(m, "frame", 2); /* a second line: the builder restarted */
  assert_int_equal(cv_metrics_write(m, f), CV_OK);
  rewind(f);
  char line[4096];
  assert_non_null(fgets(line, sizeof line, f));
  size_t L = strlen(line);
  assert_true(L > 0 && line[L - 1] == '\n');
  assert_null(memchr(line, '\n', L - 1)); /* exactly one line */
  cJSON *j = cJSON_Parse(line);
  assert_non_null(j);
  assert_int_equal((int)cJSON_GetObjectItem(j, "frame")->valuedouble, -12);
  assert_near(cJSON_GetObjectItem(j, "pi")->valuedouble, 3.14159265, 1e-8);
  assert_true(cJSON_IsNull(cJSON_GetObjectItem(j, "nan")));
  assert_true(cJSON_IsNull(cJSON_GetObjectItem(j, "ninf")));
  assert_true(cJSON_IsTrue(cJSON_GetObjectItem(j, "ok")));
  assert_string_equal(cJSON_GetObjectItem(j, "text")->valuestring, nasty);
  assert_true(cJSON_IsNull(cJSON_GetObjectItem(j, "none")));
  cJSON *a = cJSON_GetObjectItem(j, "arr");
  assert_int_equal(cJSON_GetArraySize(a), 4);
  assert_true(cJSON_GetArrayItem(a, 0)->valuedouble == 1.5);
  assert_true(cJSON_IsNull(cJSON_GetArrayItem(a, 1)));
  assert_true(cJSON_GetArrayItem(a, 2)->valuedouble == -2e-7);
  assert_true(cJSON_IsNull(cJSON_GetArrayItem(a, 3)));
  assert_int_equal(cJSON_GetArraySize(cJSON_GetObjectItem(j, "empty")), 0);
  cJSON *st = cJSON_GetObjectItem(j, "stage");
  assert_true(cJSON_GetObjectItem(st, "ms")->valuedouble == 0.125);
  assert_true(cJSON_IsObject(cJSON_GetObjectItem(st, "deep")));
  assert_int_equal((int)cJSON_GetObjectItem(st, "n")->valuedouble, 3);
  assert_string_equal(cJSON_GetObjectItem(j, "k\"ey")->valuestring, "v");
  assert_non_null(strstr(line, "\"big\":18446744073709551615"));
  assert_non_null(strstr(line, "\\u0007"));
  cJSON_Delete(j);
  assert_non_null(fgets(line, sizeof line, f));
  assert_string_equal(line, "{\"frame\":2}\n");
  assert_null(fgets(line, sizeof line, f));
  fclose(f);
  remove(path);
  cv_metrics_line_destroy(m);
}

static void test_text_and_unclosed(void **state) {
  (void)state;
  cv_metrics_line *m;
  assert_int_equal(cv_metrics_line_create(&m), CV_OK);
  assert_string_equal(cv_metrics_text(m), "{}");
  cv_metrics_double(m, "x", 0.1);
  cv_metrics_object_begin(m, "o");
  cv_metrics_double(m, "y", 1e300);
  /* %.9g: 0.1 prints as "0.1"; an open nested object is closed in the text. */
  assert_string_equal(cv_metrics_text(m), "{\"x\":0.1,\"o\":{\"y\":1e+300}}");
  cv_metrics_begin(m);
  cv_metrics_double(m, "third", 1.0 / 3.0);
  assert_string_equal(cv_metrics_text(m), "{\"third\":0.333333333}");
  /* Deep nesting is bounded. */
  cv_metrics_begin(m);
  int st = CV_OK, depth = 0;
  while (st == CV_OK && depth < 100) {
    st = cv_metrics_object_begin(m, "d");
    if (st == CV_OK) depth++;
  }
  assert_int_equal(st, CV_ERR_RANGE);
  assert_int_equal(depth, 15);
  cJSON *j = cJSON_Parse(cv_metrics_text(m));
  assert_non_null(j);
  cJSON_Delete(j);
  /* Long strings grow the buffer. */
  cv_metrics_begin(m);
  char *big = malloc(100001);
  memset(big, 'a', 100000);
  big[100000] = '\0';
  cv_metrics_string(m, "big", big);
  j = cJSON_Parse(cv_metrics_text(m));
  assert_non_null(j);
  assert_int_equal(strlen(cJSON_GetObjectItem(j, "big")->valuestring), 100000);
  cJSON_Delete(j);
  free(big);
  assert_int_equal(cv_metrics_write(m, NULL), CV_ERR_INVALID);
  cv_metrics_line_destroy(m);
  cv_metrics_line_destroy(NULL);
}

static void test_percentiles(void **state) {
  (void)state;
  /* 1..10 shuffled: r = p/100 * 9; p50 -> 5.5, p99 -> 9.91, p0 -> 1, p100 -> 10,
   * p25 -> 3.25 (numpy.percentile(range(1, 11), [50, 99, 0, 100, 25])). */
  const double v[10] = {7, 3, 10, 1, 9, 2, 8, 5, 4, 6};
  const double ps[5] = {50, 99, 0, 100, 25};
  const double want[5] = {5.5, 9.91, 1, 10, 3.25};
  double got[5];
  size_t skipped = 99;
  assert_int_equal(cv_percentiles(v, 10, ps, 5, got, &skipped), CV_OK);
  assert_int_equal(skipped, 0);
  for (int k = 0; k < 5; k++) assert_near(got[k], want[k], 1e-12);
  /* Order independence, bit for bit. */
  double rev[10], g2[5];
  for (int i = 0; i < 10; i++) rev[i] = v[9 - i];
  assert_int_equal(cv_percentiles(rev, 10, ps, 5, g2, NULL), CV_OK);
  assert_memory_equal(got, g2, sizeof got);
  /* Non-finite values are skipped and counted. */
  const double w[6] = {NAN, 2, INFINITY, 4, -INFINITY, 0};
  double p;
  assert_int_equal(cv_percentile(w, 6, 50, &p, &skipped), CV_OK);
  assert_true(p == 2.0);
  assert_int_equal(skipped, 3);
  /* One value: every percentile is it. */
  const double one = 7.25;
  assert_int_equal(cv_percentile(&one, 1, 99, &p, NULL), CV_OK);
  assert_true(p == 7.25);
  /* 1000 frame times 0.001..1.000: p99 = x[989.01] = 0.990 + 0.01 * 0.001. */
  double *t = malloc(1000 * sizeof *t);
  for (int i = 0; i < 1000; i++) t[(i * 7919) % 1000] = (i + 1) * 1e-3;
  assert_int_equal(cv_percentile(t, 1000, 99, &p, NULL), CV_OK);
  assert_near(p, 0.99001, 1e-12);
  assert_int_equal(cv_percentile(t, 1000, 50, &p, NULL), CV_OK);
  assert_near(p, 0.5005, 1e-12);
  free(t);
  /* Errors. */
  assert_int_equal(cv_percentile(w, 0, 50, &p, NULL), CV_ERR_EMPTY);
  const double bad[2] = {NAN, NAN};
  assert_int_equal(cv_percentile(bad, 2, 50, &p, &skipped), CV_ERR_EMPTY);
  assert_int_equal(skipped, 2);
  assert_int_equal(cv_percentile(v, 10, 100.5, &p, NULL), CV_ERR_RANGE);
  assert_int_equal(cv_percentile(v, 10, NAN, &p, NULL), CV_ERR_RANGE);
}

int run_metrics_tests(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_line_parses),
      cmocka_unit_test(test_text_and_unclosed),
      cmocka_unit_test(test_percentiles),
  };
  return cmocka_run_group_tests_name("metrics", tests, NULL, NULL);
}
