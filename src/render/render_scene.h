/* The scene feature of the renderer (not installed; layer 1, on
 * render_gl.h): the opaque mesh as the GL draws it, shared by the passes,
 * the shadow map and casters, the sun split and shared lighting.
 *
 * The opaque triangles (windows dropped) sorted along a Morton curve of
 * their centroids in chunks of CHUNK triangles with their bounds (frustum
 * culling per view), vertices renumbered in order of first use (those of
 * opaque triangles first, nv_used of them).  Each chunk may also be
 * partitioned in three parts in buf_idx_sun (the sun split of
 * render_light.c writes it through cvr_scene_parts_bind, chunk_na,
 * chunk_nf): n_t . s > m (chunk_na of them), |n_t . s| <= m, n_t . s < -m
 * (chunk_nf = the first two). */
#ifndef CV_RENDER_SCENE_H
#define CV_RENDER_SCENE_H

#include "render/render_gl.h"

enum { DRAW_ALL = 0, DRAW_SUNLIT = 1, DRAW_UNSUNLIT = 2, DRAW_SHADOW = 3 }; /* cvr_scene_draw parts */

#define CHUNK 1024

typedef struct cvr_scene {
  int nc;             /* SH coefficients */
  size_t nv, nt;      /* vertices, opaque triangles drawn */
  size_t nv_used;     /* vertices of opaque triangles (numbered first) */
  double lo[3], hi[3];/* bounds of all vertices */
  int closed;         /* cv_renderer_mesh_closed */
  /* GL: positions (attribute 0), relit radiance (1, written by the relight),
   * albedo (2), (u, v, layer) of textured scenes (3), triangles */
  GLuint vao_geom, buf_pos, buf_rad, buf_alb, buf_uvl, buf_idx;
  GLuint prog_depth;  /* depth only (the passes' pre-pass, the shadow map) */
  size_t nchunks;
  float *chunk_box;   /* 6 per chunk: lo xyz, hi xyz */
  uint32_t *run;      /* scratch: 2 per chunk (first triangle, count) */
  uint32_t *idx_cpu;  /* the uploaded triangles and positions */
  float *pos_cpu;
  float *tri_n;       /* unit winding normals (cvr_scene_tri_normals) */
  /* the partition (see above) */
  GLuint buf_idx_sun;
  uint32_t *chunk_na, *chunk_nf;
  GLsizei *md_count;  /* scratch for glMultiDrawElements: 1 per chunk */
  const void **md_off;
} cvr_scene;

/* Opaque triangles of p, bounds, chunks and their boxes, the Morton order
 * and the renumbering: *idx (3 nt renumbered indices) and *old_of (per new
 * vertex its vertex of p), both the caller's to pass on / free.  Sets nc
 * from p's bands. */
int cvr_scene_order(cvr_scene *sc, const cv_prt *p, uint32_t **idx, uint32_t **old_of, cv_err *err);
/* The GL buffers: positions and albedo x usc (3 per vertex of p) in the
 * renumbered order, uvl (3 per new vertex, NULL: untextured), the
 * triangles idx (taken: kept as idx_cpu); the depth program. */
int cvr_scene_upload(cvr_scene *sc, const cv_prt *p, const uint32_t *old_of, const float *usc,
                     const float *uvl, uint32_t *idx, cv_err *err);
void cvr_scene_free(cvr_scene *sc); /* GL objects (context current) */
void cvr_scene_free_cpu(cvr_scene *sc);

/* 1 when the box (lo, hi) lies entirely outside one clip plane of mvp. */
int cvr_box_outside(const float mvp[16], const float *lo, const float *hi);
/* Draws part (DRAW_*) of the chunks in mvp's frustum (all with mvp NULL or
 * opts.cull_frustum off); returns the triangles submitted. */
size_t cvr_scene_draw(const cvr_ctx *c, cvr_scene *sc, const float *mvp, int part);
/* The triangles a view of mvp would submit. */
size_t cvr_scene_view_triangles(const cvr_ctx *c, const cvr_scene *sc, const float mvp[16]);
/* Face culling of the view passes (opts.cull_back; -1: on a closed mesh). */
void cvr_scene_cull(const cvr_ctx *c, const cvr_scene *sc, int on);
/* Whether the shadow map is culled (opts.shadow_cull; -1: the mesh is closed). */
int cvr_scene_shadow_culled(const cvr_ctx *c, const cvr_scene *sc);
/* Binds buf_idx_sun to GL_ELEMENT_ARRAY_BUFFER (VAO 0), storage made once. */
void cvr_scene_parts_bind(cvr_scene *sc);
/* tri_n, built on first use: CV_OK or CV_ERR_NOMEM. */
int cvr_scene_tri_normals(cvr_scene *sc);

#endif
