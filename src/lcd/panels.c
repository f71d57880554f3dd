/* The LCD panels of a scene, stacked into one buffer (panels.h). */
#include "lcd/panels.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/hash.h"
#include "lcd/eye_veil.h"

/* The rectangle of three corners (lower-left, lower-right, upper-left). */
static void rect_from_corners(const double c[3][3], cv_lcd_panel *r) {
  double u[3], v[3], lu = 0, lv = 0;
  for (int k = 0; k < 3; k++) {
    u[k] = c[1][k] - c[0][k];
    v[k] = c[2][k] - c[0][k];
    lu += u[k] * u[k];
    lv += v[k] * v[k];
  }
  lu = sqrt(lu), lv = sqrt(lv);
  for (int k = 0; k < 3; k++) {
    r->center[k] = (float)(c[0][k] + 0.5 * (u[k] + v[k]));
    r->u[k] = (float)(u[k] / lu);
    r->v[k] = (float)(v[k] / lv);
  }
  const double n[3] = {r->u[1] * (double)r->v[2] - r->u[2] * (double)r->v[1],
                       r->u[2] * (double)r->v[0] - r->u[0] * (double)r->v[2],
                       r->u[0] * (double)r->v[1] - r->u[1] * (double)r->v[0]};
  const double ln = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  for (int k = 0; k < 3; k++) r->normal[k] = (float)(n[k] / ln);
  r->size[0] = (float)lu;
  r->size[1] = (float)lv;
}

int cv_lcd_layout_make(const cv_lcd_config *c, const cv_mesh *m, cv_lcd_layout *out, cv_err *err) {
  memset(out, 0, sizeof *out);
  const char *file = c->source[0] ? c->source : "lcd";
  if (c->n_panels < 1 || c->n_panels > CV_LCD_MAX_PANELS)
    return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.panels: run cv_lcd_config_panels first", file);
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < m->nv; i++)
    for (int k = 0; k < 3; k++) {
      lo[k] = fmin(lo[k], m->pos[3 * i + k]);
      hi[k] = fmax(hi[k], m->pos[3 * i + k]);
    }
  out->n = c->n_panels;
  for (int i = 0; i < c->n_panels; i++) {
    const cv_lcd_panel_config *pc = &c->panels[i];
    if (pc->has_corners) {
      static const char *const which[3] = {"lower-left", "lower-right", "upper-left"};
      for (int j = 0; j < 3; j++)
        for (int k = 0; k < 3; k++)
          if (!(pc->corners[j][k] >= lo[k] - 0.01 && pc->corners[j][k] <= hi[k] + 0.01))
            return cv_err_set(err, CV_ERR_CONFIG,
                              "%s: lcd.panels[%d].corners[%d]: the %s corner %g,%g,%g lies outside "
                              "the scene (%.3g,%.3g,%.3g .. %.3g,%.3g,%.3g m)",
                              file, i, j, which[j], pc->corners[j][0], pc->corners[j][1],
                              pc->corners[j][2], lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
      rect_from_corners(pc->corners, &out->rect[i]);
    } else {
      cv_err e2;
      if (cv_lcd_panel_from_mesh(m, &out->rect[i], &e2))
        return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.panels[%d] ('%s'): no corners and %s", file,
                          i, pc->name, e2.msg);
    }
    int w = pc->width > 0 ? pc->width : c->width, h = pc->width > 0 ? pc->height : c->height;
    if (w < 1) w = 400;
    if (h < 1) { /* square texels: the panel's aspect */
      const double hh = floor(w * (double)out->rect[i].size[1] / out->rect[i].size[0] + 0.5);
      h = hh < 1 ? 1 : (hh > 16384 ? 16384 : (int)hh);
    }
    out->w[i] = w;
    out->h[i] = h;
    out->y0[i] = out->H;
    out->H += h;
    if (w > out->W) out->W = w;
  }
  if (out->H > 16384)
    return cv_err_set(err, CV_ERR_CONFIG,
                      "%s: lcd: the panels are %d texels high together (16384 at most): lower "
                      "lcd.resolution", file, out->H);
  return CV_OK;
}

int cv_lcd_layout_content(const cv_lcd_config *c, const cv_lcd_layout *L, cv_image **out,
                          cv_err *err) {
  *out = NULL;
  cv_image *all;
  if (cv_image_create(L->W, L->H, 3, &all)) return cv_err_set(err, CV_ERR_NOMEM, "content: out of memory");
  for (int i = 0; i < L->n; i++) {
    const cv_lcd_panel_config *pc = &c->panels[i];
    cv_image *one;
    int st = cv_lcd_content_load(pc->content, L->w[i], L->h[i],
                                 (double)L->rect[i].size[0] / L->rect[i].size[1],
                                 pc->content_luminance, pc->black_luminance, &one, err);
    if (st) {
      cv_image_destroy(all);
      return st;
    }
    for (int y = 0; y < L->h[i]; y++)
      memcpy(cv_image_at(all, 0, L->y0[i] + y), cv_image_at(one, 0, y),
             3 * (size_t)L->w[i] * sizeof(float));
    cv_image_destroy(one);
  }
  *out = all;
  return CV_OK;
}

int cv_lcd_layout_crop(const cv_lcd_layout *L, const cv_lcd_accum *a, int i, cv_lcd_accum **out) {
  *out = NULL;
  if (i < 0 || i >= L->n || a->w != L->W || a->h != L->H) return CV_ERR_INVALID;
  cv_lcd_accum *c;
  int st = cv_lcd_accum_create(L->w[i], L->h[i], a->clamp, &c);
  if (st) return st;
  memcpy(c->data, a->data, CV_LCD_ACC_HEADER * sizeof(int64_t));
  for (int k = 0; k < 2 * CV_LCD_ACC_VEIL_SLOTS; k++) c->data[CV_LCD_ACC_VEIL + k] = 0;
  c->data[CV_LCD_ACC_VEIL] = a->data[CV_LCD_ACC_VEIL + 2 * i];
  c->data[CV_LCD_ACC_VEIL + 1] = a->data[CV_LCD_ACC_VEIL + 2 * i + 1];
  for (int y = 0; y < L->h[i]; y++) {
    memcpy(c->data + cv_lcd_acc_rgb(c, 0, y), a->data + cv_lcd_acc_rgb(a, 0, L->y0[i] + y),
           3 * (size_t)L->w[i] * sizeof(int64_t));
    memcpy(c->data + cv_lcd_acc_m2(c, 0, y), a->data + cv_lcd_acc_m2(a, 0, L->y0[i] + y),
           2 * (size_t)L->w[i] * sizeof(int64_t));
  }
  *out = c;
  return CV_OK;
}

int cv_lcd_panels_create(const cv_lcd_config *c, const cv_lcd_layout *L, const cv_rt *rt,
                         const cv_mesh *m, cv_lcd_panels **out, cv_err *err) {
  *out = NULL;
  cv_lcd_panels *ps = calloc(1, sizeof *ps);
  if (!ps) return cv_err_set(err, CV_ERR_NOMEM, "LCD panels: out of memory");
  ps->L = *L;
  for (int i = 0; i < L->n; i++) {
    cv_brdf_report rep;
    int st = cv_brdf_load(c->panels[i].brdf, &ps->brdf[i], &rep, err);
    if (!st) st = cv_lcd_gather_create(rt, m, &L->rect[i], ps->brdf[i], &ps->g[i], err);
    if (st) {
      cv_lcd_panels_destroy(ps);
      return st;
    }
  }
  *out = ps;
  return CV_OK;
}

void cv_lcd_panels_destroy(cv_lcd_panels *ps) {
  if (!ps) return;
  for (int i = 0; i < CV_LCD_MAX_PANELS; i++) {
    cv_lcd_gather_destroy(ps->g[i]);
    cv_brdf_destroy(ps->brdf[i]);
  }
  free(ps);
}

double cv_lcd_panels_clamp(const cv_lcd_panels *ps, const cv_lcd_light *l, double config_clamp) {
  if (config_clamp > 0) return config_clamp;
  double c = 0;
  for (int i = 0; i < ps->L.n; i++) {
    const double ci = cv_lcd_default_clamp(l, ps->brdf[i]);
    c = ci > c ? ci : c;
  }
  return c > 0 ? c : 1;
}

uint64_t cv_lcd_panels_setup_hash(const cv_lcd_panels *ps, const cv_lcd_params *p, double clamp,
                                  double tolerance, uint64_t scene_hash) {
  if (ps->L.n == 1) { /* one panel: the single gather's key */
    cv_lcd_params q = *p;
    q.w = ps->L.w[0], q.h = ps->L.h[0];
    return cv_lcd_setup_hash(ps->g[0], &q, clamp, tolerance, scene_hash);
  }
  uint64_t h = cv_hash64_init();
  for (int i = 0; i < ps->L.n; i++) {
    cv_lcd_params q = *p;
    q.w = ps->L.w[i], q.h = ps->L.h[i];
    h = cv_hash64_u64(h, cv_lcd_setup_hash(ps->g[i], &q, clamp, tolerance, scene_hash));
  }
  return h;
}

int cv_lcd_panels_round(const cv_lcd_panels *ps, const cv_lcd_light *l, const cv_lcd_params *p,
                        uint32_t round, cv_lcd_accum *acc) {
  const cv_lcd_layout *L = &ps->L;
  if (acc->w != L->W || acc->h != L->H) return CV_ERR_INVALID;
  if (L->n == 1 && L->w[0] == L->W) { /* one panel: straight into the buffer */
    cv_lcd_params q = *p;
    q.w = L->w[0], q.h = L->h[0], q.x0 = q.y0 = 0;
    return cv_lcd_render_round(ps->g[0], l, &q, round, acc);
  }
  int64_t spp = 0, rounds = 0;
  for (int i = 0; i < L->n; i++) {
    cv_lcd_accum *one;
    int st = cv_lcd_accum_create(L->w[i], L->h[i], acc->clamp, &one);
    if (st) return st;
    cv_lcd_params q = *p;
    q.w = L->w[i], q.h = L->h[i], q.x0 = q.y0 = 0;
    st = cv_lcd_render_round(ps->g[i], l, &q, round, one);
    if (st) {
      cv_lcd_accum_destroy(one);
      return st;
    }
    for (int y = 0; y < L->h[i]; y++) {
      int64_t *d = acc->data + cv_lcd_acc_rgb(acc, 0, L->y0[i] + y);
      const int64_t *s = one->data + cv_lcd_acc_rgb(one, 0, y);
      for (size_t k = 0; k < 3 * (size_t)L->w[i]; k++) d[k] += s[k];
      d = acc->data + cv_lcd_acc_m2(acc, 0, L->y0[i] + y);
      s = one->data + cv_lcd_acc_m2(one, 0, y);
      for (size_t k = 0; k < 2 * (size_t)L->w[i]; k++) d[k] += s[k];
    }
    /* counters: summed over the panels, but one round of spp samples */
    for (int k = 0; k < CV_LCD_ACC_VEILS; k++)
      if (k != CV_LCD_ACC_SPP && k != CV_LCD_ACC_ROUNDS) acc->data[k] += one->data[k];
    spp = one->data[CV_LCD_ACC_SPP];
    rounds = one->data[CV_LCD_ACC_ROUNDS];
    cv_lcd_accum_destroy(one);
  }
  acc->data[CV_LCD_ACC_SPP] += spp;
  acc->data[CV_LCD_ACC_ROUNDS] += rounds;
  return CV_OK;
}

int cv_lcd_panels_veils(const cv_lcd_panels *ps, const cv_lcd_light *l, const float eye[3],
                        const cv_lcd_veil_params *vp, cv_lcd_figure *lv, double *sun_deg) {
  for (int i = 0; i < ps->L.n; i++) {
    int st = cv_lcd_panel_veil(ps->g[i], l, eye, vp, &lv[i], &sun_deg[i]);
    if (st) return st;
  }
  return CV_OK;
}
