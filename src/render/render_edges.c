/* Directed-edge sets of triangle meshes on welded indices: the closedness
 * the culled shadow map relies on (cv_renderer_mesh_closed, render_scene.c) and
 * the shadow casters' closure defects (render_casters.c).  One
 * open-addressing set of edge keys (a << 32 | b); 0 marks a free slot
 * (a == b, a degenerate edge, is never stored). */
#include "render/render_edges.h"

#include "render/render_gl.h"

static uint64_t edge_key(uint32_t a, uint32_t b) { return (uint64_t)a << 32 | b; }

static uint64_t reverse_key(uint64_t k) { return edge_key((uint32_t)k, (uint32_t)(k >> 32)); }

/* The slot of key k: where it is, or the free slot where it would go. */
static size_t slot_of(const cvr_edges *e, uint64_t k) {
  size_t h = cvr_hash64(k) & (e->cap - 1);
  while (e->set[h] && e->set[h] != k) h = (h + 1) & (e->cap - 1);
  return h;
}

int cvr_edges_build(cvr_edges *e, const uint32_t *tri, size_t nt) {
  e->cap = 1, e->dup = 0;
  while (e->cap < 6 * nt + 2) e->cap <<= 1;
  e->set = calloc(e->cap, sizeof *e->set);
  if (!e->set) return CV_ERR_NOMEM;
  for (size_t t = 0; t < nt; t++) {
    const uint32_t *v = tri + 3 * t;
    if (v[0] == v[1] || v[1] == v[2] || v[2] == v[0]) continue;
    for (int k = 0; k < 3; k++) {
      const uint64_t key = edge_key(v[k], v[(k + 1) % 3]);
      const size_t h = slot_of(e, key);
      if (e->set[h] == key) e->dup++; /* the same directed edge twice */
      e->set[h] = key;
    }
  }
  return CV_OK;
}

static int has(const cvr_edges *e, uint64_t k) { return e->set[slot_of(e, k)] == k; }

size_t cvr_edges_border_unmatched(const cvr_edges *a, const cvr_edges *b) {
  size_t n = 0;
  for (size_t h = 0; h < a->cap; h++) {
    const uint64_t k = a->set[h];
    if (!k || has(a, reverse_key(k))) continue; /* not a border edge of a */
    n += !b || !has(b, k) || has(b, reverse_key(k));
  }
  return n;
}

void cvr_edges_free(cvr_edges *e) {
  free(e->set);
  e->set = NULL;
}

void cvr_unit_normals(const float *pos, const uint32_t *idx, size_t nt, float *out) {
  for (size_t t = 0; t < nt; t++) {
    const uint32_t *v = idx + 3 * t;
    const float *a = pos + 3 * v[0], *b = pos + 3 * v[1], *d = pos + 3 * v[2];
    double e1[3], e2[3];
    for (int j = 0; j < 3; j++) e1[j] = (double)b[j] - a[j], e2[j] = (double)d[j] - a[j];
    const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                         e1[0] * e2[1] - e1[1] * e2[0]};
    const double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int j = 0; j < 3; j++) out[3 * t + j] = l > 0 ? (float)(n[j] / l) : 0.0f;
  }
}
