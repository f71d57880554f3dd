/* Unit tests of the desktop preview's drawing helpers (src/view): the view
 * along the gaze (gazeview.c) samples the wall a ray from the head hits,
 * right side up, and follows the gaze (front, right, a side with no wall);
 * the 5x7 labels (label.c) have the documented size, draw lower case as
 * upper case, clip at the image's edge and draw into float images too. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <stdlib.h>
#include <string.h>

#include "view/cave.h"
#include "view/gazeview.h"
#include "view/label.h"

#define CAVES CV_SOURCE_DIR "/configs/caves"
#define WS 16

/* Five 16 x 16 walls side by side; wall w is (40 w + 20, 0, 0) in its lower
 * half and (40 w + 20, 255, 0) in its upper half (row 0 at the top). */
typedef struct walls {
  cv_cave c;
  uint8_t src[3 * 5 * WS * WS];
  int x[5], y[5], w[5], h[5];
  uint8_t shown[5];
} walls;

static void make(walls *t) {
  cv_err err;
  assert_int_equal(cv_cave_load(CAVES "/cave5.json", &t->c, &err), 0);
  assert_int_equal(t->c.n_walls, 5);
  for (int k = 0; k < 5; k++) {
    t->x[k] = k * WS, t->y[k] = 0, t->w[k] = t->h[k] = WS, t->shown[k] = 1;
    for (int y = 0; y < WS; y++)
      for (int x = 0; x < WS; x++) {
        uint8_t *p = t->src + 3 * ((size_t)y * 5 * WS + k * WS + x);
        p[0] = (uint8_t)(40 * k + 20), p[1] = y < WS / 2 ? 255 : 0, p[2] = 0;
      }
  }
}

static const uint8_t *at(const uint8_t *v, int n, int x, int y) { return v + 3 * ((size_t)y * n + x); }

static void test_front_and_right(void **state) {
  (void)state;
  walls *t = malloc(sizeof *t);
  assert_non_null(t);
  make(t);
  const int n = 32;
  uint8_t v[3 * 32 * 32];
  const double head[3] = {0, 1.2, 0}, front[3] = {0, 0, -1}, right[3] = {1, 0, 0}, back[3] = {0, 0, 1};
  /* front: every ray of a 90-degree view hits a wall (front, sides, floor, ceiling) */
  long hits = cv_gaze_view(&t->c, t->src, 5 * WS, t->x, t->y, t->w, t->h, t->shown, head, front, 90, v, n);
  assert_int_equal(hits, n * n);
  assert_int_equal(at(v, n, n / 2, n / 2 + 2)[0], 20);  /* the front wall (0) at the centre */
  assert_int_equal(at(v, n, n / 2, n / 2 + 2)[1], 0);   /* below the eye (1.2 m of 3): its lower half */
  assert_int_equal(at(v, n, n / 2, 2)[0], 20);          /* 40 degrees up: still the front wall, */
  assert_int_equal(at(v, n, n / 2, 2)[1], 255);         /* at 2.46 m: its upper half (right side up) */
  assert_int_equal(at(v, n, n / 2, n - 1)[0], 140);     /* 44 degrees down: the floor (3), 1.5 m ahead */
  const double up[3] = {0, 1, 0}, left[3] = {-1, 0, 0};
  cv_gaze_view(&t->c, t->src, 5 * WS, t->x, t->y, t->w, t->h, t->shown, head, up, 90, v, n);
  assert_int_equal(at(v, n, n / 2, n / 2)[0], 180); /* looking up: the ceiling (4) */
  cv_gaze_view(&t->c, t->src, 5 * WS, t->x, t->y, t->w, t->h, t->shown, head, left, 90, v, n);
  assert_int_equal(at(v, n, n / 2, n / 2)[0], 60); /* turned left: the left wall (1) */
  /* turned right: the right wall (2) in the middle */
  cv_gaze_view(&t->c, t->src, 5 * WS, t->x, t->y, t->w, t->h, t->shown, head, right, 90, v, n);
  assert_int_equal(at(v, n, n / 2, n / 2)[0], 100);
  /* turned back: no wall behind the viewer, the centre is black */
  hits = cv_gaze_view(&t->c, t->src, 5 * WS, t->x, t->y, t->w, t->h, t->shown, head, back, 90, v, n);
  assert_true(hits < n * n);
  assert_int_equal(at(v, n, n / 2, n / 2)[0] + at(v, n, n / 2, n / 2)[1], 0);
  /* a wall not shown lets its rays through */
  t->shown[0] = 0;
  cv_gaze_view(&t->c, t->src, 5 * WS, t->x, t->y, t->w, t->h, t->shown, head, front, 90, v, n);
  assert_int_equal(at(v, n, n / 2, n / 2)[0], 0);
  free(t);
}

static void test_labels(void **state) {
  (void)state;
  assert_int_equal(cv_label_width("AB", 1), 11);
  assert_int_equal(cv_label_width("AB\nABCD", 2), 46);
  assert_int_equal(cv_label_height(3), 27);
  enum { W = 40, H = 12 };
  uint8_t a[3 * W * H], b[3 * W * H];
  const uint8_t fg[3] = {255, 255, 160};
  memset(a, 7, sizeof a), memset(b, 7, sizeof b);
  assert_int_equal(cv_label_draw(a, W, H, 0, 0, 1, "front", fg), 9);
  cv_label_draw(b, W, H, 0, 0, 1, "FRONT", fg);
  assert_memory_equal(a, b, sizeof a);
  /* 'F' (row 0 all on: x 1..5), the box around it black, the rest untouched */
  for (int x = 1; x <= 5; x++) assert_memory_equal(a + 3 * (1 * W + x), fg, 3);
  assert_int_equal(a[3 * (2 * W + 2)], 0);
  assert_int_equal(a[3 * (10 * W + 2)], 7);
  /* clipped: a label past the edge writes nothing outside */
  memset(a, 7, sizeof a);
  cv_label_draw(a, W, H, W - 3, H - 3, 2, "WWW", fg);
  int inside = 0;
  for (int i = 0; i < W * H; i++) inside += a[3 * i] != 7;
  assert_true(inside > 0 && inside <= 9);
  /* a float image gets fg / 255 */
  cv_image *im;
  assert_int_equal(cv_image_create(W, H, 3, &im), 0);
  memset(im->px, 0, sizeof(float) * 3 * W * H);
  cv_label_draw_image(im, 0, 0, 1, "F", fg);
  assert_float_equal(im->px[3 * (1 * W + 1) + 2], 160 / 255.0f, 1e-6);
  cv_image_destroy(im);
}

int main(void) {
  const struct CMUnitTest tests[] = {cmocka_unit_test(test_front_and_right), cmocka_unit_test(test_labels)};
  return cmocka_run_group_tests(tests, NULL, NULL);
}
