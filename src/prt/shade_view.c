/* The pinhole view of `cave shade --view` (see shade_view.h). */
#include "prt/shade_view.h"

#include <math.h>

#include "io/texture.h"

void cv_point_direct(const cv_prt *p, const cv_rt *rt, uint32_t t, const float x[3],
                     const float n[3], const cv_dir_light *lights, int n_lights, float rgb[3]) {
  const uint32_t mi = p->tri_mat[t];
  static const float one[3] = {1, 1, 1};
  const float *a = cv_prt_mat_textured(p, mi) ? one : p->mats[mi].albedo;
  float org[3];
  cv_rt_offset_origin(x, n, org);
  for (int k = 0; k < n_lights; k++) {
    const double *s = lights[k].dir;
    const double c = n[0] * s[0] + n[1] * s[1] + n[2] * s[2];
    if (!(c > 0)) continue;
    const float sf[3] = {(float)s[0], (float)s[1], (float)s[2]};
    if (!cv_rt_reaches_env(rt, org, sf, 0.0f)) continue;
    for (int ch = 0; ch < 3; ch++) rgb[ch] += (float)(lights[k].E[ch] / M_PI * c * a[ch]);
  }
}

/* Unit geometric normal of the hit, turned to face the ray's origin (the
 * side the camera sees, as the reference's two-sided Lambert). */
static void facing_normal(const cv_hit *h, const float d[3], float n[3]) {
  const float l = sqrtf(h->ng[0] * h->ng[0] + h->ng[1] * h->ng[1] + h->ng[2] * h->ng[2]);
  const float dn = h->ng[0] * d[0] + h->ng[1] * d[1] + h->ng[2] * d[2];
  const float s = l > 0 ? (dn > 0 ? -1.0f : 1.0f) / l : 0.0f;
  for (int k = 0; k < 3; k++) n[k] = s * h->ng[k];
}

/* One geometry pixel: interpolated vertex radiance + pixel lights, times the texture. */
static void shade_hit(const cv_prt *p, const cv_rt *rt, const cv_shade_view_params *vp,
                      const cv_hit *h, const float d[3], float px[3]) {
  const uint32_t *t = p->tri + 3 * h->tri;
  const float w0 = 1 - h->u - h->v, *rad = vp->rad;
  for (int c = 0; c < 3; c++)
    px[c] = w0 * rad[3 * t[0] + c] + h->u * rad[3 * t[1] + c] + h->v * rad[3 * t[2] + c];
  if (vp->n_lights > 0) {
    float x[3], n[3];
    for (int k = 0; k < 3; k++)
      x[k] = w0 * p->pos[3 * t[0] + k] + h->u * p->pos[3 * t[1] + k] + h->v * p->pos[3 * t[2] + k];
    facing_normal(h, d, n);
    cv_point_direct(p, rt, h->tri, x, n, vp->lights, vp->n_lights, px);
  }
  const cv_image *tx = vp->tex ? vp->tex[p->tri_mat[h->tri]] : NULL;
  if (tx) {
    const float *q = p->tri_uv + 6 * (size_t)h->tri;
    float a[3];
    cv_texture_sample(tx, w0 * q[0] + h->u * q[2] + h->v * q[4],
                      w0 * q[1] + h->u * q[3] + h->v * q[5], a);
    for (int c = 0; c < 3; c++) px[c] *= a[c];
  }
}

void cv_shade_view(const cv_prt *p, const cv_rt *rt, const cv_shade_view_params *vp,
                   cv_image *img, cv_shade_view_stats *stats) {
  const cv_pinhole *cam = &vp->cam;
  uint64_t esc = 0, neg = 0, nonfin = 0;
#pragma omp parallel for schedule(dynamic, 4) reduction(+ : esc, neg, nonfin)
  for (int y = 0; y < cam->h; y++) {
    cv_rt_thread_init();
    for (int x = 0; x < cam->w; x++) {
      float d[3], o[3];
      cv_pinhole_ray(cam, x, y, o, d);
      float *px = cv_image_at(img, x, y);
      cv_hit h;
      if (cv_rt_intersect(rt, o, d, 0, INFINITY, &h)) {
        shade_hit(p, rt, vp, &h, d, px);
      } else if (cv_rt_reaches_env(rt, o, d, 0)) {
        px[0] = px[1] = px[2] = 0;
        if (vp->background) vp->background(vp->bg_ctx, d, px);
      } else {
        px[0] = px[1] = px[2] = 0;
        esc++;
      }
      for (int c = 0; c < 3; c++) {
        if (!isfinite(px[c])) {
          px[c] = 0;
          nonfin++;
        } else if (px[c] < 0) {
          px[c] = 0;
          neg++;
        }
      }
    }
  }
  if (stats) *stats = (cv_shade_view_stats){esc, neg, nonfin};
}
