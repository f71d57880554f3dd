/* The sun's shadow casters (not installed; layer 2, on render_scene.h): a
 * simplified copy of the opaque mesh that the shadow map draws
 * (opts.shadow_casters; render_casters.c has the details). */
#ifndef CV_RENDER_CASTERS_H
#define CV_RENDER_CASTERS_H

#include "render/render_gl.h"
#include "render/render_scene.h"

/* Built on the first map: positions, triangles, their unit normals, the
 * culled list of the last map (drawn triangles), whether culling applies,
 * the simplifier's error (m) and the build's wall ms. */
typedef struct cvr_casters {
  GLuint vao, buf_pos, buf_idx;
  float *pos, *n;
  uint32_t *idx, *draw;
  size_t nt, drawn, defects;
  int built, culled;
  double err, ms;
} cvr_casters;

/* Draws the casters for the sun s with the bound depth program (built on
 * first use from sc). */
int cvr_casters_draw(const cvr_ctx *c, cvr_casters *k, const cvr_scene *sc, const double s[3],
                     cv_err *err);
/* cv_renderer_shadow_casters */
void cvr_casters_info(const cvr_ctx *c, const cvr_casters *k, const cvr_scene *sc,
                      cv_shadow_casters *out);
void cvr_casters_free(cvr_casters *k); /* GL objects (context current) */
void cvr_casters_free_cpu(cvr_casters *k);

#endif
