/* Head tracking (tracker.h): recorded head paths, the DTrack ASCII parser,
 * a non-blocking UDP receiver (POSIX sockets) and the keyboard-and-mouse
 * head of the desktop preview. */
#define _POSIX_C_SOURCE 200809L
#include "service/tracker.h"

#include "io/textfile.h"

#include <arpa/inet.h>
#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <netinet/in.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

/* ======================= recorded head path ============================== */

typedef struct head_sample {
  double t, pos[3], gaze[3];
} head_sample;

struct cv_head_path {
  head_sample *s;
  int n;
};

#define HEAD_LINE_MAX 1024

/* Parses one line (already without its comment) into 7 numbers.  Returns
 * 0 for a blank line, 1 for a sample, or a negative status with err set. */
static int head_line(const char *line, const char *name, int lineno, double v[7], cv_err *err) {
  const char *p = line;
  while (*p && isspace((unsigned char)*p)) p++;
  if (!*p) return 0;
  for (int k = 0; k < 7; k++) {
    char *end;
    errno = 0;
    v[k] = strtod(p, &end);
    if (end == p)
      return cv_err_set(err, CV_ERR_FORMAT,
                        "%s:%d: expected 7 numbers \"t x y z gx gy gz\", found %d", name,
                        lineno, k);
    if (!isfinite(v[k]))
      return cv_err_set(err, CV_ERR_NONFINITE, "%s:%d: value %d is not finite", name, lineno,
                        k + 1);
    if (*end && !isspace((unsigned char)*end))
      return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: value %d is not a number", name, lineno,
                        k + 1);
    p = end;
  }
  while (*p && isspace((unsigned char)*p)) p++;
  if (*p)
    return cv_err_set(err, CV_ERR_FORMAT, "%s:%d: trailing text after 7 numbers", name,
                      lineno);
  return 1;
}

int cv_head_path_parse(const char *text, const char *name, cv_head_path **out, cv_err *err) {
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "head path: NULL output");
  *out = NULL;
  if (!name) name = "(head path)";
  if (!text) return cv_err_set(err, CV_ERR_INVALID, "%s: NULL text", name);
  cv_head_path *hp = calloc(1, sizeof *hp);
  if (!hp) return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", name);
  int cap = 0, lineno = 0, st = CV_OK;
  const char *p = text;
  while (*p) {
    lineno++;
    const char *e = p;
    while (*e && *e != '\n') e++;
    size_t n = (size_t)(e - p);
    const char *hash = memchr(p, '#', n);
    if (hash) n = (size_t)(hash - p);
    if (n >= HEAD_LINE_MAX) {
      st = cv_err_set(err, CV_ERR_FORMAT, "%s:%d: line longer than %d characters", name,
                      lineno, HEAD_LINE_MAX - 1);
      break;
    }
    char line[HEAD_LINE_MAX];
    memcpy(line, p, n);
    line[n] = '\0';
    p = *e ? e + 1 : e;
    double v[7];
    int r = head_line(line, name, lineno, v, err);
    if (r < 0) {
      st = r;
      break;
    }
    if (r == 0) continue;
    if (hp->n > 0 && !(v[0] > hp->s[hp->n - 1].t)) {
      st = cv_err_set(err, CV_ERR_RANGE, "%s:%d: t = %g is not after the previous %g", name,
                      lineno, v[0], hp->s[hp->n - 1].t);
      break;
    }
    double g = sqrt(v[4] * v[4] + v[5] * v[5] + v[6] * v[6]);
    if (!(g > 1e-12) || !isfinite(g)) {
      st = cv_err_set(err, CV_ERR_RANGE, "%s:%d: the gaze (%g, %g, %g) is zero", name, lineno,
                      v[4], v[5], v[6]);
      break;
    }
    if (hp->n == cap) {
      int nc = cap ? cap * 2 : 256;
      head_sample *ns = realloc(hp->s, (size_t)nc * sizeof *ns);
      if (!ns) {
        st = cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", name);
        break;
      }
      hp->s = ns;
      cap = nc;
    }
    head_sample *s = &hp->s[hp->n++];
    s->t = v[0];
    for (int k = 0; k < 3; k++) {
      s->pos[k] = v[1 + k];
      s->gaze[k] = v[4 + k] / g;
    }
  }
  if (!st && hp->n == 0) st = cv_err_set(err, CV_ERR_EMPTY, "%s: no samples", name);
  if (st) {
    cv_head_path_destroy(hp);
    return st;
  }
  *out = hp;
  return CV_OK;
}

int cv_head_path_load(const char *path, cv_head_path **out, cv_err *err) {
  if (out) *out = NULL;
  char *text;
  size_t len;
  int st = cv_read_text_file(path, &text, &len, err);
  if (st) return st;
  size_t nul = strlen(text);
  if (nul < len)
    st = cv_err_set(err, CV_ERR_FORMAT, "%s: NUL byte at offset %zu, expected a text file", path,
                    nul);
  else
    st = cv_head_path_parse(text, path, out, err);
  free(text);
  return st;
}

void cv_head_path_destroy(cv_head_path *p) {
  if (!p) return;
  free(p->s);
  free(p);
}

int cv_head_path_count(const cv_head_path *p) { return p->n; }

double cv_head_path_duration(const cv_head_path *p) { return p->s[p->n - 1].t - p->s[0].t; }

void cv_head_path_eval(const cv_head_path *p, double t, int loop, cv_head_pose *out) {
  const head_sample *s = p->s;
  int n = p->n;
  double t0 = s[0].t, t1 = s[n - 1].t, tt = isfinite(t) ? t : t0;
  if (loop && t1 > t0) {
    double d = t1 - t0, r = fmod(tt - t0, d);
    if (r < 0) r += d;
    tt = t0 + r;
  }
  out->t = t;
  out->valid = 1;
  if (n == 1 || tt <= t0 || tt >= t1) {
    const head_sample *e = (n == 1 || tt <= t0) ? &s[0] : &s[n - 1];
    memcpy(out->pos, e->pos, sizeof out->pos);
    memcpy(out->gaze, e->gaze, sizeof out->gaze);
    return;
  }
  int lo = 0, hi = n - 1; /* s[lo].t <= tt < s[hi].t */
  while (hi - lo > 1) {
    int mid = lo + (hi - lo) / 2;
    if (s[mid].t <= tt)
      lo = mid;
    else
      hi = mid;
  }
  double f = (tt - s[lo].t) / (s[hi].t - s[lo].t);
  double g[3], gn = 0;
  for (int k = 0; k < 3; k++) {
    out->pos[k] = s[lo].pos[k] + f * (s[hi].pos[k] - s[lo].pos[k]);
    g[k] = (1 - f) * s[lo].gaze[k] + f * s[hi].gaze[k];
    gn += g[k] * g[k];
  }
  gn = sqrt(gn);
  if (gn > 1e-9) {
    for (int k = 0; k < 3; k++) out->gaze[k] = g[k] / gn;
  } else { /* opposite gazes halfway: no direction in between is better */
    memcpy(out->gaze, (f < 0.5 ? s[lo] : s[hi]).gaze, sizeof out->gaze);
  }
}

/* ============================ DTrack ASCII =============================== */

typedef struct cur {
  const char *p, *end; /* current line [p, end), NUL-terminated copy */
  int line;
  cv_err *err;
} cur;

static void skip_ws(cur *c) {
  while (c->p < c->end && (*c->p == ' ' || *c->p == '\t')) c->p++;
}

static int want_char(cur *c, char ch, const char *where) {
  skip_ws(c);
  if (c->p >= c->end)
    return cv_err_set(c->err, CV_ERR_FORMAT, "dtrack: line %d: truncated, expected '%c' %s",
                      c->line, ch, where);
  if (*c->p != ch)
    return cv_err_set(c->err, CV_ERR_FORMAT, "dtrack: line %d: expected '%c' %s, found '%c'",
                      c->line, ch, where, isprint((unsigned char)*c->p) ? *c->p : '?');
  c->p++;
  return CV_OK;
}

/* A number ending at whitespace, a bracket or the line end. */
static int want_num(cur *c, const char *what, double *v) {
  skip_ws(c);
  if (c->p >= c->end)
    return cv_err_set(c->err, CV_ERR_FORMAT, "dtrack: line %d: truncated, expected %s",
                      c->line, what);
  char *e;
  *v = strtod(c->p, &e);
  if (e == c->p || e > c->end || (e < c->end && *e != ' ' && *e != '\t' && *e != '[' &&
                                  *e != ']'))
    return cv_err_set(c->err, CV_ERR_FORMAT, "dtrack: line %d: %s is not a number", c->line,
                      what);
  if (!isfinite(*v))
    return cv_err_set(c->err, CV_ERR_NONFINITE, "dtrack: line %d: %s is not finite", c->line,
                      what);
  c->p = e;
  return CV_OK;
}

static int want_uint(cur *c, const char *what, double max, double *v) {
  int st = want_num(c, what, v);
  if (st) return st;
  if (*v < 0 || *v > max || *v != floor(*v))
    return cv_err_set(c->err, CV_ERR_FORMAT, "dtrack: line %d: %s = %g is not an integer in "
                      "[0, %g]", c->line, what, *v, max);
  return CV_OK;
}

/* R^T R = I within tol and det R > 0, with R[row][col] = b[col*3 + row]:
 * the columns b[0..2], b[3..5], b[6..8] must be orthonormal. */
static int rot_ok(const double b[9], double tol) {
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      double d = b[3 * i] * b[3 * j] + b[3 * i + 1] * b[3 * j + 1] + b[3 * i + 2] * b[3 * j + 2];
      if (fabs(d - (i == j ? 1.0 : 0.0)) > tol) return 0;
    }
  /* det = c0 . (c1 x c2) */
  double det = b[0] * (b[4] * b[8] - b[5] * b[7]) - b[1] * (b[3] * b[8] - b[5] * b[6]) +
               b[2] * (b[3] * b[7] - b[4] * b[6]);
  return det > 0;
}

static int parse_6d(cur *c, cv_dtrack_frame *f) {
  double n;
  int st = want_uint(c, "the body count", 1e9, &n);
  if (st) return st;
  if (n > CV_DTRACK_MAX_BODIES)
    return cv_err_set(c->err, CV_ERR_FORMAT, "dtrack: line %d: %g bodies, at most %d", c->line,
                      n, CV_DTRACK_MAX_BODIES);
  for (int k = 0; k < (int)n; k++) {
    char where[64];
    snprintf(where, sizeof where, "(body %d of %d)", k + 1, (int)n);
    double id, v[9];
    if ((st = want_char(c, '[', where)) || (st = want_uint(c, "the body id", 2147483647.0, &id)))
      return st;
    f->body[k].id = (int)id;
    if ((st = want_num(c, "the quality", &f->body[k].quality)) || (st = want_char(c, ']', where)))
      return st;
    if ((st = want_char(c, '[', where))) return st;
    for (int i = 0; i < 6; i++)
      if ((st = want_num(c, i < 3 ? "a position" : "an angle", &v[i]))) return st;
    if ((st = want_char(c, ']', where))) return st;
    memcpy(f->body[k].pos_mm, v, 3 * sizeof(double));
    memcpy(f->body[k].euler_deg, v + 3, 3 * sizeof(double));
    if ((st = want_char(c, '[', where))) return st;
    for (int i = 0; i < 9; i++)
      if ((st = want_num(c, "a rotation entry", &f->body[k].rot[i]))) return st;
    if ((st = want_char(c, ']', where))) return st;
    if (f->body[k].quality > 0 && !rot_ok(f->body[k].rot, 1e-3))
      return cv_err_set(c->err, CV_ERR_RANGE,
                        "dtrack: line %d: body %d: rotation is not orthonormal (tolerance 1e-3)",
                        c->line, f->body[k].id);
  }
  skip_ws(c);
  if (c->p < c->end)
    return cv_err_set(c->err, CV_ERR_FORMAT,
                      "dtrack: line %d: text after the %d bodies announced (count mismatch?)",
                      c->line, (int)n);
  f->n_bodies = (int)n;
  return CV_OK;
}

static int parse_line(cur *c, cv_dtrack_frame *f, int *seen_fr, int *seen_6d) {
  skip_ws(c);
  if (c->p >= c->end) return CV_OK; /* blank line */
  const char *tok = c->p;
  while (c->p < c->end && isalnum((unsigned char)*c->p)) c->p++;
  size_t n = (size_t)(c->p - tok);
  if (n == 0 || n > 8 || (c->p < c->end && *c->p != ' ' && *c->p != '\t'))
    return cv_err_set(c->err, CV_ERR_FORMAT, "dtrack: line %d: expected a line type "
                      "(fr, ts, 6d, ...)", c->line);
  double v;
  int st;
  if (n == 2 && !memcmp(tok, "fr", 2)) {
    if (*seen_fr)
      return cv_err_set(c->err, CV_ERR_FORMAT, "dtrack: line %d: second fr line", c->line);
    if ((st = want_uint(c, "the frame counter", 4294967295.0, &v))) return st;
    f->frame = (uint32_t)v;
    *seen_fr = 1;
  } else if (n == 2 && !memcmp(tok, "ts", 2)) {
    if (f->has_ts)
      return cv_err_set(c->err, CV_ERR_FORMAT, "dtrack: line %d: second ts line", c->line);
    if ((st = want_num(c, "the timestamp", &v))) return st;
    f->ts = v;
    f->has_ts = 1;
  } else if (n == 2 && !memcmp(tok, "6d", 2)) {
    if (*seen_6d)
      return cv_err_set(c->err, CV_ERR_FORMAT, "dtrack: line %d: second 6d line", c->line);
    if ((st = parse_6d(c, f))) return st;
    *seen_6d = 1;
    return CV_OK;
  } else {
    return CV_OK; /* 3d, 6df, 6df2, gl, 6dcal, ts2 ...: not ours */
  }
  skip_ws(c);
  if (c->p < c->end)
    return cv_err_set(c->err, CV_ERR_FORMAT, "dtrack: line %d: trailing text", c->line);
  return CV_OK;
}

int cv_dtrack_parse(const char *buf, size_t len, cv_dtrack_frame *out, cv_err *err) {
  if (!buf || !out) return cv_err_set(err, CV_ERR_INVALID, "dtrack: NULL buffer");
  memset(out, 0, sizeof *out);
  if (len == 0) return cv_err_set(err, CV_ERR_FORMAT, "dtrack: empty packet");
  /* strtod needs a terminator: work on a NUL-terminated copy. */
  char *copy = malloc(len + 1);
  if (!copy) return cv_err_set(err, CV_ERR_NOMEM, "dtrack: out of memory");
  memcpy(copy, buf, len);
  copy[len] = '\0';
  if (memchr(copy, '\0', len)) {
    free(copy);
    return cv_err_set(err, CV_ERR_FORMAT, "dtrack: NUL byte inside the packet");
  }
  int seen_fr = 0, seen_6d = 0, st = CV_OK, line = 0;
  const char *p = copy, *end = copy + len;
  while (p < end && !st) {
    const char *e = p;
    while (e < end && *e != '\n' && *e != '\r') e++;
    line++;
    cur c = {p, e, line, err};
    st = parse_line(&c, out, &seen_fr, &seen_6d);
    p = e;
    if (p < end && *p == '\r') p++;
    if (p < end && *p == '\n') p++;
  }
  free(copy);
  if (!st && !seen_fr && !seen_6d)
    st = cv_err_set(err, CV_ERR_FORMAT, "dtrack: no fr or 6d line");
  return st;
}

int cv_dtrack_head_pose(const cv_dtrack_frame *f, int body_id, const double forward_local[3],
                        cv_head_pose *out) {
  static const double def_fwd[3] = {0, 0, -1};
  const double *fw = forward_local ? forward_local : def_fwd;
  double fl = sqrt(fw[0] * fw[0] + fw[1] * fw[1] + fw[2] * fw[2]);
  if (!(fl > 1e-12) || !isfinite(fl)) return CV_ERR_INVALID;
  for (int k = 0; k < f->n_bodies; k++) {
    if (f->body[k].id != body_id) continue;
    if (!(f->body[k].quality > 0)) return CV_ERR_NOT_FOUND;
    const double *b = f->body[k].rot;
    double g[3], gn = 0;
    for (int r = 0; r < 3; r++) {
      g[r] = b[r] * fw[0] + b[3 + r] * fw[1] + b[6 + r] * fw[2]; /* R[r][c] = b[3c + r] */
      gn += g[r] * g[r];
    }
    gn = sqrt(gn);
    if (!(gn > 1e-12)) return CV_ERR_NOT_FOUND; /* unusable rotation */
    for (int r = 0; r < 3; r++) {
      out->pos[r] = f->body[k].pos_mm[r] * 1e-3;
      out->gaze[r] = g[r] / gn;
    }
    out->t = f->has_ts ? f->ts : 0.0;
    out->valid = 1;
    return CV_OK;
  }
  return CV_ERR_NOT_FOUND;
}

/* ============================ UDP receiver =============================== */

#define RX_BUF 65536 /* largest UDP payload is 65507 */

struct cv_dtrack_receiver {
  int fd, port, body_id;
  char *buf;
  cv_head_pose last;
  cv_dtrack_frame last_frame; /* the frame `last` came from */
  cv_tracker_stats stats;
};

int cv_dtrack_receiver_open(const char *host, int port, int body_id, cv_dtrack_receiver **out,
                            cv_err *err) {
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "dtrack receiver: NULL output");
  *out = NULL;
  if (!host) host = "127.0.0.1";
  if (port < 0 || port > 65535)
    return cv_err_set(err, CV_ERR_INVALID, "dtrack receiver: port %d outside [0, 65535]", port);
  struct sockaddr_in a;
  memset(&a, 0, sizeof a);
  a.sin_family = AF_INET;
  a.sin_port = htons((uint16_t)port);
  if (inet_pton(AF_INET, host, &a.sin_addr) != 1)
    return cv_err_set(err, CV_ERR_INVALID, "dtrack receiver: '%s' is not an IPv4 address",
                      host);
  cv_dtrack_receiver *r = calloc(1, sizeof *r);
  if (!r || !(r->buf = malloc(RX_BUF))) {
    free(r);
    return cv_err_set(err, CV_ERR_NOMEM, "dtrack receiver: out of memory");
  }
  r->fd = socket(AF_INET, SOCK_DGRAM, 0);
  if (r->fd < 0) {
    int e = errno;
    cv_dtrack_receiver_close(r);
    return cv_err_set(err, CV_ERR_IO, "dtrack receiver: socket: %s", strerror(e));
  }
  int fl = fcntl(r->fd, F_GETFL, 0);
  if (fl < 0 || fcntl(r->fd, F_SETFL, fl | O_NONBLOCK) < 0 ||
      fcntl(r->fd, F_SETFD, FD_CLOEXEC) < 0) {
    int e = errno;
    cv_dtrack_receiver_close(r);
    return cv_err_set(err, CV_ERR_IO, "dtrack receiver: fcntl: %s", strerror(e));
  }
  if (bind(r->fd, (struct sockaddr *)&a, sizeof a) < 0) {
    int e = errno;
    cv_dtrack_receiver_close(r);
    return cv_err_set(err, CV_ERR_IO, "dtrack receiver: bind %s:%d: %s", host, port,
                      strerror(e));
  }
  socklen_t al = sizeof a;
  if (getsockname(r->fd, (struct sockaddr *)&a, &al) < 0) {
    int e = errno;
    cv_dtrack_receiver_close(r);
    return cv_err_set(err, CV_ERR_IO, "dtrack receiver: getsockname: %s", strerror(e));
  }
  r->port = ntohs(a.sin_port);
  r->body_id = body_id;
  r->stats.last_rx_time = -1.0;
  *out = r;
  return CV_OK;
}

int cv_dtrack_receiver_port(const cv_dtrack_receiver *r) { return r->port; }

/* Drains pending datagrams (at most CV_DTRACK_MAX_DRAIN); the newest frame
 * with a tracked body r->body_id goes to *fnew and its pose to *pnew. */
static int drain(cv_dtrack_receiver *r, int *got, cv_dtrack_frame *fnew, cv_head_pose *pnew) {
  int st = 0;
  *got = 0;
  for (int k = 0; k < CV_DTRACK_MAX_DRAIN; k++) {
    ssize_t n = recv(r->fd, r->buf, RX_BUF, MSG_DONTWAIT);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK) st = CV_ERR_IO;
      break;
    }
    r->stats.packets++;
    cv_dtrack_frame f;
    if (cv_dtrack_parse(r->buf, (size_t)n, &f, NULL) != CV_OK) {
      r->stats.malformed++;
      continue;
    }
    cv_head_pose p;
    if (cv_dtrack_head_pose(&f, r->body_id, NULL, &p) != CV_OK) {
      r->stats.no_body++;
      continue;
    }
    *pnew = p;
    *fnew = f;
    *got = 1;
  }
  return st;
}

int cv_dtrack_receiver_poll(cv_dtrack_receiver *r, double now, cv_head_pose *pose_out,
                            cv_tracker_stats *stats) {
  return cv_dtrack_receiver_poll_frame(r, now, pose_out, NULL, stats);
}

int cv_dtrack_receiver_poll_frame(cv_dtrack_receiver *r, double now, cv_head_pose *pose_out,
                                  cv_dtrack_frame *frame_out, cv_tracker_stats *stats) {
  int got = 0;
  cv_head_pose newest;
  cv_dtrack_frame fnew;
  int st = drain(r, &got, &fnew, &newest);
  if (got) {
    newest.t = now;
    r->last = newest;
    r->last_frame = fnew;
    r->stats.last_rx_time = now;
  }
  if (pose_out) *pose_out = r->last;
  if (frame_out) *frame_out = r->last_frame;
  if (stats) *stats = r->stats;
  return st ? st : got;
}

int cv_dtrack_receiver_join(cv_dtrack_receiver *r, const char *group, const char *iface,
                            cv_err *err) {
  struct ip_mreq mr;
  memset(&mr, 0, sizeof mr);
  if (inet_pton(AF_INET, group, &mr.imr_multiaddr) != 1 ||
      (ntohl(mr.imr_multiaddr.s_addr) >> 28) != 14)
    return cv_err_set(err, CV_ERR_INVALID,
                      "dtrack receiver: '%s' is not an IPv4 multicast group (224.0.0.0/4)", group);
  if (inet_pton(AF_INET, iface ? iface : "0.0.0.0", &mr.imr_interface) != 1)
    return cv_err_set(err, CV_ERR_INVALID, "dtrack receiver: '%s' is not an IPv4 address", iface);
  if (setsockopt(r->fd, IPPROTO_IP, IP_ADD_MEMBERSHIP, &mr, sizeof mr) < 0)
    return cv_err_set(err, CV_ERR_IO, "dtrack receiver: join %s on %s: %s", group,
                      iface ? iface : "any interface", strerror(errno));
  return CV_OK;
}

void cv_dtrack_receiver_close(cv_dtrack_receiver *r) {
  if (!r) return;
  if (r->fd >= 0) close(r->fd);
  free(r->buf);
  free(r);
}

/* ---- keyboard and mouse (desktop preview) ------------------------------- */

#define NAV_PI 3.14159265358979323846
static const double k_max_pitch = 85.0 * NAV_PI / 180.0;

static void nav_gaze(cv_head_nav *n) {
  const double cp = cos(n->pitch);
  n->pose.gaze[0] = cp * sin(n->yaw);
  n->pose.gaze[1] = sin(n->pitch);
  n->pose.gaze[2] = -cp * cos(n->yaw);
}

/* Yaw and pitch of a unit gaze (yaw kept when it looks straight up/down). */
static void nav_angles(cv_head_nav *n, const double g[3]) {
  const double h = sqrt(g[0] * g[0] + g[2] * g[2]);
  if (h > 1e-9) n->yaw = atan2(g[0], -g[2]);
  n->pitch = atan2(g[1], h);
  if (n->pitch > k_max_pitch) n->pitch = k_max_pitch;
  if (n->pitch < -k_max_pitch) n->pitch = -k_max_pitch;
}

static void nav_home(cv_head_nav *n) {
  memcpy(n->pose.pos, n->home_pos, sizeof n->pose.pos);
  memcpy(n->pose.gaze, n->home_gaze, sizeof n->pose.gaze);
  n->yaw = 0;
  nav_angles(n, n->home_gaze);
}

int cv_head_nav_init(cv_head_nav *n, const double pos[3], const double gaze[3], const double lo[3],
                     const double hi[3], double step, double deg_per_px, double now, cv_err *err) {
  memset(n, 0, sizeof *n);
  double gl = 0;
  for (int a = 0; a < 3; a++) {
    if (!isfinite(pos[a]) || !isfinite(gaze[a]) || !isfinite(lo[a]) || !isfinite(hi[a]))
      return cv_err_set(err, CV_ERR_INVALID, "head nav: non-finite pose or box");
    if (!(lo[a] <= hi[a])) return cv_err_set(err, CV_ERR_INVALID, "head nav: empty box on axis %d", a);
    if (pos[a] < lo[a] || pos[a] > hi[a])
      return cv_err_set(err, CV_ERR_INVALID, "head nav: home (%g, %g, %g) outside the box", pos[0], pos[1], pos[2]);
    gl += gaze[a] * gaze[a];
  }
  if (!(gl > 0)) return cv_err_set(err, CV_ERR_INVALID, "head nav: zero gaze");
  if (!(step > 0 && isfinite(step)) || !(deg_per_px > 0 && isfinite(deg_per_px)))
    return cv_err_set(err, CV_ERR_INVALID, "head nav: step and turn rate must be > 0");
  gl = sqrt(gl);
  for (int a = 0; a < 3; a++) {
    n->home_pos[a] = pos[a];
    n->home_gaze[a] = gaze[a] / gl;
    n->lo[a] = lo[a];
    n->hi[a] = hi[a];
  }
  n->step = step;
  n->deg_per_px = deg_per_px;
  nav_home(n);
  n->pose.t = now;
  n->pose.valid = 1;
  return CV_OK;
}

int cv_head_nav_apply(cv_head_nav *n, const cv_head_nav_input *in, double now) {
  const cv_head_pose before = n->pose;
  if (in->reset) nav_home(n);
  if ((in->drag_x != 0 || in->drag_y != 0) && isfinite(in->drag_x) && isfinite(in->drag_y)) {
    const double k = n->deg_per_px * NAV_PI / 180.0;
    n->yaw = remainder(n->yaw + in->drag_x * k, 2 * NAV_PI);
    n->pitch -= in->drag_y * k;
    if (n->pitch > k_max_pitch) n->pitch = k_max_pitch;
    if (n->pitch < -k_max_pitch) n->pitch = -k_max_pitch;
    nav_gaze(n);
  }
  if (in->right || in->forward || in->up) {
    /* the floor frame of the gaze: forward (sin yaw, 0, -cos yaw), right = forward x up */
    const double f[3] = {sin(n->yaw), 0, -cos(n->yaw)}, r[3] = {cos(n->yaw), 0, sin(n->yaw)};
    for (int a = 0; a < 3; a++) {
      double p = n->pose.pos[a] + n->step * (in->right * r[a] + in->forward * f[a] + (a == 1 ? in->up : 0));
      n->pose.pos[a] = p < n->lo[a] ? n->lo[a] : (p > n->hi[a] ? n->hi[a] : p);
    }
  }
  if (!memcmp(before.pos, n->pose.pos, sizeof before.pos) && !memcmp(before.gaze, n->pose.gaze, sizeof before.gaze))
    return 0;
  n->pose.t = now;
  n->inputs++;
  return 1;
}
