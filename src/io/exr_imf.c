/* The EXR reader's C++ fallback decoder, guarded (exr_imf.h). */
#include "io/exr_imf.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include <ImfCRgbaFile.h>

#include "io/child_guard.h"

_Static_assert(sizeof(ImfRgba) == 4 * sizeof(uint16_t), "ImfRgba is 4 halves");

void cv_exr_guard_default(cv_exr_guard *g) {
  memset(g, 0, sizeof *g);
  g->seconds = cv_child_env_limit("CAVE_EXR_TIMEOUT", CV_EXR_DEFAULT_SECONDS);
  g->memory_mb = cv_child_env_limit("CAVE_EXR_MEMORY_MB", -1.0);
  const char *v = getenv("CAVE_EXR_VERBOSE");
  g->verbose = v && v[0] == '1';
}

uint16_t *cv_exr_rgba_alloc(size_t w, size_t h) {
  size_t bytes = w * h * sizeof(ImfRgba);
  if (!bytes || bytes / sizeof(ImfRgba) / w != h) return NULL;
  void *p = mmap(NULL, bytes, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  return p == MAP_FAILED ? NULL : p;
}

void cv_exr_rgba_free(uint16_t *px, size_t w, size_t h) {
  if (px) munmap(px, w * h * sizeof(ImfRgba));
}

/* The decode itself, in whichever process runs it. */
static int decode_here(const char *path, const cv_exr_window *win, uint16_t *px, cv_err *err) {
  ImfInputFile *in = ImfOpenInputFile(path);
  if (!in)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: not a readable OpenEXR file: %s", path, ImfErrorMessage());
  int chans = ImfInputChannels(in);
  if (!(chans & (IMF_WRITE_R | IMF_WRITE_G | IMF_WRITE_B | IMF_WRITE_Y))) {
    ImfCloseInputFile(in);
    return cv_err_set(err, CV_ERR_FORMAT, "%s: no R,G,B or Y channels", path);
  }
  /* The frame buffer is addressed with absolute data-window coordinates. */
  const ptrdiff_t w = win->w;
  ImfRgba *base = (ImfRgba *)px - (ptrdiff_t)win->min_x - (ptrdiff_t)win->min_y * w;
  int ok = ImfInputSetFrameBuffer(in, base, 1, (size_t)w) &&
           ImfInputReadPixels(in, win->min_y, win->min_y + win->h - 1);
  int rc = ok ? CV_OK
              : cv_err_set(err, CV_ERR_FORMAT, "%s: cannot decode pixels: %s", path, ImfErrorMessage());
  ImfCloseInputFile(in);
  return rc;
}

/* What the child sends back; the pixels are in the shared buffer. */
typedef struct reply {
  int32_t status;
  char msg[512];
} reply;

typedef struct decode_job {
  const char *path;
  const cv_exr_window *win;
  uint16_t *px;
} decode_job;

static int decode_child(void *ctx, int fd) {
  const decode_job *job = ctx;
  reply r;
  memset(&r, 0, sizeof r);
  cv_err e;
  cv_err_clear(&e);
  r.status = decode_here(job->path, job->win, job->px, &e);
  snprintf(r.msg, sizeof r.msg, "%s", e.msg);
  return cv_child_write(fd, &r, sizeof r) ? CV_ERR_IO : CV_OK;
}

int cv_exr_imf_decode(const char *path, const cv_exr_window *win, double raw_bytes, uint16_t *px,
                      const cv_exr_guard *g, cv_err *err) {
  cv_exr_guard def;
  if (!g) {
    cv_exr_guard_default(&def);
    g = &def;
  }
  /* a bad CAVE_EXR_TIMEOUT / CAVE_EXR_MEMORY_MB is refused, not read as the default */
  if (cv_child_env_check("CAVE_EXR_TIMEOUT", g->seconds, "seconds >= 0 (0 = none)", err) ||
      cv_child_env_check("CAVE_EXR_MEMORY_MB", g->memory_mb, "megabytes >= 0 (0 = none)", err))
    return CV_ERR_RANGE;
  if (g->in_process) return decode_here(path, win, px, err);
  if (!cv_child_single_threaded()) {
    /* a fork of a threaded process (the service's LCD worker, OpenMP or
     * Embree threads) may deadlock in the child on a lock held at the fork:
     * decoded here, after the header walk's checks (docs/fuzzing.md) */
    if (g->verbose)
      fprintf(stderr, "%s: EXR decode in this process (it has threads: no guarded child)\n", path);
    return decode_here(path, win, px, err);
  }
  cv_child_limits lim = {g->seconds, g->memory_mb};
  if (lim.memory_mb < 0) lim.memory_mb = CV_EXR_BASE_MEMORY_MB + 2.0 * raw_bytes / 1048576.0;
  const cv_child_labels lab = {path, "EXR decode", "OpenEXR", "CAVE_EXR_TIMEOUT", "CAVE_EXR_MEMORY_MB"};
  decode_job job = {path, win, px};
  cv_child_result res;
  int st = cv_child_run(decode_child, &job, &lim, &res, err);
  if (st != CV_OK) {
    cv_err_prefix(err, "%s: EXR decode", path);
    return st;
  }
  if (res.outcome != CV_CHILD_DONE) {
    st = cv_child_error(&res, &lim, &lab, err);
  } else if (res.data_n != sizeof(reply)) {
    st = cv_err_set(err, CV_ERR_BACKEND, "%s: EXR decode: the child process sent %zu bytes, expected %zu",
                    path, res.data_n, sizeof(reply));
  } else {
    reply r;
    memcpy(&r, res.data, sizeof r);
    r.msg[sizeof r.msg - 1] = '\0';
    st = r.status;
    if (st != CV_OK && res.memory_limited && strstr(r.msg, "bad_alloc")) {
      /* the library caught its own std::bad_alloc: under a limit, that is the limit */
      st = cv_err_set(err, CV_ERR_NOMEM, "%s: EXR decode stopped: memory limit %.0f MB hit (%s sets it)",
                      path, lim.memory_mb, lab.memory_env);
    } else if (st != CV_OK) {
      cv_err_set(err, st, "%s", r.msg);
    }
  }
  if (g->verbose) {
    char whose[600];
    snprintf(whose, sizeof whose, "the EXR decode of %s", path);
    cv_child_show_output(&res, whose);
  }
  cv_child_result_free(&res);
  return st;
}
