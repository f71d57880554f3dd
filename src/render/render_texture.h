/* Albedo textures of the renderer (not installed; layer 1, on
 * render_gl.h): vertices split at UV seams and one sRGB texture array
 * (render_texture.c has the details). */
#ifndef CV_RENDER_TEXTURE_H
#define CV_RENDER_TEXTURE_H

#include "render/render_gl.h"

/* The array (tex 0 = none), its layers and size, textures that could not
 * be read (+ the first message), vertices added by the split, and until
 * the scene's upload (u, v, layer) and the original vertex per vertex of
 * the split PRT. */
typedef struct cvr_texture {
  GLuint tex;
  int layers, w, h, missing;
  size_t split;
  char msg[320];
  float *uvl;
  uint32_t *orig;
} cvr_texture;

/* Loads p's textures into t; *split: p with vertices split at UV seams
 * (the caller's; NULL when p is untextured). */
int cvr_texture_prepare(cvr_texture *t, const cv_prt *p, cv_prt **split, cv_err *err);
/* cv_renderer_textures: fills info, returns the layers. */
int cvr_texture_info(const cvr_texture *t, cv_render_tex_info *info);
void cvr_texture_free_upload(cvr_texture *t); /* uvl, orig: after the upload */
void cvr_texture_free(cvr_texture *t);        /* the array (context current) */

#endif
