/* Shared lighting (not installed; layer 4, on render_light.h): a lighting
 * change's products (relit colours, shadow map, sun split) exported into a
 * byte buffer and imported by another renderer of the same scene
 * (render_share.c has the layout). */
#ifndef CV_RENDER_SHARE_H
#define CV_RENDER_SHARE_H

#include "render/render_gl.h"
#include "render/render_light.h"
#include "render/render_relight.h"
#include "render/render_scene.h"

/* The scene's fingerprint (0: not computed yet). */
typedef struct cvr_share {
  uint64_t scene;
} cvr_share;

size_t cvr_share_bytes(const cvr_ctx *c, const cvr_scene *sc);
uint64_t cvr_share_scene(const cvr_ctx *c, cvr_share *sh, const cvr_scene *sc, const cvr_relight *rl);
int cvr_share_export(const cvr_ctx *c, cvr_share *sh, const cvr_scene *sc, const cvr_relight *rl,
                     cvr_light *lt, void *buf, size_t cap, cv_err *err);
int cvr_share_import(const cvr_ctx *c, cvr_share *sh, cvr_scene *sc, const cvr_relight *rl,
                     cvr_light *lt, const void *buf, size_t len, cv_frame_timing *t, cv_err *err);

#endif
