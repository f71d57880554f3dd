/* LCD panel final gather (see gather.h): the panel from its mesh, the gather
 * set-up (window openings, environment visibility and region tables, the
 * panel's view factors), its set-up hash and what the eye sees.  The
 * lighting is in lcd_light.c, the sampling strategies in lcd_strategies.c,
 * one round in lcd_round.c, the content image in lcd_content.c. */
#include "lcd/gather_internal.h"

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

static void env_tables_free(env_tables *t) {
  if (!t) return;
  cv_env_sampler_destroy(t->esr);
  for (int r = 0; r < ENV_RX * ENV_RY; r++) cv_env_sampler_destroy(t->ereg[r]);
  free(t);
}

void lcdg_env_tables_release(const cv_lcd_gather *cg, env_tables *t) {
  if (!t) return;
  cv_lcd_gather *g = (cv_lcd_gather *)cg; /* the cache is not part of the value */
  omp_set_lock(&g->etab_lock);
  const int last = --t->refs == 0;
  omp_unset_lock(&g->etab_lock);
  if (last) env_tables_free(t);
}

/* The tables of (l, eye), from the cache or built (one reference for the
 * caller).  NULL: out of memory. */
env_tables *lcdg_env_tables_get(const cv_lcd_gather *cg, const cv_lcd_light *l, const float eye[3]) {
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
    lcdg_env_tables_release(g, g->etab);
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
