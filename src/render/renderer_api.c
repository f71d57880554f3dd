/* The renderer's public entry points (renderer.h), top layer: each checks
 * the renderer, makes its context current where the feature does not, and
 * hands the feature its own state and those of the features below it
 * (renderer_internal.h).  No rendering logic lives here. */
#include "render/renderer_internal.h"

#define NULL_VIEW(err) cv_err_set(err, CV_ERR_INVALID, "renderer: NULL view")
#define MAKE_CURRENT(r, err)                                                                   \
  do {                                                                                         \
    if (cv_egl_make_current(&(r)->egl))                                                        \
      return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");                         \
  } while (0)

/* ---------------------------------------------------------------- queries */

const char *cv_renderer_gl_name(const cv_renderer *r) { return r->gl_name; }
int cv_renderer_mesh_closed(const cv_renderer *r) { return r->scene.closed; }
int cv_renderer_relight_on_cpu(const cv_renderer *r) { return r->relight.on_cpu; }
int cv_renderer_half_transfer(const cv_renderer *r) { return r->relight.half_on; }
int cv_renderer_lum_stats_on_gpu(const cv_renderer *r) { return cvr_lum_stats_gpu(&r->ctx); }
int cv_renderer_is_software(const cv_renderer *r) { return r->egl.software; }
int cv_renderer_hw_devices(const cv_renderer *r) { return r->egl.hw_devices; }
const char *cv_renderer_platform(const cv_renderer *r) { return r->egl.platform; }

int cv_renderer_textures(const cv_renderer *r, cv_render_tex_info *info) {
  return cvr_texture_info(&r->tex, info);
}

int cv_renderer_shadow_casters(const cv_renderer *r, cv_shadow_casters *out) {
  if (!r || !out) return CV_ERR_INVALID;
  cvr_casters_info(&r->ctx, &r->casters, &r->scene, out);
  return CV_OK;
}

uint64_t cv_renderer_panel_invalid(const cv_renderer *r) { return r ? r->light.panel.bad : 0; }

int cv_renderer_tone_table(const cv_renderer *r, double *drago_err) {
  const cvr_tone *t = r ? &r->passes.tone : NULL;
  if (drago_err) *drago_err = t && t->built ? t->err : NAN;
  return t && t->built && t->ok;
}

size_t cv_renderer_view_triangles(const cv_renderer *r, const cv_render_view *v) {
  float mvp[16], inv[16], eye[3], facing;
  if (!r || !v || cvr_view_matrices(v, mvp, inv, eye, &facing)) return 0;
  return cvr_scene_view_triangles(&r->ctx, &r->scene, mvp);
}

void cv_renderer_io(const cv_renderer *r, uint64_t *read_bytes, uint64_t *uploaded_bytes) {
  if (read_bytes) *read_bytes = r ? r->ctx.io_read : 0;
  if (uploaded_bytes) *uploaded_bytes = r ? r->ctx.io_up : 0;
}

void cv_renderer_set_timing(cv_renderer *r, int timing) {
  if (r) r->o.timing = timing;
}

void cv_renderer_gpu_timer_begin(cv_renderer *r) {
  if (!r || cv_egl_make_current(&r->egl)) return;
  cvr_timer_begin(&r->ctx);
}

void cv_renderer_gpu_timer_end(cv_renderer *r) {
  if (r) cvr_timer_end(&r->ctx);
}

double cv_renderer_gpu_timer_result(cv_renderer *r) { return r ? cvr_timer_result(&r->ctx) : NAN; }

/* ---------------------------------------------------------------- lighting */

int cv_renderer_set_lighting(cv_renderer *r, const cv_lighting *l, cv_render_light_stats *stats,
                             cv_frame_timing *t, cv_err *err) {
  if (!r || !l) return cv_err_set(err, CV_ERR_INVALID, "renderer: NULL lighting");
  return cvr_light_set(&r->ctx, &r->light, &r->scene, &r->relight, &r->wl, &r->casters, l, stats, t,
                       err);
}

int cv_renderer_set_split(cv_renderer *r, const cv_dir_light *lights, int n,
                          const float *direct_rgb, cv_err *err) {
  if (!r) return cv_err_set(err, CV_ERR_INVALID, "renderer: split lights: NULL or n = %d", n);
  return cvr_split_set(&r->ctx, &r->wl, r->scene.nc, r->scene.nv, r->relight.on_cpu, lights, n,
                       direct_rgb, err);
}

int cv_renderer_set_background(cv_renderer *r, const cv_image *img, cv_err *err) {
  if (!r) return cv_err_set(err, CV_ERR_INVALID, "renderer: NULL");
  MAKE_CURRENT(r, err);
  return cvr_light_background(&r->ctx, &r->light, img, err);
}

int cv_renderer_set_panel(cv_renderer *r, const float center[3], const float u[3],
                          const float v[3], const float size[2], const cv_image *img, cv_err *err) {
  if (!r) return cv_err_set(err, CV_ERR_INVALID, "renderer: NULL");
  MAKE_CURRENT(r, err);
  return cvr_light_panel(&r->ctx, &r->light, center, u, v, size, img, err);
}

size_t cv_renderer_lighting_bytes(const cv_renderer *r) {
  return r ? cvr_share_bytes(&r->ctx, &r->scene) : 0;
}

uint64_t cv_renderer_lighting_scene(cv_renderer *r) {
  return r ? cvr_share_scene(&r->ctx, &r->share, &r->scene, &r->relight) : 0;
}

int cv_renderer_lighting_export(cv_renderer *r, void *buf, size_t cap, cv_err *err) {
  if (!r) return cv_err_set(err, CV_ERR_INVALID, "lighting export: NULL");
  return cvr_share_export(&r->ctx, &r->share, &r->scene, &r->relight, &r->light, buf, cap, err);
}

int cv_renderer_lighting_import(cv_renderer *r, const void *buf, size_t len, cv_frame_timing *t,
                                cv_err *err) {
  if (!r) return cv_err_set(err, CV_ERR_INVALID, "lighting import: NULL");
  return cvr_share_import(&r->ctx, &r->share, &r->scene, &r->relight, &r->light, buf, len, t, err);
}

void cv_renderer_lighting_forget(cv_renderer *r) {
  if (r) cvr_light_forget(&r->light);
}

/* ---------------------------------------------------------------- passes */

int cv_renderer_luminance(cv_renderer *r, const cv_render_view *v, cv_image *out,
                          cv_frame_timing *t, cv_err *err) {
  if (!r) return NULL_VIEW(err);
  const cvr_inputs in = cvr_renderer_inputs(r);
  return cvr_passes_luminance(&r->ctx, &r->passes, &in, v, out, t, err);
}

int cv_renderer_shade_stats(cv_renderer *r, const cv_render_view *v, const cv_drago_consts *dc,
                            int transfer, cv_image *out_display, cv_image *out_hdr,
                            cv_image *out_lum, double *max_y, uint64_t *n_invalid,
                            cv_frame_timing *t, cv_err *err) {
  if (!r) return NULL_VIEW(err);
  const cvr_inputs in = cvr_renderer_inputs(r);
  return cvr_passes_shade(&r->ctx, &r->passes, &in, v, dc, transfer, out_display, 0, out_hdr, out_lum,
                          max_y, n_invalid, t, err);
}

int cv_renderer_shade(cv_renderer *r, const cv_render_view *v, const cv_drago_consts *dc,
                      int transfer, cv_image *out_display, cv_image *out_hdr, cv_frame_timing *t,
                      cv_err *err) {
  return cv_renderer_shade_stats(r, v, dc, transfer, out_display, out_hdr, NULL, NULL, NULL, t, err);
}

int cv_renderer_shade_gpu(cv_renderer *r, const cv_render_view *v, const cv_drago_consts *dc,
                          cv_image *out_hdr, cv_image *out_lum, double *max_y, uint64_t *n_invalid,
                          cv_frame_timing *t, cv_err *err) {
  if (!r) return NULL_VIEW(err);
  const cvr_inputs in = cvr_renderer_inputs(r);
  return cvr_passes_shade(&r->ctx, &r->passes, &in, v, dc, 0, NULL, 1, out_hdr, out_lum, max_y,
                          n_invalid, t, err);
}

int cv_renderer_frame(cv_renderer *r, const cv_render_view *v, const cv_drago_consts *dc,
                      int transfer, cv_image *out_display, cv_image *out_hdr, cv_image *out_lum,
                      cv_frame_timing *t, cv_err *err) {
  int st;
  if (out_lum && (st = cv_renderer_luminance(r, v, out_lum, t, err))) return st;
  return cv_renderer_shade(r, v, dc, transfer, out_display, out_hdr, t, err);
}

int cv_renderer_unlit(cv_renderer *r, const cv_render_view *v, cv_image *out, cv_frame_timing *t,
                      cv_err *err) {
  if (!r) return NULL_VIEW(err);
  const cvr_inputs in = cvr_renderer_inputs(r);
  return cvr_passes_unlit(&r->ctx, &r->passes, &in, v, out, t, err);
}

int cv_renderer_display_read(cv_renderer *r, cv_image *img, cv_err *err) {
  const cvr_image_ref *d = r ? &r->passes.disp : NULL;
  if (!r || !img || img->c != 3 || !img->px || !d->tex || img->w != d->w || img->h != d->h)
    return cv_err_set(err, CV_ERR_INVALID, "display read: expected a %dx%d RGB image and a display on the GPU",
                      d ? d->w : 0, d ? d->h : 0);
  MAKE_CURRENT(r, err);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, d->fbo);
  if (cvr_read_image(&r->ctx, GL_COLOR_ATTACHMENT0, !d->is_float, img))
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory reading back");
  return cvr_gl_check("display read", err);
}

/* ---------------------------------------------------------------- post */

int cv_renderer_post_available(cv_renderer *r, char *why, size_t cap) {
  return cvr_post_available(&r->ctx, &r->post, why, cap);
}

int cv_renderer_post_grid(cv_renderer *r, int nu, int nv, const double *eu, const double *ev, int w, int h,
                          cv_err *err) {
  if (!r)
    return cv_err_set(err, CV_ERR_INVALID, "post grid: %d x %d patches on %d x %d pixels (1..%d pixels, at "
                      "most one patch a pixel)", nu, nv, w, h, 0);
  return cvr_post_grid(&r->ctx, &r->post, nu, nv, eu, ev, w, h, err);
}

int cv_renderer_patch_means(cv_renderer *r, double *out, cv_err *err) {
  if (!r || !out) return cv_err_set(err, CV_ERR_INVALID, "patch means: NULL argument");
  return cvr_post_patch_means(&r->ctx, r->post, &r->passes.disp, out, err);
}

int cv_renderer_display_keep(cv_renderer *r, int slot, cv_err *err) {
  if (!r || slot < 0 || slot > 1) return cv_err_set(err, CV_ERR_INVALID, "display keep: slot 0 or 1");
  return cvr_post_keep(&r->ctx, r->post, &r->passes.disp, slot, err);
}

int cv_renderer_post(cv_renderer *r, int slot, int kept, const float *delta, cv_err *err) {
  if (!r || slot < 0 || slot > 1) return cv_err_set(err, CV_ERR_INVALID, "post: slot 0 or 1");
  return cvr_post_run(&r->ctx, r->post, &r->passes.disp, slot, kept, delta, err);
}

int cv_renderer_post_black(cv_renderer *r, int slot, cv_err *err) {
  if (!r) return cv_err_set(err, CV_ERR_INVALID, "post: no grid, or slot not 0 or 1");
  return cvr_post_black(&r->ctx, r->post, slot, err);
}

int cv_renderer_post_read(cv_renderer *r, int slot, uint8_t *codes, cv_err *err) {
  if (!r) return cv_err_set(err, CV_ERR_INVALID, "post read: no grid, or slot not 0 or 1");
  return cvr_post_read(&r->ctx, r->post, slot, codes, err);
}

/* ---------------------------------------------------------------- window */

int cv_renderer_present(cv_renderer *r, const uint8_t *left, const uint8_t *right, int w, int h,
                        int layout, cv_err *err) {
  if (!r->win) return cv_err_set(err, CV_ERR_INVALID, "renderer: no window to present on");
  return cvr_present_codes(&r->ctx, &r->present, r->win, left, right, w, h, layout, err);
}

int cv_renderer_present_slots(cv_renderer *r, int layout, cv_err *err) {
  if (!r->win) return cv_err_set(err, CV_ERR_INVALID, "renderer: no window to present on");
  const int packed = layout == CV_STEREO_SIDE_BY_SIDE || layout == CV_STEREO_TOP_BOTTOM;
  int w = 0, h = 0, w1 = 0, h1 = 0;
  GLuint tex[2] = {cvr_post_slot_texture(r->post, 0, &w, &h), cvr_post_slot_texture(r->post, 1, &w1, &h1)};
  if (!tex[0] || (packed && !tex[1]))
    return cv_err_set(err, CV_ERR_INVALID, "renderer: present: no projector image (cv_renderer_post_grid)");
  return cvr_present_textures(&r->ctx, &r->present, r->win, tex, w, h, layout, err);
}

int cv_renderer_swap(cv_renderer *r, cv_err *err) {
  if (!r->win) return CV_OK;
  if (cv_window_poll(r->win) == CV_WIN_LOST || cv_egl_swap(&r->egl))
    return cv_err_set(err, CV_ERR_BACKEND, "eglSwapBuffers on X display '%s' failed (%s)",
                      cv_window_display_name(r->win), cv_window_event_name(cv_window_poll(r->win)));
  return CV_OK;
}

int cv_renderer_window_poll(cv_renderer *r) { return r->win ? cv_window_poll(r->win) : CV_WIN_OK; }

void cv_renderer_window_size(const cv_renderer *r, int *w, int *h) {
  *w = *h = 0;
  if (r->win) cv_window_size(r->win, w, h);
}
