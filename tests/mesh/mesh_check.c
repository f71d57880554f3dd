/* Independent mesh checks for the tests (see mesh_check.h). */
#include "mesh_check.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const cv_mesh *g_m; /* qsort context (tests are single-threaded) */

static int cmp_pos(const void *x, const void *y) {
  uint32_t a = *(const uint32_t *)x, b = *(const uint32_t *)y;
  int c = memcmp(g_m->pos + 3 * (size_t)a, g_m->pos + 3 * (size_t)b, 3 * sizeof(float));
  if (c) return c;
  return a < b ? -1 : a > b;
}

uint32_t *mc_position_ids(const cv_mesh *m) {
  uint32_t *ord = malloc(m->nv * sizeof *ord), *ids = malloc(m->nv * sizeof *ids);
  for (size_t i = 0; i < m->nv; i++) ord[i] = (uint32_t)i;
  g_m = m;
  qsort(ord, m->nv, sizeof *ord, cmp_pos);
  for (size_t i = 0; i < m->nv; i++) {
    if (i > 0 && !memcmp(m->pos + 3 * (size_t)ord[i], m->pos + 3 * (size_t)ord[i - 1],
                         3 * sizeof(float)))
      ids[ord[i]] = ids[ord[i - 1]];
    else
      ids[ord[i]] = ord[i];
  }
  free(ord);
  return ids;
}

static int cmp_u64(const void *x, const void *y) {
  uint64_t a = *(const uint64_t *)x, b = *(const uint64_t *)y;
  return a < b ? -1 : a > b;
}

void mc_edge_check(const cv_mesh *m, size_t t0, size_t t1, size_t *bad_undirected,
                   size_t *bad_directed) {
  uint32_t *id = mc_position_ids(m);
  size_t ne = 3 * (t1 - t0);
  uint64_t *dir = malloc(ne * sizeof *dir), *und = malloc(ne * sizeof *und);
  for (size_t t = t0, k = 0; t < t1; t++)
    for (int j = 0; j < 3; j++, k++) {
      uint64_t a = id[m->tri[3 * t + j]], b = id[m->tri[3 * t + (j + 1) % 3]];
      dir[k] = a << 32 | b;
      und[k] = a < b ? (a << 32 | b) : (b << 32 | a);
    }
  qsort(dir, ne, sizeof *dir, cmp_u64);
  qsort(und, ne, sizeof *und, cmp_u64);
  *bad_undirected = 0;
  for (size_t i = 0; i < ne;) {
    size_t j = i;
    while (j < ne && und[j] == und[i]) j++;
    if (j - i != 2) (*bad_undirected)++;
    i = j;
  }
  *bad_directed = 0;
  for (size_t i = 0; i < ne;) {
    size_t j = i;
    while (j < ne && dir[j] == dir[i]) j++;
    uint64_t rev = (dir[i] & 0xffffffffu) << 32 | dir[i] >> 32;
    uint64_t *r = bsearch(&rev, dir, ne, sizeof *dir, cmp_u64);
    if (j - i != 1 || !r) (*bad_directed)++;
    i = j;
  }
  free(dir);
  free(und);
  free(id);
}

size_t mc_boundary_edges(const cv_mesh *m) {
  size_t ne = 3 * m->nt, n = 0;
  uint64_t *und = malloc((ne ? ne : 1) * sizeof *und);
  for (size_t t = 0, k = 0; t < m->nt; t++)
    for (int j = 0; j < 3; j++, k++) {
      uint64_t a = m->tri[3 * t + j], b = m->tri[3 * t + (j + 1) % 3];
      und[k] = a < b ? (a << 32 | b) : (b << 32 | a);
    }
  qsort(und, ne, sizeof *und, cmp_u64);
  for (size_t i = 0; i < ne;) {
    size_t j = i;
    while (j < ne && und[j] == und[i]) j++;
    n += j - i == 1;
    i = j;
  }
  free(und);
  return n;
}

static void tri_pts(const cv_mesh *m, size_t t, double p[3][3]) {
  for (int j = 0; j < 3; j++)
    for (int k = 0; k < 3; k++) p[j][k] = m->pos[3 * (size_t)m->tri[3 * t + j] + k];
}

double mc_signed_volume(const cv_mesh *m, size_t t0, size_t t1) {
  double v = 0;
  for (size_t t = t0; t < t1; t++) {
    double p[3][3];
    tri_pts(m, t, p);
    double c[3] = {p[1][1] * p[2][2] - p[1][2] * p[2][1], p[1][2] * p[2][0] - p[1][0] * p[2][2],
                   p[1][0] * p[2][1] - p[1][1] * p[2][0]};
    v += (p[0][0] * c[0] + p[0][1] * c[1] + p[0][2] * c[2]) / 6.0;
  }
  return v;
}

double mc_tri_area(const cv_mesh *m, size_t t) {
  double p[3][3];
  tri_pts(m, t, p);
  double e1[3], e2[3];
  for (int k = 0; k < 3; k++) e1[k] = p[1][k] - p[0][k], e2[k] = p[2][k] - p[0][k];
  double c[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                 e1[0] * e2[1] - e1[1] * e2[0]};
  return 0.5 * sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
}

double mc_tri_min_altitude(const cv_mesh *m, size_t t) {
  double p[3][3], lmax = 0;
  tri_pts(m, t, p);
  for (int j = 0; j < 3; j++) {
    double d = 0;
    for (int k = 0; k < 3; k++) d += (p[(j + 1) % 3][k] - p[j][k]) * (p[(j + 1) % 3][k] - p[j][k]);
    if (d > lmax) lmax = d;
  }
  return lmax > 0 ? 2.0 * mc_tri_area(m, t) / sqrt(lmax) : 0.0;
}

double mc_area_flags(const cv_mesh *m, uint32_t flags) {
  double a = 0;
  for (size_t t = 0; t < m->nt; t++)
    if (m->mats[m->tri_mat[t]].flags & flags) a += mc_tri_area(m, t);
  return a;
}

double mc_area_named(const cv_mesh *m, const char *name) {
  double a = 0;
  for (size_t t = 0; t < m->nt; t++)
    if (!strcmp(m->mats[m->tri_mat[t]].name, name)) a += mc_tri_area(m, t);
  return a;
}
