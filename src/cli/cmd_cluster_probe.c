/* `cave cluster probe`: what this host offers a CAVE run, for the pre-flight
 * (`cave cluster check`, cmd_cluster_check.c, runs it on every host through
 * the remote shell).  Prints one fact per line on stdout:
 *   host NAME
 *   build HASH PATH            FNV-1a 64 of this cave program's bytes
 *   scene ok HASH | scene error MESSAGE
 *   out ok | out error MESSAGE
 *   display D ok | display D error MESSAGE           (per --display)
 *   gpu G ok software|hardware RENDERER | gpu G error MESSAGE   (per --gpu)
 *   clock
 * then answers each "t" line on stdin with "t SECONDS" (CLOCK_REALTIME) until
 * "end" or the end of input: the checker measures the clock offset NTP style. */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "cli/cli.h"
#include "cli/cluster_check.h"
#include "core/hash.h"
#include "render/probe.h"
#include "view/cave.h"

int cv_file_hash(const char *path, uint64_t *h, char *why, size_t cap) {
  FILE *f = fopen(path, "rb");
  if (!f) return snprintf(why, cap, "%s: cannot read: %s", path, strerror(errno)), -1;
  static unsigned char buf[1 << 20];
  uint64_t x = cv_hash64_init();
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, f)) > 0) x = cv_hash64_update(x, buf, n);
  const int bad = ferror(f);
  fclose(f);
  if (bad) return snprintf(why, cap, "%s: read error", path), -1;
  *h = x;
  return 0;
}

/* The out folder: created if missing, a file written and removed there. */
static int out_writable(const char *dir, char *why, size_t cap) {
  char cmd[PATH_MAX + 16], tmp[PATH_MAX];
  struct stat st;
  if (stat(dir, &st)) {
    /* mkdir -p without a shell: each component in turn */
    snprintf(cmd, sizeof cmd, "%s", dir);
    for (char *p = cmd + 1; *p; p++)
      if (*p == '/') {
        *p = 0;
        if (mkdir(cmd, 0777) && errno != EEXIST) break;
        *p = '/';
      }
    if (mkdir(dir, 0777) && errno != EEXIST)
      return snprintf(why, cap, "%s: cannot create the folder: %s", dir, strerror(errno)), -1;
  } else if (!S_ISDIR(st.st_mode)) {
    return snprintf(why, cap, "%s: not a folder", dir), -1;
  }
  snprintf(tmp, sizeof tmp, "%s/.cave-probe.%ld", dir, (long)getpid());
  int fd = open(tmp, O_WRONLY | O_CREAT | O_EXCL, 0644);
  if (fd < 0) return snprintf(why, cap, "%s: cannot write there: %s", dir, strerror(errno)), -1;
  const int w = (int)write(fd, "x", 1);
  close(fd);
  unlink(tmp);
  if (w != 1) return snprintf(why, cap, "%s: cannot write there: %s", dir, strerror(errno)), -1;
  return 0;
}

static double realtime(void) {
  struct timespec t;
  clock_gettime(CLOCK_REALTIME, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void probe_gpu(const char *g) {
  int gpu = 0, soft = 0;
  char ren[256];
  cv_err err;
  cv_err_clear(&err);
  if (cv_gpu_parse(g, &gpu)) printf("gpu %s error expected auto, software or a hardware device index\n", g);
  else if (cv_probe_gpu(gpu, ren, sizeof ren, &soft, &err)) printf("gpu %s error %s\n", g, err.msg);
  else if (gpu >= 0 && soft) printf("gpu %s error a software renderer where hardware GPU %d was asked for: %s\n", g, gpu, ren);
  else printf("gpu %s ok %s %s\n", g, soft ? "software" : "hardware", ren);
}

static void answer_clock(void) {
  printf("clock\n");
  fflush(stdout);
  char line[64];
  while (fgets(line, sizeof line, stdin) && line[0] == 't') {
    printf("t %.9f\n", realtime());
    fflush(stdout);
  }
}

int cmd_cluster_probe(int argc, char **argv) {
  const char *scene = NULL, *out = NULL;
  for (int i = 2; i < argc; i++) {
    const char *a = argv[i];
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      printf("usage: cave cluster probe [--scene FILE] [-o DIR] [--display D]... [--gpu G]...\n\n"
             "What this host offers a CAVE run, one fact a line (the pre-flight of cave cluster\n"
             "check runs it on every host): the cave build's hash, the scene's hash, whether\n"
             "DIR is writable, each X display reachable, each GPU's renderer; then it answers\n"
             "'t' lines on stdin with this host's clock.  docs/deploy.md, \"Pre-flight\".\n");
      return 0;
    }
    if (i + 1 >= argc) return cli_fail("cluster probe", 2, "%s: expected a value (cave cluster probe --help)", a);
    if (!strcmp(a, "--scene")) scene = argv[++i];
    else if (!strcmp(a, "-o")) out = argv[++i];
    else if (!strcmp(a, "--display") || !strcmp(a, "--gpu")) i++;
    else return cli_fail("cluster probe", 2, "unknown option '%s' (cave cluster probe --help)", a);
  }
  char host[256] = "", why[PATH_MAX + 200], self[PATH_MAX];
  gethostname(host, sizeof host - 1);
  printf("host %s\n", host);
  uint64_t h = 0;
  ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
  self[n > 0 ? n : 0] = 0;
  if (n <= 0 || cv_file_hash(self, &h, why, sizeof why)) printf("build error cannot read this program (%s)\n", self);
  else printf("build %016llx %s\n", (unsigned long long)h, self);
  if (scene) {
    if (cv_file_hash(scene, &h, why, sizeof why)) printf("scene error %s\n", why);
    else printf("scene ok %016llx\n", (unsigned long long)h);
  }
  if (out) {
    if (out_writable(out, why, sizeof why)) printf("out error %s\n", why);
    else printf("out ok\n");
  }
  for (int i = 2; i + 1 < argc; i++) {
    cv_err err;
    cv_err_clear(&err);
    if (!strcmp(argv[i], "--display")) {
      if (cv_probe_display(argv[i + 1], &err)) printf("display %s error %s\n", argv[i + 1], err.msg);
      else printf("display %s ok\n", argv[i + 1]);
    } else if (!strcmp(argv[i], "--gpu")) {
      probe_gpu(argv[i + 1]);
    }
  }
  answer_clock();
  return 0;
}
