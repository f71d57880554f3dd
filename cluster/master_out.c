/* The master's out folder (issue 35, defects 2 and 9): metrics lines whole
 * or not at all, failures said and stopping the run, the last line true. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include "master_internal.h"

int master_out_open(master *m, cv_err *err) {
  cv_service *s = m->s;
  if (s->o.metrics_path[0]) snprintf(m->metrics_path, sizeof m->metrics_path, "%s", s->o.metrics_path);
  else snprintf(m->metrics_path, sizeof m->metrics_path, "%s/metrics.jsonl", s->o.out_dir);
  m->mf = fopen(m->metrics_path, "w");
  if (!m->mf) return cv_err_set(err, CV_ERR_IO, "%s: cannot write the metrics: %s", m->metrics_path, strerror(errno));
  m->metrics_good = 0;
  return CV_OK;
}

/* Free space on the disk of path, in KB (-1 unknown). */
static double free_kb(const char *path) {
  struct statvfs fs;
  return statvfs(path, &fs) == 0 ? (double)fs.f_bavail * (double)fs.f_frsize / 1024.0 : -1;
}

static void out_stop(master *m, const char *why) {
  if (!m->stop_code) {
    m->stop_code = MASTER_STOP_OUT;
    snprintf(m->stop_reason, sizeof m->stop_reason, "%.299s", why);
  }
  fprintf(stderr, "cave run: stopping: %s\n", why);
}

/* The k-th rotated name of the metrics file: metrics.jsonl -> metrics.k.jsonl,
 * any other name gets ".k" appended. */
static void rotated_name(const char *path, int k, char *out, size_t cap) {
  const size_t n = strlen(path);
  if (n > 6 && !strcmp(path + n - 6, ".jsonl")) snprintf(out, cap, "%.*s.%d.jsonl", (int)(n - 6), path, k);
  else snprintf(out, cap, "%s.%d", path, k);
}

/* Rotation (--metrics-max-mb, --metrics-keep): the file closed after its last
 * whole line, the older ones shifted up (the oldest deleted), a new file
 * opened.  0, or -1 with m->metrics_err set. */
static int metrics_rotate(master *m) {
  const int keep = m->s->o.metrics_keep;
  char a[4300], b[4300];
  if (fclose(m->mf) != 0) {
    m->mf = NULL;
    snprintf(m->metrics_err, sizeof m->metrics_err, "%.250s: close before rotation failed: %.60s", m->metrics_path,
             strerror(errno));
    return -1;
  }
  m->mf = NULL;
  rotated_name(m->metrics_path, keep, a, sizeof a);
  if (unlink(a) != 0 && errno != ENOENT) {
    snprintf(m->metrics_err, sizeof m->metrics_err, "%.250s: cannot delete the oldest: %.60s", a, strerror(errno));
    return -1;
  }
  for (int k = keep - 1; k >= 0; k--) {
    if (k) rotated_name(m->metrics_path, k, a, sizeof a);
    else snprintf(a, sizeof a, "%s", m->metrics_path);
    rotated_name(m->metrics_path, k + 1, b, sizeof b);
    if (rename(a, b) != 0 && (errno != ENOENT || k == 0)) {
      snprintf(m->metrics_err, sizeof m->metrics_err, "rotation: cannot rename %.150s to %.150s: %.60s", a, b,
               strerror(errno));
      return -1;
    }
  }
  m->mf = fopen(m->metrics_path, "w");
  if (!m->mf) {
    snprintf(m->metrics_err, sizeof m->metrics_err, "%.250s: cannot open after rotation: %.60s", m->metrics_path,
             strerror(errno));
    return -1;
  }
  m->metrics_good = 0;
  m->metrics_rotations++;
  return 0;
}

/* The line in m->ml, appended whole: a write that fails (a full disk) is cut
 * back to the last whole line (the file stays JSON lines) and stops the run;
 * so does a metrics file deleted under the run (its lines would go nowhere). */
void master_metrics_put(master *m) {
  if (m->metrics_err[0] || !m->mf) {
    cv_metrics_begin(m->ml); /* already failed: said once */
    return;
  }
  struct stat st;
  const double max_b = m->s->o.metrics_max_mb * 1e6;
  if (max_b > 0 && m->metrics_good > 0 && (double)m->metrics_good + (double)cv_metrics_length(m->ml) > max_b &&
      metrics_rotate(m) != 0) {
    cv_metrics_begin(m->ml);
  } else if (fstat(fileno(m->mf), &st) == 0 && st.st_nlink == 0) {
    snprintf(m->metrics_err, sizeof m->metrics_err, "%.300s was deleted during the run (its folder removed?)",
             m->metrics_path);
    cv_metrics_begin(m->ml);
  } else if (cv_metrics_write(m->ml, m->mf) != CV_OK) {
    const int e = errno ? errno : EIO;
    clearerr(m->mf);
    /* the buffered part is dropped with the file's tail */
    if (ftruncate(fileno(m->mf), m->metrics_good) != 0 || fseeko(m->mf, m->metrics_good, SEEK_SET) != 0) {
    }
    snprintf(m->metrics_err, sizeof m->metrics_err, "%.250s: write failed: %.60s (%.0f KB free on its disk)",
             m->metrics_path, strerror(e), free_kb(m->metrics_path));
  } else {
    m->metrics_good = ftello(m->mf);
    return;
  }
  char why[600];
  snprintf(why, sizeof why, "metrics: %.450s", m->metrics_err);
  out_stop(m, why);
}

void master_out_files_failed(master *m, int rank, uint64_t failed, const char *first) {
  if (!failed || m->files_stop_said) return;
  m->files_stop_said = 1;
  char why[900];
  snprintf(why, sizeof why, "rank %d could not write %llu frames' files into %.300s (%.0f KB free on its disk): %.300s",
           rank, (unsigned long long)failed, m->s->o.out_dir, free_kb(m->s->o.out_dir),
           first ? first : "the rank's message above");
  out_stop(m, why);
}

void master_out_final_line(master *m) {
  if (m->s->o.quiet && !m->metrics_err[0]) return;
  if (m->metrics_err[0])
    printf("cave run: %zu frames; metrics INCOMPLETE (no summary): %s\n", m->nframes_done, m->metrics_err);
  else
    printf("cave run: %zu frames; metrics in %s%s\n", m->nframes_done, m->metrics_path,
           m->metrics_rotations ? " (and the rotated files before it)" : "");
}

void master_prt_check(master *m, int from, const uint8_t *data, long len) {
  uint64_t h = 0;
  if (len < 9 || data[0] != 'O') return; /* a failed set-up says why itself */
  memcpy(&h, data + 1, 8);
  if (!h || h == m->prt_hash) return;
  if (!m->prt_nbad++) m->prt_bad_hash = h;
  /* the list kept in rank order, whatever order the ready lines came in */
  int ranks[256], n = 0;
  for (const char *p = m->prt_bad; *p && n < 255;) {
    char *end;
    ranks[n++] = (int)strtol(p, &end, 10);
    p = *end ? end + 2 : end;
  }
  int k = n++;
  while (k > 0 && ranks[k - 1] > from) ranks[k] = ranks[k - 1], k--;
  ranks[k] = from;
  size_t l = 0;
  m->prt_bad[0] = 0;
  for (int i = 0; i < n && l < sizeof m->prt_bad; i++)
    l += (size_t)snprintf(m->prt_bad + l, sizeof m->prt_bad - l, "%s%d", i ? ", " : "", ranks[i]);
}

int master_prt_mismatch(master *m, char *why, size_t cap) {
  if (!m->prt_nbad) return 0;
  snprintf(why, cap,
           "%s changed while the ranks started: rank%s %s loaded another file than the master (content hash "
           "%016llx, the master's %016llx); the eyes would show different bakes: start again",
           m->s->o.scene_path, m->prt_nbad > 1 ? "s" : "", m->prt_bad, (unsigned long long)m->prt_bad_hash,
           (unsigned long long)m->prt_hash);
  return 1;
}

double master_stall_check(master *m) {
  const double now = cv_service_now(), gap = m->stall_last > 0 ? now - m->stall_last : 0;
  m->stall_last = now;
  if (gap < 0.5) return 0;
  m->stalls++;
  m->stalled_s += gap;
  /* the ranks were not silent: the master was not looking */
  for (int r = 1; m->owed_t && r < m->s->size; r++) {
    if (m->owed_t[r] > 0) m->owed_t[r] += gap;
    if (m->alive_t[r] > 0) m->alive_t[r] += gap;
  }
  if (gap >= 1.0)
    fprintf(stderr, "cave run: master: did not run for %.1f s (stopped or starved of CPU): its waits for the "
            "ranks moved by that, no rank counted late for it\n", gap);
  return gap;
}
