/* Frame state and wall-eye report packing: round trips are bit-exact
 * (including -0.0, denormals and extreme values), the packed size is the
 * documented constant and the documented offsets hold, and corrupt buffers
 * (magic, version, length, NaN, counts) are rejected. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <float.h>
#include <math.h>
#include <string.h>

#include "service/framestate.h"
#include "test_service.h"

/* A state with every field distinct and awkward values in the doubles. */
static void fill_state(cv_frame_state *s) {
  memset(s, 0, sizeof *s);
  s->frame = 0xA1B2C3D4u;
  s->flags = CV_FS_WRITE | CV_FS_NEW_LIGHT;
  s->time = 12.3456789012345;
  s->dt = 1.0 / 60.0;
  for (int k = 0; k < 3; k++) {
    s->head[k] = 0.1 * (k + 1) - 0.2;
    s->gaze[k] = (k == 2) ? -1.0 : 0.0;
  }
  s->gaze[0] = -0.0; /* sign of zero must survive */
  s->tracker_age = DBL_MIN / 4; /* denormal */
  s->drive.t = 7.25;
  s->drive.yaw_deg = 359.999;
  s->drive.pitch_deg = -DBL_MAX;
  s->drive.roll_deg = 4.9406564584124654e-324; /* smallest denormal */
  s->drive.n_maps = 3;
  for (int i = 0; i < CV_MAX_ENV_MAPS; i++) s->drive.weights[i] = i < 3 ? 1.0 / 3.0 : 0.0;
  s->drive.is_sky = 0;
  s->drive.turbidity = 0;
  s->light_key = 0xFEDCBA9876543210ull;
  s->bands = 8;
  for (int i = 0; i < 3 * 64; i++) s->sh[i] = sin(0.37 * i) * pow(10.0, (i % 9) - 4);
  s->has_sun = 1;
  s->sun_dir[0] = 0.6;
  s->sun_dir[1] = 0.8;
  s->sun_dir[2] = -0.0;
  s->sun_E[0] = 1e5;
  s->sun_E[1] = 9.5e4;
  s->sun_E[2] = 8e4;
  s->lwa = 1234.5;
  s->lwmax = DBL_MAX;
  for (int i = 0; i < 6; i++) s->adapt[i] = 1.0 + i * 0.125;
  s->lcd_key = 42;
  s->lcd_rounds = 0xFFFFFFFFu;
  s->has_eyes = 1;
  for (int i = 0; i < 6; i++) s->eyes[i / 3][i % 3] = -0.032 + 0.01 * i;
  s->lcd_dead = 0x8000000000000005ull;
  s->lcd_dead_floor = 0xA1B2C3D4u;
}

/* Bitwise equality of two states field by field (struct padding differs). */
static void assert_same_bits(const double *a, const double *b, int n) {
  for (int i = 0; i < n; i++) assert_memory_equal(&a[i], &b[i], sizeof(double));
}

static void assert_states_equal(const cv_frame_state *a, const cv_frame_state *b) {
  assert_int_equal(a->frame, b->frame);
  assert_int_equal(a->flags, b->flags);
  assert_same_bits(&a->time, &b->time, 1);
  assert_same_bits(&a->dt, &b->dt, 1);
  assert_same_bits(a->head, b->head, 3);
  assert_same_bits(a->gaze, b->gaze, 3);
  assert_same_bits(&a->tracker_age, &b->tracker_age, 1);
  assert_same_bits(&a->drive.t, &b->drive.t, 1);
  assert_same_bits(&a->drive.yaw_deg, &b->drive.yaw_deg, 1);
  assert_same_bits(&a->drive.pitch_deg, &b->drive.pitch_deg, 1);
  assert_same_bits(&a->drive.roll_deg, &b->drive.roll_deg, 1);
  assert_int_equal(a->drive.n_maps, b->drive.n_maps);
  assert_same_bits(a->drive.weights, b->drive.weights, CV_MAX_ENV_MAPS);
  assert_int_equal(a->drive.is_sky, b->drive.is_sky);
  assert_same_bits(&a->drive.turbidity, &b->drive.turbidity, 1);
  assert_same_bits(&a->drive.sun_elevation_deg, &b->drive.sun_elevation_deg, 1);
  assert_same_bits(&a->drive.sun_azimuth_deg, &b->drive.sun_azimuth_deg, 1);
  assert_true(a->light_key == b->light_key);
  assert_int_equal(a->bands, b->bands);
  assert_same_bits(a->sh, b->sh, 3 * 64);
  assert_int_equal(a->has_sun, b->has_sun);
  assert_same_bits(a->sun_dir, b->sun_dir, 3);
  assert_same_bits(a->sun_E, b->sun_E, 3);
  assert_same_bits(&a->lwa, &b->lwa, 1);
  assert_same_bits(&a->lwmax, &b->lwmax, 1);
  assert_same_bits(a->adapt, b->adapt, 6);
  assert_true(a->lcd_key == b->lcd_key);
  assert_int_equal(a->lcd_rounds, b->lcd_rounds);
  assert_int_equal(a->has_eyes, b->has_eyes);
  assert_same_bits(&a->eyes[0][0], &b->eyes[0][0], 6);
  assert_true(a->lcd_dead == b->lcd_dead);
  assert_int_equal(a->lcd_dead_floor, b->lcd_dead_floor);
}

static void test_size_constants(void **state) {
  (void)state;
  assert_int_equal(CV_DRIVE_STATE_BYTES, 128);
  assert_int_equal(CV_FRAME_STATE_BYTES, 1956);
  assert_int_equal(CV_WALLEYE_REPORT_BYTES, 224);
}

static void test_round_trip_bit_exact(void **state) {
  (void)state;
  cv_frame_state s, u;
  fill_state(&s);
  uint8_t buf[CV_FRAME_STATE_BYTES + 16];
  memset(buf, 0xEE, sizeof buf);
  assert_int_equal(cv_frame_state_pack(&s, buf), CV_OK);
  for (int i = CV_FRAME_STATE_BYTES; i < (int)sizeof buf; i++) assert_int_equal(buf[i], 0xEE);
  cv_err err;
  memset(&u, 0x55, sizeof u);
  assert_int_equal(cv_frame_state_unpack(buf, CV_FRAME_STATE_BYTES, &u, &err), CV_OK);
  assert_states_equal(&s, &u);
  assert_true(signbit(u.gaze[0]) && u.gaze[0] == 0.0);
  assert_true(fpclassify(u.tracker_age) == FP_SUBNORMAL);
  assert_true(fpclassify(u.drive.roll_deg) == FP_SUBNORMAL);
  /* Repacking the unpacked state gives the same bytes. */
  uint8_t buf2[CV_FRAME_STATE_BYTES];
  assert_int_equal(cv_frame_state_pack(&u, buf2), CV_OK);
  assert_memory_equal(buf, buf2, CV_FRAME_STATE_BYTES);
}

/* The documented offsets, read back as little-endian bytes, independently of
 * the unpacker. */
static uint64_t le64(const uint8_t *p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; i--) v = (v << 8) | p[i];
  return v;
}
static double led(const uint8_t *p) {
  uint64_t b = le64(p);
  double d;
  memcpy(&d, &b, 8);
  return d;
}

static void test_layout_little_endian(void **state) {
  (void)state;
  cv_frame_state s;
  fill_state(&s);
  uint8_t b[CV_FRAME_STATE_BYTES];
  assert_int_equal(cv_frame_state_pack(&s, b), CV_OK);
  assert_memory_equal(b, "CVFS", 4);
  assert_int_equal(b[4], 3);
  assert_int_equal(b[8], 0xD4); /* frame 0xA1B2C3D4, low byte first */
  assert_int_equal(b[11], 0xA1);
  assert_true(led(b + 16) == s.time);
  assert_true(led(b + 88) == s.drive.t);
  assert_true(led(b + 88 + 36) == s.drive.weights[0]);
  assert_true(le64(b + 216) == s.light_key);
  assert_int_equal(b[224], 8);
  assert_true(led(b + 228 + 8 * 5) == s.sh[5]);
  assert_int_equal(b[1764], 1);
  assert_true(led(b + 1768) == 0.6);
  assert_true(led(b + 1816) == s.lwa);
  assert_true(led(b + 1832 + 8 * 5) == s.adapt[5]);
  assert_true(le64(b + 1880) == 42);
  assert_int_equal(b[1888] & b[1889] & b[1890] & b[1891], 0xFF);
  assert_int_equal(b[1892], 1); /* has_eyes */
  assert_true(led(b + 1896) == s.eyes[0][0]);
  assert_true(led(b + 1896 + 8 * 5) == s.eyes[1][2]);
  assert_true(le64(b + 1944) == 0x8000000000000005ull); /* lcd_dead */
  assert_int_equal(b[1952], 0xD4);                      /* lcd_dead_floor, low byte first */
}

static void test_pack_rejects_nonfinite(void **state) {
  (void)state;
  cv_frame_state s;
  uint8_t buf[CV_FRAME_STATE_BYTES];
  fill_state(&s);
  s.sh[100] = NAN;
  assert_int_equal(cv_frame_state_pack(&s, buf), CV_ERR_NONFINITE);
  fill_state(&s);
  s.lwmax = INFINITY;
  assert_int_equal(cv_frame_state_pack(&s, buf), CV_ERR_NONFINITE);
  fill_state(&s);
  s.bands = 9;
  assert_int_equal(cv_frame_state_pack(&s, buf), CV_ERR_RANGE);
  fill_state(&s);
  s.drive.n_maps = CV_MAX_ENV_MAPS + 1;
  assert_int_equal(cv_frame_state_pack(&s, buf), CV_ERR_RANGE);
}

/* Writes the bits of d little-endian at p. */
static void poke_double(uint8_t *p, double d) {
  uint64_t b;
  memcpy(&b, &d, 8);
  for (int i = 0; i < 8; i++) p[i] = (uint8_t)(b >> (8 * i));
}

static void test_unpack_rejects_corruption(void **state) {
  (void)state;
  cv_frame_state s, u;
  fill_state(&s);
  uint8_t good[CV_FRAME_STATE_BYTES], b[CV_FRAME_STATE_BYTES + 1];
  assert_int_equal(cv_frame_state_pack(&s, good), CV_OK);
  cv_err err;
  int rejected = 0;

  memcpy(b, good, sizeof good);
  b[0] ^= 1; /* magic */
  assert_int_equal(cv_frame_state_unpack(b, CV_FRAME_STATE_BYTES, &u, &err), CV_ERR_FORMAT);
  assert_non_null(strstr(err.msg, "magic"));
  rejected++;

  memcpy(b, good, sizeof good);
  b[4] = 1; /* version */
  assert_int_equal(cv_frame_state_unpack(b, CV_FRAME_STATE_BYTES, &u, &err), CV_ERR_FORMAT);
  assert_non_null(strstr(err.msg, "version"));
  rejected++;

  memcpy(b, good, sizeof good);
  b[1892] = 2; /* has_eyes */
  assert_int_equal(cv_frame_state_unpack(b, CV_FRAME_STATE_BYTES, &u, &err), CV_ERR_FORMAT);
  assert_non_null(strstr(err.msg, "has_eyes"));

  memcpy(b, good, sizeof good); /* lengths: short, long, zero */
  assert_int_equal(cv_frame_state_unpack(b, CV_FRAME_STATE_BYTES - 1, &u, &err), CV_ERR_FORMAT);
  assert_int_equal(cv_frame_state_unpack(b, CV_FRAME_STATE_BYTES + 1, &u, &err), CV_ERR_FORMAT);
  assert_int_equal(cv_frame_state_unpack(b, 0, &u, &err), CV_ERR_FORMAT);
  assert_non_null(strstr(err.msg, "1956"));
  rejected += 3;

  memcpy(b, good, sizeof good);
  poke_double(b + 228 + 8 * 17, NAN); /* sh[17] */
  assert_int_equal(cv_frame_state_unpack(b, CV_FRAME_STATE_BYTES, &u, &err), CV_ERR_NONFINITE);
  assert_non_null(strstr(err.msg, "sh[17]"));
  rejected++;

  memcpy(b, good, sizeof good);
  poke_double(b + 1824, -INFINITY); /* lwmax */
  assert_int_equal(cv_frame_state_unpack(b, CV_FRAME_STATE_BYTES, &u, &err), CV_ERR_NONFINITE);
  assert_non_null(strstr(err.msg, "lwmax"));
  rejected++;

  memcpy(b, good, sizeof good);
  b[224] = 9; /* bands */
  assert_int_equal(cv_frame_state_unpack(b, CV_FRAME_STATE_BYTES, &u, &err), CV_ERR_FORMAT);
  rejected++;

  memcpy(b, good, sizeof good);
  b[12] |= 0x80; /* unknown flag */
  assert_int_equal(cv_frame_state_unpack(b, CV_FRAME_STATE_BYTES, &u, &err), CV_ERR_FORMAT);
  rejected++;

  /* Failed unpacks leave *out untouched. */
  memset(&u, 0x5A, sizeof u);
  cv_frame_state before = u;
  memcpy(b, good, sizeof good);
  b[3] = 0;
  assert_int_not_equal(cv_frame_state_unpack(b, CV_FRAME_STATE_BYTES, &u, NULL), CV_OK);
  assert_memory_equal(&u, &before, sizeof u);
  assert_int_equal(rejected, 9);

  /* Every single-byte flip of the magic/version header is caught. */
  for (int i = 0; i < 8; i++)
    for (int bit = 0; bit < 8; bit++) {
      memcpy(b, good, sizeof good);
      b[i] ^= (uint8_t)(1u << bit);
      assert_int_equal(cv_frame_state_unpack(b, CV_FRAME_STATE_BYTES, &u, NULL), CV_ERR_FORMAT);
    }
}

static void fill_report(cv_walleye_report *r) {
  memset(r, 0, sizeof *r);
  r->frame = 77;
  r->rank = 9;
  r->wall = 4;
  r->eye = -1;
  r->sum_log = -1234.5678;
  r->weight = 0.0123;
  r->max_l = 5e4;
  r->n_pixels = 1ull << 40;
  r->n_invalid = 3;
  r->ms_lum = 0.25;
  r->ms_depth = -0.0;
  r->ms_shade = DBL_MIN / 8;
  r->ms_read = 1.5;
  r->ms_total = 33.3;
  r->ms_lcd = 0;
  r->lcd_rounds_done = 123456789012ull;
  r->state_hash = 0xfedcba9876543210ull;
  r->swap_frame = 76;
  r->swap_t = 12345.678901234;
  r->ms_present = 2.5;
  r->ms_barrier = 0.125;
  r->bytes_read = 68424;
  r->bytes_up = (1ull << 33) + 5;
  r->ms_cpu = 0.75;
  r->ms_gpu = -1;
  r->ms_corr_wait = 0.0625;
  r->corr_frame = 0xffffffffu;
  r->late_corr = 42;
  r->files_dropped = 7;
  r->files_failed = 1;
}

static void test_walleye_round_trip(void **state) {
  (void)state;
  cv_walleye_report r, u;
  fill_report(&r);
  uint8_t b[CV_WALLEYE_REPORT_BYTES];
  assert_int_equal(cv_walleye_report_pack(&r, b), CV_OK);
  assert_memory_equal(b, "CWER", 4);
  cv_err err;
  assert_int_equal(cv_walleye_report_unpack(b, sizeof b, &u, &err), CV_OK);
  assert_int_equal(u.frame, 77);
  assert_int_equal(u.rank, 9);
  assert_int_equal(u.wall, 4);
  assert_int_equal(u.eye, -1);
  assert_memory_equal(&u.sum_log, &r.sum_log, 8);
  assert_memory_equal(&u.weight, &r.weight, 8);
  assert_memory_equal(&u.max_l, &r.max_l, 8);
  assert_true(u.n_pixels == r.n_pixels && u.n_invalid == 3);
  assert_true(signbit(u.ms_depth));
  assert_true(fpclassify(u.ms_shade) == FP_SUBNORMAL);
  assert_memory_equal(&u.ms_shade, &r.ms_shade, 8);
  assert_memory_equal(&u.ms_total, &r.ms_total, 8);
  assert_true(u.lcd_rounds_done == r.lcd_rounds_done);
  assert_true(u.state_hash == r.state_hash);
  assert_int_equal(u.swap_frame, 76);
  assert_memory_equal(&u.swap_t, &r.swap_t, 8);
  assert_true(u.ms_present == 2.5 && u.ms_barrier == 0.125);
  assert_true(u.bytes_read == 68424 && u.bytes_up == (1ull << 33) + 5 && u.late_corr == 42);
  assert_true(u.files_dropped == 7 && u.files_failed == 1);
  assert_true(u.ms_cpu == 0.75 && u.ms_gpu == -1 && u.ms_corr_wait == 0.0625 && u.corr_frame == 0xffffffffu);

  r.max_l = NAN;
  assert_int_equal(cv_walleye_report_pack(&r, b), CV_ERR_NONFINITE);
  fill_report(&r);
  assert_int_equal(cv_walleye_report_pack(&r, b), CV_OK);
  assert_int_equal(cv_walleye_report_unpack(b, sizeof b - 1, &u, &err), CV_ERR_FORMAT);
  b[5] = 1; /* version 257 */
  assert_int_equal(cv_walleye_report_unpack(b, sizeof b, &u, &err), CV_ERR_FORMAT);
  b[5] = 0;
  poke_double(b + 24, INFINITY); /* sum_log */
  assert_int_equal(cv_walleye_report_unpack(b, sizeof b, &u, &err), CV_ERR_NONFINITE);
  assert_non_null(strstr(err.msg, "sum_log"));
  /* A frame state is not a report, and vice versa. */
  cv_frame_state s;
  fill_state(&s);
  uint8_t fb[CV_FRAME_STATE_BYTES];
  assert_int_equal(cv_frame_state_pack(&s, fb), CV_OK);
  assert_int_equal(cv_walleye_report_unpack(fb, CV_WALLEYE_REPORT_BYTES, &u, &err),
                   CV_ERR_FORMAT);
}

int run_framestate_tests(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_size_constants),
      cmocka_unit_test(test_round_trip_bit_exact),
      cmocka_unit_test(test_layout_little_endian),
      cmocka_unit_test(test_pack_rejects_nonfinite),
      cmocka_unit_test(test_unpack_rejects_corruption),
      cmocka_unit_test(test_walleye_round_trip),
  };
  return cmocka_run_group_tests_name("framestate", tests, NULL, NULL);
}
