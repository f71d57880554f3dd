/* Indexed triangle meshes (see mesh.h). */
#include "mesh/mesh.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int grow(void **p, size_t *cap, size_t need, size_t elem) {
  if (need <= *cap) return CV_OK;
  size_t nc = *cap ? *cap : 64;
  while (nc < need) nc *= 2;
  void *q = realloc(*p, nc * elem);
  if (!q) return CV_ERR_NOMEM;
  *p = q;
  *cap = nc;
  return CV_OK;
}

int cv_mesh_create(cv_mesh **out) {
  *out = calloc(1, sizeof **out);
  return *out ? CV_OK : CV_ERR_NOMEM;
}

void cv_mesh_destroy(cv_mesh *m) {
  if (!m) return;
  free(m->pos);
  free(m->tri);
  free(m->tri_mat);
  free(m->mats);
  free(m->tri_uv);
  free(m->mat_tex);
  free(m);
}

int cv_mesh_reserve(cv_mesh *m, size_t nv, size_t nt) {
  size_t cv = m->cap_v, ct = m->cap_t;
  if (grow((void **)&m->pos, &cv, nv, 3 * sizeof(float))) return CV_ERR_NOMEM;
  m->cap_v = cv;
  if (grow((void **)&m->tri, &ct, nt, 3 * sizeof(uint32_t))) return CV_ERR_NOMEM;
  size_t ct2 = m->cap_t;
  if (grow((void **)&m->tri_mat, &ct2, nt, sizeof(uint32_t))) return CV_ERR_NOMEM;
  size_t old_t = m->cap_t;
  m->cap_t = ct < ct2 ? ct : ct2;
  if (m->tri_uv && m->cap_t > old_t) {
    float *q = realloc(m->tri_uv, m->cap_t * 6 * sizeof(float));
    if (!q) return CV_ERR_NOMEM;
    m->tri_uv = q;
  }
  return CV_OK;
}

int cv_mesh_enable_uv(cv_mesh *m) {
  if (m->tri_uv) return CV_OK;
  m->tri_uv = calloc(m->cap_t * 6 + 1, sizeof(float));
  return m->tri_uv ? CV_OK : CV_ERR_NOMEM;
}

int cv_mesh_set_texture(cv_mesh *m, uint32_t mat, const char *path) {
  if (mat >= m->nm) return CV_ERR_RANGE;
  if (!m->mat_tex && !(m->mat_tex = calloc(m->cap_m + 1, CV_TEX_PATH_MAX))) return CV_ERR_NOMEM;
  memset(m->mat_tex[mat], 0, CV_TEX_PATH_MAX); /* NUL-padded: files get the same bytes */
  snprintf(m->mat_tex[mat], CV_TEX_PATH_MAX, "%s", path ? path : "");
  return CV_OK;
}

int cv_mesh_add_material(cv_mesh *m, const char *name, const float albedo[3],
                         uint32_t flags, uint32_t *idx) {
  size_t old_m = m->cap_m;
  if (grow((void **)&m->mats, &m->cap_m, m->nm + 1, sizeof(cv_material)))
    return CV_ERR_NOMEM;
  if (m->mat_tex && m->cap_m > old_m) {
    void *q = realloc(m->mat_tex, m->cap_m * CV_TEX_PATH_MAX);
    if (!q) return CV_ERR_NOMEM;
    m->mat_tex = q;
  }
  if (m->mat_tex) memset(m->mat_tex[m->nm], 0, CV_TEX_PATH_MAX);
  cv_material *mt = &m->mats[m->nm];
  memset(mt, 0, sizeof *mt);
  strncpy(mt->name, name ? name : "", sizeof mt->name - 1);
  memcpy(mt->albedo, albedo, sizeof mt->albedo);
  mt->flags = flags;
  if (idx) *idx = (uint32_t)m->nm;
  m->nm++;
  return CV_OK;
}

int cv_mesh_find_material(const cv_mesh *m, const char *name) {
  for (size_t i = 0; i < m->nm; i++)
    if (strcmp(m->mats[i].name, name) == 0) return (int)i;
  return -1;
}

int cv_mesh_add_vertex(cv_mesh *m, float x, float y, float z, uint32_t *idx) {
  if (m->nv + 1 > m->cap_v && cv_mesh_reserve(m, m->nv + 1, m->nt)) return CV_ERR_NOMEM;
  float *p = m->pos + 3 * m->nv;
  p[0] = x;
  p[1] = y;
  p[2] = z;
  if (idx) *idx = (uint32_t)m->nv;
  m->nv++;
  return CV_OK;
}

int cv_mesh_add_tri(cv_mesh *m, uint32_t a, uint32_t b, uint32_t c, uint32_t mat) {
  if (a >= m->nv || b >= m->nv || c >= m->nv || mat >= m->nm) return CV_ERR_RANGE;
  if (m->nt + 1 > m->cap_t && cv_mesh_reserve(m, m->nv, m->nt + 1)) return CV_ERR_NOMEM;
  uint32_t *t = m->tri + 3 * m->nt;
  t[0] = a;
  t[1] = b;
  t[2] = c;
  m->tri_mat[m->nt] = mat;
  if (m->tri_uv) memset(m->tri_uv + 6 * m->nt, 0, 6 * sizeof(float));
  m->nt++;
  return CV_OK;
}

int cv_mesh_clone(const cv_mesh *m, cv_mesh **out) {
  cv_mesh *c;
  if (cv_mesh_create(&c)) return CV_ERR_NOMEM;
  if (cv_mesh_reserve(c, m->nv ? m->nv : 1, m->nt ? m->nt : 1)) goto fail;
  memcpy(c->pos, m->pos, m->nv * 3 * sizeof(float));
  memcpy(c->tri, m->tri, m->nt * 3 * sizeof(uint32_t));
  memcpy(c->tri_mat, m->tri_mat, m->nt * sizeof(uint32_t));
  c->nv = m->nv;
  c->nt = m->nt;
  if (m->nm) {
    c->mats = malloc(m->nm * sizeof(cv_material));
    if (!c->mats) goto fail;
    memcpy(c->mats, m->mats, m->nm * sizeof(cv_material));
    c->nm = c->cap_m = m->nm;
  }
  if (m->tri_uv) {
    if (cv_mesh_enable_uv(c)) goto fail;
    memcpy(c->tri_uv, m->tri_uv, m->nt * 6 * sizeof(float));
  }
  for (size_t i = 0; m->mat_tex && i < m->nm; i++)
    if (cv_mesh_set_texture(c, (uint32_t)i, m->mat_tex[i])) goto fail;
  *out = c;
  return CV_OK;
fail:
  cv_mesh_destroy(c);
  *out = NULL;
  return CV_ERR_NOMEM;
}

void cv_mesh_bounds(const cv_mesh *m, float lo[3], float hi[3]) {
  for (int k = 0; k < 3; k++) lo[k] = hi[k] = 0.0f;
  for (size_t i = 0; i < m->nv; i++)
    for (int k = 0; k < 3; k++) {
      float v = m->pos[3 * i + k];
      if (i == 0 || v < lo[k]) lo[k] = v;
      if (i == 0 || v > hi[k]) hi[k] = v;
    }
}

float cv_mesh_diagonal(const cv_mesh *m) {
  float lo[3], hi[3];
  cv_mesh_bounds(m, lo, hi);
  double d = 0;
  for (int k = 0; k < 3; k++) d += (double)(hi[k] - lo[k]) * (hi[k] - lo[k]);
  return (float)sqrt(d);
}

void cv_mesh_tri_normal(const cv_mesh *m, size_t t, float n[3]) {
  const float *a = m->pos + 3 * m->tri[3 * t], *b = m->pos + 3 * m->tri[3 * t + 1],
              *c = m->pos + 3 * m->tri[3 * t + 2];
  float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  float e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  n[0] = e1[1] * e2[2] - e1[2] * e2[1];
  n[1] = e1[2] * e2[0] - e1[0] * e2[2];
  n[2] = e1[0] * e2[1] - e1[1] * e2[0];
}

void cv_mesh_vertex_normals(const cv_mesh *m, float *out) {
  double *acc = calloc(m->nv * 3, sizeof(double));
  if (!acc) {
    memset(out, 0, m->nv * 3 * sizeof(float));
    return;
  }
  for (size_t t = 0; t < m->nt; t++) {
    float n[3];
    cv_mesh_tri_normal(m, t, n);
    for (int j = 0; j < 3; j++)
      for (int k = 0; k < 3; k++) acc[3 * m->tri[3 * t + j] + k] += n[k];
  }
  for (size_t i = 0; i < m->nv; i++) {
    double l = sqrt(acc[3 * i] * acc[3 * i] + acc[3 * i + 1] * acc[3 * i + 1] +
                    acc[3 * i + 2] * acc[3 * i + 2]);
    for (int k = 0; k < 3; k++) out[3 * i + k] = l > 0 ? (float)(acc[3 * i + k] / l) : 0.0f;
  }
  free(acc);
}

int cv_mesh_validate(const cv_mesh *m, cv_err *err) {
  if (m->nt == 0) return cv_err_set(err, CV_ERR_EMPTY, "mesh has no triangles");
  for (size_t i = 0; m->tri_uv && i < 6 * m->nt; i++)
    if (!isfinite(m->tri_uv[i]))
      return cv_err_set(err, CV_ERR_NONFINITE, "triangle %zu: non-finite texture coordinate", i / 6);
  for (size_t i = 0; i < 3 * m->nv; i++)
    if (!isfinite(m->pos[i]))
      return cv_err_set(err, CV_ERR_NONFINITE, "vertex %zu has a non-finite coordinate", i / 3);
  for (size_t t = 0; t < m->nt; t++) {
    for (int j = 0; j < 3; j++)
      if (m->tri[3 * t + j] >= m->nv)
        return cv_err_set(err, CV_ERR_RANGE, "triangle %zu refers to vertex %u of %zu", t,
                          m->tri[3 * t + j], m->nv);
    if (m->tri_mat[t] >= m->nm)
      return cv_err_set(err, CV_ERR_RANGE, "triangle %zu refers to material %u of %zu", t,
                        m->tri_mat[t], m->nm);
  }
  for (size_t i = 0; i < m->nm; i++)
    for (int k = 0; k < 3; k++) {
      float a = m->mats[i].albedo[k];
      if (!isfinite(a) || a < 0.0f || a > 1.0f)
        return cv_err_set(err, CV_ERR_RANGE, "material '%s' albedo[%d] = %g, expected [0, 1]",
                          m->mats[i].name, k, (double)a);
    }
  return CV_OK;
}
