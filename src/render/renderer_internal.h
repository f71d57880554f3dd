/* The top layer of the wall-eye renderer (not installed): struct
 * cv_renderer, which embeds each feature's state.  Only renderer.c
 * (create, destroy, the scene's upload) and renderer_api.c (the public
 * entry points, each handing a feature its own state and those of the
 * features below it) include it; tests may.
 *
 * File map, bottom layer first (a file includes only headers of a lower
 * layer, a .c file also its own header; tests/render/check_layers.sh
 * declares the same order and checks it, ctest render_layers):
 *   0  renderer.h         the public API (types and entry points)
 *      shaders.c, window.c  embedded GLSL; X11 windows
 *   1  egl_context.c      EGL contexts; desktop.c the preview window
 *   2  render_gl.c        GL helpers (programs, uniforms, textures, TBOs,
 *                         framebuffers, read-back, timing, matrices, keys)
 *                         and cvr_ctx, what every feature shares
 *   3  render_edges.c     directed-edge sets, triangle normals
 *   4  render_scene.c     cvr_scene: the opaque mesh in Morton chunks, its
 *                         buffers, per-view draw, the sun split's parts
 *      render_texture.c   cvr_texture: albedo textures (seam split, array)
 *      render_split.c     cvr_split: split window lights
 *      render_post.c      cvr_post: patch means, equation 7, projector images
 *      render_present.c   cvr_present: drawing images into the window
 *   5  render_casters.c   cvr_casters: the sun's simplified shadow casters
 *      render_relight.c   cvr_relight: relight by transform feedback or on
 *                         the CPU (render_relight.c)
 *   6  render_light.c     cvr_light: a lighting change (relight, sun split,
 *                         shadow map: cvr_shadow, cvr_sunsplit), the
 *                         background, the LCD panel (cvr_panel)
 *   7  render_passes.c    cvr_passes: targets (cvr_targets), Drago table
 *                         (cvr_tone), luminance / depth / shading passes,
 *                         resolve, read-back, statistics, unlit
 *      render_share.c     cvr_share: shared lighting export / import
 *   8  renderer.c, renderer_api.c (this header)
 * Features on one layer do not include each other. */
#ifndef CV_RENDER_RENDERER_INTERNAL_H
#define CV_RENDER_RENDERER_INTERNAL_H

#include "render/render_casters.h"
#include "render/render_gl.h"
#include "render/render_light.h"
#include "render/render_passes.h"
#include "render/render_post.h"
#include "render/render_present.h"
#include "render/render_relight.h"
#include "render/render_scene.h"
#include "render/render_share.h"
#include "render/render_split.h"
#include "render/render_texture.h"
#include "render/window.h"
#include "view/cave.h"

struct cv_renderer {
  cvr_ctx ctx;        /* what every feature shares (points to o and egl) */
  cv_egl egl;
  cv_render_opts o;
  cv_window *win;     /* opts.window: the X11 window (NULL headless) */
  char gl_name[256];
  cvr_scene scene;
  cvr_texture tex;
  cvr_split wl;       /* split window lights */
  cvr_relight relight;
  cvr_casters casters;
  cvr_light light;
  cvr_share share;
  cvr_passes passes;
  cvr_post *post;     /* made on first use */
  cvr_present present;
};

/* The inputs of the passes (render_passes.h). */
static inline cvr_inputs cvr_renderer_inputs(cv_renderer *r) {
  const cvr_inputs in = {&r->scene, &r->light, &r->tex};
  return in;
}

#endif
