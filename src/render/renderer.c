/* The wall-eye renderer's top layer (see renderer.h, renderer_internal.h):
 * options, create, destroy and the scene's upload, which hands each
 * feature its part of the PRT.
 *
 * GL objects, by owner:
 *   scene (render_scene.c)   positions (attribute 0), relit radiance per
 *                            vertex (vec4: RGB, channels clamped; attribute
 *                            1, written by the relight), albedo (attribute 2,
 *                            the sun's direct term), (u, v, layer) of
 *                            textured scenes (attribute 3), the opaque
 *                            triangles (windows dropped) and their sun split
 *   relight (render_relight.c) the transfer as a texture buffer: per vertex
 *                            nc texels (td_i, ti_R,i, ti_G,i, ti_B,i) then
 *                            the albedo
 *   texture (render_texture.c) the albedo texture array
 *   passes (render_passes.c) shading targets (display, HDR: RGBA32F textures)
 *                            + depth, the supersampling resolve targets, the
 *                            luminance pass and statistics, the Drago table
 *   light (render_light.c)   the sun's shadow map, the background, the panel
 *   post, present, casters, split: their own (render_*.c) */
#include "render/renderer_internal.h"


void cv_render_default_opts(cv_render_opts *o) {
  memset(o, 0, sizeof *o);
  o->shadow_res = 2048;
  o->timing = 1;
  o->cull_frustum = 1;
  o->sun_split = 1;
  o->gpu = CV_GPU_AUTO;
  o->shadow_cull = -1;
  o->shadow_reuse = 0.5;
  o->split_margin = 0.05;
  o->shadow_casters = 0.001;
  o->relight_cpu = -1;
  o->lum_stats_gpu = -1;
  o->half_transfer = -1;
}

int cv_render_transfer_parse(const char *s, int *half_transfer) {
  if (!s) return -1;
  if (!strcmp(s, "auto")) *half_transfer = -1;
  else if (!strcmp(s, "float")) *half_transfer = 0;
  else if (!strcmp(s, "half")) *half_transfer = 1;
  else return -1;
  return 0;
}

/* The scene's upload: the scene's order and buffers, the relight's
 * transfer, the split lights' vertex map, in the renumbered order. */
static int upload_scene(cv_renderer *r, const cv_prt *p, cv_err *err) {
  const int nc = (int)(p->bands * p->bands);
  GLint max_tbo = 0;
  glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &max_tbo);
  const size_t texels = p->nv * (size_t)(nc + 1);
  if (texels > (size_t)max_tbo || p->nv > 0x7fffffff)
    return cv_err_set(err, CV_ERR_RANGE,
                      "scene too large for this GL: %zu vertices x %d coefficients (texture buffers "
                      "hold %d texels)",
                      p->nv, nc, (int)max_tbo);
  uint32_t *idx = NULL, *old_of = NULL;
  int st = cvr_scene_order(&r->scene, p, &idx, &old_of, err);
  if (st) return st;
  /* Sampled textures (render_texture.c: p is then the split PRT, without
   * the texture flag, so the scale is 1) multiply the pixels; a textured
   * PRT drawn without them gets its mean albedo back. */
  float *usc = malloc(3 * p->nv * sizeof *usc + 4), *uvl = NULL;
  if (!usc || cv_prt_untextured_scale(p, usc)) {
    st = cv_err_set(err, CV_ERR_NOMEM, "out of memory uploading the scene");
  } else if (r->tex.uvl && !(uvl = malloc(3 * p->nv * sizeof *uvl + 4))) {
    st = cv_err_set(err, CV_ERR_NOMEM, "out of memory uploading the scene");
  }
  if (!st) st = cvr_relight_upload(&r->ctx, &r->relight, p, old_of, usc, err);
  if (!st) {
    cvr_split_map(&r->wl, p, old_of, usc, r->tex.orig);
    if (uvl) /* (u, v, layer) in the renumbered order */
      for (size_t v = 0; v < p->nv; v++)
        for (int j = 0; j < 3; j++) uvl[3 * v + j] = r->tex.uvl[3 * old_of[v] + j];
    st = cvr_scene_upload(&r->scene, p, old_of, usc, uvl, idx, err);
    idx = NULL; /* the scene's now */
  }
  free(idx), free(old_of), free(usc), free(uvl);
  return st;
}

/* The context, the window (opts.window) and the GL's limits. */
static int open_context(cv_renderer *r, cv_err *err) {
  cv_egl_request rq = {r->o.gpu, NULL, r->o.window};
  int st = CV_OK;
  if (r->o.window) st = cv_window_connect(r->o.window->display, &r->win, err);
  rq.window = r->win;
  if (!st) st = cv_egl_open(&rq, &r->egl, err);
  if (st) return st;
  snprintf(r->gl_name, sizeof r->gl_name, "%s | %s (EGL %s)", (const char *)glGetString(GL_RENDERER),
           (const char *)glGetString(GL_VERSION), r->egl.platform);
  glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &r->ctx.max_rb);
  GLint tex_max = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &tex_max);
  if (tex_max < r->ctx.max_rb) r->ctx.max_rb = tex_max;
  glGenVertexArrays(1, &r->ctx.vao_empty);
  return CV_OK;
}

int cv_renderer_create(const cv_prt *prt, const cv_render_opts *opts, cv_renderer **out,
                       cv_err *err) {
  *out = NULL;
  if (!prt || prt->bands < 1 || prt->bands > CV_PRT_MAX_BANDS || !prt->nv || !prt->nt)
    return cv_err_set(err, CV_ERR_INVALID, "renderer: empty or invalid PRT");
  cv_renderer *r = calloc(1, sizeof *r);
  if (!r) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  if (opts) r->o = *opts;
  else cv_render_default_opts(&r->o);
  if (r->o.shadow_res < 16) r->o.shadow_res = 2048;
  r->ctx.o = &r->o;
  r->ctx.egl = &r->egl;
  int st = open_context(r, err);
  if (st) {
    cv_window_destroy(r->win);
    free(r);
    return st;
  }
  cv_prt *split = NULL; /* textured: vertices split at UV seams (render_texture.c) */
  if ((st = cvr_texture_prepare(&r->tex, prt, &split, err))) {
    cv_renderer_destroy(r);
    return st;
  }
  if (split) prt = split;
  st = upload_scene(r, prt, err);
  const int nc = r->scene.nc;
  cv_prt_destroy(split);
  cvr_texture_free_upload(&r->tex);
  if (st || (st = cvr_relight_init(&r->relight, nc, err)) || (st = cvr_passes_init(&r->passes, err)) ||
      (r->win && (st = cvr_present_init(&r->present, err))) ||
      (st = cvr_light_upload_background(&r->light, 1, 1, (const float[3]){0, 0, 0}, err)) ||
      (st = cvr_gl_check("renderer setup", err))) {
    cv_renderer_destroy(r);
    return st;
  }
  *out = r;
  return CV_OK;
}

void cv_renderer_destroy(cv_renderer *r) {
  if (!r) return;
  if (r->egl.dpy && cv_egl_make_current(&r->egl) == CV_OK) {
    cvr_post_free(&r->post);
    cvr_present_free(&r->present);
    cvr_passes_free(&r->passes);
    cvr_light_free(&r->light);
    cvr_casters_free(&r->casters);
    cvr_relight_free(&r->relight);
    cvr_split_free(&r->wl);
    cvr_texture_free(&r->tex);
    cvr_scene_free(&r->scene);
    cvr_ctx_free(&r->ctx);
  }
  cv_egl_close(&r->egl);
  cv_window_destroy(r->win);
  free(r->ctx.rgba8);
  cvr_passes_free_cpu(&r->passes);
  cvr_casters_free_cpu(&r->casters);
  cvr_relight_free_cpu(&r->relight);
  cvr_split_free_cpu(&r->wl);
  cvr_texture_free_upload(&r->tex);
  cvr_scene_free_cpu(&r->scene);
  free(r);
}
