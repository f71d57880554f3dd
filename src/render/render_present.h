/* Window presentation (not installed; layer 1, on render_gl.h and the X11
 * window): 8-bit images drawn into the window's back buffer, glFinish. */
#ifndef CV_RENDER_PRESENT_H
#define CV_RENDER_PRESENT_H

#include "render/render_gl.h"
#include "render/window.h"

/* The program; the uploaded codes per eye (cv_renderer_present), their size
 * and whether each texture has its storage. */
typedef struct cvr_present {
  GLuint prog, tex[2];
  int w, h, made[2];
} cvr_present;

int cvr_present_init(cvr_present *pr, cv_err *err);
/* Uploads the codes (RGB8, w x h; right for a packed layout) and draws them. */
int cvr_present_codes(cvr_ctx *c, cvr_present *pr, cv_window *win, const uint8_t *left,
                      const uint8_t *right, int w, int h, int layout, cv_err *err);
/* Draws textures tex[0] (and tex[1] for a packed layout), each w x h, drawn by GL
 * (row 0 at the image's bottom: the post pass's projector images). */
int cvr_present_textures(const cvr_ctx *c, const cvr_present *pr, cv_window *win, const GLuint tex[2],
                         int w, int h, int layout, cv_err *err);
void cvr_present_free(cvr_present *pr); /* GL objects (context current) */

#endif
