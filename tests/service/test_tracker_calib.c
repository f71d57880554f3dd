/* Tracker calibration (service/tracker_calib): the tracker config (units,
 * room-to-CAVE transform, body id, marker-to-eye offset, IPD, UDP) and its
 * errors; the eyes in CAVE metres from a DTrack body, roll included; and
 * recorded DTrack packets sent over real UDP on loopback (unicast and
 * multicast): eye positions checked in metres, a NaN packet and a packet
 * without the body counted while the last pose is held. */
#include <arpa/inet.h>
#include <math.h>
#include <netinet/in.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>
#include "cv_test_near.h"

#include "service/tracker_calib.h"

#define NEAR(a, b) assert_near(a, b, 1e-9)

/* A room rotated 90 degrees about +Y from the CAVE and shifted 1 m along +Z;
 * glasses 10 cm above and 8 cm behind the eyes' midpoint; IPD 64 mm. */
static const char *k_cfg =
    "{\"units\": \"mm\", \"body_id\": 3,"
    " \"room_to_cave\": {\"rotate_deg\": [0, 90, 0], \"translate\": [0, 0, 1]},"
    " \"eye_offset\": [0, -0.1, -0.08], \"ipd\": 0.064,"
    " \"udp\": {\"port\": 5001, \"bind\": \"127.0.0.1\"}}";

/* body 3 at (1000, 1500, -500) mm with rotation b (column-wise) */
static void packet(char *buf, size_t cap, int frame, const char *pos, const char *rot) {
  snprintf(buf, cap, "fr %d\r\nts %d.5\r\n6d 2 [1 1.000][0 0 0 0 0 0][1 0 0 0 1 0 0 0 1] "
                     "[3 1.000][%s 0 0 0][%s]\r\n", frame, frame, pos, rot);
}

static void test_config(void **state) {
  (void)state;
  cv_tracker_config c;
  cv_err e;
  assert_int_equal(cv_tracker_config_parse(k_cfg, "t.json", &c, &e), CV_OK);
  assert_true(c.unit_m == 0.001 && c.body_id == 3 && c.port == 5001 && c.ipd == 0.064);
  assert_string_equal(c.bind, "127.0.0.1");
  static const struct {
    const char *json, *want;
  } bad[] = {
      {"{\"units\": \"furlong\"}", "t.json: units: unknown unit 'furlong'"},
      {"{\"ipd\": 0.5}", "t.json: ipd: expected a number in [0, 0.1]"},
      {"{\"room_to_cave\": {\"rotate\": [0, 0, 0]}}", "room_to_cave.rotate: unknown field"},
      {"{\"forward\": [0, 0, 0]}", "forward: expected a non-zero vector"},
      {"{\"up\": [0, 0, -2]}", "up: expected a vector not parallel"},
      {"{\"udp\": {\"port\": 70000}}", "udp.port"},
      {"{\"bodyid\": 1}", "bodyid: unknown field"},
      {"{\"body_id\": 1.5}", "body_id: expected an integer"},
  };
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    assert_int_equal(cv_tracker_config_parse(bad[i].json, "t.json", &c, &e), CV_ERR_CONFIG);
    if (!strstr(e.msg, bad[i].want)) fail_msg("case %zu: '%s' lacks '%s'", i, e.msg, bad[i].want);
  }
}

static void test_eyes(void **state) {
  (void)state;
  cv_tracker_config c;
  cv_err e;
  assert_int_equal(cv_tracker_config_parse(k_cfg, "t.json", &c, &e), CV_OK);
  char buf[512];
  cv_dtrack_frame f;
  packet(buf, sizeof buf, 1, "1000 1500 -500", "1 0 0 0 1 0 0 0 1");
  assert_int_equal(cv_dtrack_parse(buf, strlen(buf), &f, &e), CV_OK);
  cv_tracked_head h;
  assert_int_equal(cv_tracker_head(&c, &f, &h), CV_OK);
  /* room (1, 1.5, -0.5) m -> Ry(90): (-0.5, 1.5, -1) -> + (0, 0, 1) */
  NEAR(h.marker[0], -0.5), NEAR(h.marker[1], 1.5), NEAR(h.marker[2], 0.0);
  /* looking along -X; right is -Z; offset (0, -0.1, -0.08) -> (-0.08, -0.1, 0) */
  NEAR(h.gaze[0], -1), NEAR(h.gaze[1], 0), NEAR(h.gaze[2], 0);
  NEAR(h.center[0], -0.58), NEAR(h.center[1], 1.4), NEAR(h.center[2], 0);
  NEAR(h.eye[0][0], -0.58), NEAR(h.eye[0][1], 1.4), NEAR(h.eye[0][2], 0.032);
  NEAR(h.eye[1][0], -0.58), NEAR(h.eye[1][1], 1.4), NEAR(h.eye[1][2], -0.032);
  assert_near(h.yaw_deg, -90, 1e-9);
  assert_near(h.roll_deg, 0, 1e-9);
  /* units: the same numbers in cm are 10x further */
  c.unit_m = 0.01;
  assert_int_equal(cv_tracker_head(&c, &f, &h), CV_OK);
  NEAR(h.marker[0], -5), NEAR(h.marker[1], 15), NEAR(h.marker[2], -9);
  /* a body that is not tracked, or absent */
  c.body_id = 4;
  assert_int_equal(cv_tracker_head(&c, &f, &h), CV_ERR_NOT_FOUND);
}

/* Roll from the full matrix: the head tilted 30 degrees to its right. */
static void test_roll(void **state) {
  (void)state;
  cv_tracker_config c;
  cv_tracker_config_default(&c);
  c.body_id = 3;
  const double a = 30 * M_PI / 180;
  /* B = Rz(-30): columns (cos a, -sin a, 0), (sin a, cos a, 0), (0, 0, 1) */
  char rot[200], buf[512];
  snprintf(rot, sizeof rot, "%.12f %.12f 0 %.12f %.12f 0 0 0 1", cos(a), -sin(a), sin(a), cos(a));
  packet(buf, sizeof buf, 2, "0 1600 0", rot);
  cv_dtrack_frame f;
  cv_err e;
  assert_int_equal(cv_dtrack_parse(buf, strlen(buf), &f, &e), CV_OK);
  cv_tracked_head h;
  assert_int_equal(cv_tracker_head(&c, &f, &h), CV_OK);
  assert_near(h.roll_deg, 30, 1e-6);
  assert_near(h.yaw_deg, 0, 1e-6);
  assert_near(h.pitch_deg, 0, 1e-6);
  /* the right eye is lower by ipd sin(30) */
  assert_near((h.eye[0][1] - h.eye[1][1]), 0.064 * sin(a), 1e-9);
  assert_near(h.eye[1][0] - h.eye[0][0], 0.064 * cos(a), 1e-9);
}

static void send_to(const char *group, int port, const char *pkt) {
  int s = socket(AF_INET, SOCK_DGRAM, 0);
  assert_true(s >= 0);
  struct sockaddr_in a;
  memset(&a, 0, sizeof a);
  a.sin_family = AF_INET;
  a.sin_port = htons((uint16_t)port);
  inet_pton(AF_INET, group, &a.sin_addr);
  if (IN_MULTICAST(ntohl(a.sin_addr.s_addr))) {
    struct in_addr lo;
    inet_pton(AF_INET, "127.0.0.1", &lo);
    assert_int_equal(setsockopt(s, IPPROTO_IP, IP_MULTICAST_IF, &lo, sizeof lo), 0);
    unsigned char loop = 1;
    setsockopt(s, IPPROTO_IP, IP_MULTICAST_LOOP, &loop, sizeof loop);
  }
  assert_int_equal(sendto(s, pkt, strlen(pkt), 0, (struct sockaddr *)&a, sizeof a),
                   (ssize_t)strlen(pkt));
  close(s);
}

/* Polls until a datagram count is reached (loopback delivery is immediate,
 * but give it up to 2 s). */
static int poll_until(cv_dtrack_receiver *rx, uint64_t packets, cv_dtrack_frame *f,
                      cv_tracker_stats *st) {
  int got = 0;
  for (int i = 0; i < 2000; i++) {
    int r = cv_dtrack_receiver_poll_frame(rx, i * 1e-3, NULL, f, st);
    assert_true(r >= 0);
    got |= r;
    if (st->packets >= packets) return got;
    struct timespec ts = {0, 1000000};
    nanosleep(&ts, NULL);
  }
  fail_msg("only %llu of %llu packets arrived", (unsigned long long)st->packets,
           (unsigned long long)packets);
  return got;
}

static void round_trip(const cv_tracker_config *c, const char *to) {
  cv_err e;
  cv_dtrack_receiver *rx;
  assert_int_equal(cv_tracker_open(c, 0, &rx, &e), CV_OK);
  const int port = cv_dtrack_receiver_port(rx);
  char buf[512];
  packet(buf, sizeof buf, 7, "1000 1500 -500", "1 0 0 0 1 0 0 0 1");
  send_to(to, port, buf);
  cv_dtrack_frame f;
  cv_tracker_stats st;
  assert_int_equal(poll_until(rx, 1, &f, &st), 1);
  cv_tracked_head h;
  assert_int_equal(cv_tracker_head(c, &f, &h), CV_OK);
  NEAR(h.eye[0][0], -0.58), NEAR(h.eye[0][1], 1.4), NEAR(h.eye[0][2], 0.032);
  NEAR(h.eye[1][2], -0.032);
  /* NaN in the position, then a packet where body 3 is not tracked: both
   * counted, the pose of frame 7 held */
  packet(buf, sizeof buf, 8, "nan 1500 -500", "1 0 0 0 1 0 0 0 1");
  send_to(to, port, buf);
  send_to(to, port, "fr 9\r\n6d 1 [3 -1.000][0 0 0 0 0 0][0 0 0 0 0 0 0 0 0]\r\n");
  send_to(to, port, "fr 10\r\n6d 1 [1 1.000][0 0 0 0 0 0][1 0 0 0 1 0 0 0 1]\r\n");
  assert_int_equal(poll_until(rx, 4, &f, &st), 0);
  assert_int_equal(st.malformed, 1);
  assert_int_equal(st.no_body, 2);
  assert_int_equal(f.frame, 7);
  assert_int_equal(cv_tracker_head(c, &f, &h), CV_OK);
  NEAR(h.eye[0][2], 0.032);
  cv_dtrack_receiver_close(rx);
}

static void test_udp_unicast(void **state) {
  (void)state;
  cv_tracker_config c;
  cv_err e;
  assert_int_equal(cv_tracker_config_parse(k_cfg, "t.json", &c, &e), CV_OK);
  round_trip(&c, "127.0.0.1");
}

static void test_udp_multicast(void **state) {
  (void)state;
  cv_tracker_config c;
  cv_err e;
  assert_int_equal(cv_tracker_config_parse(k_cfg, "t.json", &c, &e), CV_OK);
  snprintf(c.multicast, sizeof c.multicast, "239.255.42.99");
  snprintf(c.iface, sizeof c.iface, "127.0.0.1");
  round_trip(&c, "239.255.42.99");
  snprintf(c.multicast, sizeof c.multicast, "10.0.0.1");
  cv_dtrack_receiver *rx;
  assert_int_equal(cv_tracker_open(&c, 0, &rx, &e), CV_ERR_INVALID);
  assert_non_null(strstr(e.msg, "not an IPv4 multicast group"));
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_config),      cmocka_unit_test(test_eyes),
      cmocka_unit_test(test_roll),        cmocka_unit_test(test_udp_unicast),
      cmocka_unit_test(test_udp_multicast),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
