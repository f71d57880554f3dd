/* Guarded mesh import (mesh_import.h): assimp runs in a forked child under a
 * memory limit (RLIMIT_AS) and a wall-clock limit (the parent kills it), so
 * a file that makes assimp loop or allocate without end costs the caller at
 * most the limits.  The child sends the mesh back through a pipe; whatever
 * assimp prints (stray "nullptr returned by creating DDLNode." lines and the
 * like) goes to a second pipe and is dropped, unless the child crashed or
 * CAVE_IMPORT_VERBOSE=1, when it is copied to our stderr after the error. */
#define _GNU_SOURCE
#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "io/mesh_import.h"

#if defined(__SANITIZE_ADDRESS__)
#define CV_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define CV_ASAN 1
#endif
#endif

/* The record the child writes first; the arrays follow. */
typedef struct reply {
  int32_t status;
  char msg[512];
  cv_import_stats stats;
  uint64_t nv, nt, nm;
  uint32_t has_uv, has_tex; /* corner UVs (6*nt floats) and texture paths (nm x CV_TEX_PATH_MAX) follow */
} reply;

static double env_number(const char *name, double fallback) {
  const char *s = getenv(name);
  if (!s || !*s) return fallback;
  char *end;
  double v = strtod(s, &end);
  return (*end == '\0' && v >= 0) ? v : fallback;
}

void cv_import_limits_default(cv_import_opts *o) {
  long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  double ram_mb = (pages > 0 && page > 0) ? (double)pages * (double)page / 1048576.0 : 0;
  o->limit_seconds = env_number("CAVE_IMPORT_TIMEOUT", CV_IMPORT_DEFAULT_SECONDS);
  double mb = ram_mb * 0.75;
  if (mb <= 0 || mb > CV_IMPORT_DEFAULT_MEMORY_MB) mb = CV_IMPORT_DEFAULT_MEMORY_MB;
  o->limit_memory_mb = env_number("CAVE_IMPORT_MEMORY_MB", mb);
}

static int write_all(int fd, const void *buf, size_t n) {
  const char *p = buf;
  while (n) {
    ssize_t w = write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return -1;
    p += w;
    n -= (size_t)w;
  }
  return 0;
}

/* In the child: limits, import, reply; never returns. */
static void child(const char *path, const cv_import_opts *opts, int data_fd, int out_fd) {
  dup2(out_fd, STDOUT_FILENO);
  dup2(out_fd, STDERR_FILENO);
  close(out_fd);
#ifndef CV_ASAN /* ASan reserves terabytes of address space: RLIMIT_AS would stop it at once */
  if (opts->limit_memory_mb > 0) {
    rlim_t b = (rlim_t)(opts->limit_memory_mb * 1048576.0);
    struct rlimit rl = {b, b};
    setrlimit(RLIMIT_AS, &rl);
  }
#endif
  if (opts->limit_seconds > 0) {
    rlim_t s = (rlim_t)opts->limit_seconds + 1;
    struct rlimit rl = {s, s + 1};
    setrlimit(RLIMIT_CPU, &rl);
  }
  reply r;
  memset(&r, 0, sizeof r);
  cv_err err;
  cv_err_clear(&err);
  cv_mesh *m = NULL;
  r.status = cv_mesh_import_direct(path, opts, &m, &r.stats, &err);
  snprintf(r.msg, sizeof r.msg, "%s", err.msg);
  if (m) {
    r.nv = m->nv;
    r.nt = m->nt;
    r.nm = m->nm;
    r.has_uv = m->tri_uv != NULL;
    r.has_tex = m->mat_tex != NULL;
  }
  int bad = write_all(data_fd, &r, sizeof r);
  if (!bad && m)
    bad = write_all(data_fd, m->pos, 3 * m->nv * sizeof(float)) ||
          write_all(data_fd, m->tri, 3 * m->nt * sizeof(uint32_t)) ||
          write_all(data_fd, m->tri_mat, m->nt * sizeof(uint32_t)) ||
          write_all(data_fd, m->mats, m->nm * sizeof(cv_material)) ||
          (r.has_uv && write_all(data_fd, m->tri_uv, 6 * m->nt * sizeof(float))) ||
          (r.has_tex && write_all(data_fd, m->mat_tex, m->nm * (size_t)CV_TEX_PATH_MAX));
  cv_mesh_destroy(m);
  close(data_fd);
  fflush(NULL);
  exit(bad ? 3 : 0); /* exit, not _exit: LeakSanitizer checks the child too */
}

typedef struct buf {
  unsigned char *p;
  size_t n, cap;
  int failed; /* out of memory: the rest is drained and dropped */
} buf;

static void buf_take(buf *b, int fd, int *open_fd) {
  unsigned char tmp[65536];
  ssize_t r = read(fd, tmp, sizeof tmp);
  if (r < 0 && (errno == EINTR || errno == EAGAIN)) return;
  if (r <= 0) {
    *open_fd = 0;
    return;
  }
  if (b->failed) return;
  if (b->n + (size_t)r > b->cap) {
    size_t cap = b->cap ? b->cap : 1 << 16;
    while (cap < b->n + (size_t)r) cap *= 2;
    unsigned char *np = realloc(b->p, cap);
    if (!np) {
      b->failed = 1;
      return;
    }
    b->p = np;
    b->cap = cap;
  }
  memcpy(b->p + b->n, tmp, (size_t)r);
  b->n += (size_t)r;
}

static double now_s(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Reads both pipes until the child closes them or the deadline passes;
 * returns 1 when the deadline killed the child. */
static int collect(pid_t pid, int data_fd, int out_fd, double seconds, buf *data, buf *out) {
  int data_open = 1, out_open = 1, killed = 0;
  double deadline = seconds > 0 ? now_s() + seconds : 0;
  while (data_open || out_open) {
    struct pollfd pf[2] = {{data_open ? data_fd : -1, POLLIN, 0}, {out_open ? out_fd : -1, POLLIN, 0}};
    int wait_ms = -1;
    if (deadline > 0) {
      double left = deadline - now_s();
      if (left <= 0) {
        kill(pid, SIGKILL);
        killed = 1;
        break;
      }
      wait_ms = (int)(left * 1000) + 1;
    }
    int n = poll(pf, 2, wait_ms);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) break;
    if (pf[0].revents) buf_take(data, data_fd, &data_open);
    if (pf[1].revents) buf_take(out, out_fd, &out_open);
  }
  return killed;
}

static const char *format_of(const char *path, char *fmt, size_t n) {
  const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
  if (!dot || (slash && dot < slash) || !dot[1]) return "unknown format";
  size_t k = 0;
  for (const char *p = dot + 1; *p && k + 1 < n; p++) fmt[k++] = (char)((*p >= 'a' && *p <= 'z') ? *p - 32 : *p);
  fmt[k] = '\0';
  return fmt;
}

/* Copies the child's output to stderr (a crash or CAVE_IMPORT_VERBOSE=1). */
static void show_output(const char *path, const buf *out) {
  if (!out->n) return;
  fprintf(stderr, "--- output of the import of %s ---\n", path);
  fwrite(out->p, 1, out->n, stderr);
  if (out->p[out->n - 1] != '\n') fputc('\n', stderr);
  fprintf(stderr, "--- end of output ---\n");
}

/* Builds the mesh from the child's reply. */
static int unpack(const char *path, const buf *data, cv_mesh **out, cv_import_stats *stats,
                  cv_err *err) {
  reply r;
  memcpy(&r, data->p, sizeof r);
  if (stats) *stats = r.stats;
  if (r.status) {
    r.msg[sizeof r.msg - 1] = '\0';
    return cv_err_set(err, r.status, "%s", r.msg);
  }
  size_t want = sizeof r + (size_t)r.nv * 3 * sizeof(float) + (size_t)r.nt * 4 * sizeof(uint32_t) +
                (size_t)r.nm * sizeof(cv_material) +
                (r.has_uv ? (size_t)r.nt * 6 * sizeof(float) : 0) +
                (r.has_tex ? (size_t)r.nm * CV_TEX_PATH_MAX : 0);
  if (data->n != want)
    return cv_err_set(err, CV_ERR_BACKEND, "%s: import: the child process sent %zu bytes, expected %zu",
                      path, data->n, want);
  cv_mesh *m;
  if (cv_mesh_create(&m) || cv_mesh_reserve(m, r.nv, r.nt)) {
    if (m) cv_mesh_destroy(m);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory for %llu vertices", path,
                      (unsigned long long)r.nv);
  }
  const unsigned char *p = data->p + sizeof r;
  memcpy(m->pos, p, r.nv * 3 * sizeof(float));
  p += r.nv * 3 * sizeof(float);
  memcpy(m->tri, p, r.nt * 3 * sizeof(uint32_t));
  p += r.nt * 3 * sizeof(uint32_t);
  memcpy(m->tri_mat, p, r.nt * sizeof(uint32_t));
  p += r.nt * sizeof(uint32_t);
  m->nv = r.nv;
  m->nt = r.nt;
  for (size_t i = 0; i < r.nm; i++) {
    cv_material mt;
    memcpy(&mt, p + i * sizeof mt, sizeof mt);
    mt.name[sizeof mt.name - 1] = '\0';
    if (cv_mesh_add_material(m, mt.name, mt.albedo, mt.flags, NULL)) {
      cv_mesh_destroy(m);
      return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
    }
  }
  p += r.nm * sizeof(cv_material);
  if (r.has_uv) {
    if (cv_mesh_enable_uv(m)) goto nomem;
    memcpy(m->tri_uv, p, r.nt * 6 * sizeof(float));
    p += r.nt * 6 * sizeof(float);
  }
  for (size_t i = 0; r.has_tex && i < r.nm; i++) {
    char t[CV_TEX_PATH_MAX];
    memcpy(t, p + i * CV_TEX_PATH_MAX, sizeof t);
    t[sizeof t - 1] = '\0';
    if (cv_mesh_set_texture(m, (uint32_t)i, t)) goto nomem;
  }
  *out = m;
  return CV_OK;
nomem:
  cv_mesh_destroy(m);
  return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
}

int cv_mesh_import_ex(const char *path, const cv_import_opts *opts, cv_mesh **out,
                      cv_import_stats *stats, cv_err *err) {
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "mesh import: out is NULL");
  *out = NULL;
  if (!path) return cv_err_set(err, CV_ERR_INVALID, "mesh import: path is NULL");
  cv_import_opts def;
  if (!opts) {
    cv_import_opts_default(&def);
    opts = &def;
  }
  if (stats) memset(stats, 0, sizeof *stats);
  int dp[2], op[2];
  if (pipe(dp)) return cv_err_set(err, CV_ERR_IO, "%s: import: pipe: %s", path, strerror(errno));
  if (pipe(op)) {
    close(dp[0]);
    close(dp[1]);
    return cv_err_set(err, CV_ERR_IO, "%s: import: pipe: %s", path, strerror(errno));
  }
  fflush(NULL); /* nothing buffered is written twice */
  pid_t pid = fork();
  if (pid < 0) {
    close(dp[0]), close(dp[1]), close(op[0]), close(op[1]);
    return cv_err_set(err, CV_ERR_IO, "%s: import: fork: %s", path, strerror(errno));
  }
  if (pid == 0) {
    close(dp[0]);
    close(op[0]);
    child(path, opts, dp[1], op[1]);
  }
  close(dp[1]);
  close(op[1]);
  buf data = {0}, outb = {0};
  double t0 = now_s();
  int killed = collect(pid, dp[0], op[0], opts->limit_seconds, &data, &outb);
  close(dp[0]);
  close(op[0]);
  int ws = 0;
  while (waitpid(pid, &ws, 0) < 0 && errno == EINTR) {
  }
  double took = now_s() - t0;
  char fmtb[16];
  const char *fmt = format_of(path, fmtb, sizeof fmtb);
  int st;
  const char *verbose = getenv("CAVE_IMPORT_VERBOSE");
  int show = verbose && verbose[0] == '1';
  if (killed || (WIFSIGNALED(ws) && WTERMSIG(ws) == SIGXCPU)) {
    st = cv_err_set(err, CV_ERR_RANGE,
                    "%s: import (%s) stopped after %.1f s: time limit %g s hit (CAVE_IMPORT_TIMEOUT "
                    "sets it)",
                    path, fmt, took, opts->limit_seconds);
  } else if (data.failed) {
    st = cv_err_set(err, CV_ERR_NOMEM, "%s: import (%s): out of memory receiving the mesh", path, fmt);
  } else if (WIFEXITED(ws) && WEXITSTATUS(ws) == 0 && data.n >= sizeof(reply)) {
    st = unpack(path, &data, out, stats, err);
    if (err && (st == CV_ERR_NOMEM || (st && strstr(err->msg, "bad_alloc"))) &&
        opts->limit_memory_mb > 0) {
      char was[sizeof err->msg];
      size_t np = strlen(path);
      const char *why = strncmp(err->msg, path, np) == 0 && err->msg[np] == ':' ? err->msg + np + 2
                                                                                 : err->msg;
      snprintf(was, sizeof was, "%s", why);
      st = cv_err_set(err, CV_ERR_NOMEM,
                      "%s: import (%s) stopped: memory limit %.0f MB hit (CAVE_IMPORT_MEMORY_MB "
                      "sets it): %.300s",
                      path, fmt, opts->limit_memory_mb, was);
    }
  } else {
    /* The child died without a reply: with RLIMIT_AS set, assimp's failed
     * new (std::bad_alloc, uncaught) ends it with SIGABRT. */
    int sig = WIFSIGNALED(ws) ? WTERMSIG(ws) : 0;
    int mem = sig == SIGABRT && opts->limit_memory_mb > 0;
#ifdef CV_ASAN
    mem = 0;
#endif
    if (mem)
      st = cv_err_set(err, CV_ERR_NOMEM,
                      "%s: import (%s) stopped: memory limit %.0f MB hit (CAVE_IMPORT_MEMORY_MB "
                      "sets it)",
                      path, fmt, opts->limit_memory_mb);
    else if (sig)
      st = cv_err_set(err, CV_ERR_BACKEND, "%s: import (%s) crashed: signal %d (%s) in assimp", path,
                      fmt, sig, strsignal(sig));
    else
      st = cv_err_set(err, CV_ERR_BACKEND, "%s: import (%s) failed: child exit status %d", path,
                      fmt, WIFEXITED(ws) ? WEXITSTATUS(ws) : -1);
    show = show || !mem;
  }
  if (show) show_output(path, &outb);
  free(data.p);
  free(outb.p);
  return st;
}
