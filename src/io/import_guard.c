/* Guarded mesh import (mesh_import.h): assimp runs in a guarded child
 * (child_guard.h) under a memory limit and a wall-clock limit, so a file
 * that makes assimp loop or allocate without end costs the caller at most
 * the limits.  The child sends the mesh back through the pipe; whatever
 * assimp prints (stray "nullptr returned by creating DDLNode." lines and the
 * like) is dropped, unless the child crashed or CAVE_IMPORT_VERBOSE=1, when
 * it is copied to our stderr after the error. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "io/child_guard.h"
#include "io/mesh_import.h"

/* The record the child writes first; the arrays follow. */
typedef struct reply {
  int32_t status;
  char msg[512];
  cv_import_stats stats;
  uint64_t nv, nt, nm;
  uint32_t has_uv, has_tex; /* corner UVs (6*nt floats) and texture paths (nm x CV_TEX_PATH_MAX) follow */
} reply;

typedef struct import_job {
  const char *path;
  const cv_import_opts *opts;
} import_job;

/* In the child: the import, then the reply and the arrays to fd. */
static int import_child(void *ctx, int fd) {
  const import_job *job = ctx;
  reply r;
  memset(&r, 0, sizeof r);
  cv_err err;
  cv_err_clear(&err);
  cv_mesh *m = NULL;
  r.status = cv_mesh_import_direct(job->path, job->opts, &m, &r.stats, &err);
  snprintf(r.msg, sizeof r.msg, "%s", err.msg);
  if (m) {
    r.nv = m->nv;
    r.nt = m->nt;
    r.nm = m->nm;
    r.has_uv = m->tri_uv != NULL;
    r.has_tex = m->mat_tex != NULL;
  }
  int bad = cv_child_write(fd, &r, sizeof r);
  if (!bad && m)
    bad = cv_child_write(fd, m->pos, 3 * m->nv * sizeof(float)) ||
          cv_child_write(fd, m->tri, 3 * m->nt * sizeof(uint32_t)) ||
          cv_child_write(fd, m->tri_mat, m->nt * sizeof(uint32_t)) ||
          cv_child_write(fd, m->mats, m->nm * sizeof(cv_material)) ||
          (r.has_uv && cv_child_write(fd, m->tri_uv, 6 * m->nt * sizeof(float))) ||
          (r.has_tex && cv_child_write(fd, m->mat_tex, m->nm * (size_t)CV_TEX_PATH_MAX));
  cv_mesh_destroy(m);
  return bad ? CV_ERR_IO : CV_OK;
}

static const char *format_of(const char *path, char *fmt, size_t n) {
  const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
  if (!dot || (slash && dot < slash) || !dot[1]) return "unknown format";
  size_t k = 0;
  for (const char *p = dot + 1; *p && k + 1 < n; p++) fmt[k++] = (char)((*p >= 'a' && *p <= 'z') ? *p - 32 : *p);
  fmt[k] = '\0';
  return fmt;
}

/* Builds the mesh from the child's reply. */
static int unpack(const char *path, const cv_child_result *data, cv_mesh **out,
                  cv_import_stats *stats, cv_err *err) {
  reply r;
  memcpy(&r, data->data, sizeof r);
  if (stats) *stats = r.stats;
  if (r.status) {
    r.msg[sizeof r.msg - 1] = '\0';
    return cv_err_set(err, r.status, "%s", r.msg);
  }
  size_t want = sizeof r + (size_t)r.nv * 3 * sizeof(float) + (size_t)r.nt * 4 * sizeof(uint32_t) +
                (size_t)r.nm * sizeof(cv_material) +
                (r.has_uv ? (size_t)r.nt * 6 * sizeof(float) : 0) +
                (r.has_tex ? (size_t)r.nm * CV_TEX_PATH_MAX : 0);
  if (data->data_n != want)
    return cv_err_set(err, CV_ERR_BACKEND, "%s: import: the child process sent %zu bytes, expected %zu",
                      path, data->data_n, want);
  cv_mesh *m;
  if (cv_mesh_create(&m) || cv_mesh_reserve(m, r.nv, r.nt)) {
    if (m) cv_mesh_destroy(m);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory for %llu vertices", path,
                      (unsigned long long)r.nv);
  }
  const unsigned char *p = data->data + sizeof r;
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
  char fmtb[16], what[40];
  snprintf(what, sizeof what, "import (%s)", format_of(path, fmtb, sizeof fmtb));
  /* a bad CAVE_IMPORT_TIMEOUT / CAVE_IMPORT_MEMORY_MB is refused, not read as the default */
  if (cv_child_env_check("CAVE_IMPORT_TIMEOUT", opts->limit_seconds, "seconds >= 0 (0 = none)", err) ||
      cv_child_env_check("CAVE_IMPORT_MEMORY_MB", opts->limit_memory_mb, "megabytes >= 0 (0 = none)", err))
    return CV_ERR_RANGE;
  const cv_child_limits lim = {opts->limit_seconds, opts->limit_memory_mb};
  const cv_child_labels lab = {path, what, "assimp", "CAVE_IMPORT_TIMEOUT", "CAVE_IMPORT_MEMORY_MB"};
  import_job job = {path, opts};
  cv_child_result res;
  int st = cv_child_run(import_child, &job, &lim, &res, err);
  if (st != CV_OK) {
    cv_err_prefix(err, "%s: import", path);
    return st;
  }
  const char *verbose = getenv("CAVE_IMPORT_VERBOSE");
  int show = verbose && verbose[0] == '1';
  if (res.outcome == CV_CHILD_DONE && res.data_n >= sizeof(reply)) {
    st = unpack(path, &res, out, stats, err);
    /* assimp caught its own std::bad_alloc: under a limit, that is the limit */
    if (err && (st == CV_ERR_NOMEM || (st && strstr(err->msg, "bad_alloc"))) && res.memory_limited) {
      char was[sizeof err->msg];
      size_t np = strlen(path);
      const char *why = strncmp(err->msg, path, np) == 0 && err->msg[np] == ':' ? err->msg + np + 2
                                                                                 : err->msg;
      snprintf(was, sizeof was, "%s", why);
      st = cv_err_set(err, CV_ERR_NOMEM, "%s: %s stopped: memory limit %.0f MB hit (%s sets it): %.300s",
                      path, what, opts->limit_memory_mb, lab.memory_env, was);
    }
  } else if (res.outcome == CV_CHILD_DONE) {
    st = cv_err_set(err, CV_ERR_BACKEND, "%s: %s: the child process sent %zu bytes, no reply", path,
                    what, res.data_n);
  } else {
    st = cv_child_error(&res, &lim, &lab, err);
    show = show || res.outcome == CV_CHILD_SIGNAL || res.outcome == CV_CHILD_FAILED;
  }
  if (show) {
    char whose[600];
    snprintf(whose, sizeof whose, "the import of %s", path);
    cv_child_show_output(&res, whose);
  }
  cv_child_result_free(&res);
  return st;
}

int cv_mesh_import(const char *path, const cv_import_opts *opts, cv_mesh **out, cv_err *err) {
  return cv_mesh_import_ex(path, opts, out, NULL, err);
}
