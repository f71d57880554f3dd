/* The live console's HTTP server (issue 33; docs/service.md "Live console"):
 * libmicrohttpd with its own polling thread (epoll), a connection limit, a
 * per-connection timeout and memory limit, so that malformed, slow or many
 * requests cost the master's frame loop nothing: the server only reads the
 * console's snapshots and queues controls (service/console.h).  No MPI.
 *
 *   GET  /              the page (web/console.html, embedded at build time)
 *   GET  /state.json    the state and the recent per-frame samples (?since=F)
 *   GET  /events        server-sent events: the same JSON after every frame
 *                       (at most 4 a second), samples since the last event
 *   GET  /metrics       Prometheus text format 0.0.4 (docs/metrics.md)
 *   GET  /image/NAME.png  projector, uncompensated, viewer (the montages of
 *                       the last written frame), heatmap (the LCD's CR)
 *   POST /control       action=pause|resume|quit|head|sky|yaw|drive and its
 *                       fields (form-encoded body): queued for the master
 * With a token every request needs it: "Authorization: Bearer TOKEN" or
 * ?token=TOKEN (the page passes it on); else 401. */
#ifndef CV_HTTP_HTTP_H
#define CV_HTTP_HTTP_H

#include <stddef.h>

#include "core/status.h"
#include "service/console.h"

#define CV_HTTP_DEFAULT_PORT 8033

typedef struct cv_http_opts {
  char addr[64];          /* IPv4 address to bind (a.b.c.d) */
  int port;               /* 0: a free port (cv_http_port says which) */
  char token[256];        /* "" none; else required on every request */
  int max_connections;    /* default 256 */
  int max_events;         /* concurrent /events streams, default 8 */
  int timeout_s;          /* idle connections closed after this, default 3 */
  size_t memory_limit;    /* per connection (request headers included), default 32 KiB */
} cv_http_opts;

void cv_http_opts_default(cv_http_opts *o);

/* --http's value: "off" (*off = 1), "ADDR:PORT" or "PORT" (address
 * 127.0.0.1); PORT 0..65535.  CV_ERR_CONFIG naming what was expected. */
int cv_http_parse_listen(const char *spec, char *addr, size_t cap, int *port, int *off, cv_err *err);
/* 1 when addr (IPv4 a.b.c.d) is in 127.0.0.0/8. */
int cv_http_is_loopback(const char *addr);
/* The token: the file's first line, blanks trimmed; 16..255 characters of
 * [A-Za-z0-9._~+/=-].  CV_ERR_IO, CV_ERR_CONFIG naming the file. */
int cv_http_load_token(const char *path, char *token, size_t cap, cv_err *err);

typedef struct cv_http cv_http;

/* Binds and starts the server.  A port in use, an address not of this host:
 * CV_ERR_IO naming ADDR:PORT and the reason (never another port). */
int cv_http_start(const cv_http_opts *o, cv_console *console, cv_http **out, cv_err *err);
int cv_http_port(const cv_http *h);
/* Counts since the start: requests answered, refused for the token (401),
 * refused as malformed or over a limit (4xx/5xx other than 401/404). */
void cv_http_counts(const cv_http *h, unsigned long long *requests, unsigned long long *unauthorized,
                    unsigned long long *refused);
void cv_http_stop(cv_http *h); /* accepts NULL; ends the event streams, joins the threads */

/* The page, embedded (console_page.c, generated from web/console.html). */
extern const unsigned char cv_console_page[];
extern const size_t cv_console_page_len;

#endif
