/* Split window lights of the renderer (not installed; layer 1, on
 * render_gl.h): cv_renderer_set_split's per-vertex direct light, added in
 * the relight, and its SH projection for the interreflected transfer. */
#ifndef CV_RENDER_SPLIT_H
#define CV_RENDER_SPLIT_H

#include "render/render_gl.h"

/* src gives each renderer vertex its PRT vertex (renumbering and texture
 * seam copies undone); usc: a textured PRT drawn without its textures has
 * its mean albedo folded back per renderer vertex (else NULL); tex (texture
 * buffer, RGBA32F per renderer vertex, used while n > 0; on the CPU relight
 * cpu instead) holds the lights' direct light; sh their SH projection
 * sum_k E_k y_i(s_k) ([3*i + c]). */
typedef struct cvr_split {
  uint32_t *src;
  float *usc;
  GLuint buf, tex;
  float *cpu;
  double sh[3 * CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS];
  int n;
} cvr_split;

/* At the upload: src and usc from the renumbering old_of, the untextured
 * scale usc of p's vertices and the texture split's orig (or NULL). */
void cvr_split_map(cvr_split *s, const cv_prt *p, const uint32_t *old_of, const float *usc,
                   const uint32_t *orig);
/* cv_renderer_set_split for a scene of nc coefficients and nv vertices
 * (on_cpu: the CPU relight reads it). */
int cvr_split_set(const cvr_ctx *c, cvr_split *s, int nc, size_t nv, int on_cpu,
                  const cv_dir_light *lights, int n, const float *direct_rgb, cv_err *err);
/* Binds the split lights for the relight program p (in use). */
void cvr_split_bind(const cvr_split *s, GLuint p);
void cvr_split_free(cvr_split *s);     /* GL objects (context current) */
void cvr_split_free_cpu(cvr_split *s);

#endif
