/* The output folder's lock (see dirlock.h). */
#include "core/dirlock.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define LOCK_NAME ".cave.lock"

static void lock_path(const char *dir, char *p, size_t cap) { snprintf(p, cap, "%s/" LOCK_NAME, dir); }

/* The holder's line, for the refusal. */
static void read_holder(int fd, char *buf, size_t cap) {
  ssize_t n = pread(fd, buf, cap - 1, 0);
  if (n < 0) n = 0;
  buf[n] = '\0';
  char *nl = strchr(buf, '\n');
  if (nl) *nl = '\0';
  if (!buf[0]) snprintf(buf, cap, "holder unknown");
}

int cv_dirlock_take(const char *dir, int *fd, cv_err *err) {
  *fd = -1;
  char p[4200];
  lock_path(dir, p, sizeof p);
  /* A holder that releases unlinks the file: a lock taken on an unlinked
   * file is no lock, so take it again on the file now at the path. */
  for (int attempt = 0; attempt < 5; attempt++) {
    int f = open(p, O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (f < 0) return cv_err_set(err, CV_ERR_IO, "%s: cannot create the lock file: %s", p, strerror(errno));
    if (flock(f, LOCK_EX | LOCK_NB) != 0) {
      const int e = errno;
      char who[256];
      read_holder(f, who, sizeof who);
      close(f);
      if (e == EWOULDBLOCK)
        return cv_err_set(err, CV_ERR_IO,
                          "%s: another cave run (%s) writes into this folder (lock %s): give another -o",
                          dir, who, LOCK_NAME);
      return cv_err_set(err, CV_ERR_IO, "%s: cannot lock: %s", p, strerror(e));
    }
    struct stat a, b;
    if (fstat(f, &a) == 0 && stat(p, &b) == 0 && a.st_ino == b.st_ino && a.st_dev == b.st_dev) {
      char host[128] = "?", line[512];
      gethostname(host, sizeof host);
      host[sizeof host - 1] = '\0';
      char when[32] = "?";
      time_t now = time(NULL);
      struct tm tm;
      if (localtime_r(&now, &tm)) strftime(when, sizeof when, "%Y-%m-%d %H:%M:%S", &tm);
      int n = snprintf(line, sizeof line, "pid %ld on host %s since %s\n", (long)getpid(), host, when);
      if (ftruncate(f, 0) != 0 || pwrite(f, line, (size_t)n, 0) != n) { /* the lock holds without its text */
      }
      *fd = f;
      return CV_OK;
    }
    close(f); /* released and removed meanwhile: again */
  }
  return cv_err_set(err, CV_ERR_IO, "%s: cannot take the lock (removed and made again 5 times)", p);
}

void cv_dirlock_release(const char *dir, int fd) {
  if (fd < 0) return;
  char p[4200];
  lock_path(dir, p, sizeof p);
  unlink(p); /* still holding it: a waiting run sees the file gone and retries */
  close(fd);
}
