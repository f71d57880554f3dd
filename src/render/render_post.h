/* The frame's end on the GPU (not installed; layer 1, on render_gl.h):
 * patch means of the display image, equation 7, the 8-bit projector image
 * per eye ("slot"; render_post.c has the details).  The state (struct
 * cvr_post) is made on first use; the display image comes from the caller
 * as a cvr_image_ref. */
#ifndef CV_RENDER_POST_H
#define CV_RENDER_POST_H

#include "render/render_gl.h"

typedef struct cvr_post cvr_post;

/* cv_renderer_post_available: makes *pp and its programs if it can. */
int cvr_post_available(const cvr_ctx *c, cvr_post **pp, char *why, size_t cap);
int cvr_post_grid(cvr_ctx *c, cvr_post **pp, int nu, int nv, const double *eu, const double *ev, int w,
                  int h, cv_err *err);
int cvr_post_patch_means(cvr_ctx *c, cvr_post *p, const cvr_image_ref *src, double *out, cv_err *err);
int cvr_post_keep(const cvr_ctx *c, cvr_post *p, const cvr_image_ref *src, int slot, cv_err *err);
int cvr_post_run(cvr_ctx *c, cvr_post *p, const cvr_image_ref *src, int slot, int kept, const float *delta,
                 cv_err *err);
int cvr_post_black(const cvr_ctx *c, cvr_post *p, int slot, cv_err *err);
int cvr_post_read(cvr_ctx *c, cvr_post *p, int slot, uint8_t *codes, cv_err *err);
/* The 8-bit projector image of slot (0 none: no grid), its size. */
GLuint cvr_post_slot_texture(const cvr_post *p, int slot, int *w, int *h);
void cvr_post_free(cvr_post **pp); /* GL objects (context current) */

#endif
