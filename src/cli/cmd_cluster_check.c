/* `cave cluster check CONFIG`: the pre-flight of a multi-host CAVE.  For
 * every host of the rank layout (view/deploy.h), the master's host first,
 * runs `cave cluster probe` there through the remote shell (--rsh, default
 * ssh; a host "localhost" runs it here) and compares what it says:
 *   - the same cave build (hash of the program's bytes) as the master's host;
 *   - the same scene file (hash of its bytes) as the master's host, readable;
 *   - the out folder writable;
 *   - with windows (--present window), each output's X display reachable;
 *   - each output's GPU present (its renderer; "software" or "auto" accept
 *     llvmpipe, a hardware index needs that hardware device);
 *   - the clock within --max-offset-ms of the master's host's (NTP style:
 *     eight "t" exchanges over the probe's stdin/stdout, the one with the
 *     smallest round trip).
 * Prints one line per problem naming the host and its outputs (ranks) and
 * exits 1; else a line per host and exit 0. */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "cli/cli.h"
#include "cli/cluster_check.h"
#include "view/cave.h"
#include "view/deploy.h"

extern char **environ;

#define MAX_ITEMS 32
#define LINE 1024

typedef struct check_opts {
  const char *cfg, *scene, *out, *gpu, *rsh, *master, *farm;
  int windows, n_gather;
  double max_offset_s, timeout_s;
} check_opts;

/* What is asked of one host, and what its probe answered. */
typedef struct host_check {
  const char *host;
  char disp[MAX_ITEMS][64];
  int n_disp;
  char gpu[MAX_ITEMS][16];
  int n_gpu;
  int answered;          /* the probe reached "clock" */
  char fail[LINE];       /* why it did not */
  char facts[64][LINE];  /* its lines up to "clock" */
  int n_facts;
  double offset, rtt;    /* this host's clock minus this machine's, s; best round trip */
} host_check;

typedef struct line_reader {
  int fd;
  char buf[8192];
  size_t len;
} line_reader;

static double now_real(void) {
  struct timespec t;
  clock_gettime(CLOCK_REALTIME, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Reads one line (without its newline) before the deadline; -1 on end of
 * input or time out. */
static int read_line(line_reader *r, char *line, size_t cap, double deadline) {
  for (;;) {
    char *nl = memchr(r->buf, '\n', r->len);
    if (nl) {
      size_t n = (size_t)(nl - r->buf);
      snprintf(line, cap, "%.*s", (int)n, r->buf);
      memmove(r->buf, nl + 1, r->len - n - 1);
      r->len -= n + 1;
      return 0;
    }
    double left = deadline - now_real();
    if (left <= 0 || r->len == sizeof r->buf) return -1;
    struct pollfd p = {r->fd, POLLIN, 0};
    if (poll(&p, 1, (int)(left * 1000) + 1) <= 0) continue;
    ssize_t got = read(r->fd, r->buf + r->len, sizeof r->buf - r->len);
    if (got <= 0) return -1;
    r->len += (size_t)got;
  }
}

/* Appends sep, then s as one single-quoted shell word, to cmd. */
static void shell_word(char *cmd, size_t cap, const char *sep, const char *s) {
  size_t n = strlen(cmd);
  n += (size_t)snprintf(cmd + n, n < cap ? cap - n : 0, "%s'", sep);
  for (; *s && n + 5 < cap; s++) {
    if (*s == '\'') n += (size_t)snprintf(cmd + n, cap - n, "'\\''");
    else cmd[n++] = *s, cmd[n] = 0;
  }
  snprintf(cmd + n, n < cap ? cap - n : 0, "'");
}

/* The probe's argument list for host h (argv[0]: this program's path). */
static int probe_args(const check_opts *o, const host_check *h, const char *self, char **av, int cap) {
  int n = 0;
  av[n++] = (char *)self, av[n++] = "cluster", av[n++] = "probe";
  if (o->scene) av[n++] = "--scene", av[n++] = (char *)o->scene;
  if (o->out) av[n++] = "-o", av[n++] = (char *)o->out;
  for (int i = 0; i < h->n_disp && n + 3 < cap; i++) av[n++] = "--display", av[n++] = (char *)h->disp[i];
  for (int i = 0; i < h->n_gpu && n + 3 < cap; i++) av[n++] = "--gpu", av[n++] = (char *)h->gpu[i];
  av[n] = NULL;
  return n;
}

/* Starts the probe on host h: here for localhost, else `RSH HOST 'cmd'`.
 * *to / *from: its stdin / stdout (stderr to *err).  The pid, or -1. */
static pid_t spawn_probe(const check_opts *o, const host_check *h, const char *self, int *to, int *from,
                         int *errfd) {
  char *pav[8 + 4 * MAX_ITEMS], *av[64], rsh[512], cmd[8192] = "";
  int np = probe_args(o, h, self, pav, (int)(sizeof pav / sizeof pav[0]));
  char **argv = pav;
  if (strcmp(h->host, "localhost")) {
    int n = 0;
    snprintf(rsh, sizeof rsh, "%s", o->rsh);
    for (char *s = NULL, *w = strtok_r(rsh, " \t", &s); w && n < 60; w = strtok_r(NULL, " \t", &s)) av[n++] = w;
    av[n++] = (char *)h->host;
    /* in this folder, as mpirun starts the ranks (relative paths mean the same) */
    char cwd[PATH_MAX];
    if (getcwd(cwd, sizeof cwd)) {
      snprintf(cmd, sizeof cmd, "cd");
      shell_word(cmd, sizeof cmd, " ", cwd);
      snprintf(cmd + strlen(cmd), sizeof cmd - strlen(cmd), " &&");
    }
    const char *xa = getenv("XAUTHORITY");
    if (xa && xa[0]) {
      snprintf(cmd + strlen(cmd), sizeof cmd - strlen(cmd), " XAUTHORITY=");
      shell_word(cmd, sizeof cmd, "", xa);
    }
    for (int i = 0; i < np; i++) shell_word(cmd, sizeof cmd, " ", pav[i]);
    av[n++] = cmd;
    av[n] = NULL;
    argv = av;
  }
  int pin[2], pout[2], perr[2];
  if (pipe(pin)) return -1;
  if (pipe(pout)) return close(pin[0]), close(pin[1]), -1;
  if (pipe(perr)) return close(pin[0]), close(pin[1]), close(pout[0]), close(pout[1]), -1;
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, pin[0], 0);
  posix_spawn_file_actions_adddup2(&fa, pout[1], 1);
  posix_spawn_file_actions_adddup2(&fa, perr[1], 2);
  int fds[6] = {pin[0], pin[1], pout[0], pout[1], perr[0], perr[1]};
  for (int i = 0; i < 6; i++) posix_spawn_file_actions_addclose(&fa, fds[i]);
  pid_t pid;
  int st = posix_spawnp(&pid, argv[0], &fa, NULL, argv, environ);
  posix_spawn_file_actions_destroy(&fa);
  close(pin[0]), close(pout[1]), close(perr[1]);
  if (st) {
    close(pin[1]), close(pout[0]), close(perr[0]);
    errno = st;
    return -1;
  }
  *to = pin[1], *from = pout[0], *errfd = perr[0];
  return pid;
}

/* The clock exchange: eight "t" lines; keeps the smallest round trip. */
static void measure_clock(host_check *h, int to, line_reader *r, double deadline) {
  char line[LINE];
  h->rtt = INFINITY;
  for (int k = 0; k < 8; k++) {
    const double t0 = now_real();
    if (write(to, "t\n", 2) != 2 || read_line(r, line, sizeof line, deadline) || strncmp(line, "t ", 2)) break;
    const double t3 = now_real(), t = strtod(line + 2, NULL);
    if (t3 - t0 < h->rtt) h->rtt = t3 - t0, h->offset = t - 0.5 * (t0 + t3);
  }
  if (write(to, "end\n", 4) != 4) { /* the probe ends on the end of input anyway */ }
}

/* The last line of what the probe (or the remote shell) said on stderr. */
static void stderr_tail(int fd, char *out, size_t cap) {
  char buf[4096];
  ssize_t n = read(fd, buf, sizeof buf - 1);
  buf[n > 0 ? n : 0] = 0;
  while (n > 0 && (buf[n - 1] == '\n' || buf[n - 1] == ' ')) buf[--n] = 0;
  char *last = strrchr(buf, '\n');
  const char *src = last ? last + 1 : buf;
  size_t len = strlen(src);
  if (len >= cap) len = cap - 1;
  memcpy(out, src, len);
  out[len] = 0;
}

/* Runs the probe on h and reads its facts and clock. */
static void run_probe(const check_opts *o, host_check *h, const char *self) {
  int to, from, errfd;
  pid_t pid = spawn_probe(o, h, self, &to, &from, &errfd);
  if (pid < 0) {
    snprintf(h->fail, sizeof h->fail, "cannot start the probe (%s %s ...): %s", o->rsh, h->host, strerror(errno));
    return;
  }
  line_reader r = {from, "", 0};
  const double deadline = now_real() + o->timeout_s;
  char line[LINE];
  while (!read_line(&r, line, sizeof line, deadline)) {
    if (!strcmp(line, "clock")) {
      h->answered = 1;
      measure_clock(h, to, &r, deadline);
      break;
    }
    if (h->n_facts < 64) snprintf(h->facts[h->n_facts++], LINE, "%s", line);
  }
  close(to);
  const int timed_out = now_real() >= deadline;
  int status = 0, killed = 0;
  for (int i = 0; i < 50 && waitpid(pid, &status, WNOHANG) == 0; i++) {
    struct timespec ms100 = {0, 100000000};
    nanosleep(&ms100, NULL);
    if (i == 49) kill(pid, SIGKILL), waitpid(pid, &status, 0), killed = 1;
  }
  if (!h->answered) {
    char tail[600];
    stderr_tail(errfd, tail, sizeof tail);
    const int remote = strcmp(h->host, "localhost") != 0;
    snprintf(h->fail, sizeof h->fail, "%s (%.100s%s%.64s %.300s cluster probe): %.400s",
             timed_out ? "the probe did not answer in time (--probe-timeout)" : "the probe failed",
             remote ? o->rsh : "", remote ? " " : "", remote ? h->host : "", self,
             tail[0] ? tail : killed ? "killed" : "no message");
  }
  close(from), close(errfd);
}

/* The fact line starting with key (and, for display/gpu, the item), or NULL. */
static const char *fact(const host_check *h, const char *key, const char *item) {
  char pre[128];
  snprintf(pre, sizeof pre, item ? "%s %s " : "%s ", key, item);
  for (int i = 0; i < h->n_facts; i++)
    if (!strncmp(h->facts[i], pre, strlen(pre))) return h->facts[i] + strlen(pre);
  return NULL;
}

static const char *eff_gpu(const check_opts *o, const cv_output *out, char *buf, size_t cap) {
  if (o->gpu) return o->gpu;
  if (out->gpu == CV_GPU_AUTO) return "auto";
  if (out->gpu == CV_GPU_SOFTWARE) return "software";
  snprintf(buf, cap, "%d", out->gpu);
  return buf;
}

static const char *eff_display(const cv_output *out) {
  const char *d = out->display[0] ? out->display : getenv("DISPLAY");
  return d ? d : "";
}

/* "rank 7 floor L, rank 8 floor R": h's ranks, only the render ranks on
 * display disp or gpu when given. */
static void who(const check_opts *o, const cv_deploy *d, const char *host, const char *disp, const char *gpu,
                char *buf, size_t cap) {
  size_t n = 0;
  buf[0] = 0;
  for (int i = 0; i < d->n_ranks && n + 64 < cap; i++) {
    const cv_deploy_rank *k = &d->ranks[i];
    if (strcmp(k->host, host)) continue;
    char g[16], what[96];
    if (k->role == CV_ROLE_RENDER) {
      const cv_output *out = &d->cave->outputs[k->output];
      if (disp && strcmp(eff_display(out), disp)) continue;
      if (gpu && strcmp(eff_gpu(o, out, g, sizeof g), gpu)) continue;
      snprintf(what, sizeof what, "%s %s", d->cave->walls[out->wall].name,
               out->eyes == 3 ? "LR" : out->eyes == 1 ? "L" : "R");
    } else {
      if (disp || gpu) continue;
      snprintf(what, sizeof what, "%s", k->role == CV_ROLE_MASTER ? "master" : "gather");
    }
    n += (size_t)snprintf(buf + n, cap - n, "%srank %d %s", n ? ", " : "", k->rank, what);
  }
}

/* What host h is asked: its outputs' X displays (with windows) and GPUs. */
static void host_needs(const check_opts *o, const cv_deploy *d, host_check *h) {
  for (int i = 0; i < d->n_ranks; i++) {
    const cv_deploy_rank *k = &d->ranks[i];
    if (k->role != CV_ROLE_RENDER || strcmp(k->host, h->host)) continue;
    const cv_output *out = &d->cave->outputs[k->output];
    char g[16];
    const char *gs = eff_gpu(o, out, g, sizeof g), *ds = eff_display(out);
    int have = 0;
    for (int j = 0; j < h->n_gpu; j++) have |= !strcmp(h->gpu[j], gs);
    if (!have && h->n_gpu < MAX_ITEMS) snprintf(h->gpu[h->n_gpu++], sizeof h->gpu[0], "%s", gs);
    if (!o->windows) continue;
    have = 0;
    for (int j = 0; j < h->n_disp; j++) have |= !strcmp(h->disp[j], ds);
    if (!have && h->n_disp < MAX_ITEMS) snprintf(h->disp[h->n_disp++], sizeof h->disp[0], "%s", ds);
  }
}

#define PROBLEM(...) (fprintf(stderr, "cave cluster check: " __VA_ARGS__), fputc('\n', stderr), problems++)

/* The problems of host h against the master's host m; their count. */
static int host_problems(const check_opts *o, const cv_deploy *d, const host_check *h, const host_check *m) {
  int problems = 0;
  char ranks[2048], sub[2048];
  who(o, d, h->host, NULL, NULL, ranks, sizeof ranks);
  if (!h->answered) {
    PROBLEM("%s (%s): %s", h->host, ranks, h->fail);
    return problems;
  }
  const char *b = fact(h, "build", NULL), *mb = fact(m, "build", NULL);
  if (!b || strncmp(b, "error", 5) == 0) PROBLEM("%s (%s): cave build: %s", h->host, ranks, b ? b + 6 : "not said");
  else if (h != m && mb && strncmp(b, mb, 16))
    PROBLEM("%s (%s): another cave build: %.16s (%s) against %.16s on the master's host %s", h->host, ranks, b,
            b + 17, mb, m->host);
  const char *s = fact(h, "scene", NULL), *ms = fact(m, "scene", NULL);
  if (o->scene && (!s || strncmp(s, "ok ", 3)))
    PROBLEM("%s (%s): scene %s", h->host, ranks, s ? s + 6 : "not said");
  else if (o->scene && h != m && ms && !strncmp(ms, "ok ", 3) && strcmp(s, ms))
    PROBLEM("%s (%s): another scene file %s: hash %s against %s on the master's host %s", h->host, ranks, o->scene,
            s + 3, ms + 3, m->host);
  const char *f = fact(h, "out", NULL);
  if (o->out && (!f || strcmp(f, "ok"))) PROBLEM("%s (%s): out folder %s", h->host, ranks, f ? f + 6 : "not said");
  for (int i = 0; i < h->n_disp; i++) {
    const char *x = fact(h, "display", h->disp[i]);
    who(o, d, h->host, h->disp[i], NULL, sub, sizeof sub);
    if (!x || strcmp(x, "ok"))
      PROBLEM("%s, X display '%s' (%s): %s", h->host, h->disp[i], sub, x ? x + 6 : "not said");
  }
  for (int i = 0; i < h->n_gpu; i++) {
    const char *x = fact(h, "gpu", h->gpu[i]);
    who(o, d, h->host, NULL, h->gpu[i], sub, sizeof sub);
    if (!x || strncmp(x, "ok ", 3)) PROBLEM("%s, GPU %s (%s): %s", h->host, h->gpu[i], sub, x ? x + 6 : "not said");
  }
  const double off = h->offset - m->offset, unc = 0.5 * (h->rtt + m->rtt);
  if (isfinite(off) && isfinite(unc) && fabs(off) - unc > o->max_offset_s)
    PROBLEM("%s (%s): clock %+.3f s (+- %.3f s) off the master's host %s, more than --max-offset-ms %.0f", h->host,
            ranks, off, unc, m->host, 1000 * o->max_offset_s);
  return problems;
}

/* One line per host that passed. */
static void host_summary(const host_check *h, const host_check *m) {
  const char *b = fact(h, "build", NULL), *s = fact(h, "scene", NULL);
  printf("cave cluster check: %s: build %.16s, scene %s, clock %+.1f ms (+- %.1f ms) off %s", h->host, b ? b : "?",
         s ? s + 3 : "not asked", 1000 * (h->offset - m->offset), 500 * (h->rtt + m->rtt), m->host);
  for (int i = 0; i < h->n_disp; i++) printf(", X %s ok", h->disp[i]);
  for (int i = 0; i < h->n_gpu; i++) {
    const char *x = fact(h, "gpu", h->gpu[i]);
    printf(", GPU %s: %s", h->gpu[i], x ? x + 3 : "?");
  }
  printf("\n");
}

static void check_help(FILE *f) {
  fprintf(f,
          "usage: cave cluster check <cave.json> [--scene FILE] [-o DIR] [--present WHAT] [--gpu G]\n"
          "                          [--rsh CMD] [--max-offset-ms MS] [--probe-timeout S]\n"
          "                          [--gather N | --farm HOSTFILE] [--master-host H]\n\n"
          "The pre-flight of a multi-host CAVE: runs `cave cluster probe` on every host of the\n"
          "rank layout (cave cluster rankfile's, the master's host first) through the remote\n"
          "shell and checks, before anything starts:\n"
          "  - the same cave build (hash of the program at this program's path) as the master's host;\n"
          "  - the same scene file (--scene, hash of its bytes), readable on every host;\n"
          "  - the out folder (-o) writable (created when missing);\n"
          "  - with --present window (or a list with it): each output's X display reachable;\n"
          "  - each output's GPU (its \"gpu\", or --gpu for all): a context on that EGL device\n"
          "    (\"software\" and \"auto\" accept llvmpipe, an index needs that hardware device);\n"
          "  - the clock within --max-offset-ms (default 100) of the master's host's.\n"
          "One line per problem on stderr, naming the host and its ranks/outputs; exit 1.  All\n"
          "good: one line per host on stdout, exit 0.\n\n"
          "  --rsh CMD          remote shell, split on blanks (default: $CAVE_RSH, else ssh); a\n"
          "                     host named localhost is probed here\n"
          "  --probe-timeout S  seconds a host's probe may take (default 60)\n"
          "  --scene, -o, --present, --gpu: as in cave run; --gather, --farm, --master-host:\n"
          "  as in cave cluster rankfile.  Exit status: 0 ready, 1 problems, 2 usage error.\n");
}

static int parse_check(int argc, char **argv, check_opts *o) {
  memset(o, 0, sizeof *o);
  o->rsh = getenv("CAVE_RSH") && getenv("CAVE_RSH")[0] ? getenv("CAVE_RSH") : "ssh";
  o->max_offset_s = 0.1, o->timeout_s = 60;
  for (int i = 2; i < argc; i++) {
    const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
    double x;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) return check_help(stdout), 1;
    if (a[0] != '-') {
      if (o->cfg) return cli_fail("cluster check", 2, "unexpected argument '%s' (cave cluster check --help)", a);
      o->cfg = a;
      continue;
    }
    if (!v) return cli_fail("cluster check", 2, "%s: expected a value (cave cluster check --help)", a);
    i++;
    if (!strcmp(a, "--scene")) o->scene = v;
    else if (!strcmp(a, "-o")) o->out = v;
    else if (!strcmp(a, "--present")) o->windows = strstr(v, "window") != NULL;
    else if (!strcmp(a, "--rsh")) o->rsh = v;
    else if (!strcmp(a, "--master-host")) o->master = v;
    else if (!strcmp(a, "--farm")) o->farm = v;
    else if (!strcmp(a, "--gpu")) {
      int g;
      if (cv_gpu_parse(v, &g)) return cli_fail("cluster check", 2, "--gpu: expected auto, software or a hardware device index, got '%s'", v);
      o->gpu = v;
    } else if (!strcmp(a, "--gather")) {
      if (cli_parse_int(v, 0, CV_DEPLOY_MAX_RANKS, &o->n_gather))
        return cli_fail("cluster check", 2, "--gather: expected a rank count 0..%d, got '%s'", CV_DEPLOY_MAX_RANKS, v);
    } else if (!strcmp(a, "--max-offset-ms")) {
      if (cli_parse_double(v, &x) || !(x > 0)) return cli_fail("cluster check", 2, "--max-offset-ms: expected milliseconds > 0, got '%s'", v);
      o->max_offset_s = x / 1000;
    } else if (!strcmp(a, "--probe-timeout")) {
      if (cli_parse_double(v, &x) || !(x > 0)) return cli_fail("cluster check", 2, "--probe-timeout: expected seconds > 0, got '%s'", v);
      o->timeout_s = x;
    } else {
      return cli_fail("cluster check", 2, "unknown option '%s' (cave cluster check --help)", a);
    }
  }
  if (!o->cfg) return cli_fail("cluster check", 2, "expected a CAVE config (e.g. configs/caves/cave5-2hosts.json)");
  return 0;
}

/* Probes every host of the plan and prints the verdict; the exit status. */
static int check_hosts(const check_opts *o, const cv_deploy *d) {
  char self[PATH_MAX];
  ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
  if (n <= 0) return cli_fail("cluster check", 1, "cannot find this program's path (/proc/self/exe)");
  self[n] = 0;
  host_check *hs = calloc((size_t)d->n_hosts, sizeof *hs);
  if (!hs) return cli_fail("cluster check", 1, "out of memory");
  for (int i = 0; i < d->n_hosts; i++) {
    hs[i].host = d->hosts[i].name;
    hs[i].offset = NAN, hs[i].rtt = NAN;
    host_needs(o, d, &hs[i]);
    run_probe(o, &hs[i], self);
  }
  int problems = 0;
  for (int i = 0; i < d->n_hosts; i++) problems += host_problems(o, d, &hs[i], &hs[0]);
  if (problems) {
    fprintf(stderr, "cave cluster check: %d problem%s on %d host%s: nothing started\n", problems,
            problems > 1 ? "s" : "", d->n_hosts, d->n_hosts > 1 ? "s" : "");
  } else {
    for (int i = 0; i < d->n_hosts; i++) host_summary(&hs[i], &hs[0]);
    printf("cave cluster check: %d host%s ready\n", d->n_hosts, d->n_hosts > 1 ? "s" : "");
  }
  free(hs);
  return problems ? 1 : 0;
}

int cmd_cluster_check(int argc, char **argv) {
  check_opts o;
  int st = parse_check(argc, argv, &o);
  if (st) return st == 1 ? 0 : st;
  static cv_cave cave; /* large: not on the stack */
  static char buf[8192];
  int n = 0;
  cv_err err;
  cv_err_clear(&err);
  if (cv_cave_load_all(o.cfg, &cave, buf, sizeof buf, &n, &err)) {
    fprintf(stderr, "cave cluster check: %s\n", buf[0] ? buf : err.msg);
    return 1;
  }
  cv_farm farm;
  memset(&farm, 0, sizeof farm);
  if (o.farm && cv_farm_load(o.farm, &farm, &err)) return cli_fail("cluster check", 1, "--farm: %s", err.msg);
  cv_deploy_opts dopt = {o.master, o.n_gather, o.farm ? &farm : NULL, 0};
  cv_deploy d;
  st = cv_deploy_plan(&cave, &dopt, &d, &err);
  cv_farm_free(&farm);
  if (st) return cli_fail("cluster check", st == CV_ERR_INVALID ? 2 : 1, "%s", err.msg);
  st = check_hosts(&o, &d);
  cv_deploy_free(&d);
  return st;
}
