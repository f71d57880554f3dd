/* The console's HTTP server on libmicrohttpd (http.h). */
#include "http/http.h"

#include <arpa/inet.h>
#include <errno.h>
#include <microhttpd.h>
#include <netinet/in.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#define BODY_MAX 4096 /* a control's form fields */
#define MAX_FIELDS 16

enum { SSE_FREE = 0, SSE_ACTIVE, SSE_SUSPENDED };

typedef struct sse {
  struct cv_http *h;
  struct MHD_Connection *conn;
  int state;
  int64_t last_frame;      /* samples up to this frame were sent */
  uint64_t last_version;
  double last_send;
  char *buf;               /* the event being sent */
  size_t n, off;
} sse;

struct cv_http {
  struct MHD_Daemon *d;
  int port;
  cv_console *con;
  cv_http_opts o;
  pthread_mutex_t mu;      /* sse slots, stopping */
  sse *ev;
  int stopping;
  pthread_t ticker;
  int ticker_on;
  _Atomic unsigned long long requests, unauthorized, refused;
};

typedef struct req {
  char body[BODY_MAX + 1];
  size_t n;
  int too_big;
  char *key[MAX_FIELDS], *val[MAX_FIELDS];
  int nf;
  struct MHD_Connection *conn;
} req;

static double mono(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The server's threads run at nice 10: on a busy host the frame loop's
 * ranks come first (setpriority on a thread id is per thread on Linux). */
static void lower_priority(void) {
  static __thread int done;
  if (done) return;
  done = 1;
  (void)setpriority(PRIO_PROCESS, (id_t)syscall(SYS_gettid), 10);
}

void cv_http_opts_default(cv_http_opts *o) {
  memset(o, 0, sizeof *o);
  snprintf(o->addr, sizeof o->addr, "127.0.0.1");
  o->port = CV_HTTP_DEFAULT_PORT;
  o->max_connections = 256;
  o->max_events = 8;
  o->timeout_s = 3;
  o->memory_limit = 32 * 1024;
}

int cv_http_parse_listen(const char *spec, char *addr, size_t cap, int *port, int *off, cv_err *err) {
  *off = 0;
  if (!strcmp(spec, "off")) {
    *off = 1;
    return CV_OK;
  }
  const char *colon = strrchr(spec, ':');
  const char *ps = colon ? colon + 1 : spec;
  char a[64] = "127.0.0.1";
  if (colon) {
    const size_t l = (size_t)(colon - spec);
    if (l == 0 || l >= sizeof a) return cv_err_set(err, CV_ERR_CONFIG, "--http: expected off, ADDR:PORT or PORT, got '%s'", spec);
    memcpy(a, spec, l);
    a[l] = 0;
  }
  struct in_addr ia;
  if (inet_pton(AF_INET, a, &ia) != 1)
    return cv_err_set(err, CV_ERR_CONFIG, "--http: '%s' is not an IPv4 address (expected a.b.c.d:PORT, off, or PORT)", a);
  char *end;
  errno = 0;
  const long p = strtol(ps, &end, 10);
  if (!*ps || *end || errno || p < 0 || p > 65535)
    return cv_err_set(err, CV_ERR_CONFIG, "--http: expected a TCP port 0..65535 (0: any free port) after the address, got '%s'", spec);
  snprintf(addr, cap, "%s", a);
  *port = (int)p;
  return CV_OK;
}

int cv_http_is_loopback(const char *addr) {
  struct in_addr ia;
  if (inet_pton(AF_INET, addr, &ia) != 1) return 0;
  return (ntohl(ia.s_addr) >> 24) == 127;
}

int cv_http_load_token(const char *path, char *token, size_t cap, cv_err *err) {
  FILE *f = fopen(path, "r");
  if (!f) return cv_err_set(err, CV_ERR_IO, "--http-token: %s: cannot open: %s", path, strerror(errno));
  char line[512] = "";
  if (!fgets(line, sizeof line, f)) line[0] = 0;
  fclose(f);
  char *s = line;
  while (*s == ' ' || *s == '\t') s++;
  size_t n = strlen(s);
  while (n && (s[n - 1] == '\n' || s[n - 1] == '\r' || s[n - 1] == ' ' || s[n - 1] == '\t')) s[--n] = 0;
  if (n < 16 || n >= cap || n > 255)
    return cv_err_set(err, CV_ERR_CONFIG, "--http-token: %s: expected a token of 16..255 characters on its first line, got %zu", path, n);
  for (size_t i = 0; i < n; i++)
    if (!strchr("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789._~+/=-", s[i]))
      return cv_err_set(err, CV_ERR_CONFIG, "--http-token: %s: character %zu is not one of A-Z a-z 0-9 . _ ~ + / = -", path, i + 1);
  snprintf(token, cap, "%s", s);
  return CV_OK;
}

/* ---- requests ------------------------------------------------------------------ */

static int hexval(char c) {
  return c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
}

/* Decodes %XX and '+' in place. */
static void url_decode(char *s) {
  char *o = s;
  for (; *s; s++) {
    if (*s == '+') *o++ = ' ';
    else if (*s == '%' && hexval(s[1]) >= 0 && hexval(s[2]) >= 0) {
      *o++ = (char)(hexval(s[1]) * 16 + hexval(s[2]));
      s += 2;
    } else *o++ = *s;
  }
  *o = 0;
}

/* The body's form fields (application/x-www-form-urlencoded). */
static void parse_form(req *r) {
  r->body[r->n] = 0;
  char *save = NULL;
  for (char *p = strtok_r(r->body, "&", &save); p && r->nf < MAX_FIELDS; p = strtok_r(NULL, "&", &save)) {
    char *eq = strchr(p, '=');
    if (!eq) continue;
    *eq = 0;
    url_decode(p);
    url_decode(eq + 1);
    r->key[r->nf] = p;
    r->val[r->nf++] = eq + 1;
  }
}

/* A field: the body's, else the query string's. */
static const char *field(void *ctx, const char *name) {
  req *r = ctx;
  for (int i = 0; i < r->nf; i++)
    if (!strcmp(r->key[i], name)) return r->val[i];
  return MHD_lookup_connection_value(r->conn, MHD_GET_ARGUMENT_KIND, name);
}

/* Constant-time comparison of a presented token with ours. */
static int token_ok(const cv_http *h, struct MHD_Connection *c) {
  if (!h->o.token[0]) return 1;
  const char *t = MHD_lookup_connection_value(c, MHD_GET_ARGUMENT_KIND, "token");
  const char *auth = MHD_lookup_connection_value(c, MHD_HEADER_KIND, MHD_HTTP_HEADER_AUTHORIZATION);
  if (auth && !strncmp(auth, "Bearer ", 7)) t = auth + 7;
  if (!t) return 0;
  const size_t n = strlen(h->o.token), m = strlen(t);
  unsigned char d = n != m;
  for (size_t i = 0; i < n; i++) d |= (unsigned char)(h->o.token[i] ^ (i < m ? t[i] : 0));
  return d == 0;
}

static enum MHD_Result reply(struct MHD_Connection *c, unsigned code, const char *type, void *data, size_t n,
                             enum MHD_ResponseMemoryMode mode) {
  struct MHD_Response *rs = MHD_create_response_from_buffer(n, data, mode);
  if (!rs) {
    if (mode == MHD_RESPMEM_MUST_FREE) free(data);
    return MHD_NO;
  }
  MHD_add_response_header(rs, MHD_HTTP_HEADER_CONTENT_TYPE, type);
  MHD_add_response_header(rs, MHD_HTTP_HEADER_CACHE_CONTROL, "no-store");
  if (code == MHD_HTTP_UNAUTHORIZED) MHD_add_response_header(rs, MHD_HTTP_HEADER_WWW_AUTHENTICATE, "Bearer realm=\"cave\"");
  const enum MHD_Result ret = MHD_queue_response(c, code, rs);
  MHD_destroy_response(rs);
  return ret;
}

static enum MHD_Result reply_text(cv_http *h, struct MHD_Connection *c, unsigned code, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static enum MHD_Result reply_text(cv_http *h, struct MHD_Connection *c, unsigned code, const char *fmt, ...) {
  char *msg = malloc(512);
  if (!msg) return MHD_NO;
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, 511, fmt, ap);
  va_end(ap);
  strcat(msg, "\n");
  if (code == MHD_HTTP_UNAUTHORIZED) h->unauthorized++;
  else if (code >= 400 && code != MHD_HTTP_NOT_FOUND) h->refused++;
  return reply(c, code, "text/plain; charset=utf-8", msg, strlen(msg), MHD_RESPMEM_MUST_FREE);
}

static enum MHD_Result get_state(cv_http *h, struct MHD_Connection *c, int metrics) {
  cv_console_state *st = malloc(sizeof *st);
  cv_console_sample *ring = metrics ? NULL : malloc(CV_CONSOLE_RING * sizeof *ring);
  size_t n = 0;
  char *txt = NULL;
  size_t len = 0;
  int rc = CV_ERR_NOMEM;
  if (st && (metrics || ring)) {
    cv_console_read(h->con, st, ring, ring ? CV_CONSOLE_RING : 0, &n, NULL);
    if (metrics) rc = cv_console_prometheus(st, &txt, &len);
    else {
      const char *since = MHD_lookup_connection_value(c, MHD_GET_ARGUMENT_KIND, "since");
      rc = cv_console_json(st, ring, n, since ? strtoll(since, NULL, 10) : -1, &txt, &len);
    }
  }
  free(st);
  free(ring);
  if (rc) return reply_text(h, c, MHD_HTTP_INTERNAL_SERVER_ERROR, "out of memory");
  return reply(c, MHD_HTTP_OK, metrics ? "text/plain; version=0.0.4; charset=utf-8" : "application/json", txt, len,
               MHD_RESPMEM_MUST_FREE);
}

static enum MHD_Result get_image(cv_http *h, struct MHD_Connection *c, const char *name) {
  for (int i = 0; i < CV_IMG_COUNT; i++) {
    char want[64];
    snprintf(want, sizeof want, "%s.png", cv_console_image_names[i]);
    if (strcmp(name, want)) continue;
    uint8_t *png;
    size_t n;
    uint32_t frame;
    cv_err err;
    if (cv_console_image_png(h->con, i, &png, &n, &frame, &err))
      return reply_text(h, c, MHD_HTTP_NOT_FOUND, "%s", err.msg);
    return reply(c, MHD_HTTP_OK, "image/png", png, n, MHD_RESPMEM_MUST_FREE);
  }
  return reply_text(h, c, MHD_HTTP_NOT_FOUND, "no image '%.60s' (projector, uncompensated, viewer, heatmap)", name);
}

static enum MHD_Result post_control(cv_http *h, struct MHD_Connection *c, req *r) {
  if (r->too_big) return reply_text(h, c, 413, "control: the body is over %d bytes", BODY_MAX);
  parse_form(r);
  cv_console_ctl ctl;
  cv_err err;
  if (cv_console_parse_control(field, r, &ctl, &err)) return reply_text(h, c, MHD_HTTP_BAD_REQUEST, "control: %s", err.msg);
  char txt[200];
  cv_console_ctl_text(&ctl, txt, sizeof txt);
  if (cv_console_push(h->con, &ctl))
    return reply_text(h, c, MHD_HTTP_SERVICE_UNAVAILABLE, "control: %d controls wait for the master already", CV_CONSOLE_QUEUE);
  return reply_text(h, c, MHD_HTTP_OK, "queued: %s (the master applies it at the start of its next frame)", txt);
}

/* ---- server-sent events -------------------------------------------------------- */

/* The next event of a stream into e->buf: the state and the samples since
 * the last event.  0 when made. */
static int sse_make(sse *e) {
  cv_console_state *st = malloc(sizeof *st);
  cv_console_sample *ring = malloc(CV_CONSOLE_RING * sizeof *ring);
  size_t n = 0;
  uint64_t ver = 0;
  char *txt = NULL;
  size_t len = 0;
  int rc = -1;
  if (st && ring) {
    cv_console_read(e->h->con, st, ring, CV_CONSOLE_RING, &n, &ver);
    rc = cv_console_json(st, ring, n, e->last_frame, &txt, &len);
  }
  if (!rc) {
    free(e->buf);
    e->buf = malloc(len + 16);
    if (e->buf) {
      e->n = (size_t)snprintf(e->buf, len + 16, "data: %s\n\n", txt);
      e->off = 0;
      e->last_version = ver;
      if (n) e->last_frame = ring[n - 1].frame;
    }
    rc = e->buf ? 0 : -1;
  }
  free(txt);
  free(st);
  free(ring);
  return rc;
}

static ssize_t sse_read(void *cls, uint64_t pos, char *buf, size_t max) {
  (void)pos;
  sse *e = cls;
  cv_http *h = e->h;
  if (e->off >= e->n) {
    const double now = mono();
    const uint64_t v = cv_console_version(h->con);
    if (v != e->last_version && now - e->last_send >= 0.25) {
      if (sse_make(e)) return MHD_CONTENT_READER_END_WITH_ERROR;
      e->last_send = now;
    } else if (now - e->last_send >= 15) { /* keeps proxies from closing an idle stream */
      free(e->buf);
      e->buf = strdup(": idle\n\n");
      e->n = e->buf ? strlen(e->buf) : 0;
      e->off = 0;
      e->last_send = now;
    }
  }
  if (e->off < e->n) {
    const size_t k = e->n - e->off < max ? e->n - e->off : max;
    memcpy(buf, e->buf + e->off, k);
    e->off += k;
    return (ssize_t)k;
  }
  pthread_mutex_lock(&h->mu);
  if (h->stopping) {
    pthread_mutex_unlock(&h->mu);
    return MHD_CONTENT_READER_END_OF_STREAM;
  }
  e->state = SSE_SUSPENDED; /* the ticker resumes it when there is news */
  MHD_suspend_connection(e->conn);
  pthread_mutex_unlock(&h->mu);
  return 0;
}

static void sse_free(void *cls) {
  sse *e = cls;
  pthread_mutex_lock(&e->h->mu);
  free(e->buf);
  e->buf = NULL;
  e->n = e->off = 0;
  e->conn = NULL;
  e->state = SSE_FREE;
  pthread_mutex_unlock(&e->h->mu);
}

static void *ticker_main(void *p) {
  cv_http *h = p;
  lower_priority();
  for (;;) {
    struct timespec ts = {0, 100 * 1000 * 1000};
    nanosleep(&ts, NULL);
    const uint64_t v = cv_console_version(h->con);
    const double now = mono();
    pthread_mutex_lock(&h->mu);
    const int stop = h->stopping;
    for (int i = 0; i < h->o.max_events; i++) {
      sse *e = &h->ev[i];
      if (e->state != SSE_SUSPENDED) continue;
      if (stop || (v != e->last_version && now - e->last_send >= 0.25) || now - e->last_send >= 15) {
        e->state = SSE_ACTIVE;
        MHD_resume_connection(e->conn);
      }
    }
    pthread_mutex_unlock(&h->mu);
    if (stop) return NULL;
  }
}

static enum MHD_Result get_events(cv_http *h, struct MHD_Connection *c) {
  sse *e = NULL;
  pthread_mutex_lock(&h->mu);
  for (int i = 0; i < h->o.max_events && !e; i++)
    if (h->ev[i].state == SSE_FREE) e = &h->ev[i];
  if (e) {
    e->state = SSE_ACTIVE;
    e->conn = c;
    e->last_frame = -1;
    e->last_version = 0;
    e->last_send = 0;
    e->n = e->off = 0;
  }
  pthread_mutex_unlock(&h->mu);
  if (!e) return reply_text(h, c, MHD_HTTP_SERVICE_UNAVAILABLE, "events: %d streams are open already", h->o.max_events);
  struct MHD_Response *rs = MHD_create_response_from_callback(MHD_SIZE_UNKNOWN, 32 * 1024, sse_read, e, sse_free);
  if (!rs) {
    sse_free(e);
    return MHD_NO;
  }
  MHD_add_response_header(rs, MHD_HTTP_HEADER_CONTENT_TYPE, "text/event-stream");
  MHD_add_response_header(rs, MHD_HTTP_HEADER_CACHE_CONTROL, "no-store");
  const enum MHD_Result ret = MHD_queue_response(c, MHD_HTTP_OK, rs);
  MHD_destroy_response(rs);
  return ret;
}

/* ---- dispatch ------------------------------------------------------------------- */

static enum MHD_Result route(cv_http *h, struct MHD_Connection *c, const char *url, int post, req *r) {
  h->requests++;
  if (post) {
    if (!strcmp(url, "/control")) return post_control(h, c, r);
    return reply_text(h, c, MHD_HTTP_METHOD_NOT_ALLOWED, "POST only to /control");
  }
  if (!strcmp(url, "/") || !strcmp(url, "/index.html"))
    return reply(c, MHD_HTTP_OK, "text/html; charset=utf-8", (void *)cv_console_page, cv_console_page_len,
                 MHD_RESPMEM_PERSISTENT);
  if (!strcmp(url, "/state.json")) return get_state(h, c, 0);
  if (!strcmp(url, "/metrics")) return get_state(h, c, 1);
  if (!strcmp(url, "/events")) return get_events(h, c);
  if (!strncmp(url, "/image/", 7)) return get_image(h, c, url + 7);
  if (!strcmp(url, "/control")) return reply_text(h, c, MHD_HTTP_METHOD_NOT_ALLOWED, "/control takes POST");
  return reply_text(h, c, MHD_HTTP_NOT_FOUND, "no such page: / /state.json /events /metrics /image/NAME.png /control");
}

static enum MHD_Result on_request(void *cls, struct MHD_Connection *c, const char *url, const char *method,
                                  const char *version, const char *upload_data, size_t *upload_data_size,
                                  void **con_cls) {
  (void)version;
  cv_http *h = cls;
  req *r = *con_cls;
  const int get = !strcmp(method, MHD_HTTP_METHOD_GET) || !strcmp(method, MHD_HTTP_METHOD_HEAD);
  const int post = !strcmp(method, MHD_HTTP_METHOD_POST);
  if (!r) {
    lower_priority();
    if (!(r = calloc(1, sizeof *r))) return MHD_NO;
    r->conn = c;
    *con_cls = r;
    if (!get && !post) return reply_text(h, c, MHD_HTTP_METHOD_NOT_ALLOWED, "method %.20s: GET or POST only", method);
    if (!token_ok(h, c)) return reply_text(h, c, MHD_HTTP_UNAUTHORIZED, "a token is required (--http-token)");
    if (post) return MHD_YES; /* the body comes next */
    return route(h, c, url, 0, r);
  }
  if (*upload_data_size) {
    if (r->n + *upload_data_size > BODY_MAX) r->too_big = 1;
    else {
      memcpy(r->body + r->n, upload_data, *upload_data_size);
      r->n += *upload_data_size;
    }
    *upload_data_size = 0;
    return MHD_YES;
  }
  return route(h, c, url, post, r);
}

static void on_completed(void *cls, struct MHD_Connection *c, void **con_cls, enum MHD_RequestTerminationCode t) {
  (void)cls, (void)c, (void)t;
  free(*con_cls);
  *con_cls = NULL;
}

/* The listening socket, bound here so that a port in use is named. */
static int listen_socket(const cv_http_opts *o, int *fd_out, int *port, cv_err *err) {
  const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return cv_err_set(err, CV_ERR_IO, "--http: socket: %s", strerror(errno));
  const int one = 1;
  setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one); /* TIME_WAIT only: a live listener still refuses */
  struct sockaddr_in sa;
  memset(&sa, 0, sizeof sa);
  sa.sin_family = AF_INET;
  sa.sin_port = htons((uint16_t)o->port);
  inet_pton(AF_INET, o->addr, &sa.sin_addr);
  if (bind(fd, (struct sockaddr *)&sa, sizeof sa) || listen(fd, 128)) {
    const int e = errno;
    close(fd);
    return cv_err_set(err, CV_ERR_IO, "--http %s:%d: cannot listen: %s%s", o->addr, o->port, strerror(e),
                      e == EADDRINUSE ? " (another cave run? give --http ADDR:PORT with a free port, :0 for any, or --http off)" : "");
  }
  socklen_t sl = sizeof sa;
  getsockname(fd, (struct sockaddr *)&sa, &sl);
  *port = ntohs(sa.sin_port);
  *fd_out = fd;
  return CV_OK;
}

int cv_http_start(const cv_http_opts *o, cv_console *console, cv_http **out, cv_err *err) {
  *out = NULL;
  cv_http *h = calloc(1, sizeof *h);
  if (!h || !(h->ev = calloc((size_t)(o->max_events > 0 ? o->max_events : 1), sizeof *h->ev))) {
    free(h);
    return cv_err_set(err, CV_ERR_NOMEM, "--http: out of memory");
  }
  h->o = *o;
  h->con = console;
  pthread_mutex_init(&h->mu, NULL);
  for (int i = 0; i < o->max_events; i++) h->ev[i].h = h;
  int fd = -1, st = listen_socket(o, &fd, &h->port, err);
  if (st) {
    pthread_mutex_destroy(&h->mu);
    free(h->ev);
    free(h);
    return st;
  }
  h->d = MHD_start_daemon(MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_EPOLL | MHD_ALLOW_SUSPEND_RESUME, 0, NULL, NULL,
                          on_request, h, MHD_OPTION_LISTEN_SOCKET, fd, MHD_OPTION_CONNECTION_LIMIT,
                          (unsigned)o->max_connections, MHD_OPTION_CONNECTION_TIMEOUT, (unsigned)o->timeout_s,
                          MHD_OPTION_CONNECTION_MEMORY_LIMIT, o->memory_limit, MHD_OPTION_NOTIFY_COMPLETED,
                          on_completed, h, MHD_OPTION_END);
  if (!h->d) {
    close(fd);
    pthread_mutex_destroy(&h->mu);
    free(h->ev);
    free(h);
    return cv_err_set(err, CV_ERR_BACKEND, "--http %s:%d: libmicrohttpd did not start", o->addr, o->port);
  }
  if (pthread_create(&h->ticker, NULL, ticker_main, h) == 0) h->ticker_on = 1;
  *out = h;
  return CV_OK;
}

int cv_http_port(const cv_http *h) { return h ? h->port : 0; }

void cv_http_counts(const cv_http *h, unsigned long long *requests, unsigned long long *unauthorized,
                    unsigned long long *refused) {
  *requests = h ? h->requests : 0;
  *unauthorized = h ? h->unauthorized : 0;
  *refused = h ? h->refused : 0;
}

void cv_http_stop(cv_http *h) {
  if (!h) return;
  pthread_mutex_lock(&h->mu);
  h->stopping = 1;
  for (int i = 0; i < h->o.max_events; i++) /* suspended streams must be resumed before the stop */
    if (h->ev[i].state == SSE_SUSPENDED) {
      h->ev[i].state = SSE_ACTIVE;
      MHD_resume_connection(h->ev[i].conn);
    }
  pthread_mutex_unlock(&h->mu);
  if (h->ticker_on) pthread_join(h->ticker, NULL);
  MHD_stop_daemon(h->d);
  pthread_mutex_destroy(&h->mu);
  free(h->ev);
  free(h);
}
