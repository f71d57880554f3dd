/* The renderer's lighting (not installed; layer 3, on render_scene.h,
 * render_split.h, render_relight.h and render_casters.h): a lighting
 * change (relight, the sun split of the chunks, the sun's shadow map), the
 * background image and the dashboard LCD panel.  Owns the state below;
 * the passes read it when they shade, shared lighting copies it. */
#ifndef CV_RENDER_LIGHT_H
#define CV_RENDER_LIGHT_H

#include "render/render_casters.h"
#include "render/render_gl.h"
#include "render/render_relight.h"
#include "render/render_scene.h"
#include "render/render_split.h"

/* The sun's shadow map: the scene -> shadow-map texel space matrix q
 * (prt.frag), its axis scales k (D^2, -D_z), the sign of its determinant,
 * the bias; the depth texture (drawn here) or an imported map in tex_imp,
 * an R32F texture of imp_res texels (a colour upload is a copy; llvmpipe
 * converts a depth upload texel by texel, 16 ms for 2048^2), from_import:
 * the current map is that one (fbo_imp reads it back for a re-export).  The
 * current map: drawn for opts.shadow_res (res; an imported one may differ)
 * in its lower-left w x h texels; depth_res: tex's size (0: none yet).  s:
 * the sun of the current map, texel its texel (m); gen / import: maps drawn
 * here so far (the generation an export names), the exporter's generation
 * of the imported one (0: made here). */
typedef struct cvr_shadow {
  float q[16], k[4], bias;
  int detsign;
  GLuint fbo, tex, tex_imp, fbo_imp;
  int imp_res, from_import, depth_res, res, w, h;
  double s[3], texel;
  int valid;
  uint64_t gen, import;
} cvr_shadow;

/* The sun split of the scene's chunks (cvr_scene's partition) for the
 * direction s; gen / import as the shadow map's. */
typedef struct cvr_sunsplit {
  double s[3];
  int valid;
  uint64_t gen, import;
} cvr_sunsplit;

/* The dashboard LCD image (cv_renderer_set_panel). */
typedef struct cvr_panel {
  GLuint tex;
  int on;
  uint64_t bad;
  float c[3], u[3], v[3], n[3], half[2];
} cvr_panel;

typedef struct cvr_light {
  int lit, has_sun, sun_split; /* a lighting set; with a sun; drawn split */
  float sun_e[3];              /* the sun's E / pi */
  cvr_shadow shadow;
  cvr_sunsplit split;
  GLuint tex_bg;               /* the background (lat-long RGB32F) */
  cvr_panel panel;
} cvr_light;

/* Orthographic sun view of sc's opaque vertices for the sun s: the clip
 * matrix of the map, its texel (m) and size; sets sh->q, k, detsign. */
void cvr_sun_matrices(const cvr_ctx *c, cvr_shadow *sh, const cvr_scene *sc, const double s[3],
                      float clip[16], float *texel, int size[2]);
/* cv_renderer_set_lighting. */
int cvr_light_set(const cvr_ctx *c, cvr_light *lt, cvr_scene *sc, cvr_relight *rl,
                  const cvr_split *wl, cvr_casters *k, const cv_lighting *l,
                  cv_render_light_stats *stats, cv_frame_timing *t, cv_err *err);
int cvr_light_upload_background(cvr_light *lt, int w, int h, const float *rgb, cv_err *err);
/* cv_renderer_set_background (context current). */
int cvr_light_background(const cvr_ctx *c, cvr_light *lt, const cv_image *img, cv_err *err);
/* cv_renderer_set_panel (context current; img NULL: off). */
int cvr_light_panel(const cvr_ctx *c, cvr_light *lt, const float center[3], const float u[3],
                    const float v[3], const float size[2], const cv_image *img, cv_err *err);
void cvr_light_forget(cvr_light *lt); /* cv_renderer_lighting_forget */
void cvr_light_free(cvr_light *lt);   /* GL objects (context current) */

#endif
