/* Directed-edge sets of triangle meshes and triangle normals (bottom layer
 * of the renderer, beside render_gl.h; no GL): the closedness the culled
 * shadow map relies on (render_scene.c) and the shadow casters' closure
 * defects (render_casters.c). */
#ifndef CV_RENDER_EDGES_H
#define CV_RENDER_EDGES_H

#include <stddef.h>
#include <stdint.h>

/* Directed edges of triangles on welded indices: degenerate triangles
 * skipped, dup = directed edges met again. */
typedef struct cvr_edges {
  uint64_t *set;
  size_t cap, dup;
} cvr_edges;
/* CV_OK, or CV_ERR_NOMEM. */
int cvr_edges_build(cvr_edges *e, const uint32_t *tri, size_t nt);
/* a's border edges (reverse not in a) that are not border edges of b (all
 * of them when b is NULL). */
size_t cvr_edges_border_unmatched(const cvr_edges *a, const cvr_edges *b);
void cvr_edges_free(cvr_edges *e);
/* Unit winding normals of nt triangles (0 for a degenerate one) into out[3 nt]. */
void cvr_unit_normals(const float *pos, const uint32_t *idx, size_t nt, float *out);

#endif
