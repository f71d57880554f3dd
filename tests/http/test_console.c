/* The live console without MPI (issue 33): the state rendered as Prometheus
 * text and JSON, the sample ring, the controls, the images as PNG, and the
 * HTTP server on loopback (real sockets): token (401), methods (405), an
 * oversized header refused, a control queued, an event stream, a port in
 * use named. */
#include <arpa/inet.h>
#include <cjson/cJSON.h>
#include <math.h>
#include <netinet/in.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cmocka.h>

#include "http/http.h"
#include "io/png.h"
#include "service/console.h"

static void fill_state(cv_console_state *st) {
  memset(st, 0, sizeof *st);
  snprintf(st->master_host, sizeof st->master_host, "node0");
  snprintf(st->url, sizeof st->url, "http://127.0.0.1:8033/");
  snprintf(st->clock, sizeof st->clock, "sim");
  st->lcd = 1;
  st->n_panels = 2;
  snprintf(st->panel_name[0], 32, "centre");
  snprintf(st->panel_name[1], 32, "cluster");
  st->cr[0] = 4.5;
  st->cr[1] = NAN;
  st->skew_us = NAN;
  st->mtp_ms = 25;
  st->n_ranks = 3;
  st->ranks[0] = (cv_console_rank){.rank = 0, .role = CV_ROLE_NAME_MASTER, .host = "node0"};
  st->ranks[1] = (cv_console_rank){.rank = 1, .role = CV_ROLE_NAME_WALLEYE, .host = "a\"b\\c", .view = "front L",
                                   .fps = 29.5, .late = 2, .dead = 1, .error = "declared dead"};
  st->ranks[2] = (cv_console_rank){.rank = 2, .role = CV_ROLE_NAME_GATHER, .host = "node2"};
  cv_console_hist_add(st, 0.004);
  cv_console_hist_add(st, 0.03);
  cv_console_hist_add(st, 3.0);
}

/* Every line a comment or `name{labels} value` with a number Prometheus reads. */
static void check_lines(const char *txt) {
  char *copy = strdup(txt), *save = NULL;
  int n = 0;
  for (char *l = strtok_r(copy, "\n", &save); l; l = strtok_r(NULL, "\n", &save), n++) {
    if (l[0] == '#') {
      assert_true(!strncmp(l, "# HELP cave_", 12) || !strncmp(l, "# TYPE cave_", 12));
      continue;
    }
    assert_true(!strncmp(l, "cave_", 5));
    const char *sp = strrchr(l, ' ');
    assert_non_null(sp);
    char *end;
    const double v = strtod(sp + 1, &end);
    assert_true(*end == 0 || !strcmp(sp + 1, "NaN") || !strcmp(sp + 1, "+Inf"));
    (void)v;
  }
  assert_true(n > 40);
  free(copy);
}

static void test_prometheus(void **state) {
  (void)state;
  cv_console_state *st = malloc(sizeof *st);
  fill_state(st);
  char *txt;
  size_t len;
  assert_int_equal(cv_console_prometheus(st, &txt, &len), CV_OK);
  assert_int_equal(strlen(txt), len);
  check_lines(txt);
  assert_non_null(strstr(txt, "\ncave_frames_total 3\n"));
  assert_non_null(strstr(txt, "# TYPE cave_frame_seconds histogram\n"));
  assert_non_null(strstr(txt, "cave_frame_seconds_bucket{le=\"0.005\"} 1\n"));
  assert_non_null(strstr(txt, "cave_frame_seconds_bucket{le=\"0.05\"} 2\n"));
  assert_non_null(strstr(txt, "cave_frame_seconds_bucket{le=\"+Inf\"} 3\n"));
  assert_non_null(strstr(txt, "cave_frame_seconds_count 3\n"));
  assert_non_null(strstr(txt, "cave_frame_seconds_sum 3.034\n"));
  /* label values escaped; a dead rank is down */
  assert_non_null(strstr(txt, "cave_rank_up{rank=\"1\",host=\"a\\\"b\\\\c\",role=\"wall-eye\"} 0\n"));
  assert_non_null(strstr(txt, "cave_rank_up{rank=\"2\",host=\"node2\",role=\"gather\"} 1\n"));
  assert_non_null(strstr(txt, "cave_rank_late_frames_total{rank=\"1\",host=\"a\\\"b\\\\c\",role=\"wall-eye\"} 2\n"));
  /* a panel without a figure is left out; no unmeasured skew */
  assert_non_null(strstr(txt, "cave_lcd_contrast_ratio{panel=\"centre\"} 4.5\n"));
  assert_null(strstr(txt, "panel=\"cluster\""));
  assert_null(strstr(txt, "cave_swap_skew_seconds"));
  assert_non_null(strstr(txt, "cave_motion_to_photon_seconds 0.025\n"));
  free(txt);
  free(st);
}

static void test_json(void **state) {
  (void)state;
  cv_console_state *st = malloc(sizeof *st);
  fill_state(st);
  cv_console_sample ring[5];
  for (int i = 0; i < 5; i++)
    ring[i] = (cv_console_sample){.frame = (uint32_t)(10 + i), .frame_s = 0.03, .master_s = 1e-4, .skew_s = NAN,
                                  .mtp_s = 0.02, .cr = {3.5, NAN}};
  char *txt;
  size_t len;
  assert_int_equal(cv_console_json(st, ring, 5, 12, &txt, &len), CV_OK);
  cJSON *root = cJSON_Parse(txt);
  assert_non_null(root);
  const cJSON *s = cJSON_GetObjectItem(root, "state"), *sm = cJSON_GetObjectItem(root, "samples");
  assert_string_equal(cJSON_GetObjectItem(s, "master_host")->valuestring, "node0");
  const cJSON *ranks = cJSON_GetObjectItem(s, "ranks");
  assert_int_equal(cJSON_GetArraySize(ranks), 3);
  assert_true(cJSON_IsTrue(cJSON_GetObjectItem(cJSON_GetArrayItem(ranks, 1), "dead")));
  assert_string_equal(cJSON_GetObjectItem(cJSON_GetArrayItem(ranks, 1), "host")->valuestring, "a\"b\\c");
  /* frames after 12 only; NaN as null */
  const cJSON *fr = cJSON_GetObjectItem(sm, "frame");
  assert_int_equal(cJSON_GetArraySize(fr), 2);
  assert_int_equal(cJSON_GetArrayItem(fr, 0)->valueint, 13);
  assert_true(cJSON_IsNull(cJSON_GetArrayItem(cJSON_GetObjectItem(sm, "skew_us"), 0)));
  assert_true(fabs(cJSON_GetArrayItem(cJSON_GetObjectItem(sm, "frame_ms"), 1)->valuedouble - 30) < 1e-9);
  const cJSON *cr = cJSON_GetObjectItem(sm, "cr");
  assert_int_equal(cJSON_GetArraySize(cr), 2);
  assert_true(cJSON_IsNull(cJSON_GetArrayItem(cJSON_GetArrayItem(cr, 1), 0)));
  cJSON_Delete(root);
  free(txt);
  free(st);
}

static void test_ring(void **state) {
  (void)state;
  cv_console *c;
  assert_int_equal(cv_console_create(&c), CV_OK);
  cv_console_state *st = malloc(sizeof *st), *rd = malloc(sizeof *rd);
  cv_console_sample *ring = malloc(CV_CONSOLE_RING * sizeof *ring);
  fill_state(st);
  for (uint32_t f = 0; f < 700; f++) {
    cv_console_sample smp = {.frame = f};
    st->frame = f;
    assert_int_equal(cv_console_publish(c, st, &smp), 1); /* nobody holds the lock */
  }
  size_t n;
  uint64_t ver;
  cv_console_read(c, rd, ring, CV_CONSOLE_RING, &n, &ver);
  assert_int_equal(n, CV_CONSOLE_RING);
  assert_int_equal(ring[0].frame, 700 - CV_CONSOLE_RING);
  assert_int_equal(ring[n - 1].frame, 699);
  assert_int_equal(ver, 700);
  assert_int_equal(rd->frame, 699);
  assert_int_equal(rd->n_ranks, 3);
  assert_string_equal(rd->ranks[2].host, "node2");
  free(st), free(rd), free(ring);
  cv_console_destroy(c);
}

typedef struct kv {
  const char *k[8], *v[8];
  int n;
} kv;

static const char *kv_get(void *ctx, const char *name) {
  kv *p = ctx;
  for (int i = 0; i < p->n; i++)
    if (!strcmp(p->k[i], name)) return p->v[i];
  return NULL;
}

static void test_controls(void **state) {
  (void)state;
  cv_console_ctl c;
  cv_err err;
  kv a = {{"action", "x", "y", "z", "gx", "gy", "gz"}, {"head", "0.1", "1.6", "-0.2", "0", "0", "-2"}, 7};
  assert_int_equal(cv_console_parse_control(kv_get, &a, &c, &err), CV_OK);
  assert_int_equal(c.kind, CV_CTL_HEAD);
  assert_int_equal(c.mask, 1);
  assert_true(fabs(c.v[5] + 1) < 1e-12); /* gaze normalised */
  kv b = {{"action", "x", "y"}, {"head", "0.1", "1.6"}, 3};
  assert_int_equal(cv_console_parse_control(kv_get, &b, &c, &err), CV_ERR_CONFIG);
  assert_non_null(strstr(err.msg, "z"));
  kv d = {{"action", "turbidity"}, {"sky", "11"}, 2};
  assert_int_equal(cv_console_parse_control(kv_get, &d, &c, &err), CV_ERR_RANGE);
  assert_non_null(strstr(err.msg, "turbidity"));
  kv e = {{"action", "elevation", "azimuth"}, {"sky", "20", "nan"}, 3};
  assert_int_equal(cv_console_parse_control(kv_get, &e, &c, &err), CV_ERR_RANGE);
  kv f = {{"action", "elevation"}, {"sky", "20"}, 2};
  assert_int_equal(cv_console_parse_control(kv_get, &f, &c, &err), CV_OK);
  assert_int_equal(c.mask, 1);
  kv g = {{"action"}, {"reboot"}, 1};
  assert_int_equal(cv_console_parse_control(kv_get, &g, &c, &err), CV_ERR_CONFIG);
  /* the queue holds CV_CONSOLE_QUEUE, then refuses */
  cv_console *q;
  assert_int_equal(cv_console_create(&q), CV_OK);
  cv_console_ctl p = {.kind = CV_CTL_PAUSE};
  for (int i = 0; i < CV_CONSOLE_QUEUE; i++) assert_int_equal(cv_console_push(q, &p), 0);
  assert_int_equal(cv_console_push(q, &p), -1);
  int n = 0;
  while (cv_console_take(q, &c)) n++;
  assert_int_equal(n, CV_CONSOLE_QUEUE);
  cv_console_destroy(q);
}

static void test_image_png(void **state) {
  (void)state;
  cv_console *c;
  assert_int_equal(cv_console_create(&c), CV_OK);
  uint8_t *png;
  size_t n;
  uint32_t frame;
  cv_err err;
  assert_int_equal(cv_console_image_png(c, CV_IMG_VIEWER, &png, &n, &frame, &err), CV_ERR_NOT_FOUND);
  uint8_t rgb[4 * 2 * 3];
  for (int i = 0; i < 24; i++) rgb[i] = (uint8_t)(10 * i);
  assert_int_equal(cv_console_set_image(c, CV_IMG_VIEWER, 7, 4, 2, rgb, 1), 0);
  assert_int_equal(cv_console_image_png(c, CV_IMG_VIEWER, &png, &n, &frame, &err), CV_OK);
  assert_int_equal(frame, 7);
  char path[512];
  snprintf(path, sizeof path, "%s/console_test.png", CV_TEST_TMP_DIR);
  FILE *f = fopen(path, "wb");
  assert_non_null(f);
  assert_int_equal(fwrite(png, 1, n, f), n);
  fclose(f);
  cv_image *img;
  assert_int_equal(cv_png_read(path, &img, &err), CV_OK);
  assert_int_equal(img->w, 4);
  assert_int_equal(img->h, 2);
  for (int i = 0; i < 24; i++) assert_int_equal((int)lroundf(img->px[i] * 255), 10 * i);
  cv_image_destroy(img);
  uint8_t *png2;
  size_t n2;
  assert_int_equal(cv_console_image_png(c, CV_IMG_VIEWER, &png2, &n2, &frame, &err), CV_OK); /* cached */
  assert_int_equal(n2, n);
  assert_memory_equal(png, png2, n);
  free(png), free(png2);
  remove(path);
  cv_console_destroy(c);
}

static void test_listen_parse(void **state) {
  (void)state;
  char a[64];
  int port, off;
  cv_err err;
  assert_int_equal(cv_http_parse_listen("off", a, sizeof a, &port, &off, &err), CV_OK);
  assert_int_equal(off, 1);
  assert_int_equal(cv_http_parse_listen("8040", a, sizeof a, &port, &off, &err), CV_OK);
  assert_string_equal(a, "127.0.0.1");
  assert_int_equal(port, 8040);
  assert_int_equal(cv_http_parse_listen("10.1.2.3:0", a, sizeof a, &port, &off, &err), CV_OK);
  assert_int_equal(port, 0);
  assert_false(cv_http_is_loopback(a));
  assert_true(cv_http_is_loopback("127.0.0.2"));
  assert_int_equal(cv_http_parse_listen("0.0.0.0:65536", a, sizeof a, &port, &off, &err), CV_ERR_CONFIG);
  assert_int_equal(cv_http_parse_listen("host:80", a, sizeof a, &port, &off, &err), CV_ERR_CONFIG);
  assert_non_null(strstr(err.msg, "IPv4"));
  assert_int_equal(cv_http_parse_listen(":80", a, sizeof a, &port, &off, &err), CV_ERR_CONFIG);
}

/* ---- the server on loopback --------------------------------------------------- */

/* Sends req to 127.0.0.1:port and reads the answer (at most cap - 1 bytes,
 * 3 s); returns the status code, 0 when the connection closed without one. */
static int http_raw(int port, const char *req, size_t req_len, char *out, size_t cap) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  assert_true(fd >= 0);
  struct timeval tv = {3, 0};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  struct sockaddr_in sa = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port)};
  inet_pton(AF_INET, "127.0.0.1", &sa.sin_addr);
  assert_int_equal(connect(fd, (struct sockaddr *)&sa, sizeof sa), 0);
  size_t sent = 0;
  while (sent < req_len) {
    const ssize_t w = send(fd, req + sent, req_len - sent, MSG_NOSIGNAL);
    if (w <= 0) break;
    sent += (size_t)w;
  }
  size_t n = 0;
  for (;;) {
    const ssize_t r = recv(fd, out + n, cap - 1 - n, 0);
    if (r <= 0) break;
    n += (size_t)r;
    if (n == cap - 1 || strstr(out, "\r\n\r\n")) { /* headers in: enough for events */
      out[n] = 0;
      if (!strstr(out, "text/event-stream") || strstr(out, "\n\ndata: {")) {
        const char *cl = strstr(out, "Content-Length: ");
        const char *body = strstr(out, "\r\n\r\n");
        if (!cl || (size_t)(out + n - body - 4) >= (size_t)atol(cl + 16)) break;
      }
    }
  }
  out[n] = 0;
  close(fd);
  int code = 0;
  if (sscanf(out, "HTTP/1.%*d %d", &code) != 1) code = 0;
  return code;
}

static int get(int port, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static char g_buf[1 << 16];
static int get(int port, const char *fmt, ...) {
  char req[2048];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(req, sizeof req, fmt, ap);
  va_end(ap);
  return http_raw(port, req, strlen(req), g_buf, sizeof g_buf);
}

#define TOKEN "test-token-0123456789abcdef"

static void test_server(void **state) {
  (void)state;
  cv_console *c;
  assert_int_equal(cv_console_create(&c), CV_OK);
  cv_console_state *st = malloc(sizeof *st);
  fill_state(st);
  cv_console_sample smp = {.frame = 1};
  cv_console_publish(c, st, &smp);
  cv_http_opts o;
  cv_http_opts_default(&o);
  o.port = 0;
  snprintf(o.token, sizeof o.token, TOKEN);
  cv_http *h;
  cv_err err;
  assert_int_equal(cv_http_start(&o, c, &h, &err), CV_OK);
  const int port = cv_http_port(h);
  assert_true(port > 0);
  assert_int_equal(get(port, "GET /metrics HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"), 401);
  assert_int_equal(get(port, "GET /metrics?token=wrong%s HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", TOKEN), 401);
  assert_int_equal(get(port, "GET /metrics?token=%s HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", TOKEN), 200);
  assert_non_null(strstr(g_buf, "text/plain; version=0.0.4"));
  assert_non_null(strstr(g_buf, "cave_frames_total 3"));
  assert_int_equal(get(port, "GET / HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer %s\r\nConnection: close\r\n\r\n", TOKEN), 200);
  assert_non_null(strstr(g_buf, "<canvas"));
  assert_int_equal(get(port, "BREW /metrics HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer %s\r\nConnection: close\r\n\r\n", TOKEN), 405);
  assert_int_equal(get(port, "GET /image/viewer.png HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer %s\r\nConnection: close\r\n\r\n", TOKEN), 404);
  /* a control: queued for the master */
  assert_int_equal(get(port, "POST /control HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer %s\r\nContent-Type: "
                             "application/x-www-form-urlencoded\r\nContent-Length: 12\r\nConnection: close\r\n\r\naction=pause", TOKEN), 200);
  cv_console_ctl ctl;
  assert_int_equal(cv_console_take(c, &ctl), 1);
  assert_int_equal(ctl.kind, CV_CTL_PAUSE);
  assert_int_equal(get(port, "POST /control HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer %s\r\nContent-Type: "
                             "application/x-www-form-urlencoded\r\nContent-Length: 13\r\nConnection: close\r\n\r\naction=reboot", TOKEN), 400);
  assert_int_equal(cv_console_take(c, &ctl), 0);
  /* a header over the connection's memory: refused, never a 200 */
  size_t big = 100 * 1024;
  char *req = malloc(big + 256);
  int k = snprintf(req, 256, "GET /metrics?token=%s HTTP/1.1\r\nHost: x\r\nX-Big: ", TOKEN);
  memset(req + k, 'a', big);
  memcpy(req + k + big, "\r\n\r\n", 5);
  const int code = http_raw(port, req, strlen(req), g_buf, sizeof g_buf);
  assert_true(code == 0 || code == 431 || code == 413 || code == 400);
  free(req);
  /* the event stream: the state after a publish */
  assert_int_equal(get(port, "GET /events?token=%s HTTP/1.1\r\nHost: x\r\n\r\n", TOKEN), 200);
  assert_non_null(strstr(g_buf, "text/event-stream"));
  assert_non_null(strstr(g_buf, "data: {\"state\":"));
  /* the same port again: named, no other port taken */
  cv_http *h2 = NULL;
  o.port = port;
  assert_int_equal(cv_http_start(&o, c, &h2, &err), CV_ERR_IO);
  assert_null(h2);
  assert_non_null(strstr(err.msg, "Address already in use"));
  unsigned long long nreq, unauth, refused;
  cv_http_counts(h, &nreq, &unauth, &refused);
  assert_int_equal(unauth, 2);
  cv_http_stop(h);
  cv_console_destroy(c);
  free(st);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_prometheus), cmocka_unit_test(test_json),         cmocka_unit_test(test_ring),
      cmocka_unit_test(test_controls),   cmocka_unit_test(test_image_png),    cmocka_unit_test(test_listen_parse),
      cmocka_unit_test(test_server),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
