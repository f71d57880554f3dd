/* Guarded child process (child_guard.h). */
#define _GNU_SOURCE
#include "io/child_guard.h"

#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#if defined(__SANITIZE_ADDRESS__)
#define CV_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define CV_ASAN 1
#endif
#endif
#if defined(CV_ASAN) && !defined(CAVE_FUZZ)
#include <sanitizer/lsan_interface.h>
#endif

/* A child's cv_status travels in its exit code as 100 - status (CV_OK: 0),
 * away from the codes sanitizers (1, 23) and shells use. */
#define CODE_BASE 100

int cv_child_memory_limit_applies(void) {
#ifdef CV_ASAN
  return 0;
#else
  return 1;
#endif
}

int cv_child_write(int fd, const void *buf, size_t n) {
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

/* Address space of this process in bytes (/proc/self/statm), 0 if unknown. */
static double address_space_bytes(void) {
  FILE *f = fopen("/proc/self/statm", "r");
  if (!f) return 0;
  unsigned long pages = 0;
  int ok = fscanf(f, "%lu", &pages) == 1;
  fclose(f);
  long page = sysconf(_SC_PAGESIZE);
  return ok && page > 0 ? (double)pages * (double)page : 0;
}

static void set_limits(const cv_child_limits *lim) {
  if (lim->memory_mb > 0 && cv_child_memory_limit_applies()) {
    rlim_t b = (rlim_t)(address_space_bytes() + lim->memory_mb * 1048576.0);
    struct rlimit rl = {b, b};
    setrlimit(RLIMIT_AS, &rl);
  }
  if (lim->seconds > 0) {
    rlim_t s = (rlim_t)lim->seconds + 1;
    struct rlimit rl = {s, s + 1};
    setrlimit(RLIMIT_CPU, &rl);
  }
}

/* A crash ends the child with its signal, for the parent to name, whatever
 * handler the parent installed (a test framework's, say).  Under
 * AddressSanitizer its handlers stay: its report is worth more. */
static void default_crash_signals(void) {
#ifndef CV_ASAN
  static const int sigs[] = {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGTRAP, SIGSYS};
  for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++) signal(sigs[i], SIG_DFL);
#endif
}

double cv_child_env_limit(const char *name, double fallback) {
  const char *s = getenv(name);
  if (!s || !*s) return fallback;
  char *end;
  double v = strtod(s, &end);
  return (*end == '\0' && v >= 0 && isfinite(v)) ? v : NAN;
}

int cv_child_env_check(const char *name, double value, const char *what, cv_err *err) {
  if (!isnan(value)) return CV_OK;
  const char *s = getenv(name);
  return cv_err_set(err, CV_ERR_RANGE, "%s: expected %s, got '%s'", name, what, s ? s : "");
}

int cv_child_single_threaded(void) {
  FILE *f = fopen("/proc/self/status", "r");
  if (!f) return 0;
  char line[256];
  int n = 0;
  while (fgets(line, sizeof line, f))
    if (sscanf(line, "Threads: %d", &n) == 1) break;
  fclose(f);
  return n == 1;
}

/* In the child: output redirected, limits set, fn run; never returns.
 * leak_check: run LeakSanitizer before the end (ASan builds). */
static void child(cv_child_fn fn, void *ctx, const cv_child_limits *lim, int data_fd, int out_fd,
                  int leak_check) {
  dup2(out_fd, STDOUT_FILENO);
  dup2(out_fd, STDERR_FILENO);
  close(out_fd);
  default_crash_signals();
  set_limits(lim);
  int st = fn(ctx, data_fd);
  close(data_fd);
  fflush(NULL);
#if defined(CV_ASAN) && !defined(CAVE_FUZZ)
  /* _exit skips the at-exit check.  Not in the libFuzzer build: there it
   * costs about 75 ms a child and reports false leaks (libFuzzer's threads
   * are gone in the child), while libFuzzer checks the parent itself.  Not
   * either when the parent had other threads at the fork (OpenMP, Embree):
   * the check locks the allocator and the thread registry, which one of
   * them may have held at that moment, and the child then waits for ever
   * (seen once under load in CI: an EXR decode stopped at its time limit). */
  if (leak_check) __lsan_do_leak_check();
#else
  (void)leak_check;
#endif
  _exit(st == CV_OK ? 0 : CODE_BASE - st);
}

typedef struct recv_buf {
  unsigned char *p;
  size_t n, cap;
  int failed; /* out of memory: the rest is drained and dropped */
} recv_buf;

/* Reads what is there from fd into b; *open_fd = 0 at end of file. */
static void buf_take(recv_buf *b, int fd, int *open_fd) {
  unsigned char tmp[65536];
  ssize_t r = read(fd, tmp, sizeof tmp);
  if (r < 0 && (errno == EINTR || errno == EAGAIN)) return;
  if (r <= 0) {
    *open_fd = 0;
    return;
  }
  if (b->failed) return;
  if (b->n + (size_t)r + 1 > b->cap) { /* + 1: room for a NUL after text */
    size_t cap = b->cap ? b->cap : 1 << 16;
    while (cap < b->n + (size_t)r + 1) cap *= 2;
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
  b->p[b->n] = '\0';
}

static double now_s(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Reads both pipes until the child closes them or the deadline passes;
 * returns 1 when the deadline killed the child. */
static int collect(pid_t pid, int data_fd, int out_fd, double seconds, recv_buf *data, recv_buf *out) {
  int data_open = 1, out_open = 1;
  double deadline = seconds > 0 ? now_s() + seconds : 0;
  while (data_open || out_open) {
    struct pollfd pf[2] = {{data_open ? data_fd : -1, POLLIN, 0}, {out_open ? out_fd : -1, POLLIN, 0}};
    int wait_ms = -1;
    if (deadline > 0) {
      double left = deadline - now_s();
      if (left <= 0) {
        kill(pid, SIGKILL);
        return 1;
      }
      wait_ms = (int)(left * 1000) + 1;
    }
    int n = poll(pf, 2, wait_ms);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) break;
    if (pf[0].revents) buf_take(data, data_fd, &data_open);
    if (pf[1].revents) buf_take(out, out_fd, &out_open);
  }
  return 0;
}

/* How the child ended, from its wait status and output. */
static void classify(cv_child_result *res, int ws, int killed, int data_failed) {
  res->exit_code = WIFEXITED(ws) ? WEXITSTATUS(ws) : -1;
  res->signal = WIFSIGNALED(ws) ? WTERMSIG(ws) : 0;
  int code = res->exit_code;
  int child_status = code > CODE_BASE && code <= CODE_BASE + 20 ? CODE_BASE - code : CV_ERR_BACKEND;
  /* An uncaught std::bad_alloc (the C++ runtime prints its name, then aborts). */
  int bad_alloc = res->signal == SIGABRT && res->output && strstr(res->output, "bad_alloc");
  if (killed || res->signal == SIGXCPU)
    res->outcome = CV_CHILD_TIMEOUT;
  else if (data_failed)
    res->outcome = CV_CHILD_RECEIVE;
  else if (code == 0)
    res->outcome = CV_CHILD_DONE;
  else if (res->memory_limited && (bad_alloc || (code > 0 && child_status == CV_ERR_NOMEM)))
    res->outcome = CV_CHILD_MEMORY;
  else if (res->signal)
    res->outcome = CV_CHILD_SIGNAL;
  else
    res->outcome = CV_CHILD_FAILED;
  res->status = res->outcome == CV_CHILD_FAILED ? child_status : CV_OK;
}

int cv_child_run(cv_child_fn fn, void *ctx, const cv_child_limits *lim, cv_child_result *res,
                 cv_err *err) {
  static const cv_child_limits none = {0, 0};
  if (!lim) lim = &none;
  memset(res, 0, sizeof *res);
  res->exit_code = -1;
  int dp[2], op[2];
  if (pipe(dp)) return cv_err_set(err, CV_ERR_IO, "pipe: %s", strerror(errno));
  if (pipe(op)) {
    close(dp[0]);
    close(dp[1]);
    return cv_err_set(err, CV_ERR_IO, "pipe: %s", strerror(errno));
  }
  fflush(NULL); /* nothing buffered is written twice */
#if defined(CV_ASAN) && !defined(CAVE_FUZZ)
  const int leak_check = cv_child_single_threaded();
#else
  const int leak_check = 0;
#endif
  double t0 = now_s();
  pid_t pid = fork();
  if (pid < 0) {
    int e = errno;
    close(dp[0]), close(dp[1]), close(op[0]), close(op[1]);
    return cv_err_set(err, CV_ERR_IO, "fork: %s", strerror(e));
  }
  if (pid == 0) {
    close(dp[0]);
    close(op[0]);
    child(fn, ctx, lim, dp[1], op[1], leak_check);
  }
  close(dp[1]);
  close(op[1]);
  recv_buf data = {0}, out = {0};
  int killed = collect(pid, dp[0], op[0], lim->seconds, &data, &out);
  close(dp[0]);
  close(op[0]);
  int ws = 0;
  while (waitpid(pid, &ws, 0) < 0 && errno == EINTR) {
  }
  res->seconds = now_s() - t0;
  res->memory_limited = lim->memory_mb > 0 && cv_child_memory_limit_applies();
  res->data = data.p;
  res->data_n = data.n;
  res->output = (char *)out.p;
  res->output_n = out.n;
  classify(res, ws, killed, data.failed);
  return CV_OK;
}

void cv_child_result_free(cv_child_result *res) {
  if (!res) return;
  free(res->data);
  free(res->output);
  res->data = NULL;
  res->output = NULL;
  res->data_n = res->output_n = 0;
}

const char *cv_child_signal_name(int sig, char *buf, size_t n) {
  static const struct {
    int sig;
    const char *name;
  } names[] = {{SIGSEGV, "SIGSEGV"}, {SIGABRT, "SIGABRT"}, {SIGBUS, "SIGBUS"},
               {SIGFPE, "SIGFPE"},   {SIGILL, "SIGILL"},   {SIGKILL, "SIGKILL"},
               {SIGTERM, "SIGTERM"}, {SIGXCPU, "SIGXCPU"}, {SIGXFSZ, "SIGXFSZ"},
               {SIGPIPE, "SIGPIPE"}, {SIGTRAP, "SIGTRAP"}, {SIGSYS, "SIGSYS"},
               {SIGINT, "SIGINT"},   {SIGHUP, "SIGHUP"},   {SIGALRM, "SIGALRM"}};
  for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
    if (names[i].sig == sig) return names[i].name;
  snprintf(buf, n, "signal %d", sig);
  return buf;
}

int cv_child_error(const cv_child_result *res, const cv_child_limits *lim,
                   const cv_child_labels *lab, cv_err *err) {
  const char *p = lab->path ? lab->path : "?", *w = lab->what ? lab->what : "child";
  char sb[24];
  switch (res->outcome) {
  case CV_CHILD_DONE:
    return CV_OK;
  case CV_CHILD_TIMEOUT:
    return cv_err_set(err, CV_ERR_RANGE, "%s: %s stopped after %.1f s: time limit %g s hit (%s sets it)",
                      p, w, res->seconds, lim ? lim->seconds : 0.0, lab->timeout_env);
  case CV_CHILD_MEMORY:
    return cv_err_set(err, CV_ERR_NOMEM, "%s: %s stopped: memory limit %.0f MB hit (%s sets it)", p, w,
                      lim ? lim->memory_mb : 0.0, lab->memory_env);
  case CV_CHILD_SIGNAL:
    return cv_err_set(err, CV_ERR_BACKEND, "%s: %s crashed: signal %s (%s) in %s", p, w,
                      cv_child_signal_name(res->signal, sb, sizeof sb), strsignal(res->signal),
                      lab->library ? lab->library : "the child");
  case CV_CHILD_RECEIVE:
    return cv_err_set(err, CV_ERR_NOMEM, "%s: %s: out of memory receiving the result", p, w);
  case CV_CHILD_FAILED:
    break;
  }
  if (res->status != CV_ERR_BACKEND)
    return cv_err_set(err, res->status, "%s: %s failed: %s", p, w, cv_status_str(res->status));
  return cv_err_set(err, CV_ERR_BACKEND, "%s: %s failed: child exit status %d%s", p, w, res->exit_code,
                    res->output_n && strstr(res->output, "Sanitizer") ? " (a sanitizer report)" : "");
}

void cv_child_show_output(const cv_child_result *res, const char *whose) {
  if (!res->output_n) return;
  fprintf(stderr, "--- output of %s ---\n", whose);
  fwrite(res->output, 1, res->output_n, stderr);
  if (res->output[res->output_n - 1] != '\n') fputc('\n', stderr);
  fprintf(stderr, "--- end of output ---\n");
}
