/* OBJ + MTL writer (see obj_write.h). */
#include "io/obj_write.h"

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Opens a temporary file next to path; *tmp (malloc'd) gets its name. */
static FILE *open_tmp(const char *path, char **tmp, cv_err *err) {
  size_t plen = strlen(path);
  *tmp = malloc(plen + 16);
  if (!*tmp) {
    cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
    return NULL;
  }
  snprintf(*tmp, plen + 16, "%s.tmp.XXXXXX", path);
  int fd = mkstemp(*tmp);
  FILE *f = fd >= 0 ? fdopen(fd, "w") : NULL;
  if (!f) {
    cv_err_set(err, CV_ERR_IO, "%s: cannot create temporary file: %s", path, strerror(errno));
    if (fd >= 0) {
      close(fd);
      unlink(*tmp);
    }
    free(*tmp);
    *tmp = NULL;
  }
  return f;
}

/* Closes f and renames tmp to path; removes tmp on failure. */
static int close_rename(FILE *f, char *tmp, const char *path, cv_err *err) {
  int rc = CV_OK;
  if (fflush(f) != 0 || ferror(f)) rc = cv_err_set(err, CV_ERR_IO, "%s: write failed: %s", path, strerror(errno));
  if (fclose(f) != 0 && rc == CV_OK) rc = cv_err_set(err, CV_ERR_IO, "%s: close failed", path);
  if (rc == CV_OK && rename(tmp, path) != 0)
    rc = cv_err_set(err, CV_ERR_IO, "%s: cannot rename temporary file: %s", path, strerror(errno));
  if (rc != CV_OK) unlink(tmp);
  free(tmp);
  return rc;
}

int cv_obj_write(const char *obj_path, const cv_mesh *m, cv_err *err) {
  if (!obj_path || !m) return cv_err_set(err, CV_ERR_INVALID, "cv_obj_write: NULL argument");
  int rc = cv_mesh_validate(m, err);
  if (rc != CV_OK) return cv_err_prefix(err, "%s", obj_path);
  for (size_t i = 0; i < m->nm; ++i) {
    const char *nm = m->mats[i].name;
    int bad = nm[0] == '\0';
    for (const char *c = nm; *c; ++c)
      if (isspace((unsigned char)*c)) bad = 1;
    if (bad)
      return cv_err_set(err, CV_ERR_INVALID, "%s: material %zu name '%s' is empty or has whitespace", obj_path,
                        i, nm);
  }
  /* sibling .mtl path and its base name for mtllib */
  size_t plen = strlen(obj_path);
  char *mtl_path = malloc(plen + 8);
  if (!mtl_path) return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", obj_path);
  memcpy(mtl_path, obj_path, plen + 1);
  if (plen >= 4 && strcmp(obj_path + plen - 4, ".obj") == 0)
    memcpy(mtl_path + plen - 4, ".mtl", 5);
  else
    memcpy(mtl_path + plen, ".mtl", 5);
  const char *slash = strrchr(mtl_path, '/');
  const char *mtl_base = slash ? slash + 1 : mtl_path;

  char *tmp = NULL;
  FILE *f = open_tmp(mtl_path, &tmp, err);
  if (!f) {
    free(mtl_path);
    return err ? err->status : CV_ERR_IO;
  }
  fprintf(f, "# %zu materials, written by cave (cv_obj_write)\n", m->nm);
  for (size_t i = 0; i < m->nm; ++i) {
    const cv_material *mt = &m->mats[i];
    fprintf(f, "\nnewmtl %s\nKd %.9g %.9g %.9g\n", mt->name, mt->albedo[0], mt->albedo[1], mt->albedo[2]);
  }
  rc = close_rename(f, tmp, mtl_path, err);
  if (rc != CV_OK) {
    free(mtl_path);
    return rc;
  }

  f = open_tmp(obj_path, &tmp, err);
  if (!f) {
    free(mtl_path);
    return err ? err->status : CV_ERR_IO;
  }
  fprintf(f, "# %zu vertices, %zu triangles, %zu materials, written by cave (cv_obj_write)\n", m->nv,
          m->nt, m->nm);
  fprintf(f, "mtllib %s\n", mtl_base);
  for (size_t i = 0; i < m->nv; ++i)
    fprintf(f, "v %.9g %.9g %.9g\n", m->pos[3 * i], m->pos[3 * i + 1], m->pos[3 * i + 2]);
  /* one usemtl group per material, triangles in their original order */
  for (size_t mi = 0; mi < m->nm; ++mi) {
    int started = 0;
    for (size_t t = 0; t < m->nt; ++t) {
      if (m->tri_mat[t] != mi) continue;
      if (!started) {
        fprintf(f, "usemtl %s\n", m->mats[mi].name);
        started = 1;
      }
      fprintf(f, "f %u %u %u\n", m->tri[3 * t] + 1, m->tri[3 * t + 1] + 1, m->tri[3 * t + 2] + 1);
    }
  }
  rc = close_rename(f, tmp, obj_path, err);
  free(mtl_path);
  return rc;
}
