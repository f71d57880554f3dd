/* LCD panel final gather (see gather.h). */
#include "lcd/gather.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "core/fast_trig.h"
#include "core/hash.h"
#include "io/exr.h"
#include "io/png.h"
#include "light/sun.h"
#include "prt/relight.h"

struct cv_lcd_gather {
  const cv_rt *rt;
  uint32_t *tri;
  size_t nt, nv;
  int has_windows;
  cv_lcd_panel panel;
  const cv_brdf *brdf;
  cv_brdf_sampler *smp;
  cv_sobol_tab sobol;
  /* window openings (one per window material) for window sampling: the
   * distinct vertices of each, xyz */
  int nopen;
  float **open_pos;
  int *open_nv;
  /* interior light sampling: vertex positions (3 nv) and per triangle the
   * unit normal and area (4 nt) */
  float *pos;
  float *tnA;
  float *envvis; /* ENV_RX x ENV_RY regions of VIS_H x VIS_W lat-long cells: the fraction of
                    probe rays from the region that reach the environment (NULL: no windows);
                    computed by cv_lcd_gather_create, like tgeo */
  /* the environment strategy's tables of the last (light, eye) (env_tables
   * below); a pure function of them, kept across calls under the lock */
  struct env_tables *etab;
  omp_lock_t etab_lock;
  int lock_ready;
  float *tgeo;  /* per triangle: unoccluded share of its light the panel receives, up to a
                   constant: cos at the triangle x cos at the panel / r^2 from the panel
                   centre, times the fraction of 5 panel points that see its centroid */
};

static inline float dot3(const float a[3], const float b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void cross3(const float a[3], const float b[3], float o[3]) {
  o[0] = a[1] * b[2] - a[2] * b[1];
  o[1] = a[2] * b[0] - a[0] * b[2];
  o[2] = a[0] * b[1] - a[1] * b[0];
}
static inline int normalize3(float a[3]) {
  float l = sqrtf(dot3(a, a));
  if (!(l > 0)) return 0;
  for (int k = 0; k < 3; k++) a[k] /= l;
  return 1;
}

/* --- panel --------------------------------------------------------------- */

int cv_lcd_panel_from_mesh(const cv_mesh *m, cv_lcd_panel *out, cv_err *err) {
  memset(out, 0, sizeof *out);
  double N[3] = {0, 0, 0}, C[3] = {0, 0, 0}, A = 0;
  size_t count = 0;
  for (size_t t = 0; t < m->nt; t++) {
    if (!(m->mats[m->tri_mat[t]].flags & CV_MAT_LCD)) continue;
    float n[3];
    cv_mesh_tri_normal(m, t, n);
    double a = 0.5 * sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
    for (int k = 0; k < 3; k++) {
      N[k] += n[k];
      double c = 0;
      for (int j = 0; j < 3; j++) c += m->pos[3 * m->tri[3 * t + j] + k];
      C[k] += a * c / 3;
    }
    A += a;
    count++;
  }
  if (!count)
    return cv_err_set(err, CV_ERR_NOT_FOUND,
                      "the scene has no LCD panel (no triangle with a material tagged lcd)");
  double nl = sqrt(N[0] * N[0] + N[1] * N[1] + N[2] * N[2]);
  if (!(nl > 0) || !(A > 0))
    return cv_err_set(err, CV_ERR_INVALID, "the LCD triangles have no area or no common normal");
  float n[3], u[3], v[3], c[3];
  for (int k = 0; k < 3; k++) {
    n[k] = (float)(N[k] / nl);
    c[k] = (float)(C[k] / A);
  }
  const float up[3] = {0, 1, 0};
  cross3(up, n, u);
  if (!normalize3(u)) {
    u[0] = 1, u[1] = 0, u[2] = 0; /* facing straight up or down */
    float d = dot3(u, n);
    for (int k = 0; k < 3; k++) u[k] -= d * n[k];
    normalize3(u);
  }
  cross3(n, u, v);
  normalize3(v);
  float lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  for (size_t t = 0; t < m->nt; t++) {
    if (!(m->mats[m->tri_mat[t]].flags & CV_MAT_LCD)) continue;
    for (int j = 0; j < 3; j++) {
      const float *p = m->pos + 3 * m->tri[3 * t + j];
      float d[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
      float a = dot3(d, u), b = dot3(d, v);
      lo[0] = fminf(lo[0], a), hi[0] = fmaxf(hi[0], a);
      lo[1] = fminf(lo[1], b), hi[1] = fmaxf(hi[1], b);
    }
  }
  for (int k = 0; k < 3; k++) {
    out->center[k] = c[k] + u[k] * 0.5f * (lo[0] + hi[0]) + v[k] * 0.5f * (lo[1] + hi[1]);
    out->u[k] = u[k];
    out->v[k] = v[k];
    out->normal[k] = n[k];
  }
  out->size[0] = hi[0] - lo[0];
  out->size[1] = hi[1] - lo[1];
  if (!(out->size[0] > 0) || !(out->size[1] > 0))
    return cv_err_set(err, CV_ERR_INVALID, "the LCD panel has zero width or height");
  return CV_OK;
}

/* --- lighting ------------------------------------------------------------ */

void cv_lcd_light_destroy(cv_lcd_light *l) {
  if (!l) return;
  cv_envmap_destroy(l->env);
  cv_env_sampler_destroy(l->env_smp);
  free(l->vrad);
  free(l);
}

/* Takes ownership of env and vrad (freed on error). */
static int light_finish(cv_envmap *env, float *vrad, size_t nv, int has_sun, const double sd[3],
                        const double sE[3], cv_lcd_light **out) {
  *out = NULL;
  cv_lcd_light *l = calloc(1, sizeof *l);
  if (!l) {
    cv_envmap_destroy(env);
    free(vrad);
    return CV_ERR_NOMEM;
  }
  l->env = env;
  l->vrad = vrad;
  l->nv = nv;
  int st = cv_env_sampler_create(env, &l->env_smp);
  if (st) {
    cv_lcd_light_destroy(l);
    return st;
  }
  snprintf(l->sun_source, sizeof l->sun_source, "none");
  if (has_sun) {
    double len = sqrt(sd[0] * sd[0] + sd[1] * sd[1] + sd[2] * sd[2]);
    if (!(len > 0) || !isfinite(len) || !isfinite(sE[0]) || !isfinite(sE[1]) || !isfinite(sE[2])) {
      cv_lcd_light_destroy(l);
      return CV_ERR_NONFINITE;
    }
    l->has_sun = 1;
    for (int k = 0; k < 3; k++) {
      l->sun_dir[k] = (float)(sd[k] / len);
      l->sun_E[k] = (float)(sE[k] > 0 ? sE[k] : 0);
    }
    snprintf(l->sun_source, sizeof l->sun_source, "given");
  }
  double mx = 0;
  size_t npx = (size_t)env->img->w * env->img->h * 3;
  for (size_t i = 0; i < npx; i++) mx = fmax(mx, env->img->px[i]);
  for (size_t i = 0; i < 3 * nv; i++) {
    if (!isfinite(vrad[i]) || vrad[i] < 0) {
      vrad[i] = 0;
      l->vrad_fixed++;
    }
    mx = fmax(mx, vrad[i]);
  }
  l->max_radiance = mx;
  uint64_t h = cv_hash64_init();
  h = cv_hash64_u64(h, (uint64_t)env->img->w);
  h = cv_hash64_u64(h, (uint64_t)env->img->h);
  h = cv_hash64_floats(h, env->img->px, npx);
  h = cv_hash64_u64(h, (uint64_t)nv);
  h = cv_hash64_floats(h, vrad, 3 * nv);
  h = cv_hash64_u64(h, (uint64_t)l->has_sun);
  h = cv_hash64_floats(h, l->sun_dir, 3);
  h = cv_hash64_floats(h, l->sun_E, 3);
  l->hash = h;
  *out = l;
  return CV_OK;
}

int cv_lcd_light_create(const cv_envmap *env_car, const float *vrad, size_t nv, int has_sun,
                        const double sun_dir[3], const double sun_E[3], cv_lcd_light **out) {
  *out = NULL;
  if (!env_car || !env_car->img || (has_sun && (!sun_dir || !sun_E))) return CV_ERR_INVALID;
  cv_envmap *env;
  int st = cv_envmap_clone(env_car, &env);
  if (st) return st;
  float *v = calloc(3 * nv + 1, sizeof(float));
  if (!v) {
    cv_envmap_destroy(env);
    return CV_ERR_NOMEM;
  }
  if (vrad) memcpy(v, vrad, 3 * nv * sizeof(float));
  return light_finish(env, v, nv, has_sun, sun_dir, sun_E, out);
}

int cv_lcd_light_from_scene(const cv_scene_light *sl, const cv_light_spec *spec, const cv_prt *p,
                            const cv_tracer *tr, int sun_samples, int env_w, cv_lcd_light **out,
                            cv_err *err) {
  *out = NULL;
  if (!sl || !spec || !p || env_w < 4 || env_w > 16384 || sun_samples < 1)
    return cv_err_set(err, CV_ERR_INVALID, "lcd lighting: invalid arguments");
  int env_h = env_w / 2;
  cv_envmap *tab = NULL, *residual = NULL;
  float *vrad = NULL;
  int st = cv_envmap_create(env_w, env_h, &tab);
  if (st) return cv_err_set(err, st, "lcd lighting: out of memory");
  /* car-frame lat-long table (layout of sh/latlong.h) */
  for (int y = 0; y < env_h; y++) {
    double th = M_PI * (y + 0.5) / env_h;
    for (int x = 0; x < env_w; x++) {
      double ph = 2 * M_PI * ((x + 0.5) / env_w - 0.5);
      float d[3] = {(float)(sin(th) * sin(ph)), (float)cos(th), (float)(-sin(th) * cos(ph))};
      cv_scene_light_background(sl, d, cv_image_at(tab->img, x, y));
    }
  }
  cv_lighting lt = cv_scene_light_sh(sl);
  int has_sun = 0;
  double sd[3] = {0, 0, 0}, sE[3] = {0, 0, 0};
  const char *src = "none";
  if (lt.has_sun && spec->kind == CV_LIGHT_ENV) {
    cv_sun_info si;
    if ((st = cv_sun_extract(tab, NULL, &si, &residual))) {
      cv_envmap_destroy(tab);
      return cv_err_set(err, st, "lcd lighting: sun extraction failed");
    }
    if (si.found) {
      cv_envmap_destroy(tab);
      tab = residual;
      residual = NULL;
      has_sun = 1;
      memcpy(sd, si.dir, sizeof sd);
      memcpy(sE, si.rgb, sizeof sE);
      src = "extracted from the car-frame background";
    } else {
      cv_envmap_destroy(residual);
      residual = NULL;
      src = "kept in the background (not compact in the car-frame table)";
    }
  } else if (lt.has_sun) {
    has_sun = 1;
    memcpy(sd, lt.sun_dir, sizeof sd);
    memcpy(sE, lt.sun_E, sizeof sE);
    src = "analytic sky";
  }
  vrad = malloc(3 * p->nv * sizeof(float) + 1);
  if (!vrad) {
    cv_envmap_destroy(tab);
    return cv_err_set(err, CV_ERR_NOMEM, "lcd lighting: out of memory");
  }
  cv_relight_stats rs;
  if ((st = cv_prt_relight(p, &lt, tr, sun_samples, vrad, &rs)) ||
      (st = cv_prt_fold_texture_means(p, vrad))) { /* textures as their mean albedo */
    cv_envmap_destroy(tab);
    free(vrad);
    return cv_err_set(err, st, "lcd lighting: relighting failed (%s)", cv_status_str(st));
  }
  if ((st = light_finish(tab, vrad, p->nv, has_sun, sd, sE, out)))
    return cv_err_set(err, st, "lcd lighting: %s", cv_status_str(st));
  snprintf((*out)->sun_source, sizeof (*out)->sun_source, "%s", src);
  return CV_OK;
}

/* --- gather -------------------------------------------------------------- */

/* The window openings: the distinct vertices of each window material's
 * triangles (at most CV_LCD_MAX_OPENINGS openings; further ones are still
 * reached by BRDF and cosine sampling). */
static int collect_openings(cv_lcd_gather *g, const cv_mesh *m) {
  uint32_t *mark = calloc(m->nv + 1, sizeof(uint32_t));
  g->open_pos = calloc(CV_LCD_MAX_OPENINGS, sizeof(float *));
  g->open_nv = calloc(CV_LCD_MAX_OPENINGS, sizeof(int));
  if (!mark || !g->open_pos || !g->open_nv) {
    free(mark);
    return CV_ERR_NOMEM;
  }
  for (size_t mi = 0; mi < m->nm && g->nopen < CV_LCD_MAX_OPENINGS; mi++) {
    if (!(m->mats[mi].flags & CV_MAT_WINDOW)) continue;
    int n = 0;
    const uint32_t tag = (uint32_t)mi + 1;
    for (size_t t = 0; t < m->nt; t++) {
      if (m->tri_mat[t] != mi) continue;
      for (int j = 0; j < 3; j++) {
        uint32_t v = m->tri[3 * t + j];
        if (mark[v] != tag) mark[v] = tag, n++;
      }
    }
    if (!n) continue;
    float *pos = malloc(3 * (size_t)n * sizeof(float));
    if (!pos) {
      free(mark);
      return CV_ERR_NOMEM;
    }
    int k = 0;
    for (size_t t = 0; t < m->nt; t++) {
      if (m->tri_mat[t] != mi) continue;
      for (int j = 0; j < 3; j++) {
        uint32_t v = m->tri[3 * t + j];
        if (mark[v] == tag) {
          mark[v] = 0xFFFFFFFFu; /* taken */
          memcpy(pos + 3 * k++, m->pos + 3 * (size_t)v, 3 * sizeof(float));
        }
      }
    }
    /* vertices shared with an earlier opening were re-tagged: reset */
    for (size_t t = 0; t < m->nt; t++)
      if (m->tri_mat[t] == mi)
        for (int j = 0; j < 3; j++) mark[m->tri[3 * t + j]] = 0;
    g->open_pos[g->nopen] = pos;
    g->open_nv[g->nopen++] = k;
  }
  free(mark);
  return CV_OK;
}

/* Regions of the panel for the environment strategy: ENV_RX x ENV_RY equal
 * parts of the panel rectangle (a block belongs to the one that holds its
 * centre); VIS_W x VIS_H lat-long cells (layout of light/env_sample.h). */
#define ENV_RX 4
#define ENV_RY 3
#define VIS_W 128
#define VIS_H 64

/* Panel point at fractions (fx from the left, fy from the top), offset. */
static void panel_point(const cv_lcd_panel *pn, float fx, float fy, float o[3]) {
  float c[3];
  for (int k = 0; k < 3; k++)
    c[k] = pn->center[k] + pn->u[k] * (fx - 0.5f) * pn->size[0] + pn->v[k] * (0.5f - fy) * pn->size[1];
  cv_rt_offset_origin(c, pn->normal, o);
}

/* Each region's visibility table made softer and wider (gather.h,
 * cv_lcd_soften_visibility).  The probes see the sky from 4 points of the
 * region; its other texels see it through the same gaps shifted by
 * parallax (window frames, pillars, headrests at 0.3-1.5 m, the panel
 * 0.2-0.3 m wide), often by a cell or more, and a table that is 0 where a
 * texel does see the sky leaves those directions to the BRDF and cosine
 * samples.  Measured against the probes' plain mean (docs/benchmarks.md,
 * issue 12, "Softer visibility tables"): 1.2-2x fewer samples to the same
 * error in sunlight; a 5 x 5 maximum, a 3 x 3 blur, the square root or a
 * yes/no mask did no better. */
int cv_lcd_soften_visibility(float *vis, int w, int h, int n) {
  if (!vis || w < 1 || h < 1 || n < 0) return CV_ERR_INVALID;
  const size_t nc = (size_t)w * (size_t)h;
  float *tmp = malloc(nc * sizeof(float));
  if (!tmp) return CV_ERR_NOMEM;
  for (int r = 0; r < n; r++) {
    float *v = vis + (size_t)r * nc;
    for (int Y = 0; Y < h; Y++)
      for (int X = 0; X < w; X++) {
        float mx = 0;
        for (int dy = -1; dy <= 1; dy++) {
          const int yy = Y + dy;
          if (yy < 0 || yy >= h) continue; /* the poles: no wrap */
          for (int dx = -1; dx <= 1; dx++) {
            const float t = v[(size_t)yy * w + (size_t)((X + dx + w) % w)]; /* azimuth wraps */
            if (t > mx) mx = t;
          }
        }
        tmp[(size_t)Y * w + X] = 0.5f * (v[(size_t)Y * w + X] + mx);
      }
    memcpy(v, tmp, nc * sizeof(float));
  }
  free(tmp);
  return CV_OK;
}

/* envvis: from 4 points of each region (its quarters' centres), one ray
 * each into the centres of the 4 quarters of each cell in front of the
 * panel (16 probes a cell): the share that reaches the environment through
 * a window.  About 0.8 M rays, once per gather. */
static int env_visibility(cv_lcd_gather *g) {
  const cv_lcd_panel *pn = &g->panel;
  g->envvis = calloc((size_t)ENV_RX * ENV_RY * VIS_W * VIS_H, sizeof(float));
  if (!g->envvis) return CV_ERR_NOMEM;
  const int ncell = ENV_RX * ENV_RY * VIS_H;
#pragma omp parallel
  {
    cv_rt_thread_init();
#pragma omp for schedule(dynamic, 4)
    for (int i = 0; i < ncell; i++) {
      const int r = i / VIS_H, Y = i % VIS_H, rx = r % ENV_RX, ry = r / ENV_RX;
      float o[4][3];
      for (int k = 0; k < 4; k++)
        panel_point(pn, ((float)rx + 0.25f + 0.5f * (float)(k & 1)) / ENV_RX,
                    ((float)ry + 0.25f + 0.5f * (float)(k >> 1)) / ENV_RY, o[k]);
      float *row = g->envvis + ((size_t)r * VIS_H + (size_t)Y) * VIS_W;
      for (int X = 0; X < VIS_W; X++) {
        int seen = 0;
        for (int q = 0; q < 4; q++) {
          const double u = (X + 0.25 + 0.5 * (q & 1)) / VIS_W, th = M_PI * (Y + 0.25 + 0.5 * (q >> 1)) / VIS_H;
          const double ph = 2 * M_PI * (u - 0.5);
          const float d[3] = {(float)(sin(th) * sin(ph)), (float)cos(th), (float)(-sin(th) * cos(ph))};
          if (!(dot3(d, pn->normal) > 0)) continue;
          for (int k = 0; k < 4; k++) seen += cv_rt_reaches_env(g->rt, o[k], d, 0.0f);
        }
        row[X] = (float)seen / 16;
      }
    }
  }
  return cv_lcd_soften_visibility(g->envvis, VIS_W, VIS_H, ENV_RX * ENV_RY);
}

/* One environment table per region: src (restricted to the panel's front)
 * with each cell's probability times (the region's visibility of it +
 * ENV_VIS_FLOOR) x the luminance of f cos for the view from the region's
 * centre (cell centre direction): the strategy then draws about
 * L f cos V, the whole integrand but for the texel's own view and
 * visibility.  Any weights keep the estimate unbiased (BRDF and cosine
 * sampling cover every direction; the density is the table's own). */
#define ENV_VIS_FLOOR 0.01f
static int env_regions(const cv_lcd_gather *g, const cv_env_sampler *src, const float eye[3],
                       cv_env_sampler **out) {
  const cv_lcd_panel *pn = &g->panel;
  const cv_brdf_sampler *smp = g->smp;
  const int w = src->w, h = src->h;
  float *cw = malloc((size_t)w * (size_t)h * sizeof(float));
  float *dir = malloc(3 * (size_t)w * (size_t)h * sizeof(float));
  if (!cw || !dir) {
    free(cw);
    free(dir);
    return CV_ERR_NOMEM;
  }
  for (int y = 0; y < h; y++) {
    const double ct = 0.5 * ((double)src->cos_edge[y] + src->cos_edge[y + 1]), st = sqrt(fmax(0.0, 1 - ct * ct));
    for (int x = 0; x < w; x++) {
      const double ph = 2 * M_PI * ((x + 0.5) / w - 0.5);
      float *d = dir + 3 * ((size_t)y * (size_t)w + (size_t)x);
      d[0] = (float)(st * sin(ph)), d[1] = (float)ct, d[2] = (float)(-st * cos(ph));
    }
  }
  for (int r = 0; r < ENV_RX * ENV_RY; r++) {
    const float *vis = g->envvis + (size_t)r * VIS_H * VIS_W;
    /* the view from the region's centre */
    float c[3], wo[3], tn[3], bn[3];
    const float fx = ((float)(r % ENV_RX) + 0.5f) / ENV_RX, fy = ((float)(r / ENV_RX) + 0.5f) / ENV_RY;
    for (int k = 0; k < 3; k++) {
      c[k] = pn->center[k] + pn->u[k] * (fx - 0.5f) * pn->size[0] + pn->v[k] * (0.5f - fy) * pn->size[1];
      wo[k] = eye[k] - c[k];
    }
    normalize3(wo);
    const float co = dot3(wo, pn->normal);
    int kb = 0;
    float tb = 0;
    for (int k = 0; k < 3; k++) tn[k] = wo[k] - co * pn->normal[k];
    if (!normalize3(tn)) memcpy(tn, pn->u, sizeof tn);
    cross3(pn->normal, tn, bn);
    cv_brdf_view_bins(smp, acosf(co > 1 ? 1 : (co < 0 ? 0 : co)), &kb, &tb);
    for (int y = 0; y < h; y++) {
      const int Y = (int)(((double)y + 0.5) * VIS_H / h);
      for (int x = 0; x < w; x++) {
        const size_t i = (size_t)y * (size_t)w + (size_t)x;
        const float *d = dir + 3 * i;
        const float z = dot3(d, pn->normal);
        float fc = 0;
        if (z > 0) {
          float f[3];
          const float th = acosf(z > 1 ? 1 : z), ph = fabsf(cv_fast_atan2(dot3(d, bn), dot3(d, tn)));
          cv_brdf_eval_bins(smp, kb, tb, th, ph, f);
          fc = (0.2126f * f[0] + 0.7152f * f[1] + 0.0722f * f[2]) * z;
        }
        const int X = (int)(((double)x + 0.5) * VIS_W / w);
        /* cells behind the plane by their centre keep src's front probes */
        cw[i] = (vis[(size_t)Y * VIS_W + (size_t)X] + ENV_VIS_FLOOR) * (fc > 0 ? fc : 1e-6f);
      }
    }
    if (cv_env_sampler_reweight(src, cw, &out[r])) {
      free(cw);
      free(dir);
      return CV_ERR_NOMEM;
    }
  }
  free(cw);
  free(dir);
  return CV_OK;
}

/* The environment strategy's tables for one (light, eye): the light's
 * tables restricted to the panel's front and, with windows, the region
 * tables (env_regions).  About 12 ms to build on the default cabin, so
 * they are kept for the last (light, eye) a call used: a progressive
 * gather renders round after round, tile after tile, with the same light
 * and eye.  Reference-counted (the cache holds one reference, each round
 * using them another), so a call never sees them freed under it; being a
 * pure function of (gather, light, eye), whoever builds them, the samples
 * are the same. */
typedef struct env_tables {
  int refs;
  uint64_t light_hash;
  float eye[3];
  cv_env_sampler *esr;                   /* restricted to the panel's front */
  cv_env_sampler *ereg[ENV_RX * ENV_RY]; /* per region (NULL: esr for all) */
} env_tables;

static void env_tables_free(env_tables *t) {
  if (!t) return;
  cv_env_sampler_destroy(t->esr);
  for (int r = 0; r < ENV_RX * ENV_RY; r++) cv_env_sampler_destroy(t->ereg[r]);
  free(t);
}

static void env_tables_release(const cv_lcd_gather *cg, env_tables *t) {
  if (!t) return;
  cv_lcd_gather *g = (cv_lcd_gather *)cg; /* the cache is not part of the value */
  omp_set_lock(&g->etab_lock);
  const int last = --t->refs == 0;
  omp_unset_lock(&g->etab_lock);
  if (last) env_tables_free(t);
}

/* The tables of (l, eye), from the cache or built (one reference for the
 * caller).  NULL: out of memory. */
static env_tables *env_tables_get(const cv_lcd_gather *cg, const cv_lcd_light *l, const float eye[3]) {
  cv_lcd_gather *g = (cv_lcd_gather *)cg;
  omp_set_lock(&g->etab_lock);
  env_tables *t = g->etab;
  if (t && t->light_hash == l->hash && !memcmp(t->eye, eye, sizeof t->eye)) {
    t->refs++;
    omp_unset_lock(&g->etab_lock);
    return t;
  }
  omp_unset_lock(&g->etab_lock);
  if (!(t = calloc(1, sizeof *t))) return NULL;
  t->light_hash = l->hash;
  memcpy(t->eye, eye, sizeof t->eye);
  if (cv_env_sampler_restrict(l->env_smp, g->panel.normal, &t->esr) ||
      (t->esr->total > 0 && g->envvis && env_regions(g, t->esr, eye, t->ereg))) {
    env_tables_free(t);
    return NULL;
  }
  t->refs = 2; /* the caller's and the cache's */
  omp_set_lock(&g->etab_lock);
  env_tables *old = g->etab;
  g->etab = t;
  const int drop = old && --old->refs == 0;
  omp_unset_lock(&g->etab_lock);
  if (drop) env_tables_free(old);
  return t;
}

/* tgeo: how much of each triangle's exit radiance the panel can receive
 * (the interior strategy's weights, gather.h), from the panel centre and 4
 * points halfway to its corners; one shadow ray each (nt x 5 rays). */
static int panel_view_factors(cv_lcd_gather *g) {
  const cv_lcd_panel *pn = &g->panel;
  if (!(g->tgeo = malloc(g->nt * sizeof(float) + 1))) return CV_ERR_NOMEM;
  float pts[5][3];
  const float a[5] = {0, -0.25f, 0.25f, -0.25f, 0.25f}, b[5] = {0, -0.25f, -0.25f, 0.25f, 0.25f};
  for (int i = 0; i < 5; i++) {
    float c[3];
    for (int k = 0; k < 3; k++)
      c[k] = pn->center[k] + pn->u[k] * a[i] * pn->size[0] + pn->v[k] * b[i] * pn->size[1];
    cv_rt_offset_origin(c, pn->normal, pts[i]);
  }
  const long nt = (long)g->nt;
#pragma omp parallel
  {
    cv_rt_thread_init();
#pragma omp for schedule(dynamic, 256)
  for (long t = 0; t < nt; t++) {
    const uint32_t *v = g->tri + 3 * (size_t)t;
    float x[3];
    for (int k = 0; k < 3; k++)
      x[k] = (g->pos[3 * (size_t)v[0] + k] + g->pos[3 * (size_t)v[1] + k] + g->pos[3 * (size_t)v[2] + k]) / 3;
    float d[3] = {x[0] - pts[0][0], x[1] - pts[0][1], x[2] - pts[0][2]};
    const float r2 = dot3(d, d), r = sqrtf(r2);
    g->tgeo[t] = 0;
    if (!(r > 1e-4f)) continue;
    for (int k = 0; k < 3; k++) d[k] /= r;
    const float co = dot3(d, pn->normal), ct = -dot3(d, g->tnA + 4 * (size_t)t);
    if (!(co > 0) || !(ct > 0)) continue; /* behind the panel, or facing away */
    int seen = 0;
    for (int i = 0; i < 5; i++) {
      float e[3] = {x[0] - pts[i][0], x[1] - pts[i][1], x[2] - pts[i][2]};
      const float l = sqrtf(dot3(e, e));
      if (!(l > 1e-4f)) continue;
      for (int k = 0; k < 3; k++) e[k] /= l;
      seen += !cv_rt_occluded(g->rt, pts[i], e, 0.0f, l * 0.999f);
    }
    g->tgeo[t] = co * ct / r2 * (float)seen / 5;
  }
  }
  return CV_OK;
}

int cv_lcd_gather_create(const cv_rt *rt, const cv_mesh *m, const cv_lcd_panel *panel,
                         const cv_brdf *brdf, cv_lcd_gather **out, cv_err *err) {
  *out = NULL;
  if (!rt || !m || !panel || !brdf) return cv_err_set(err, CV_ERR_INVALID, "lcd gather: NULL argument");
  cv_lcd_gather *g = calloc(1, sizeof *g);
  if (!g) return cv_err_set(err, CV_ERR_NOMEM, "lcd gather: out of memory");
  g->rt = rt;
  g->nt = m->nt;
  g->nv = m->nv;
  g->has_windows = cv_rt_has_windows(rt);
  g->panel = *panel;
  g->brdf = brdf;
  omp_init_lock(&g->etab_lock);
  g->lock_ready = 1;
  g->tri = malloc(3 * m->nt * sizeof(uint32_t) + 1);
  if (!g->tri || cv_brdf_sampler_create(brdf, &g->smp)) {
    cv_lcd_gather_destroy(g);
    return cv_err_set(err, CV_ERR_NOMEM, "lcd gather: out of memory");
  }
  memcpy(g->tri, m->tri, 3 * m->nt * sizeof(uint32_t));
  g->pos = malloc(3 * m->nv * sizeof(float) + 1);
  g->tnA = malloc(4 * m->nt * sizeof(float) + 1);
  if (!g->pos || !g->tnA) {
    cv_lcd_gather_destroy(g);
    return cv_err_set(err, CV_ERR_NOMEM, "lcd gather: out of memory");
  }
  memcpy(g->pos, m->pos, 3 * m->nv * sizeof(float));
  for (size_t t = 0; t < m->nt; t++) {
    float n[3];
    cv_mesh_tri_normal(m, t, n); /* length: twice the area */
    const float l = sqrtf(dot3(n, n));
    for (int k = 0; k < 3; k++) g->tnA[4 * t + k] = l > 0 ? n[k] / l : 0.0f;
    g->tnA[4 * t + 3] = 0.5f * l;
  }
  /* the openings, and the geometry tables of the environment and interior
   * strategies (probe rays, once per gather: the same whoever computes
   * them) */
  if ((g->has_windows && (collect_openings(g, m) || env_visibility(g))) || panel_view_factors(g)) {
    cv_lcd_gather_destroy(g);
    return cv_err_set(err, CV_ERR_NOMEM, "lcd gather: out of memory");
  }
  cv_sobol_tab_init(&g->sobol);
  *out = g;
  return CV_OK;
}

void cv_lcd_gather_destroy(cv_lcd_gather *g) {
  if (!g) return;
  for (int k = 0; k < g->nopen; k++) free(g->open_pos[k]);
  free(g->open_pos);
  free(g->open_nv);
  free(g->tri);
  free(g->pos);
  free(g->tnA);
  free(g->tgeo);
  free(g->envvis);
  if (g->lock_ready) {
    env_tables_release(g, g->etab);
    omp_destroy_lock(&g->etab_lock);
  }
  cv_brdf_sampler_destroy(g->smp);
  free(g);
}

const cv_brdf_sampler *cv_lcd_gather_sampler(const cv_lcd_gather *g) { return g->smp; }
const cv_lcd_panel *cv_lcd_gather_panel(const cv_lcd_gather *g) { return &g->panel; }

void cv_lcd_params_default(cv_lcd_params *p) {
  memset(p, 0, sizeof *p);
  p->w = 400;
  p->h = 300;
  p->spp = 40;
  p->brdf_fraction = 0.9;
  p->window_fraction = CV_LCD_WINDOW_FRACTION;
  p->env_fraction = CV_LCD_ENV_FRACTION;
  p->interior_fraction = CV_LCD_INTERIOR_FRACTION;
  p->seed = 1;
  p->sun = 1;
}

double cv_lcd_default_clamp(const cv_lcd_light *l, const cv_brdf *b) {
  double fm = 0, emax = 0;
  size_t n = (size_t)b->n_theta * b->n_theta * b->n_phi * 3;
  for (size_t i = 0; i < n; i++) fm = fm > b->f[i] ? fm : b->f[i];
  if (l->has_sun)
    for (int k = 0; k < 3; k++) emax = fmax(emax, l->sun_E[k]);
  double c = fmax(1e4 * l->max_radiance, 10 * fm * emax);
  return c > 0 && isfinite(c) ? c : 1.0;
}

uint64_t cv_lcd_setup_hash(const cv_lcd_gather *g, const cv_lcd_params *p, double clamp,
                           double tolerance, uint64_t scene_hash) {
  uint64_t h = cv_hash64_init();
  h = cv_hash64_u64(h, scene_hash);
  h = cv_hash64_u64(h, g->nv);
  h = cv_hash64_u64(h, g->nt);
  h = cv_hash64_u64(h, g->brdf->hash);
  h = cv_hash64_floats(h, &g->panel.center[0], 14);
  h = cv_hash64_u64(h, (uint64_t)p->w);
  h = cv_hash64_u64(h, (uint64_t)p->h);
  h = cv_hash64_u64(h, (uint64_t)p->spp);
  h = cv_hash64_double(h, p->brdf_fraction);
  h = cv_hash64_double(h, p->window_fraction);
  if (p->env_fraction != 0) h = cv_hash64_double(h, p->env_fraction); /* keys without it unchanged */
  if (p->interior_fraction != 0) h = cv_hash64_double(cv_hash64_u64(h, 0x1A7u), p->interior_fraction);
  h = cv_hash64_u64(h, p->seed);
  h = cv_hash64_u64(h, (uint64_t)p->sun);
  h = cv_hash64_double(h, clamp);
  h = cv_hash64_double(h, tolerance);
  return h;
}

/* Trace blocks: the gather rays of BLOCK x BLOCK texels (aligned to the
 * panel's texel grid, clipped to the panel, never to the tile) and at most
 * CHUNK_SPP samples per texel are sorted by direction and traced in packets
 * of CV_RT_PACKET_MAX.  Rays of one texel spread over the BRDF lobe, but the
 * mirror direction moves slowly across the panel, so sorting thousands of
 * rays by direction gathers nearly parallel rays from nearby origins into
 * each packet, which Embree's coherent packet traversal walks together.
 * The composition of every packet depends only on (panel size, block,
 * samples), never on the tile, split or thread count: a tile that cuts a
 * block still traces the whole block (and keeps its own texels), so that
 * every ray's hit, and hence every texel's sums, are bit-identical whatever
 * the tiling (Embree's packet kernels may round t, u, v differently for
 * another packet composition). */
#define BLOCK 16
#define CHUNK_SPP 64

/* Clamps one sample's RGB (counted) and adds it in fixed point. */
static inline void add_sample(float v[3], double clamp, double inv_unit, int64_t s[3],
                              int64_t s2[2], int64_t *cnt) {
  for (int c = 0; c < 3; c++) {
    if (!isfinite(v[c]) || v[c] < 0) {
      v[c] = 0;
      cnt[CV_LCD_ACC_NONFINITE]++;
    } else if (v[c] > clamp) {
      v[c] = (float)clamp;
      cnt[CV_LCD_ACC_CLAMPED]++;
    }
    s[c] += (int64_t)((double)v[c] * inv_unit + 0.5);
  }
  double y = 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
  unsigned __int128 q = (uint64_t)(y * inv_unit + 0.5);
  q *= q; /* < 2^81: the clamp bounds y */
  s2[0] += (int64_t)(q >> CV_LCD_M2_SHIFT);
  s2[1] += (int64_t)(q & ((1ull << CV_LCD_M2_SHIFT) - 1));
}

/* Strategies (gather.h). */
enum { STRAT_BRDF = 0, STRAT_COS, STRAT_WIN, STRAT_ENV, STRAT_INT, NSTRAT };

/* Per-texel state of a block. */
typedef struct texel_state {
  int in_tile;        /* its sums go to the buffer */
  int behind;         /* the eye sees the panel's back: no rays */
  size_t aix;         /* buffer texel (in_tile only) */
  float pc[3], off[3], tn[3], bn[3];
  int kb;
  float tb;
  uint32_t seed[NSTRAT], dseed[NSTRAT][4]; /* one sequence per strategy */
  float nee[3];       /* sun term of the round */
  int64_t s[3], s2[2];
} texel_state;

/* Window-strategy rectangles of one block, in the panel's projected disk
 * (a, b) = (w.u, w.v): cosine-weighted directions restricted to them have
 * the density p_w = cos * (rectangles holding (a, b)) / (their total area). */
typedef struct win_rects {
  int n;
  float r[CV_LCD_MAX_OPENINGS][4]; /* a0, a1, b0, b1 */
  float cum[CV_LCD_MAX_OPENINGS];  /* cumulative areas */
  float total;
} win_rects;

/* Scratch of one thread: the rays of one block and chunk. */
typedef struct block_buf {
  size_t cap;
  float *org, *dir;      /* 3 per ray */
  float *fc;             /* f cos (RGB) and the interior MIS denominator c_b p_b + c_c p_c;
                            window-strategy rays: the local direction and -1 (f and p_b are
                            evaluated only if the ray leaves through a window) */
  uint32_t *tex;         /* texel in the block; | TEX_WIN for window- and environment-strategy
                            rays */
  uint16_t *key;
  uint32_t *ord, *tmp;
  /* the rays permuted into direction order (traced and shaded in order) */
  float *sorg, *sdir, *sfc;
  uint32_t *stex;
  uint32_t *want, *swant;/* interior-strategy rays: the triangle aimed at (the sample counts
                            only if it is the first hit); other rays: NO_TRI */
  uint32_t *htri;        /* hit triangle (kind 1) */
  float *huv;            /* its barycentrics u, v */
  float *ht;             /* its distance */
  uint8_t *kind;
  texel_state *ts;       /* BLOCK * BLOCK */
} block_buf;

#define TEX_WIN 0x80000000u
#define NO_TRI 0xFFFFFFFFu

static void block_buf_free(block_buf *b) {
  free(b->org);
  free(b->dir);
  free(b->fc);
  free(b->tex);
  free(b->key);
  free(b->ord);
  free(b->tmp);
  free(b->sorg);
  free(b->sdir);
  free(b->sfc);
  free(b->stex);
  free(b->htri);
  free(b->huv);
  free(b->ht);
  free(b->want);
  free(b->swant);
  free(b->kind);
  free(b->ts);
  memset(b, 0, sizeof *b);
}

static int block_buf_alloc(block_buf *b, size_t cap) {
  memset(b, 0, sizeof *b);
  b->cap = cap;
  b->org = malloc(3 * cap * sizeof(float));
  b->dir = malloc(3 * cap * sizeof(float));
  b->fc = malloc(4 * cap * sizeof(float));
  b->tex = malloc(cap * sizeof(uint32_t));
  b->key = malloc(cap * sizeof(uint16_t));
  b->ord = malloc(cap * sizeof(uint32_t));
  b->tmp = malloc(cap * sizeof(uint32_t));
  b->sorg = malloc(3 * cap * sizeof(float));
  b->sdir = malloc(3 * cap * sizeof(float));
  b->sfc = malloc(4 * cap * sizeof(float));
  b->stex = malloc(cap * sizeof(uint32_t));
  b->htri = malloc(cap * sizeof(uint32_t));
  b->huv = malloc(2 * cap * sizeof(float));
  b->ht = malloc(cap * sizeof(float));
  b->want = malloc(cap * sizeof(uint32_t));
  b->swant = malloc(cap * sizeof(uint32_t));
  b->kind = malloc(cap);
  b->ts = malloc(BLOCK * BLOCK * sizeof(texel_state));
  if (!b->org || !b->dir || !b->fc || !b->tex || !b->key || !b->ord || !b->tmp || !b->sorg ||
      !b->sdir || !b->sfc || !b->stex || !b->htri || !b->huv || !b->kind || !b->ts || !b->ht ||
      !b->want || !b->swant) {
    block_buf_free(b);
    return CV_ERR_NOMEM;
  }
  return CV_OK;
}

/* The block's rectangles: each opening's vertices seen from the block's
 * centre c (behind the panel plane: pushed onto the rim), bounded, widened
 * by the angle the block's half diagonal hd subtends from the nearest
 * vertex, clipped to [-1, 1]^2.  They need not hold the openings exactly:
 * any rectangle gives an unbiased estimate (BRDF and cosine sampling cover
 * every direction); a tight one wastes fewer samples. */
static void block_rects(const cv_lcd_gather *g, const float c[3], float hd, win_rects *wr) {
  const cv_lcd_panel *pn = &g->panel;
  wr->n = 0;
  wr->total = 0;
  for (int o = 0; o < g->nopen; o++) {
    float a0 = INFINITY, a1 = -INFINITY, b0 = INFINITY, b1 = -INFINITY, dmin = INFINITY;
    int front = 0;
    for (int i = 0; i < g->open_nv[o]; i++) {
      const float *q = g->open_pos[o] + 3 * i;
      float d[3] = {q[0] - c[0], q[1] - c[1], q[2] - c[2]};
      float l = sqrtf(dot3(d, d));
      if (!(l > 0)) continue;
      dmin = fminf(dmin, l);
      float a = dot3(d, pn->u) / l, b = dot3(d, pn->v) / l, z = dot3(d, pn->normal) / l;
      if (z > 0) {
        front = 1;
      } else {
        float r = sqrtf(a * a + b * b);
        if (!(r > 0)) continue;
        a /= r, b /= r;
      }
      a0 = fminf(a0, a), a1 = fmaxf(a1, a), b0 = fminf(b0, b), b1 = fmaxf(b1, b);
    }
    if (!front) continue;
    const float m = hd / dmin;
    a0 = fmaxf(a0 - m, -1.0f), a1 = fminf(a1 + m, 1.0f);
    b0 = fmaxf(b0 - m, -1.0f), b1 = fminf(b1 + m, 1.0f);
    const float area = (a1 - a0) * (b1 - b0);
    if (!(area > 0)) continue;
    float *r = wr->r[wr->n];
    r[0] = a0, r[1] = a1, r[2] = b0, r[3] = b1;
    wr->total += area;
    wr->cum[wr->n++] = wr->total;
  }
}

/* Density of the window strategy for a world direction d (1/sr). */
static inline float window_pdf(const cv_lcd_panel *pn, const win_rects *wr, const float d[3]) {
  const float z = dot3(d, pn->normal);
  if (!(z > 0) || !(wr->total > 0)) return 0;
  const float a = dot3(d, pn->u), b = dot3(d, pn->v);
  int in = 0;
  for (int k = 0; k < wr->n; k++)
    in += a >= wr->r[k][0] && a < wr->r[k][1] && b >= wr->r[k][2] && b < wr->r[k][3];
  return z * (float)in / wr->total;
}

/* A window-strategy direction from u[0..1]: a rectangle by area, a point in
 * it (u0 rescaled within the rectangle's share, so the map stays monotone
 * in each), lifted to the hemisphere.  Returns 0 outside the disk. */
static inline int window_sample(const cv_lcd_panel *pn, const win_rects *wr, const float u[2],
                                float d[3]) {
  if (!(wr->total > 0)) return 0;
  const float x = u[0] * wr->total;
  int k = 0;
  while (k < wr->n - 1 && wr->cum[k] <= x) k++;
  const float c0 = k ? wr->cum[k - 1] : 0.0f, w = wr->cum[k] - c0;
  float s = w > 0 ? (x - c0) / w : 0.5f;
  s = s < 0 ? 0 : (s > 1 ? 1 : s);
  const float *r = wr->r[k];
  const float a = r[0] + s * (r[1] - r[0]), b = r[2] + u[1] * (r[3] - r[2]);
  const float z2 = 1 - a * a - b * b;
  if (!(z2 > 0)) return 0;
  const float z = sqrtf(z2);
  for (int i = 0; i < 3; i++) d[i] = a * pn->u[i] + b * pn->v[i] + z * pn->normal[i];
  return 1;
}

/* 16-bit sort key of a unit direction: Morton order of its octahedral
 * coordinates quantised to 8 bits each (cells of about 1 degree). */
static inline uint16_t dir_key(const float d[3]) {
  float s = fabsf(d[0]) + fabsf(d[1]) + fabsf(d[2]);
  float x = d[0] / s, y = d[1] / s;
  if (d[2] < 0) {
    float ox = x;
    x = (1 - fabsf(y)) * (x >= 0 ? 1.0f : -1.0f);
    y = (1 - fabsf(ox)) * (y >= 0 ? 1.0f : -1.0f);
  }
  uint32_t qx = (uint32_t)((x * 0.5f + 0.5f) * 255.0f + 0.5f);
  uint32_t qy = (uint32_t)((y * 0.5f + 0.5f) * 255.0f + 0.5f);
  qx &= 255, qy &= 255;
  qx = (qx | (qx << 4)) & 0x0F0Fu;
  qx = (qx | (qx << 2)) & 0x3333u;
  qx = (qx | (qx << 1)) & 0x5555u;
  qy = (qy | (qy << 4)) & 0x0F0Fu;
  qy = (qy | (qy << 2)) & 0x3333u;
  qy = (qy | (qy << 1)) & 0x5555u;
  return (uint16_t)(qx | (qy << 1));
}

/* ord = 0..n-1 stably sorted by key (LSD radix sort, two 8-bit passes). */
static void sort_by_key(const uint16_t *key, size_t n, uint32_t *ord, uint32_t *tmp) {
  size_t c0[257], c1[257];
  memset(c0, 0, sizeof c0);
  memset(c1, 0, sizeof c1);
  for (size_t i = 0; i < n; i++) {
    c0[(key[i] & 255) + 1]++;
    c1[(key[i] >> 8) + 1]++;
  }
  for (int b = 0; b < 256; b++) {
    c0[b + 1] += c0[b];
    c1[b + 1] += c1[b];
  }
  for (size_t i = 0; i < n; i++) tmp[c0[key[i] & 255]++] = (uint32_t)i;
  for (size_t i = 0; i < n; i++) {
    uint32_t j = tmp[i];
    ord[c1[key[j] >> 8]++] = j;
  }
}

/* This thread's CPU seconds (the phase_seconds hook). */
static double thread_seconds(void) {
  struct timespec t;
  if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t)) return 0;
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* The phase_seconds hook: with ph non-NULL, the thread time since the last
 * mark (*tm) is added to ph[k] (k == CV_LCD_PHASES: a mark only). */
static inline void phase_mark(double *ph, int k, double *tm) {
  if (!ph) return;
  const double t = thread_seconds();
  if (k < CV_LCD_PHASES) ph[k] += t - *tm;
  *tm = t;
}

/* Window crossings of the escaped rays esc[0..ne) (indices into the
 * sorted arrays), in packets of up to CV_RT_PACKET_MAX: kind 2
 * (environment) or 3 (lost). */
static void trace_windows(const cv_rt *rt, block_buf *b, const uint32_t *esc, size_t ne) {
  float po[3 * CV_RT_PACKET_MAX] = {0}, pd[3 * CV_RT_PACKET_MAX] = {0};
  uint8_t pf[CV_RT_PACKET_MAX];
  for (size_t e0 = 0; e0 < ne; e0 += CV_RT_PACKET_MAX) {
    const int m = ne - e0 < CV_RT_PACKET_MAX ? (int)(ne - e0) : CV_RT_PACKET_MAX;
    for (int l = 0; l < m; l++) {
      memcpy(po + 3 * l, b->sorg + 3 * (size_t)esc[e0 + l], 3 * sizeof(float));
      memcpy(pd + 3 * l, b->sdir + 3 * (size_t)esc[e0 + l], 3 * sizeof(float));
    }
    cv_rt_window_any_packet(rt, m, po, pd, 0.0f, 1, pf); /* crossing or not: no hit record */
    for (int l = 0; l < m; l++) b->kind[esc[e0 + l]] = pf[l] ? 2 : 3;
  }
}

/* Traces the n sorted rays in consecutive packets: opaque closest hits,
 * then the window crossings of the rays that escaped (still in direction
 * order, in packets of their own; their indices go to b->tmp, free once
 * order_rays has permuted the rays).  kind: 1 interior, 2 environment,
 * 3 lost (escaped without crossing a window).  The two passes are marked
 * as phases of the phase_seconds hook (ph, tm: see phase_mark). */
static void trace_sorted(const cv_rt *rt, int has_windows, block_buf *b, size_t n, double *ph,
                         double *tm) {
  cv_hit hit[CV_RT_PACKET_MAX];
  uint8_t pf[CV_RT_PACKET_MAX];
  uint32_t *esc = b->tmp;
  size_t ne = 0;
  for (size_t i0 = 0; i0 < n; i0 += CV_RT_PACKET_MAX) {
    const int m = n - i0 < CV_RT_PACKET_MAX ? (int)(n - i0) : CV_RT_PACKET_MAX;
    cv_rt_intersect_packet(rt, m, b->sorg + 3 * i0, b->sdir + 3 * i0, NULL, 0.0f, INFINITY, 1, hit, pf);
    for (int l = 0; l < m; l++) {
      const size_t r = i0 + (size_t)l;
      if (pf[l]) {
        b->htri[r] = hit[l].tri;
        b->huv[2 * r] = hit[l].u;
        b->huv[2 * r + 1] = hit[l].v;
        b->ht[r] = hit[l].t;
        b->kind[r] = 1;
        continue;
      }
      b->kind[r] = 2;
      if (has_windows) esc[ne++] = (uint32_t)r;
    }
  }
  phase_mark(ph, CV_LCD_PHASE_CLOSEST, tm);
  trace_windows(rt, b, esc, ne);
  phase_mark(ph, CV_LCD_PHASE_WINDOWS, tm);
}

/* Bilinear lookup of a lat-long table in float (the layout and filter of
 * light/envmap.c's cv_envmap_lookup, without its double-precision
 * trigonometry), in two steps so that the texels of many rays can be
 * prefetched before any is read: env_texel gives the top-left texel
 * (y0 << 16 | x0) and the weights of d (unit), env_fetch filters. */
static inline uint32_t env_texel(const cv_image *img, const float d[3], float *tx, float *ty) {
  const int w = img->w, h = img->h;
  float y = d[1];
  y = y > 1 ? 1 : (y < -1 ? -1 : y);
  float u = 0.5f + cv_fast_atan2(d[0], -d[2]) * (float)(0.5 * M_1_PI);
  if (u >= 1) u -= 1;
  if (u < 0) u = 0;
  const float v = acosf(y) * (float)M_1_PI;
  const float fx = u * (float)w - 0.5f, fy = v * (float)h - 0.5f;
  const float flx = floorf(fx), fly = floorf(fy);
  *tx = fx - flx;
  *ty = fy - fly;
  int x0 = (int)flx;
  if (x0 < 0) x0 += w;
  if (x0 >= w) x0 -= w;
  int y0 = (int)fly;
  if (y0 < 0) {
    y0 = 0;
    *ty = 0;
  } else if (y0 + 1 >= h) {
    y0 = h - 1;
    *ty = 0;
  }
  return (uint32_t)y0 << 16 | (uint32_t)x0;
}

static inline const float *env_px(const cv_image *img, uint32_t t) {
  return img->px + 3 * ((size_t)(t >> 16) * (size_t)img->w + (t & 0xFFFFu));
}

static inline void env_fetch(const cv_image *img, uint32_t t, float tx, float ty, float rgb[3]) {
  const int w = img->w, x0 = (int)(t & 0xFFFFu), x1 = x0 + 1 == w ? 0 : x0 + 1;
  const float *p00 = env_px(img, t), *p10 = p00 + 3 * (x1 - x0);
  const size_t row = ty > 0 ? 3 * (size_t)w : 0; /* ty = 0: the lower row has no weight */
  const float *p01 = p00 + row, *p11 = p10 + row;
  for (int c = 0; c < 3; c++) {
    const float a = p00[c] + tx * (p10[c] - p00[c]), b = p01[c] + tx * (p11[c] - p01[c]);
    rgb[c] = a + ty * (b - a);
  }
}

/* Interior light sampling: triangles drawn by area x mean luminance of the
 * PRT exit radiance at their vertices x tgeo (what the panel receives of
 * them: view factor to the panel centre and visibility, computed once per
 * gather) (Walker's alias table, Vose's construction), a point uniform on
 * the triangle; only triangles with a vertex in front of the panel's plane
 * take part.  The density of a point
 * (area measure) is pa[t] = luminance(t) / total; a direction d that first
 * hits triangle t at distance r has the density pa[t] r^2 / |d . n_t|. */
typedef struct int_table {
  size_t n;
  float *prob;   /* alias acceptance */
  uint32_t *alias;
  float *pa;     /* area density of each triangle's points (0: never drawn) */
  double total;
} int_table;

static void int_table_free(int_table *it) {
  free(it->prob);
  free(it->alias);
  free(it->pa);
  memset(it, 0, sizeof *it);
}

static int int_table_build(const cv_lcd_gather *g, const cv_lcd_light *l, int_table *it) {
  const size_t n = g->nt;
  memset(it, 0, sizeof *it);
  it->n = n;
  it->prob = malloc(n * sizeof(float) + 1);
  it->alias = malloc(n * sizeof(uint32_t) + 1);
  it->pa = malloc(n * sizeof(float) + 1);
  double *w = malloc(n * sizeof(double) + 1);
  uint32_t *small = malloc(n * sizeof(uint32_t) + 1), *large = malloc(n * sizeof(uint32_t) + 1);
  if (!it->prob || !it->alias || !it->pa || !w || !small || !large) {
    free(w), free(small), free(large);
    int_table_free(it);
    return CV_ERR_NOMEM;
  }
  const cv_lcd_panel *pn = &g->panel;
  double total = 0;
  for (size_t t = 0; t < n; t++) {
    const uint32_t *v = g->tri + 3 * t;
    int front = 0;
    double y = 0;
    for (int j = 0; j < 3; j++) {
      const float *q = g->pos + 3 * (size_t)v[j], *r = l->vrad + 3 * (size_t)v[j];
      const float d[3] = {q[0] - pn->center[0], q[1] - pn->center[1], q[2] - pn->center[2]};
      front |= dot3(d, pn->normal) > 1e-4f;
      y += (0.2126 * r[0] + 0.7152 * r[1] + 0.0722 * r[2]) / 3;
    }
    /* luminance x what the panel receives of it (view factor, visibility) */
    const double e = front && y > 0 ? y * (double)g->tgeo[t] : 0.0;
    w[t] = e * g->tnA[4 * t + 3];
    it->pa[t] = (float)e;
    total += w[t];
  }
  it->total = total;
  if (!(total > 0)) {
    free(w), free(small), free(large);
    return CV_OK;
  }
  for (size_t t = 0; t < n; t++) it->pa[t] = (float)(it->pa[t] / total);
  /* Vose: scaled weights, small and large worklists */
  size_t ns = 0, nl = 0;
  for (size_t t = 0; t < n; t++) {
    w[t] = w[t] * (double)n / total;
    if (w[t] < 1) small[ns++] = (uint32_t)t;
    else large[nl++] = (uint32_t)t;
  }
  while (ns && nl) {
    const uint32_t a = small[--ns], b = large[nl - 1];
    it->prob[a] = (float)w[a];
    it->alias[a] = b;
    w[b] -= 1 - w[a];
    if (w[b] < 1) {
      nl--;
      small[ns++] = b;
    }
  }
  while (nl) it->prob[large[--nl]] = 1.0f, it->alias[large[nl]] = large[nl];
  while (ns) it->prob[small[--ns]] = 1.0f, it->alias[small[ns]] = small[ns];
  free(w), free(small), free(large);
  return CV_OK;
}

/* An interior-strategy direction from o: u[0] picks the triangle (alias
 * table; its remainder and u[1] the point), h a third uniform coordinate.
 * Returns the triangle, or NO_TRI when the point is degenerate; *pd = the
 * direction's density pa r^2 / |d . n| (1/sr). */
static inline uint32_t interior_sample(const cv_lcd_gather *g, const int_table *it, const float o[3],
                                       const float u[2], uint32_t h, float d[3], float *pd) {
  const float x = u[0] * (float)it->n;
  size_t i = (size_t)x;
  if (i >= it->n) i = it->n - 1;
  float fr = x - (float)i;
  uint32_t t = (uint32_t)i;
  if (fr >= it->prob[i]) t = it->alias[i];
  const float s = sqrtf(u[1]), b1 = (float)(h >> 8) * 0x1p-24f;
  const float w1 = (1 - b1) * s, w2 = b1 * s, w0 = 1 - s;
  const uint32_t *v = g->tri + 3 * (size_t)t;
  const float *p0 = g->pos + 3 * (size_t)v[0], *p1 = g->pos + 3 * (size_t)v[1], *p2 = g->pos + 3 * (size_t)v[2];
  float r2 = 0;
  for (int k = 0; k < 3; k++) {
    d[k] = w0 * p0[k] + w1 * p1[k] + w2 * p2[k] - o[k];
    r2 += d[k] * d[k];
  }
  if (!(r2 > 0)) return NO_TRI;
  const float r = sqrtf(r2);
  for (int k = 0; k < 3; k++) d[k] /= r;
  const float c = fabsf(dot3(d, g->tnA + 4 * (size_t)t));
  if (!(c > 1e-6f) || !(it->pa[t] > 0)) return NO_TRI;
  *pd = it->pa[t] * r2 / c;
  return t;
}

/* The density of the interior strategy for a ray that first hits triangle
 * t at distance r along d. */
static inline float interior_pdf(const cv_lcd_gather *g, const int_table *it, uint32_t t, float r,
                                 const float d[3]) {
  const float c = fabsf(dot3(d, g->tnA + 4 * (size_t)t));
  return c > 1e-6f ? it->pa[t] * r * r / c : 0.0f;
}

/* The sun as a uniform disc of angular radius CV_LCD_SUN_HALF_ANGLE_DEG
 * around sun_dir (its irradiance at normal incidence E = L pi sin^2(alpha)
 * is the light's sun_E): radiance L, a frame around its centre, and the
 * one-direction estimate's factor L Omega = E 2 / (1 + cos alpha) (a
 * direction drawn uniformly in the cone has the density 1 / Omega). */
typedef struct sun_disc {
  float dir[3], t[3], b[3];
  float cos_a;      /* cos(alpha) */
  float L[3];       /* disc radiance */
  float E_omega[3]; /* L Omega */
} sun_disc;

static void sun_disc_init(const cv_lcd_light *l, sun_disc *sf) {
  const double a = CV_LCD_SUN_HALF_ANGLE_DEG * M_PI / 180, s = sin(a);
  memcpy(sf->dir, l->sun_dir, sizeof sf->dir);
  sf->cos_a = (float)cos(a);
  for (int c = 0; c < 3; c++) {
    sf->L[c] = (float)(l->sun_E[c] / (M_PI * s * s));
    sf->E_omega[c] = (float)(l->sun_E[c] * 2 / (1 + cos(a)));
  }
  const float up[3] = {fabsf(sf->dir[1]) < 0.9f ? 0.0f : 1.0f, fabsf(sf->dir[1]) < 0.9f ? 1.0f : 0.0f, 0};
  cross3(up, sf->dir, sf->t);
  normalize3(sf->t);
  cross3(sf->dir, sf->t, sf->b);
}

/* A direction uniform in the disc's cone from two hashed integers. */
static inline void sun_disc_dir(const sun_disc *sf, uint32_t h0, uint32_t h1, float d[3]) {
  const float u0 = (float)(h0 >> 8) * 0x1p-24f, u1 = (float)(h1 >> 8) * 0x1p-24f;
  const float ct = 1 - u0 * (1 - sf->cos_a), st = sqrtf(fmaxf(0.0f, 1 - ct * ct));
  float sp, cp;
  cv_fast_sincos2pi(u1, &sp, &cp);
  const float a = st * cp, b = st * sp;
  for (int k = 0; k < 3; k++) d[k] = ct * sf->dir[k] + a * sf->t[k] + b * sf->b[k];
}

/* --- one round, in phases -------------------------------------------------
 *
 * cv_lcd_render_round: round_setup (strategy counts, light tables), then per
 * 16 x 16 block: block_setup (texel frames and seeds, window rectangles),
 * sun_next_event (the sun's shadow ray per texel), and per chunk of
 * samples generate_rays (Sobol points -> strategy directions, rays that
 * carry no sample are added at once), order_rays (sort by direction),
 * trace_sorted (Embree packets), shade_rays (MIS weights and radiance read
 * at the hits), then accumulate_block (texel sums into the buffer). */

/* What a round shares, read-only in the parallel part. */
typedef struct round_ctx {
  const cv_lcd_gather *g;
  const cv_lcd_light *l;
  const cv_lcd_params *p;
  uint32_t round;
  int nstr[NSTRAT], first[NSTRAT];
  float cb, cc, cw, ce, ci; /* c_s = n_s / spp */
  env_tables *et;           /* the environment strategy's tables (NULL: not used) */
  const cv_env_sampler *esr;/* et's: restricted to the panel's front */
  const cv_env_sampler *const *ereg; /* and per region (ereg[0] NULL: esr for all) */
  int_table itab;
  double clamp, inv_unit;
  int sun, sun_in_env;
  sun_disc sf;
  int chunk;
  int acc_w, acc_h; /* the buffer's tile */
} round_ctx;

static void round_free(round_ctx *R) {
  env_tables_release(R->g, R->et);
  int_table_free(&R->itab);
}

/* Samples per strategy and the light tables of this round (R zeroed). */
static int round_setup(const cv_lcd_gather *g, const cv_lcd_light *l, const cv_lcd_params *p,
                       uint32_t round, const cv_lcd_accum *acc, round_ctx *R) {
  const int spp = p->spp;
  R->g = g, R->l = l, R->p = p, R->round = round;
  int *nstr = R->nstr;
  /* samples per strategy and round; at least one non-window sample */
  nstr[STRAT_WIN] = g->nopen > 0 ? (int)lround(p->window_fraction * spp) : 0;
  if (nstr[STRAT_WIN] > spp - 1) nstr[STRAT_WIN] = spp - 1;
  /* environment-light tables restricted to the panel's hemisphere (the
   * light's own tables cover the whole sphere: half of their samples would
   * fall behind the panel) */
  if (p->env_fraction > 0 && l->env_smp && l->env_smp->total > 0) {
    if (!(R->et = env_tables_get(g, l, p->eye))) return CV_ERR_NOMEM;
    R->esr = R->et->esr;
    R->ereg = (const cv_env_sampler *const *)R->et->ereg;
  }
  nstr[STRAT_ENV] = R->esr && R->esr->total > 0 ? (int)lround(p->env_fraction * spp) : 0;
  if (nstr[STRAT_ENV] > spp - 1 - nstr[STRAT_WIN]) nstr[STRAT_ENV] = spp - 1 - nstr[STRAT_WIN];
  /* interior light tables from this light's vertex radiance */
  if (p->interior_fraction > 0 && int_table_build(g, l, &R->itab)) return CV_ERR_NOMEM;
  nstr[STRAT_INT] = R->itab.total > 0 ? (int)lround(p->interior_fraction * spp) : 0;
  if (nstr[STRAT_INT] > spp - 1 - nstr[STRAT_WIN] - nstr[STRAT_ENV])
    nstr[STRAT_INT] = spp - 1 - nstr[STRAT_WIN] - nstr[STRAT_ENV];
  const int nbc = spp - nstr[STRAT_WIN] - nstr[STRAT_ENV] - nstr[STRAT_INT];
  nstr[STRAT_BRDF] = (int)lround(p->brdf_fraction * nbc);
  nstr[STRAT_COS] = nbc - nstr[STRAT_BRDF];
  R->first[STRAT_BRDF] = 0;
  R->first[STRAT_COS] = nstr[STRAT_BRDF];
  R->first[STRAT_WIN] = R->first[STRAT_COS] + nstr[STRAT_COS];
  R->first[STRAT_ENV] = R->first[STRAT_WIN] + nstr[STRAT_WIN];
  R->first[STRAT_INT] = R->first[STRAT_ENV] + nstr[STRAT_ENV];
  R->cb = (float)nstr[STRAT_BRDF] / (float)spp, R->cc = (float)nstr[STRAT_COS] / (float)spp;
  R->cw = (float)nstr[STRAT_WIN] / (float)spp, R->ce = (float)nstr[STRAT_ENV] / (float)spp;
  R->ci = (float)nstr[STRAT_INT] / (float)spp;
  R->clamp = acc->clamp, R->inv_unit = 1 / acc->unit;
  R->sun = p->sun && l->has_sun;
  /* without next-event estimation the rays that leave find the sun's disc */
  R->sun_in_env = !p->sun && l->has_sun;
  if (l->has_sun) sun_disc_init(l, &R->sf);
  R->chunk = spp < CHUNK_SPP ? spp : CHUNK_SPP;
  return CV_OK;
}

/* The strategy of sample j of a round. */
static inline int strategy_of(const round_ctx *R, int j) {
  return j >= R->first[STRAT_INT] ? STRAT_INT
         : j >= R->first[STRAT_ENV] ? STRAT_ENV
         : j >= R->first[STRAT_WIN] ? STRAT_WIN
         : (j >= R->first[STRAT_COS] ? STRAT_COS : STRAT_BRDF);
}

/* Sample j's ray origin on texel (x, y) from its position coordinates u[2..3]. */
static inline void sample_origin(const round_ctx *R, const texel_state *T, int x, int y,
                                 const float u[4], float o[3]) {
  const cv_lcd_panel *pn = &R->g->panel;
  const float jx = ((float)x + u[2]) / (float)R->p->w - 0.5f, jy = 0.5f - ((float)y + u[3]) / (float)R->p->h;
  for (int k = 0; k < 3; k++)
    o[k] = pn->center[k] + pn->u[k] * jx * pn->size[0] + pn->v[k] * jy * pn->size[1] + T->off[k];
}

/* The Sobol point of sample j of the round (dims 0, 1 (a (0,2)-sequence):
 * direction; 2, 3: position) and its strategy. */
static inline int sample_point(const round_ctx *R, const texel_state *T, int j, float u[4]) {
  const int st = strategy_of(R, j);
  const uint32_t idx = R->round * (uint32_t)R->nstr[st] + (uint32_t)(j - R->first[st]);
  cv_sobol_owen_tab4(&R->g->sobol, idx, T->seed[st], T->dseed[st], u);
  return st;
}

/* Per-texel state of the block (tx0, ty0, bw x bh) and its window
 * rectangles; texels whose back the eye sees are counted. */
static void block_setup(const round_ctx *R, block_buf *bb, int tx0, int ty0, int bw, int bh,
                        win_rects *wr, int64_t *cnt) {
  const cv_lcd_gather *g = R->g;
  const cv_lcd_params *p = R->p;
  const cv_lcd_panel *pn = &g->panel;
  const int w = p->w, h = p->h, aw = (int)R->acc_w, ah = (int)R->acc_h;
  wr->n = 0;
  wr->total = 0;
  if (R->nstr[STRAT_WIN] > 0) {
    const float fx = ((float)tx0 + 0.5f * (float)bw) / (float)w - 0.5f;
    const float fy = 0.5f - ((float)ty0 + 0.5f * (float)bh) / (float)h;
    const float ex = (float)bw / (float)w * pn->size[0], ey = (float)bh / (float)h * pn->size[1];
    float c[3];
    for (int k = 0; k < 3; k++)
      c[k] = pn->center[k] + pn->u[k] * fx * pn->size[0] + pn->v[k] * fy * pn->size[1];
    block_rects(g, c, 0.5f * sqrtf(ex * ex + ey * ey), wr);
  }
  for (int i = 0; i < bw * bh; i++) {
    texel_state *T = &bb->ts[i];
    const int x = tx0 + i % bw, y = ty0 + i / bw;
    T->in_tile = x >= p->x0 && x < p->x0 + aw && y >= p->y0 && y < p->y0 + ah;
    T->aix = T->in_tile ? (size_t)(y - p->y0) * (size_t)aw + (size_t)(x - p->x0) : 0;
    memset(T->s, 0, sizeof T->s);
    memset(T->s2, 0, sizeof T->s2);
    memset(T->nee, 0, sizeof T->nee);
    float wo[3];
    const float fx = ((float)x + 0.5f) / (float)w - 0.5f, fy = 0.5f - ((float)y + 0.5f) / (float)h;
    for (int k = 0; k < 3; k++) {
      T->pc[k] = pn->center[k] + pn->u[k] * fx * pn->size[0] + pn->v[k] * fy * pn->size[1];
      wo[k] = p->eye[k] - T->pc[k];
    }
    normalize3(wo);
    const float co = dot3(wo, pn->normal);
    T->behind = !(co > 1e-6f);
    if (T->behind) {
      if (T->in_tile) cnt[CV_LCD_ACC_BEHIND] += p->spp; /* the eye sees the panel's back: black */
      continue;
    }
    for (int k = 0; k < 3; k++) T->tn[k] = wo[k] - co * pn->normal[k];
    if (!normalize3(T->tn)) memcpy(T->tn, pn->u, sizeof T->tn);
    cross3(pn->normal, T->tn, T->bn);
    /* The panel is flat: one scale-aware offset along the normal serves
     * every jittered origin of the texel. */
    cv_rt_offset_origin(T->pc, pn->normal, T->off);
    for (int k = 0; k < 3; k++) T->off[k] -= T->pc[k];
    cv_brdf_view_bins(g->smp, acosf(co > 1 ? 1 : co), &T->kb, &T->tb);
    const uint32_t tix = (uint32_t)y * (uint32_t)w + (uint32_t)x; /* panel texel: the seed */
    const uint32_t ts = cv_hash_combine(p->seed, tix);
    for (int st = 0; st < NSTRAT; st++) {
      T->seed[st] = st == STRAT_BRDF ? ts : cv_hash_combine(ts, 0x51u + (uint32_t)st);
      cv_sobol_dim_seeds(T->seed[st], 4, T->dseed[st]);
    }
  }
}

/* The sun's next-event estimate of each texel of the tile for the round,
 * from sample 0's position: one direction drawn uniformly in the solar
 * disc, one shadow ray; the term is added to every sample of the round. */
static void sun_next_event(const round_ctx *R, block_buf *bb, int tx0, int ty0, int bw, int bh,
                           int64_t *cnt) {
  if (!R->sun) return;
  const cv_lcd_panel *pn = &R->g->panel;
  for (int i = 0; i < bw * bh; i++) {
    texel_state *T = &bb->ts[i];
    if (T->behind || !T->in_tile) continue;
    float u[4], o[3], sd[3];
    sample_point(R, T, 0, u);
    sample_origin(R, T, tx0 + i % bw, ty0 + i / bw, u, o);
    const uint32_t hs = cv_hash_combine(T->seed[STRAT_BRDF] ^ 0x5017u, R->round);
    sun_disc_dir(&R->sf, hs, cv_hash_combine(hs, 0x9e3779b9u), sd);
    const float cs = dot3(sd, pn->normal);
    if (!(cs > 0)) continue;
    cnt[CV_LCD_ACC_SHADOW]++;
    if (!cv_rt_reaches_env(R->g->rt, o, sd, 0)) continue;
    cnt[CV_LCD_ACC_SUNLIT]++;
    const float th = acosf(cs > 1 ? 1 : cs);
    const float ph = fabsf(cv_fast_atan2(dot3(sd, T->bn), dot3(sd, T->tn)));
    cv_brdf_eval_bins(R->g->smp, T->kb, T->tb, th, ph, T->nee);
    for (int c = 0; c < 3; c++) T->nee[c] *= cs * R->sf.E_omega[c];
  }
}

/* Samples j0 .. j0 + nj - 1 of every texel of the block: a direction by
 * the sample's strategy and what its weight needs (f cos and the interior
 * MIS denominator, or, for window and environment samples, the local
 * direction: evaluated only if the ray leaves), appended to bb's rays with
 * their sort keys; a sample without a ray (below the horizon, a zero
 * density) is added at once as the sun term alone.  Returns the rays. */
static size_t generate_rays(const round_ctx *R, block_buf *bb, int tx0, int ty0, int bw, int bh,
                            const win_rects *wr, const cv_env_sampler *esm, int j0, int nj,
                            int64_t *cnt) {
  const cv_lcd_gather *g = R->g;
  const cv_lcd_panel *pn = &g->panel;
  const cv_brdf_sampler *smp = g->smp;
  const cv_lcd_params *p = R->p;
  const float cb = R->cb, cc = R->cc, ci = R->ci;
  size_t n = 0;
  for (int i = 0; i < bw * bh; i++) {
    texel_state *T = &bb->ts[i];
    if (T->behind) continue;
    const int x = tx0 + i % bw, y = ty0 + i / bw;
    /* the texel's points first: short independent iterations overlap */
    float uu[CHUNK_SPP][4];
    uint8_t sj[CHUNK_SPP];
    for (int j = j0; j < j0 + nj; j++) sj[j - j0] = (uint8_t)sample_point(R, T, j, uu[j - j0]);
    for (int j = j0; j < j0 + nj; j++) {
      const float *u = uu[j - j0];
      const int st = sj[j - j0];
      float o[3];
      sample_origin(R, T, x, y, u, o);
      float wl[3] = {0, 0, 0}, rd[3], th = 0, ph = 0, pb = 0, pe = 0, f[3] = {0, 0, 0};
      float pint = 0;
      uint32_t want = NO_TRI;
      int live = 0;
      if (st == STRAT_BRDF) {
        live = cv_brdf_sample(smp, T->kb, T->tb, u, wl, &th, &ph, &pb, f);
      } else if (st == STRAT_COS) {
        cv_cosine_sample(u, wl);
        live = 1;
      } else if (st == STRAT_INT) {
        /* a point on a bright interior triangle; counts only if it is the
         * ray's first hit */
        const uint32_t hh = cv_hash_combine(T->seed[STRAT_INT], R->round * (uint32_t)p->spp + (uint32_t)j);
        want = interior_sample(g, &R->itab, o, u, hh, rd, &pint);
        live = want != NO_TRI;
      } else {
        /* window, environment: f and p_b wait until the ray is known to
         * leave (only then does the sample count) */
        live = st == STRAT_ENV ? cv_env_sampler_sample(esm, u, rd, &pe) : window_sample(pn, wr, u, rd);
      }
      if (live && (st == STRAT_BRDF || st == STRAT_COS)) {
        for (int k = 0; k < 3; k++) rd[k] = T->tn[k] * wl[0] + T->bn[k] * wl[1] + pn->normal[k] * wl[2];
      } else if (live) {
        wl[0] = dot3(rd, T->tn);
        wl[1] = dot3(rd, T->bn);
        wl[2] = dot3(rd, pn->normal);
        live = st != STRAT_INT || wl[2] > 0;
      }
      if (live && (st == STRAT_COS || st == STRAT_INT)) {
        th = acosf(wl[2] > 1 ? 1 : wl[2]);
        ph = fabsf(cv_fast_atan2(wl[1], wl[0]));
        if (cb > 0) pb = cv_brdf_pdf_cs(smp, T->kb, T->tb, wl[2], wl[0] * wl[0] + wl[1] * wl[1], th, ph);
        cv_brdf_eval_bins(smp, T->kb, T->tb, th, ph, f);
      }
      const int defer = st == STRAT_WIN || st == STRAT_ENV;
      /* the interior MIS denominator; an interior-strategy ray's own
       * density is known now, the others' p_int when they hit */
      const float dint = defer ? -1.0f : cb * pb + cc * wl[2] * (float)M_1_PI + ci * pint;
      if (!(live && wl[2] > 0 && (dint > 0 || defer))) {
        /* no ray: the sample is the sun term alone */
        if (T->in_tile) add_sample((float[3]){T->nee[0], T->nee[1], T->nee[2]}, R->clamp, R->inv_unit, T->s, T->s2, cnt);
        continue;
      }
      float *ro = bb->org + 3 * n, *rdir = bb->dir + 3 * n, *rf = bb->fc + 4 * n;
      for (int k = 0; k < 3; k++) {
        ro[k] = o[k];
        rdir[k] = rd[k];
        rf[k] = defer ? wl[k] : f[k] * wl[2]; /* window, environment: the local direction */
      }
      rf[3] = dint;
      bb->tex[n] = (uint32_t)i | (defer ? TEX_WIN : 0u);
      bb->want[n] = want;
      bb->key[n] = dir_key(rd);
      if (p->ray_log && R->round == 0 && T->in_tile) {
        float *rl = p->ray_log + 6 * (T->aix * (size_t)p->spp + (size_t)j);
        memcpy(rl, ro, 3 * sizeof(float));
        memcpy(rl + 3, rd, 3 * sizeof(float));
      }
      n++;
    }
  }
  return n;
}

/* Sorts the n rays by direction and permutes them once into that order:
 * packets and shading then read consecutive memory. */
static void order_rays(block_buf *bb, size_t n) {
  sort_by_key(bb->key, n, bb->ord, bb->tmp);
  for (size_t q = 0; q < n; q++) {
    const uint32_t r = bb->ord[q];
    memcpy(bb->sorg + 3 * q, bb->org + 3 * (size_t)r, 3 * sizeof(float));
    memcpy(bb->sdir + 3 * q, bb->dir + 3 * (size_t)r, 3 * sizeof(float));
    memcpy(bb->sfc + 4 * q, bb->fc + 4 * (size_t)r, 4 * sizeof(float));
    bb->stex[q] = bb->tex[r];
    bb->swant[q] = bb->want[r];
  }
}

/* The value of each traced sample (in direction order): MIS-weighted
 * radiance read at the interior hit or in the environment, plus the sun
 * term, added to its texel's sums. */
static void shade_rays(const round_ctx *R, block_buf *bb, size_t n, const win_rects *wr,
                       const cv_env_sampler *esm, int64_t *cnt) {
  const cv_lcd_gather *g = R->g;
  const cv_lcd_light *l = R->l;
  const cv_lcd_panel *pn = &g->panel;
  const cv_brdf_sampler *smp = g->smp;
  const cv_image *img = l->env->img;
  const float cb = R->cb, cc = R->cc, cw = R->cw, ce = R->ce, ci = R->ci;
  /* environment texels of the rays that left: computed and prefetched for
   * all of them first (they miss the cache; this overlaps the misses),
   * kept in htri / huv, which only interior hits use */
  for (size_t q = 0; q < n; q++) {
    if (bb->kind[q] != 2) continue;
    const uint32_t t = env_texel(img, bb->sdir + 3 * q, &bb->huv[2 * q], &bb->huv[2 * q + 1]);
    bb->htri[q] = t;
    const float *px = env_px(img, t);
    __builtin_prefetch(px);
    __builtin_prefetch(px + 3 * (size_t)img->w);
  }
  /* shade in direction order: consecutive rays hit nearby triangles; the
   * vertex records of a hit a few rays ahead are prefetched */
  for (size_t q = 0; q < n; q++) {
    if (q + 8 < n && bb->kind[q + 8] == 1) {
      const uint32_t *t8 = g->tri + 3 * (size_t)bb->htri[q + 8];
      __builtin_prefetch(l->vrad + 3 * (size_t)t8[0]);
      __builtin_prefetch(l->vrad + 3 * (size_t)t8[1]);
      __builtin_prefetch(l->vrad + 3 * (size_t)t8[2]);
    }
    if (q + 16 < n && bb->kind[q + 16] == 1) __builtin_prefetch(g->tri + 3 * (size_t)bb->htri[q + 16]);
    texel_state *T = &bb->ts[bb->stex[q] & ~TEX_WIN];
    if (!T->in_tile) continue;
    const int win = (bb->stex[q] & TEX_WIN) != 0;
    const float *rf = bb->sfc + 4 * q;
    float v[3] = {T->nee[0], T->nee[1], T->nee[2]};
    if (bb->kind[q] == 1) {
      cnt[CV_LCD_ACC_HITS]++;
      /* interior: MIS over BRDF, cosine and interior sampling; an
       * interior-strategy ray counts only on the triangle it aimed at */
      const uint32_t ht = bb->htri[q], aim = bb->swant[q];
      if (!win && (aim == NO_TRI || aim == ht)) {
        const uint32_t *t = g->tri + 3 * (size_t)ht;
        const float *r0 = l->vrad + 3 * (size_t)t[0], *r1 = l->vrad + 3 * (size_t)t[1],
                    *r2 = l->vrad + 3 * (size_t)t[2];
        const float hu = bb->huv[2 * q], hv = bb->huv[2 * q + 1];
        float den = rf[3];
        if (aim == NO_TRI && ci > 0) den += ci * interior_pdf(g, &R->itab, ht, bb->ht[q], bb->sdir + 3 * q);
        const float w0 = 1 - hu - hv, inv = 1 / den;
        for (int c = 0; c < 3; c++) v[c] += rf[c] * inv * (w0 * r0[c] + hu * r1[c] + hv * r2[c]);
      }
    } else if (bb->kind[q] == 2) {
      float L[3], fc[3], dint = rf[3];
      cnt[CV_LCD_ACC_ENV]++;
      if (bb->swant[q] != NO_TRI) { /* an interior-strategy ray: weight 0 outside */
        add_sample(v, R->clamp, R->inv_unit, T->s, T->s2, cnt);
        continue;
      }
      env_fetch(img, bb->htri[q], bb->huv[2 * q], bb->huv[2 * q + 1], L);
      if (R->sun_in_env && dot3(bb->sdir + 3 * q, R->sf.dir) >= R->sf.cos_a)
        for (int c = 0; c < 3; c++) L[c] += R->sf.L[c];
      if (win) {
        /* the deferred f cos and interior denominator of a window or
         * environment sample */
        const float th = acosf(rf[2] > 1 ? 1 : rf[2]), ph = fabsf(cv_fast_atan2(rf[1], rf[0]));
        const float pb = cb > 0 ? cv_brdf_pdf_cs(smp, T->kb, T->tb, rf[2], rf[0] * rf[0] + rf[1] * rf[1], th, ph) : 0.0f;
        cv_brdf_eval_bins(smp, T->kb, T->tb, th, ph, fc);
        for (int c = 0; c < 3; c++) fc[c] *= rf[2];
        dint = cb * pb + cc * rf[2] * (float)M_1_PI;
      } else {
        memcpy(fc, rf, sizeof fc);
      }
      const float den = dint + (cw > 0 ? cw * window_pdf(pn, wr, bb->sdir + 3 * q) : 0.0f) +
                        (ce > 0 ? ce * cv_env_sampler_pdf(esm, bb->sdir + 3 * q) : 0.0f);
      if (den > 0)
        for (int c = 0; c < 3; c++) v[c] += fc[c] / den * L[c];
    } else {
      cnt[CV_LCD_ACC_LOST]++;
    }
    add_sample(v, R->clamp, R->inv_unit, T->s, T->s2, cnt);
  }
}

/* The block's texel sums into the buffer (each texel belongs to one block:
 * no two threads write the same words). */
static void accumulate_block(const round_ctx *R, const block_buf *bb, int nbt, int64_t *data,
                             int aw, int ah) {
  (void)R;
  for (int i = 0; i < nbt; i++) {
    const texel_state *T = &bb->ts[i];
    if (!T->in_tile || T->behind) continue;
    int64_t *q = data + CV_LCD_ACC_HEADER + 3 * T->aix;
    for (int c = 0; c < 3; c++) q[c] += T->s[c];
    int64_t *q2 = data + CV_LCD_ACC_HEADER + 3 * (size_t)aw * (size_t)ah + 2 * T->aix;
    q2[0] += T->s2[0];
    q2[1] += T->s2[1];
  }
}

int cv_lcd_render_round(const cv_lcd_gather *g, const cv_lcd_light *l, const cv_lcd_params *p,
                        uint32_t round, cv_lcd_accum *acc) {
  if (!g || !l || !p || !acc || p->w < 1 || p->h < 1 || p->x0 < 0 || p->y0 < 0 ||
      p->x0 + acc->w > p->w || p->y0 + acc->h > p->h || p->spp < 1 ||
      l->nv != g->nv || !(p->brdf_fraction >= 0 && p->brdf_fraction <= 1) ||
      !(p->window_fraction >= 0 && p->window_fraction < 1) ||
      !(p->env_fraction >= 0 && p->env_fraction < 1) ||
      !(p->interior_fraction >= 0 && p->interior_fraction < 1) ||
      !(p->window_fraction + p->env_fraction + p->interior_fraction < 1) ||
      !isfinite(p->eye[0]) || !isfinite(p->eye[1]) || !isfinite(p->eye[2]))
    return CV_ERR_INVALID;
  if (acc->data[CV_LCD_ACC_SPP] + p->spp > CV_LCD_MAX_SPP) return CV_ERR_RANGE;
  if ((uint64_t)round * (uint64_t)p->spp + (uint64_t)p->spp > 4294967296ull) return CV_ERR_RANGE;
  round_ctx R;
  memset(&R, 0, sizeof R);
  R.acc_w = acc->w, R.acc_h = acc->h;
  if (round_setup(g, l, p, round, acc, &R)) {
    round_free(&R);
    return CV_ERR_NOMEM;
  }
  const int w = p->w, h = p->h, spp = p->spp, aw = acc->w, ah = acc->h, chunk = R.chunk;
  const int nthreads = p->threads > 0 ? p->threads : omp_get_max_threads();
  /* blocks that hold a texel of the tile */
  const int bx0 = p->x0 / BLOCK, bx1 = (p->x0 + aw - 1) / BLOCK;
  const int by0 = p->y0 / BLOCK, by1 = (p->y0 + ah - 1) / BLOCK;
  const int nbx = bx1 - bx0 + 1, nblocks = nbx * (by1 - by0 + 1);
  int64_t cnt[CV_LCD_ACC_HEADER];
  memset(cnt, 0, sizeof cnt);
  int64_t *data = acc->data;
  int status = CV_OK;

#pragma omp parallel num_threads(nthreads) reduction(+ : cnt[:CV_LCD_ACC_HEADER])
  {
    cv_rt_thread_init();
    double phase_local[CV_LCD_PHASES] = {0}, tm = 0;
    double *ph = p->phase_seconds ? phase_local : NULL;
    block_buf bb;
    int ok = block_buf_alloc(&bb, (size_t)BLOCK * BLOCK * (size_t)chunk) == CV_OK;
    if (!ok) {
#pragma omp atomic write
      status = CV_ERR_NOMEM;
    }
#pragma omp for schedule(dynamic, 1)
    for (int bi = 0; bi < nblocks; bi++) {
      if (!ok) continue;
      const int tx0 = (bx0 + bi % nbx) * BLOCK, ty0 = (by0 + bi / nbx) * BLOCK;
      const int bw = w - tx0 < BLOCK ? w - tx0 : BLOCK, bh = h - ty0 < BLOCK ? h - ty0 : BLOCK;
      /* the environment table of the region that holds the block's centre */
      const int erx = (int)((2 * tx0 + bw) * ENV_RX / (2 * w)), ery = (int)((2 * ty0 + bh) * ENV_RY / (2 * h));
      const cv_env_sampler *esm = R.ereg && R.ereg[0] ? R.ereg[ery * ENV_RX + erx] : R.esr;
      win_rects wr;
      phase_mark(ph, CV_LCD_PHASES, &tm);
      block_setup(&R, &bb, tx0, ty0, bw, bh, &wr, cnt);
      sun_next_event(&R, &bb, tx0, ty0, bw, bh, cnt);
      phase_mark(ph, CV_LCD_PHASE_SETUP, &tm);
      for (int j0 = 0; j0 < spp; j0 += chunk) {
        const int nj = spp - j0 < chunk ? spp - j0 : chunk;
        const size_t n = generate_rays(&R, &bb, tx0, ty0, bw, bh, &wr, esm, j0, nj, cnt);
        phase_mark(ph, CV_LCD_PHASE_GENERATE, &tm);
        order_rays(&bb, n);
        phase_mark(ph, CV_LCD_PHASE_ORDER, &tm);
        trace_sorted(g->rt, g->has_windows, &bb, n, ph, &tm);
        shade_rays(&R, &bb, n, &wr, esm, cnt);
        phase_mark(ph, CV_LCD_PHASE_SHADE, &tm);
      }
      accumulate_block(&R, &bb, bw * bh, data, aw, ah);
      phase_mark(ph, CV_LCD_PHASE_SHADE, &tm);
    }
    block_buf_free(&bb);
    if (ph) {
#pragma omp critical(cv_lcd_phase_sum)
      for (int k = 0; k < CV_LCD_PHASES; k++) p->phase_seconds[k] += ph[k];
    }
  }
  round_free(&R);
  if (status != CV_OK) return status;
  for (int i = 0; i < CV_LCD_ACC_HEADER; i++) data[i] += cnt[i];
  data[CV_LCD_ACC_SPP] += spp;
  data[CV_LCD_ACC_ROUNDS] += 1;
  return CV_OK;
}

/* --- content -------------------------------------------------------------- */

/* --- what the eye sees ---------------------------------------------------- */

/* Distance along the ray to the panel rectangle, or INFINITY. */
static float panel_distance(const cv_lcd_panel *pn, const float o[3], const float d[3]) {
  const float dn = dot3(d, pn->normal);
  if (fabsf(dn) < 1e-8f) return INFINITY;
  const float c[3] = {pn->center[0] - o[0], pn->center[1] - o[1], pn->center[2] - o[2]};
  const float t = dot3(c, pn->normal) / dn;
  if (!(t > 0)) return INFINITY;
  const float q[3] = {o[0] + t * d[0] - pn->center[0], o[1] + t * d[1] - pn->center[1],
                      o[2] + t * d[2] - pn->center[2]};
  if (fabsf(dot3(q, pn->u)) > 0.5f * pn->size[0] || fabsf(dot3(q, pn->v)) > 0.5f * pn->size[1])
    return INFINITY;
  return t;
}

int cv_lcd_eye_radiance(const cv_lcd_gather *g, const cv_lcd_light *l, const float eye[3],
                        const float dir[3], float rgb[3]) {
  rgb[0] = rgb[1] = rgb[2] = 0;
  cv_hit h;
  const int hit = cv_rt_intersect(g->rt, eye, dir, 0.0f, INFINITY, &h);
  const float tp = panel_distance(&g->panel, eye, dir);
  if (tp < INFINITY && (!hit || tp <= h.t * 1.0001f + 1e-4f)) return 1;
  if (hit) {
    if (l->nv != g->nv || h.tri >= g->nt) return 0;
    const uint32_t *t = g->tri + 3 * (size_t)h.tri;
    const float w0 = 1 - h.u - h.v;
    for (int c = 0; c < 3; c++)
      rgb[c] = w0 * l->vrad[3 * (size_t)t[0] + c] + h.u * l->vrad[3 * (size_t)t[1] + c] +
               h.v * l->vrad[3 * (size_t)t[2] + c];
    return 0;
  }
  if (g->has_windows) {
    cv_hit wh;
    if (!cv_rt_window_hit(g->rt, eye, dir, 0.0f, &wh)) return 0;
  }
  cv_envmap_lookup(l->env, dir, rgb);
  return 0;
}

int cv_lcd_sun_visible(const cv_lcd_gather *g, const cv_lcd_light *l, const float eye[3]) {
  if (!l->has_sun) return 0;
  return cv_rt_reaches_env(g->rt, eye, l->sun_dir, 0.0f);
}

static double srgb_decode(double v) {
  return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
}

static void builtin_pattern(cv_image *img) {
  const int w = img->w, h = img->h;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      float *px = cv_image_at(img, x, y);
      double fx = (x + 0.5) / w, fy = (y + 0.5) / h;
      double r = 0, g = 0, b = 0; /* black (the panel's black luminance) */
      /* six lines of "text": blocks of glyph-sized bars */
      int line = (int)(fy * 12);
      if (fx > 0.06 && fx < 0.55 && line >= 2 && line < 12 && line % 2 == 0) {
        double gx = fx * 60;
        if (gx - floor(gx) < 0.7 && ((int)gx * 7 + line) % 5 != 0) r = g = b = 1.0;
      }
      /* a gauge: a coloured ring on the right */
      double dx = (fx - 0.78) * w / h, dy = fy - 0.5, rr = sqrt(dx * dx + dy * dy);
      if (rr > 0.25 && rr < 0.32) {
        double a = atan2(dy, dx);
        if (a < 0.6) r = 0.9, g = 0.15, b = 0.1;
        else r = 0.1, g = 0.8, b = 0.3;
      }
      px[0] = (float)r, px[1] = (float)g, px[2] = (float)b;
    }
}

int cv_lcd_content_load(const char *path, int w, int h, double panel_aspect, double white,
                        double black, cv_image **out, cv_err *err) {
  *out = NULL;
  if (w < 1 || h < 1 || !(black >= 0) || !(white >= black) || !isfinite(white) ||
      !isfinite(panel_aspect))
    return cv_err_set(err, CV_ERR_INVALID, "content: size %dx%d, white %g, black %g", w, h, white,
                      black);
  cv_image *img;
  if (cv_image_create(w, h, 3, &img)) return cv_err_set(err, CV_ERR_NOMEM, "content: out of memory");
  if (!path || !path[0]) {
    builtin_pattern(img);
  } else {
    cv_image *src = NULL;
    int st, is_png = 0;
    size_t n = strlen(path);
    if (n >= 4 && (!strcmp(path + n - 4, ".png") || !strcmp(path + n - 4, ".PNG"))) {
      is_png = 1;
      st = cv_png_read(path, &src, err);
    } else {
      st = cv_exr_read(path, &src, err);
    }
    if (st) {
      cv_image_destroy(img);
      return st;
    }
    double scale = 1;
    if (!is_png) {
      double ymax = 0;
      for (size_t i = 0; i < (size_t)src->w * src->h; i++) {
        const float *q = src->px + i * src->c;
        ymax = fmax(ymax, 0.2126 * q[0] + 0.7152 * q[1] + 0.0722 * q[2]);
      }
      scale = ymax > 0 ? 1 / ymax : 1;
    }
    /* the content's rectangle on the panel: its own aspect, as large as
     * fits, centred (no stretch); black around it */
    double fw = 1, fh = 1;
    const double ca = (double)src->w / src->h;
    if (panel_aspect > 0 && ca > panel_aspect) fh = panel_aspect / ca;
    else if (panel_aspect > 0) fw = ca / panel_aspect;
    const double ox = 0.5 * (1 - fw), oy = 0.5 * (1 - fh);
    /* box filter: average of a grid of nearest source pixels per texel */
    int gx = (int)ceil(src->w / (fw * w)), gy = (int)ceil(src->h / (fh * h));
    for (int y = 0; y < h; y++)
      for (int x = 0; x < w; x++) {
        double acc[3] = {0, 0, 0};
        for (int j = 0; j < gy; j++)
          for (int i = 0; i < gx; i++) {
            const double cu = ((x + (i + 0.5) / gx) / w - ox) / fw;
            const double cv = ((y + (j + 0.5) / gy) / h - oy) / fh;
            if (cu < 0 || cu >= 1 || cv < 0 || cv >= 1) continue; /* outside: black */
            int sx = (int)(cu * src->w), sy = (int)(cv * src->h);
            if (sx >= src->w) sx = src->w - 1;
            if (sy >= src->h) sy = src->h - 1;
            const float *q = cv_image_at(src, sx, sy);
            for (int c = 0; c < 3; c++) {
              double v = src->c >= 3 ? q[c] : q[0];
              acc[c] += is_png ? srgb_decode(v) : v * scale;
            }
          }
        float *px = cv_image_at(img, x, y);
        for (int c = 0; c < 3; c++) px[c] = (float)(acc[c] / (gx * gy));
      }
    cv_image_destroy(src);
  }
  size_t n3 = (size_t)w * h * 3;
  for (size_t i = 0; i < n3; i++) img->px[i] = (float)(black + img->px[i] * (white - black));
  *out = img;
  return CV_OK;
}
