/* Unit tests of the EXR reader's guarded C++ fallback (src/io/exr_imf.c):
 * blender-data's DWAB maps decode to the same pixels in the guarded child
 * as in this process and as the reader did before the guard (OpenEXR's
 * C++ library called here directly); the input libFuzzer found to damage
 * that library's heap is refused by the header walk and, handed to the
 * decoder directly, gives one clean line; a file that blocks hits the time
 * limit; the limits come from the environment. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <ImfCRgbaFile.h>

#include "core/image.h"
#include "core/status.h"
#include "io/child_guard.h"
#include "io/exr.h"
#include "io/exr_imf.h"

#define CRASH_INPUT CV_SOURCE_DIR "/tests/fuzz/exr/crash-c6cbe384935c05f9da81bcc6fd5412461b91743e"
/* A channel list shorter than its declared size: OpenEXR's Core skips the
 * declared 329 bytes, the C++ library reads on after the list's 73 and
 * finds a 1.8 GB attribute (libFuzzer: a 14 s timeout under ASan). */
#define CHLIST_INPUT CV_SOURCE_DIR "/tests/fuzz/exr/timeout-1326518f36b4cecbad43d54c526f2a771fbb3f5a"

static const char *k_maps[] = {"city", "courtyard", "forest", "interior",
                               "night", "studio", "sunrise", "sunset"};

static void assert_no_child(void) {
  errno = 0;
  assert_int_equal(waitpid(-1, NULL, WNOHANG), -1);
  assert_int_equal(errno, ECHILD);
}

/* The reader as it was before the guard: OpenEXR's C++ library in this
 * process, halves converted by the library, negatives clamped. */
static cv_image *read_before(const char *path) {
  ImfInputFile *in = ImfOpenInputFile(path);
  assert_non_null(in);
  const ImfHeader *hd = ImfInputHeader(in);
  int x0, y0, x1, y1;
  ImfHeaderDataWindow(hd, &x0, &y0, &x1, &y1);
  size_t w = (size_t)(x1 - x0 + 1), h = (size_t)(y1 - y0 + 1);
  ImfRgba *buf = malloc(w * h * sizeof *buf);
  assert_non_null(buf);
  assert_true(ImfInputSetFrameBuffer(in, buf - x0 - (ptrdiff_t)y0 * (ptrdiff_t)w, 1, w));
  assert_true(ImfInputReadPixels(in, y0, y1));
  ImfCloseInputFile(in);
  cv_image *img = NULL;
  assert_int_equal(cv_image_create((int)w, (int)h, 3, &img), CV_OK);
  for (size_t y = 0; y < h; y++)
    for (size_t x = 0; x < w; x++) {
      const ImfRgba *p = &buf[y * w + x];
      float v[3] = {ImfHalfToFloat(p->r), ImfHalfToFloat(p->g), ImfHalfToFloat(p->b)};
      float *d = cv_image_at(img, (int)x, (int)y);
      for (int k = 0; k < 3; k++) d[k] = v[k] < 0 ? 0.0f : v[k];
    }
  free(buf);
  return img;
}

static void assert_same_pixels(const cv_image *a, const cv_image *b) {
  assert_int_equal(a->w, b->w);
  assert_int_equal(a->h, b->h);
  assert_int_equal(a->c, b->c);
  assert_memory_equal(a->px, b->px, (size_t)a->w * a->h * a->c * sizeof(float));
}

static void test_dwab_maps_same_pixels(void **state) {
  (void)state;
  int found = 0;
  for (size_t i = 0; i < sizeof k_maps / sizeof k_maps[0]; i++) {
    char path[512];
    snprintf(path, sizeof path, "%s/%s.exr", CAVE_BLENDER_WORLD_DIR, k_maps[i]);
    if (access(path, R_OK) != 0) continue;
    found++;
    cv_exr_guard here, guarded;
    cv_exr_guard_default(&guarded);
    here = guarded;
    here.in_process = 1;
    cv_image *a = NULL, *b = NULL;
    cv_exr_read_info ia, ib;
    cv_err err;
    assert_int_equal(cv_exr_read_with(path, &guarded, &a, &ia, &err), CV_OK);
    assert_int_equal(cv_exr_read_with(path, &here, &b, &ib, &err), CV_OK);
    assert_string_equal(ia.compression_name, "dwab");
    assert_int_equal(ia.guarded, 1);
    assert_int_equal(ib.guarded, 0);
    assert_same_pixels(a, b);
    assert_true(ia.negative_clamped == ib.negative_clamped);
    cv_image *c = read_before(path);
    assert_same_pixels(a, c);
    cv_image_destroy(a);
    cv_image_destroy(b);
    cv_image_destroy(c);
    assert_no_child();
  }
  print_message("%d DWAB maps of %s compared\n", found, CAVE_BLENDER_WORLD_DIR);
  if (!found) skip();
}

static void test_crash_input(void **state) {
  (void)state;
  cv_image *img = NULL;
  cv_err err;
  /* the reader: refused by the header walk before any library sees it */
  assert_int_equal(cv_exr_read(CRASH_INPUT, &img, &err), CV_ERR_FORMAT);
  assert_null(img);
  print_message("%s\n", err.msg);
  assert_non_null(strstr(err.msg, "declares 1919120128 bytes, the file has 118 after it"));
  assert_int_equal(cv_exr_read(CHLIST_INPUT, &img, &err), CV_ERR_FORMAT);
  print_message("%s\n", err.msg);
  assert_non_null(strstr(err.msg, ": header attribute 'channels' (chlist) declares 329 bytes, its "
                                  "channel list takes 73"));

  /* the decoder itself, bypassing the walk: whatever the library does with
   * it (a clean exception in a Release build, heap damage under ASan), the
   * caller gets one line naming the file and goes on */
  uint16_t *px = cv_exr_rgba_alloc(3, 2);
  assert_non_null(px);
  const cv_exr_window win = {0, 0, 3, 2};
  cv_exr_guard g;
  cv_exr_guard_default(&g);
  g.memory_mb = 0; /* what the library does unhindered; with a limit it stops at the limit */
  int st = cv_exr_imf_decode(CRASH_INPUT, &win, 3 * 2 * 6, px, &g, &err);
  print_message("%s\n", err.msg);
  assert_int_not_equal(st, CV_OK);
  assert_null(strchr(err.msg, '\n'));
  assert_int_equal(strncmp(err.msg, CRASH_INPUT ": ", strlen(CRASH_INPUT) + 2), 0);
  cv_exr_rgba_free(px, 3, 2);
  assert_no_child();
}

/* A FIFO nobody writes: the library blocks in its first read. */
static void test_time_limit(void **state) {
  (void)state;
  char fifo[512];
  snprintf(fifo, sizeof fifo, "%s/blocked.exr", CV_TEST_TMP_DIR);
  unlink(fifo);
  assert_int_equal(mkfifo(fifo, 0600), 0);
  cv_image *img = NULL;
  cv_err err;
  assert_int_equal(cv_exr_read(fifo, &img, &err), CV_ERR_IO); /* the reader: at once */
  assert_non_null(strstr(err.msg, "blocked.exr: not a regular file"));
  cv_exr_guard g;
  cv_exr_guard_default(&g);
  g.seconds = 1;
  uint16_t *px = cv_exr_rgba_alloc(4, 4);
  const cv_exr_window win = {0, 0, 4, 4};
  assert_int_equal(cv_exr_imf_decode(fifo, &win, 96, px, &g, &err), CV_ERR_RANGE);
  print_message("%s\n", err.msg);
  assert_non_null(strstr(err.msg, "blocked.exr: EXR decode stopped after ")); /* 1.0 s, more if loaded */
  assert_non_null(strstr(err.msg, " s: time limit 1 s hit (CAVE_EXR_TIMEOUT sets it)"));
  cv_exr_rgba_free(px, 4, 4);
  unlink(fifo);
  assert_no_child();
}

/* A memory limit: the crash input's attribute of 1.9 GB, handed to the
 * decoder directly, is more than 256 MB (not under ASan). */
static void test_memory_limit(void **state) {
  (void)state;
  if (!cv_child_memory_limit_applies()) skip();
  cv_exr_guard g;
  cv_exr_guard_default(&g);
  g.memory_mb = 256;
  uint16_t *px = cv_exr_rgba_alloc(3, 2);
  const cv_exr_window win = {0, 0, 3, 2};
  cv_err err;
  int st = cv_exr_imf_decode(CRASH_INPUT, &win, 3 * 2 * 6, px, &g, &err);
  print_message("%s\n", err.msg);
  assert_int_equal(st, CV_ERR_NOMEM);
  assert_non_null(strstr(err.msg, ": EXR decode stopped: memory limit 256 MB hit (CAVE_EXR_MEMORY_MB sets it)"));
  cv_exr_rgba_free(px, 3, 2);
  assert_no_child();
}

static void test_environment(void **state) {
  (void)state;
  cv_exr_guard g;
  unsetenv("CAVE_EXR_TIMEOUT");
  unsetenv("CAVE_EXR_MEMORY_MB");
  unsetenv("CAVE_EXR_VERBOSE");
  cv_exr_guard_default(&g);
  assert_int_equal(g.in_process, 0);
  assert_true(g.seconds == CV_EXR_DEFAULT_SECONDS);
  assert_true(g.memory_mb < 0); /* 1024 MB + twice the raw pixel bytes */
  assert_int_equal(g.verbose, 0);
  setenv("CAVE_EXR_TIMEOUT", "7.5", 1);
  setenv("CAVE_EXR_MEMORY_MB", "300", 1);
  setenv("CAVE_EXR_VERBOSE", "1", 1);
  cv_exr_guard_default(&g);
  assert_true(g.seconds == 7.5);
  assert_true(g.memory_mb == 300);
  assert_int_equal(g.verbose, 1);
  /* a bad value is refused by the decode, naming the variable (it fell
   * back to the default silently) */
  setenv("CAVE_EXR_TIMEOUT", "-3", 1);
  setenv("CAVE_EXR_MEMORY_MB", "lots", 1);
  cv_exr_guard_default(&g);
  assert_true(isnan(g.seconds) && isnan(g.memory_mb));
  uint16_t *px = cv_exr_rgba_alloc(3, 2);
  const cv_exr_window win = {0, 0, 3, 2};
  cv_err err;
  assert_int_equal(cv_exr_imf_decode(CRASH_INPUT, &win, 3 * 2 * 6, px, &g, &err), CV_ERR_RANGE);
  assert_string_equal(err.msg, "CAVE_EXR_TIMEOUT: expected seconds >= 0 (0 = none), got '-3'");
  setenv("CAVE_EXR_TIMEOUT", "2", 1);
  cv_exr_guard_default(&g);
  assert_int_equal(cv_exr_imf_decode(CRASH_INPUT, &win, 3 * 2 * 6, px, &g, &err), CV_ERR_RANGE);
  assert_string_equal(err.msg, "CAVE_EXR_MEMORY_MB: expected megabytes >= 0 (0 = none), got 'lots'");
  cv_exr_rgba_free(px, 3, 2);
  assert_no_child();
  unsetenv("CAVE_EXR_TIMEOUT");
  unsetenv("CAVE_EXR_MEMORY_MB");
  unsetenv("CAVE_EXR_VERBOSE");
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_dwab_maps_same_pixels), cmocka_unit_test(test_crash_input),
      cmocka_unit_test(test_time_limit),            cmocka_unit_test(test_memory_limit),
      cmocka_unit_test(test_environment),
  };
  return cmocka_run_group_tests_name("exr_guarded_decoder", tests, NULL, NULL);
}
