/* OBJ + MTL writer (see obj_write.h). */
#include "io/obj_write.h"

#include "core/outfile.h"

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

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

  cv_outfile of;
  if ((rc = cv_outfile_open(&of, mtl_path, 1, err)) != CV_OK) {
    free(mtl_path);
    return rc;
  }
  FILE *f = of.f;
  fprintf(f, "# %zu materials, written by cave (cv_obj_write)\n", m->nm);
  for (size_t i = 0; i < m->nm; ++i) {
    const cv_material *mt = &m->mats[i];
    fprintf(f, "\nnewmtl %s\nKd %.9g %.9g %.9g\n", mt->name, mt->albedo[0], mt->albedo[1], mt->albedo[2]);
  }
  rc = cv_outfile_commit(&of, err);
  if (rc != CV_OK) {
    free(mtl_path);
    return rc;
  }

  if ((rc = cv_outfile_open(&of, obj_path, 1, err)) != CV_OK) {
    free(mtl_path);
    return rc;
  }
  f = of.f;
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
  rc = cv_outfile_commit(&of, err);
  free(mtl_path);
  return rc;
}
