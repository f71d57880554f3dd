/* Head tracking: the recorded path (interpolation against hand-computed
 * values, loop and hold, every error naming file:line), the DTrack ASCII
 * parser (good packets with two bodies, and each kind of malformed packet
 * rejected), the head pose from a body (rotation applied column-wise), a
 * real UDP round trip on loopback, and the keyboard-and-mouse head (steps
 * along the gaze's floor axes, turns, the box, reset). */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include "cv_test_near.h"

#include <arpa/inet.h>
#include <math.h>
#include <netinet/in.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "service/tracker.h"
#include "test_service.h"

/* --- head path ------------------------------------------------------------ */

static const char *path_text =
    "# t x y z gx gy gz\n"
    "0 0 1.2 0   0 0 -1\n"
    "\n"
    "1 1 1.2 0   0 0 -2   # not unit: normalised\n"
    "  3 1 1.6 -2  1 0 0\n";

static void test_head_path_eval(void **state) {
  (void)state;
  cv_head_path *p;
  cv_err err;
  assert_int_equal(cv_head_path_parse(path_text, "mem", &p, &err), CV_OK);
  assert_int_equal(cv_head_path_count(p), 3);
  assert_true(cv_head_path_duration(p) == 3.0);
  cv_head_pose h;
  cv_head_path_eval(p, 0.25, 0, &h);
  assert_true(h.valid && h.t == 0.25);
  assert_near(h.pos[0], 0.25, 1e-15);
  assert_near(h.pos[1], 1.2, 1e-15);
  assert_near(h.gaze[2], -1, 1e-15);
  /* Between samples 1 and 2 at t = 2: f = 0.5, pos (1, 1.4, -1); gaze
   * nlerp((0,0,-1), (1,0,0)) = (1, 0, -1)/sqrt(2). */
  cv_head_path_eval(p, 2.0, 0, &h);
  assert_near(h.pos[0], 1, 1e-15);
  assert_near(h.pos[1], 1.4, 1e-15);
  assert_near(h.pos[2], -1, 1e-15);
  assert_near(h.gaze[0], M_SQRT1_2, 1e-15);
  assert_near(h.gaze[2], -M_SQRT1_2, 1e-15);
  /* Hold the ends. */
  cv_head_path_eval(p, -5, 0, &h);
  assert_true(h.pos[0] == 0 && h.gaze[2] == -1);
  cv_head_path_eval(p, 99, 0, &h);
  assert_true(h.pos[2] == -2 && h.gaze[0] == 1);
  /* Loop: t = 3 + 0.25 behaves like 0.25, and -0.5 like 2.5. */
  cv_head_pose a, b;
  cv_head_path_eval(p, 3.25, 1, &a);
  cv_head_path_eval(p, 0.25, 1, &b);
  assert_near(a.pos[0], b.pos[0], 1e-12);
  cv_head_path_eval(p, -0.5, 1, &a);
  cv_head_path_eval(p, 2.5, 1, &b);
  assert_near(a.pos[2], b.pos[2], 1e-12);
  assert_near(a.gaze[0], b.gaze[0], 1e-12);
  /* NaN time: the first sample. */
  cv_head_path_eval(p, NAN, 1, &a);
  assert_true(a.pos[0] == 0 && isfinite(a.gaze[2]));
  cv_head_path_destroy(p);

  /* Opposite gazes halfway: no NaN, the nearer sample's gaze. */
  assert_int_equal(cv_head_path_parse("0 0 0 0 0 0 -1\n1 0 0 0 0 0 1\n", "opp", &p, &err), CV_OK);
  cv_head_path_eval(p, 0.5, 0, &a);
  assert_true(isfinite(a.gaze[2]));
  assert_near(fabs(a.gaze[2]), 1, 1e-15);
  cv_head_path_eval(p, 0.25, 0, &a);
  assert_true(a.gaze[2] == -1);
  cv_head_path_destroy(p);
}

static void expect_path_error(const char *text, int status, const char *where) {
  cv_head_path *p = (cv_head_path *)1;
  cv_err err;
  cv_err_clear(&err);
  assert_int_equal(cv_head_path_parse(text, "h.txt", &p, &err), status);
  assert_null(p);
  if (!strstr(err.msg, where)) fail_msg("expected '%s' in '%s'", where, err.msg);
}

static void test_head_path_errors(void **state) {
  (void)state;
  expect_path_error("0 0 1 0 0 0 -1\n1 0 1 0 0 0\n", CV_ERR_FORMAT, "h.txt:2:");
  expect_path_error("0 0 1 0 0 0 -1\n\n# c\n1 0 1 0 0 0 -1 7\n", CV_ERR_FORMAT, "h.txt:4:");
  expect_path_error("0 0 1 0 0 0 -1\n1 0 1 x 0 0 -1\n", CV_ERR_FORMAT, "h.txt:2:");
  expect_path_error("0 0 1 0 0 0 -1\n1 0 1,5 0 0 0 -1\n", CV_ERR_FORMAT, "h.txt:2:");
  expect_path_error("0 0 1 0 0 0 -1\n1 0 nan 0 0 0 -1\n", CV_ERR_NONFINITE, "h.txt:2:");
  expect_path_error("0 0 1 0 0 0 -1\n0 0 1 0 0 0 -1\n", CV_ERR_RANGE, "h.txt:2:");
  expect_path_error("1 0 1 0 0 0 -1\n0.5 0 1 0 0 0 -1\n", CV_ERR_RANGE, "not after");
  expect_path_error("0 0 1 0 0 0 0\n", CV_ERR_RANGE, "h.txt:1: the gaze");
  expect_path_error("# only comments\n\n", CV_ERR_EMPTY, "no samples");
  cv_head_path *p;
  cv_err err;
  assert_int_equal(cv_head_path_load("/nonexistent/head.txt", &p, &err), CV_ERR_IO);
  assert_non_null(strstr(err.msg, "/nonexistent/head.txt"));
  /* a NUL byte (a binary file) is named, not read as the end of the text */
  char bin[512];
  snprintf(bin, sizeof bin, "%s/binary_head.txt", CV_TEST_TMP_DIR);
  FILE *f = fopen(bin, "wb");
  assert_non_null(f);
  fwrite("0 0 1 0 0 0 -1\n\0\x01\x02garbage", 1, 26, f);
  fclose(f);
  assert_int_equal(cv_head_path_load(bin, &p, &err), CV_ERR_FORMAT);
  assert_null(p);
  assert_non_null(strstr(err.msg, "binary_head.txt"));
  assert_non_null(strstr(err.msg, "NUL byte at offset 15"));
}

static void test_default_head_path(void **state) {
  (void)state;
  cv_head_path *p;
  cv_err err;
  const char *file = CV_SOURCE_DIR "/configs/heads/default.txt";
  if (cv_head_path_load(file, &p, &err)) fail_msg("%s", err.msg);
  assert_true(cv_head_path_count(p) > 500);
  assert_near(cv_head_path_duration(p), 20.0, 1e-9);
  /* Inside the 3 m CAVE near (0, 1.2, 0), looking mostly at the front wall,
   * with glances left (gaze x < -0.5), right (x > 0.5) and down (y < -0.4). */
  int front = 0, n = 0, left = 0, right = 0, down = 0;
  for (double t = 0; t < 20; t += 0.01, n++) {
    cv_head_pose h;
    cv_head_path_eval(p, t, 1, &h);
    assert_near(h.pos[0], 0, 0.2);
    assert_near(h.pos[1], 1.2, 0.1);
    assert_near(h.pos[2], 0, 0.2);
    double g = sqrt(h.gaze[0] * h.gaze[0] + h.gaze[1] * h.gaze[1] + h.gaze[2] * h.gaze[2]);
    assert_near(g, 1, 1e-9);
    front += h.gaze[2] < -0.95;
    left += h.gaze[0] < -0.5;
    right += h.gaze[0] > 0.5;
    down += h.gaze[1] < -0.4;
  }
  assert_true(front > n / 2);
  assert_true(left > 0 && right > 0 && down > 0);
  /* Seamless loop: t = 20 - eps is close to t = 0. */
  cv_head_pose a, b;
  cv_head_path_eval(p, 19.999, 1, &a);
  cv_head_path_eval(p, 0, 1, &b);
  assert_near(a.pos[0], b.pos[0], 1e-3);
  assert_near(a.gaze[1], b.gaze[1], 1e-3);
  cv_head_path_destroy(p);
}

/* --- DTrack parser ---------------------------------------------------------- */

/* Body 1: rotation 90 degrees about +Y (R = [[0,0,1],[0,1,0],[-1,0,0]], sent
 * column-wise: columns (0,0,-1), (0,1,0), (1,0,0)); body 7: identity. */
static const char *good =
    "fr 21753\r\n"
    "ts 39596.024000\r\n"
    "3d 1 [1 1.000][100 200 300]\r\n"
    "6d 2 [1 1.000][100.0 1200.0 -50.5 0 90 0][0 0 -1 0 1 0 1 0 0] "
    "[7 0.800][-1500 0 1500 0 0 0][1 0 0 0 1 0 0 0 1]\r\n"
    "6df2 1 3 [0 1.000 3 0][0 0 0][1 0 0 0 1 0 0 0 1][0 0 0]\r\n";

static void test_dtrack_good(void **state) {
  (void)state;
  cv_dtrack_frame f;
  cv_err err;
  assert_int_equal(cv_dtrack_parse(good, strlen(good), &f, &err), CV_OK);
  assert_int_equal(f.frame, 21753);
  assert_true(f.has_ts);
  assert_near(f.ts, 39596.024, 1e-9);
  assert_int_equal(f.n_bodies, 2);
  assert_int_equal(f.body[0].id, 1);
  assert_true(f.body[0].quality == 1.0 && f.body[0].pos_mm[2] == -50.5);
  assert_true(f.body[0].euler_deg[1] == 90);
  assert_int_equal(f.body[1].id, 7);
  assert_true(f.body[1].quality == 0.8 && f.body[1].pos_mm[0] == -1500);

  /* Head pose of body 1: pos in metres; forward (0,0,-1) -> R (0,0,-1) = -column 2
   * = (-1, 0, 0): the head turned 90 degrees left. */
  cv_head_pose h;
  assert_int_equal(cv_dtrack_head_pose(&f, 1, NULL, &h), CV_OK);
  assert_near(h.pos[0], 0.1, 1e-12);
  assert_near(h.pos[1], 1.2, 1e-12);
  assert_near(h.pos[2], -0.0505, 1e-12);
  assert_near(h.gaze[0], -1, 1e-12);
  assert_near(h.gaze[1], 0, 1e-12);
  assert_near(h.gaze[2], 0, 1e-12);
  assert_true(h.valid && h.t == f.ts);
  /* Another forward axis: local +X -> column 0 = (0, 0, -1). */
  const double fx[3] = {2, 0, 0};
  assert_int_equal(cv_dtrack_head_pose(&f, 1, fx, &h), CV_OK);
  assert_near(h.gaze[2], -1, 1e-12);
  assert_int_equal(cv_dtrack_head_pose(&f, 7, NULL, &h), CV_OK);
  assert_near(h.pos[0], -1.5, 1e-12);
  assert_true(h.gaze[2] == -1);
  assert_int_equal(cv_dtrack_head_pose(&f, 3, NULL, &h), CV_ERR_NOT_FOUND);
  const double zero[3] = {0, 0, 0};
  assert_int_equal(cv_dtrack_head_pose(&f, 1, zero, &h), CV_ERR_INVALID);

  /* Minimal packets: no ts, LF only, 6d 0; an untracked body (quality -1,
   * zero matrix) is accepted by the parser but gives no pose. */
  const char *minimal = "fr 5\n6d 0\n";
  assert_int_equal(cv_dtrack_parse(minimal, strlen(minimal), &f, &err), CV_OK);
  assert_int_equal(f.n_bodies, 0);
  assert_false(f.has_ts);
  const char *untracked = "fr 6\n6d 1 [1 -1.000][0 0 0 0 0 0][0 0 0 0 0 0 0 0 0]";
  assert_int_equal(cv_dtrack_parse(untracked, strlen(untracked), &f, &err), CV_OK);
  assert_int_equal(cv_dtrack_head_pose(&f, 1, NULL, &h), CV_ERR_NOT_FOUND);
  /* len bounds the packet: the text after it is not read. */
  const char *cut = "fr 7\n6d 0\nGARBAGE";
  assert_int_equal(cv_dtrack_parse(cut, 10, &f, &err), CV_OK);
  assert_int_equal(f.frame, 7);
}

typedef struct bad_case {
  const char *what, *pkt;
  int status;
} bad_case;

static const bad_case bad[] = {
    {"truncated bracket", "fr 1\n6d 1 [1 1.0][0 0 0 0 0 0][1 0 0 0 1 0 0 0 1", CV_ERR_FORMAT},
    {"truncated block", "fr 1\n6d 1 [1 1.0][0 0 0 0 0 0][1 0 0 0 1 0", CV_ERR_FORMAT},
    {"cut mid-line", "fr 1\n6d 1 [1 1.0][0 0", CV_ERR_FORMAT},
    {"count too high",
     "fr 1\n6d 2 [1 1.0][0 0 0 0 0 0][1 0 0 0 1 0 0 0 1]\n", CV_ERR_FORMAT},
    {"count too low",
     "fr 1\n6d 1 [1 1.0][0 0 0 0 0 0][1 0 0 0 1 0 0 0 1] [2 1.0][0 0 0 0 0 0][1 0 0 0 1 0 0 0 1]",
     CV_ERR_FORMAT},
    {"too many entries", "fr 1\n6d 1 [1 1.0][0 0 0 0 0 0 0][1 0 0 0 1 0 0 0 1]", CV_ERR_FORMAT},
    {"NaN position", "fr 1\n6d 1 [1 1.0][0 nan 0 0 0 0][1 0 0 0 1 0 0 0 1]", CV_ERR_NONFINITE},
    {"Inf rotation", "fr 1\n6d 1 [1 1.0][0 0 0 0 0 0][1 0 0 0 1 0 0 0 inf]", CV_ERR_NONFINITE},
    {"NaN timestamp", "fr 1\nts NaN\n6d 0", CV_ERR_NONFINITE},
    {"not orthonormal", "fr 1\n6d 1 [1 1.0][0 0 0 0 0 0][1 0 0 0 1 0 0 0 1.01]", CV_ERR_RANGE},
    {"sheared", "fr 1\n6d 1 [1 1.0][0 0 0 0 0 0][1 0 0 0.1 1 0 0 0 1]", CV_ERR_RANGE},
    {"reflection", "fr 1\n6d 1 [1 1.0][0 0 0 0 0 0][1 0 0 0 1 0 0 0 -1]", CV_ERR_RANGE},
    {"non-number", "fr 1\n6d 1 [1 1.0][0 0 zero 0 0 0][1 0 0 0 1 0 0 0 1]", CV_ERR_FORMAT},
    {"number glued to text", "fr 12abc\n", CV_ERR_FORMAT},
    {"negative frame", "fr -3\n", CV_ERR_FORMAT},
    {"fractional body count", "fr 1\n6d 1.5\n", CV_ERR_FORMAT},
    {"garbage text", "hello world, this is not dtrack", CV_ERR_FORMAT},
    {"binary garbage", "\x01\x02\xff\xfe\x80 junk", CV_ERR_FORMAT},
    {"empty", "", CV_ERR_FORMAT},
    {"17 bodies", "fr 1\n6d 17\n", CV_ERR_FORMAT},
    {"second fr", "fr 1\nfr 2\n", CV_ERR_FORMAT},
};

static void test_dtrack_malformed(void **state) {
  (void)state;
  int n = (int)(sizeof bad / sizeof bad[0]), rejected = 0;
  for (int i = 0; i < n; i++) {
    cv_dtrack_frame f;
    cv_err err;
    cv_err_clear(&err);
    int st = cv_dtrack_parse(bad[i].pkt, strlen(bad[i].pkt), &f, &err);
    if (st != bad[i].status)
      fail_msg("%s: got %d (%s), expected %d", bad[i].what, st, err.msg, bad[i].status);
    assert_non_null(strstr(err.msg, "dtrack"));
    rejected++;
  }
  assert_int_equal(rejected, 21);
  /* A NUL inside the datagram. */
  cv_dtrack_frame f;
  assert_int_equal(cv_dtrack_parse("fr 1\0\n6d 0", 10, &f, NULL), CV_ERR_FORMAT);
  /* Within the 1e-3 tolerance: accepted. */
  const char *near = "fr 1\n6d 1 [1 1.0][0 0 0 0 0 0][1 0 0 0 1 0 0 0 1.0004]";
  assert_int_equal(cv_dtrack_parse(near, strlen(near), &f, NULL), CV_OK);
}

/* --- UDP round trip --------------------------------------------------------- */

static void send_to(int port, const char *pkt) {
  int s = socket(AF_INET, SOCK_DGRAM, 0);
  assert_true(s >= 0);
  struct sockaddr_in a;
  memset(&a, 0, sizeof a);
  a.sin_family = AF_INET;
  a.sin_port = htons((uint16_t)port);
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ssize_t n = sendto(s, pkt, strlen(pkt), 0, (struct sockaddr *)&a, sizeof a);
  assert_int_equal(n, (ssize_t)strlen(pkt));
  close(s);
}

/* Polls until something arrives or 2 s pass (loopback delivery is
 * practically immediate, but not synchronous). */
static int poll_wait(cv_dtrack_receiver *r, double now, cv_head_pose *h, cv_tracker_stats *s,
                     uint64_t want_packets) {
  int got = 0;
  for (int i = 0; i < 2000; i++) {
    int st = cv_dtrack_receiver_poll(r, now, h, s);
    assert_true(st >= 0);
    got |= st;
    if (s->packets >= want_packets) return got;
    struct timespec ts = {0, 1000000};
    nanosleep(&ts, NULL);
  }
  return got;
}

static void test_udp_round_trip(void **state) {
  (void)state;
  cv_dtrack_receiver *r;
  cv_err err;
  assert_int_equal(cv_dtrack_receiver_open(NULL, 0, 1, &r, &err), CV_OK);
  int port = cv_dtrack_receiver_port(r);
  assert_true(port > 0);

  cv_head_pose h;
  cv_tracker_stats s;
  /* Nothing yet: 0, no valid pose. */
  assert_int_equal(cv_dtrack_receiver_poll(r, 0.0, &h, &s), 0);
  assert_false(h.valid);
  assert_true(s.packets == 0 && s.last_rx_time == -1.0);

  /* Two packets in one poll: the newest wins. */
  send_to(port, "fr 1\n6d 1 [1 1.0][0 1200 0 0 0 0][1 0 0 0 1 0 0 0 1]\n");
  send_to(port, "fr 2\n6d 1 [1 1.0][500 1200 0 0 0 0][1 0 0 0 1 0 0 0 1]\n");
  assert_int_equal(poll_wait(r, 1.0, &h, &s, 2), 1);
  assert_true(h.valid);
  assert_near(h.pos[0], 0.5, 1e-12);
  assert_near(h.pos[1], 1.2, 1e-12);
  assert_true(h.t == 1.0 && s.last_rx_time == 1.0);
  assert_true(s.packets == 2 && s.malformed == 0 && s.no_body == 0);

  /* Malformed and body-less packets are counted and dropped: the pose holds. */
  send_to(port, "fr 3\n6d 1 [1 1.0][0 0 0 0 0 0][1 0 0 0 1 0");
  send_to(port, "fr 4\n6d 1 [1 1.0][nan 0 0 0 0 0][1 0 0 0 1 0 0 0 1]");
  send_to(port, "fr 5\n6d 1 [9 1.0][0 0 0 0 0 0][1 0 0 0 1 0 0 0 1]");
  assert_int_equal(poll_wait(r, 2.0, &h, &s, 5), 0);
  assert_true(s.packets == 5 && s.malformed == 2 && s.no_body == 1);
  assert_true(h.valid);
  assert_near(h.pos[0], 0.5, 1e-12);
  assert_true(s.last_rx_time == 1.0);

  /* A silent tracker holds the last pose. */
  assert_int_equal(cv_dtrack_receiver_poll(r, 3.0, &h, &s), 0);
  assert_true(h.valid);
  assert_near(h.pos[0], 0.5, 1e-12);
  assert_true(h.t == 1.0);
  assert_true(s.packets == 5);

  /* A good packet after the bad ones is taken. */
  send_to(port, "fr 6\nts 1.5\n6d 1 [1 1.0][-250 1100 100 0 0 0][1 0 0 0 1 0 0 0 1]\n");
  assert_int_equal(poll_wait(r, 4.0, &h, &s, 6), 1);
  assert_near(h.pos[0], -0.25, 1e-12);
  assert_near(h.pos[2], 0.1, 1e-12);
  assert_true(h.t == 4.0);

  /* A second receiver on the same port fails with the address in the message. */
  cv_dtrack_receiver *r2 = NULL;
  assert_int_equal(cv_dtrack_receiver_open("127.0.0.1", port, 1, &r2, &err), CV_ERR_IO);
  assert_null(r2);
  char want[32];
  snprintf(want, sizeof want, "127.0.0.1:%d", port);
  assert_non_null(strstr(err.msg, want));
  assert_int_equal(cv_dtrack_receiver_open("not-an-ip", 0, 1, &r2, &err), CV_ERR_INVALID);
  assert_int_equal(cv_dtrack_receiver_open(NULL, 70000, 1, &r2, &err), CV_ERR_INVALID);
  cv_dtrack_receiver_close(r);
  cv_dtrack_receiver_close(NULL);
}

static void test_head_nav(void **state) {
  (void)state;
  cv_head_nav n;
  cv_err err;
  const double pos[3] = {0, 1.2, 0}, gaze[3] = {0, 0, -2}, lo[3] = {-1.4, 0.1, -1.4}, hi[3] = {1.4, 2.9, 1.4};
  assert_int_equal(cv_head_nav_init(&n, pos, gaze, lo, hi, 0.05, 0.25, 7.0, &err), CV_OK);
  assert_true(n.pose.valid && n.pose.t == 7.0 && n.pose.gaze[2] == -1.0);
  /* nothing pressed: no change */
  cv_head_nav_input in = {0};
  assert_int_equal(cv_head_nav_apply(&n, &in, 8.0), 0);
  assert_true(n.pose.t == 7.0 && n.inputs == 0);
  /* right x4, up x2 (gaze along -z: right is +x) */
  in.right = 4, in.up = 2;
  assert_int_equal(cv_head_nav_apply(&n, &in, 9.0), 1);
  assert_near(n.pose.pos[0], 0.2, 1e-12);
  assert_near(n.pose.pos[1], 1.3, 1e-12);
  assert_true(n.pose.pos[2] == 0);
  assert_true(n.pose.t == 9.0 && n.inputs == 1);
  /* the box: 100 steps right stop at hi; against the side nothing changes */
  memset(&in, 0, sizeof in);
  in.right = 100;
  assert_int_equal(cv_head_nav_apply(&n, &in, 9.5), 1);
  assert_true(n.pose.pos[0] == 1.4 && n.pose.pos[2] == 0);
  assert_int_equal(cv_head_nav_apply(&n, &in, 9.7), 0);
  assert_true(n.pose.t == 9.5);
  /* drag 360 px right = 90 degrees: the gaze looks along +x; forward is +x,
   * back is -x */
  memset(&in, 0, sizeof in);
  in.drag_x = 360, in.forward = -2;
  assert_int_equal(cv_head_nav_apply(&n, &in, 10.0), 1);
  assert_near(n.pose.gaze[0], 1, 1e-12);
  assert_near(n.pose.gaze[2], 0, 1e-12);
  assert_near(n.pose.pos[0], 1.3, 1e-12);
  assert_near(n.pose.pos[2], 0, 1e-12);
  /* pitch is held within 85 degrees; dragging up looks up */
  memset(&in, 0, sizeof in);
  in.drag_y = -10000;
  cv_head_nav_apply(&n, &in, 11.0);
  assert_near(n.pose.gaze[1], sin(85 * 3.14159265358979323846 / 180), 1e-12);
  /* reset: home pose and gaze exactly */
  memset(&in, 0, sizeof in);
  in.reset = 1;
  assert_int_equal(cv_head_nav_apply(&n, &in, 14.0), 1);
  assert_memory_equal(n.pose.pos, pos, sizeof pos);
  assert_true(n.pose.gaze[0] == 0 && n.pose.gaze[1] == 0 && n.pose.gaze[2] == -1);
  /* errors */
  const double zero[3] = {0, 0, 0}, out[3] = {5, 1, 0};
  assert_int_equal(cv_head_nav_init(&n, pos, zero, lo, hi, 0.05, 0.25, 0, &err), CV_ERR_INVALID);
  assert_int_equal(cv_head_nav_init(&n, out, gaze, lo, hi, 0.05, 0.25, 0, &err), CV_ERR_INVALID);
  assert_non_null(strstr(err.msg, "outside the box"));
  assert_int_equal(cv_head_nav_init(&n, pos, gaze, hi, lo, 0.05, 0.25, 0, &err), CV_ERR_INVALID);
  assert_int_equal(cv_head_nav_init(&n, pos, gaze, lo, hi, 0, 0.25, 0, &err), CV_ERR_INVALID);
}

int run_tracker_tests(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_head_path_eval),   cmocka_unit_test(test_head_path_errors),
      cmocka_unit_test(test_default_head_path), cmocka_unit_test(test_dtrack_good),
      cmocka_unit_test(test_dtrack_malformed), cmocka_unit_test(test_udp_round_trip),
      cmocka_unit_test(test_head_nav),
  };
  return cmocka_run_group_tests_name("tracker", tests, NULL, NULL);
}
