/* LCD panel final gather (see gather.h). */
#include "lcd/gather.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

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
  if ((st = cv_prt_relight(p, &lt, tr, sun_samples, vrad, &rs))) {
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
  g->tri = malloc(3 * m->nt * sizeof(uint32_t) + 1);
  if (!g->tri || cv_brdf_sampler_create(brdf, &g->smp)) {
    cv_lcd_gather_destroy(g);
    return cv_err_set(err, CV_ERR_NOMEM, "lcd gather: out of memory");
  }
  memcpy(g->tri, m->tri, 3 * m->nt * sizeof(uint32_t));
  cv_sobol_tab_init(&g->sobol);
  *out = g;
  return CV_OK;
}

void cv_lcd_gather_destroy(cv_lcd_gather *g) {
  if (!g) return;
  free(g->tri);
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
  h = cv_hash64_u64(h, p->seed);
  h = cv_hash64_u64(h, (uint64_t)p->sun);
  h = cv_hash64_double(h, clamp);
  h = cv_hash64_double(h, tolerance);
  return h;
}

#define GATHER_BATCH 64

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

int cv_lcd_render_round(const cv_lcd_gather *g, const cv_lcd_light *l, const cv_lcd_params *p,
                        uint32_t round, cv_lcd_accum *acc) {
  if (!g || !l || !p || !acc || p->w < 1 || p->h < 1 || p->x0 < 0 || p->y0 < 0 ||
      p->x0 + acc->w > p->w || p->y0 + acc->h > p->h || p->spp < 1 ||
      l->nv != g->nv || !(p->brdf_fraction >= 0 && p->brdf_fraction <= 1) ||
      !isfinite(p->eye[0]) || !isfinite(p->eye[1]) || !isfinite(p->eye[2]))
    return CV_ERR_INVALID;
  if (acc->data[CV_LCD_ACC_SPP] + p->spp > CV_LCD_MAX_SPP) return CV_ERR_RANGE;
  if ((uint64_t)round * (uint64_t)p->spp + (uint64_t)p->spp > 4294967296ull) return CV_ERR_RANGE;
  const cv_lcd_panel *pn = &g->panel;
  const cv_brdf_sampler *smp = g->smp;
  const int w = p->w, h = p->h, spp = p->spp, aw = acc->w, ah = acc->h;
  const float cfrac = (float)p->brdf_fraction;
  const double clamp = acc->clamp, inv_unit = 1 / acc->unit;
  const int sun = p->sun && l->has_sun;
  const int nthreads = p->threads > 0 ? p->threads : omp_get_max_threads();
  int64_t cnt[CV_LCD_ACC_HEADER];
  memset(cnt, 0, sizeof cnt);
  int64_t *data = acc->data;

#pragma omp parallel for schedule(dynamic, 1) num_threads(nthreads) reduction(+ : cnt[:CV_LCD_ACC_HEADER])
  for (int ay = 0; ay < ah; ay++) {
    cv_rt_thread_init();
    for (int ax = 0; ax < aw; ax++) {
      const int x = p->x0 + ax, y = p->y0 + ay;
      const uint32_t tix = (uint32_t)y * (uint32_t)w + (uint32_t)x; /* panel texel: the seed */
      const size_t aix = (size_t)ay * (size_t)aw + (size_t)ax;     /* buffer texel */
      int64_t s[3] = {0, 0, 0}, s2[2] = {0, 0};
      float pc[3], wo[3], tn[3], bn[3];
      const float fx = ((float)x + 0.5f) / (float)w - 0.5f, fy = 0.5f - ((float)y + 0.5f) / (float)h;
      for (int k = 0; k < 3; k++) {
        pc[k] = pn->center[k] + pn->u[k] * fx * pn->size[0] + pn->v[k] * fy * pn->size[1];
        wo[k] = p->eye[k] - pc[k];
      }
      normalize3(wo);
      const float co = dot3(wo, pn->normal);
      if (!(co > 1e-6f)) {
        cnt[CV_LCD_ACC_BEHIND] += spp; /* the eye sees the panel's back: black */
        continue;
      }
      for (int k = 0; k < 3; k++) tn[k] = wo[k] - co * pn->normal[k];
      if (!normalize3(tn)) memcpy(tn, pn->u, sizeof tn);
      cross3(pn->normal, tn, bn);
      int kb;
      float tb;
      cv_brdf_view_bins(smp, acosf(co > 1 ? 1 : co), &kb, &tb);
      /* sun term constants: f(s, w_o) cos(theta_s) E */
      float fsun[3] = {0, 0, 0};
      int sun_here = 0;
      if (sun) {
        float cs = dot3(l->sun_dir, pn->normal);
        if (cs > 0) {
          float th = acosf(cs > 1 ? 1 : cs);
          float ph = fabsf(atan2f(dot3(l->sun_dir, bn), dot3(l->sun_dir, tn)));
          cv_brdf_eval_bins(smp, kb, tb, th, ph, fsun);
          for (int c = 0; c < 3; c++) fsun[c] *= cs * l->sun_E[c];
          sun_here = 1;
        }
      }
      float nee[3] = {0, 0, 0};
      const uint32_t seed = cv_hash_combine(p->seed, tix);
      uint32_t dseed[5];
      cv_sobol_dim_seeds(seed, 5, dseed);
      /* The panel is flat: one scale-aware offset along the normal serves
       * every jittered origin of the texel. */
      float off[3];
      cv_rt_offset_origin(pc, pn->normal, off);
      for (int k = 0; k < 3; k++) off[k] -= pc[k];
      /* Samples in batches: (1) draw directions and BRDF weights, (2) trace,
       * (3) shade.  Keeping the table look-ups apart from the traversal lets
       * their cache misses overlap. */
      for (int j0 = 0; j0 < spp; j0 += GATHER_BATCH) {
        const int nb = spp - j0 < GATHER_BATCH ? spp - j0 : GATHER_BATCH;
        float org[GATHER_BATCH][3], dir[GATHER_BATCH][3], wt[GATHER_BATCH][3];
        int live[GATHER_BATCH];
        for (int j = 0; j < nb; j++) {
          float u[5];
          cv_sobol_owen_tab(&g->sobol, round * (uint32_t)spp + (uint32_t)(j0 + j), seed, dseed, 5, u);
          /* dims 0, 1 (a (0,2)-sequence): direction; 2, 3: position; 4: strategy */
          const float jx = ((float)x + u[2]) / (float)w - 0.5f, jy = 0.5f - ((float)y + u[3]) / (float)h;
          for (int k = 0; k < 3; k++)
            org[j][k] = pn->center[k] + pn->u[k] * jx * pn->size[0] + pn->v[k] * jy * pn->size[1] + off[k];
          float wl[3], th, ph, pdf;
          live[j] = 0;
          if (u[4] < cfrac) {
            const float ub[3] = {u[0], u[1], u[4] / cfrac};
            float pb;
            if (!cv_brdf_sample(smp, kb, tb, ub, wl, &th, &ph, &pb)) continue;
            pdf = cfrac < 1 ? cfrac * pb + (1 - cfrac) * wl[2] * (float)M_1_PI : pb;
          } else {
            cv_cosine_sample(u, wl);
            th = acosf(wl[2] > 1 ? 1 : wl[2]);
            ph = fabsf(atan2f(wl[1], wl[0]));
            pdf = (1 - cfrac) * wl[2] * (float)M_1_PI;
            if (cfrac > 0) pdf += cfrac * cv_brdf_pdf(smp, kb, tb, th, ph);
          }
          if (!(wl[2] > 0 && pdf > 0)) continue;
          float f[3];
          cv_brdf_eval_bins(smp, kb, tb, th, ph, f);
          const float r = wl[2] / pdf;
          for (int k = 0; k < 3; k++) {
            wt[j][k] = f[k] * r;
            dir[j][k] = tn[k] * wl[0] + bn[k] * wl[1] + pn->normal[k] * wl[2];
          }
          live[j] = 1;
          if (p->ray_log && round == 0) {
            float *rl = p->ray_log + 6 * (aix * (size_t)spp + (size_t)(j0 + j));
            memcpy(rl, org[j], 3 * sizeof(float));
            memcpy(rl + 3, dir[j], 3 * sizeof(float));
          }
        }
        if (j0 == 0 && sun_here) {
          /* next-event estimate of the sun from sample 0's position, for the round */
          cnt[CV_LCD_ACC_SHADOW]++;
          if (cv_rt_reaches_env(g->rt, org[0], l->sun_dir, 0)) {
            cnt[CV_LCD_ACC_SUNLIT]++;
            memcpy(nee, fsun, sizeof nee);
          }
        }
        cv_hit hit[GATHER_BATCH];
        int kind[GATHER_BATCH]; /* 0 dead, 1 interior, 2 environment, 3 lost */
        for (int j = 0; j < nb; j++) {
          kind[j] = 0;
          if (!live[j]) continue;
          if (cv_rt_intersect(g->rt, org[j], dir[j], 0, INFINITY, &hit[j])) kind[j] = 1;
          else kind[j] = (!g->has_windows || cv_rt_window_hit(g->rt, org[j], dir[j], 0, &hit[j])) ? 2 : 3;
        }
        for (int j = 0; j < nb; j++) {
          float v[3] = {nee[0], nee[1], nee[2]}, L[3] = {0, 0, 0};
          if (kind[j] == 1) {
            const uint32_t *t = g->tri + 3 * (size_t)hit[j].tri;
            const float *r0 = l->vrad + 3 * (size_t)t[0], *r1 = l->vrad + 3 * (size_t)t[1],
                        *r2 = l->vrad + 3 * (size_t)t[2];
            const float w0 = 1 - hit[j].u - hit[j].v;
            for (int c = 0; c < 3; c++) L[c] = w0 * r0[c] + hit[j].u * r1[c] + hit[j].v * r2[c];
            cnt[CV_LCD_ACC_HITS]++;
          } else if (kind[j] == 2) {
            cv_envmap_lookup(l->env, dir[j], L);
            cnt[CV_LCD_ACC_ENV]++;
          } else if (kind[j] == 3) {
            cnt[CV_LCD_ACC_LOST]++;
          }
          if (kind[j])
            for (int c = 0; c < 3; c++) v[c] += wt[j][c] * L[c];
          add_sample(v, clamp, inv_unit, s, s2, cnt);
        }
      }
      int64_t *q = data + CV_LCD_ACC_HEADER + 3 * aix;
      for (int c = 0; c < 3; c++) q[c] += s[c];
      int64_t *q2 = data + CV_LCD_ACC_HEADER + 3 * (size_t)aw * (size_t)ah + 2 * aix;
      q2[0] += s2[0];
      q2[1] += s2[1];
    }
  }
  for (int i = 0; i < CV_LCD_ACC_HEADER; i++) data[i] += cnt[i];
  data[CV_LCD_ACC_SPP] += spp;
  data[CV_LCD_ACC_ROUNDS] += 1;
  return CV_OK;
}

/* --- content -------------------------------------------------------------- */

static double srgb_decode(double v) {
  return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
}

static void builtin_pattern(cv_image *img) {
  const int w = img->w, h = img->h;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      float *px = cv_image_at(img, x, y);
      double fx = (x + 0.5) / w, fy = (y + 0.5) / h;
      double r = 0.002, g = 0.002, b = 0.002; /* black level */
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

int cv_lcd_content_load(const char *path, int w, int h, double luminance, cv_image **out,
                        cv_err *err) {
  *out = NULL;
  if (w < 1 || h < 1 || !(luminance >= 0) || !isfinite(luminance))
    return cv_err_set(err, CV_ERR_INVALID, "content: size %dx%d, luminance %g", w, h, luminance);
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
    /* box filter: average of a grid of nearest source pixels per texel */
    int gx = (src->w + w - 1) / w, gy = (src->h + h - 1) / h;
    for (int y = 0; y < h; y++)
      for (int x = 0; x < w; x++) {
        double acc[3] = {0, 0, 0};
        for (int j = 0; j < gy; j++)
          for (int i = 0; i < gx; i++) {
            int sx = (int)(((x + (i + 0.5) / gx) / w) * src->w);
            int sy = (int)(((y + (j + 0.5) / gy) / h) * src->h);
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
  for (size_t i = 0; i < n3; i++) img->px[i] = (float)(img->px[i] * luminance);
  *out = img;
  return CV_OK;
}
