/* The bake's sampling context (see tracer.h). */
#include "prt/tracer.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "prt/tracer_internal.h"

void cv_tracer_destroy(cv_tracer *tr) {
  if (!tr) return;
  cv_rt_destroy(tr->rt);
  cv_mesh_destroy(tr->m);
  free(tr->tri_n);
  free(tr->fan_off);
  free(tr->fan_tri);
  free(tr->fan_cdf);
  free(tr->win_tri);
  free(tr->win_cdf);
  free(tr->groups);
  free(tr->tri_group);
  free(tr);
}

static int is_window(const cv_mesh *m, size_t t) {
  return (m->mats[m->tri_mat[t]].flags & CV_MAT_WINDOW) != 0;
}

int cv_tracer_create(const cv_mesh *m, cv_tracer **out, cv_err *err) {
  *out = NULL;
  cv_tracer *tr = calloc(1, sizeof *tr);
  if (!tr) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  int st = cv_mesh_clone(m, &tr->m);
  if (!st) st = cv_rt_create(m, &tr->rt, err);
  if (st) {
    cv_tracer_destroy(tr);
    return st == CV_ERR_NOMEM ? cv_err_set(err, st, "out of memory") : st;
  }
  size_t nv = m->nv, nt = m->nt;
  cv_sobol_tab_init(&tr->sobol);
  tr->spread = CV_BAKE_DEFAULT_SPREAD;
  cv_tracer_set_simd(tr, 1);
  tr->tri_n = malloc(3 * nt * sizeof(float));
  tr->fan_off = calloc(nv + 1, sizeof(size_t));
  double *area = malloc(nt * sizeof(double));
  if (!tr->tri_n || !tr->fan_off || !area) goto nomem;
  size_t total = 0;
  for (size_t t = 0; t < nt; t++) {
    float n[3];
    cv_mesh_tri_normal(m, t, n);
    double l = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
    area[t] = 0.5 * l;
    for (int k = 0; k < 3; k++) tr->tri_n[3 * t + k] = l > 0 ? (float)(n[k] / l) : 0.0f;
    if (is_window(m, t) || l <= 0) continue;
    for (int j = 0; j < 3; j++) tr->fan_off[m->tri[3 * t + j] + 1]++;
    total += 3;
  }
  for (size_t v = 0; v < nv; v++) tr->fan_off[v + 1] += tr->fan_off[v];
  tr->fan_tri = malloc((total + 1) * sizeof(uint32_t));
  tr->fan_cdf = malloc((total + 1) * sizeof(float));
  size_t *fill = malloc((nv + 1) * sizeof(size_t));
  if (!tr->fan_tri || !tr->fan_cdf || !fill) {
    free(fill);
    goto nomem;
  }
  memcpy(fill, tr->fan_off, (nv + 1) * sizeof(size_t));
  for (size_t t = 0; t < nt; t++) {
    if (is_window(m, t) || area[t] <= 0) continue;
    for (uint32_t j = 0; j < 3; j++) {
      uint32_t v = m->tri[3 * t + j];
      tr->fan_tri[fill[v]++] = (uint32_t)(t << 2) | j;
    }
  }
  free(fill);
  for (size_t v = 0; v < nv; v++) {
    double sum = 0;
    for (size_t k = tr->fan_off[v]; k < tr->fan_off[v + 1]; k++) sum += area[tr->fan_tri[k] >> 2];
    double acc = 0;
    for (size_t k = tr->fan_off[v]; k < tr->fan_off[v + 1]; k++) {
      acc += area[tr->fan_tri[k] >> 2];
      tr->fan_cdf[k] = (float)(acc / sum);
    }
    if (tr->fan_off[v + 1] > tr->fan_off[v]) tr->fan_cdf[tr->fan_off[v + 1] - 1] = 1.0f;
  }
  /* Window triangles grouped by material, by area within each group. */
  tr->window_mis = 1;
  tr->win_tri = malloc((nt + 1) * sizeof(uint32_t));
  tr->win_cdf = malloc((nt + 1) * sizeof(float));
  tr->groups = calloc(m->nm + 1, sizeof *tr->groups);
  tr->tri_group = malloc((nt + 1) * sizeof(int));
  if (!tr->win_tri || !tr->win_cdf || !tr->groups || !tr->tri_group) goto nomem;
  for (size_t t = 0; t < nt; t++) tr->tri_group[t] = -1;
  for (size_t mi = 0; mi < m->nm; mi++) {
    if (!(m->mats[mi].flags & CV_MAT_WINDOW)) continue;
    struct win_group *g = &tr->groups[tr->ngroup];
    memset(g, 0, sizeof *g);
    g->begin = tr->nwin;
    for (size_t t = 0; t < nt; t++) {
      if (m->tri_mat[t] != mi || !(area[t] > 0)) continue;
      const uint32_t *tv = m->tri + 3 * t;
      for (int k = 0; k < 3; k++) {
        double c = ((double)m->pos[3 * tv[0] + k] + m->pos[3 * tv[1] + k] + m->pos[3 * tv[2] + k]) / 3;
        g->centroid[k] += area[t] * c;
        g->normal[k] += area[t] * tr->tri_n[3 * t + k];
      }
      g->area += area[t];
      tr->win_tri[tr->nwin] = (uint32_t)t;
      tr->win_cdf[tr->nwin++] = (float)g->area;
      tr->tri_group[t] = tr->ngroup;
    }
    g->end = tr->nwin;
    if (g->end == g->begin) continue;
    double nl = 0;
    for (int k = 0; k < 3; k++) {
      g->centroid[k] /= g->area;
      nl += g->normal[k] * g->normal[k];
    }
    for (int k = 0; k < 3; k++) g->normal[k] = nl > 0 ? g->normal[k] / sqrt(nl) : 0;
    for (size_t k = g->begin; k < g->end; k++) tr->win_cdf[k] = (float)(tr->win_cdf[k] / g->area);
    tr->win_cdf[g->end - 1] = 1.0f;
    tr->win_area += g->area;
    tr->ngroup++;
  }
  free(area);
  *out = tr;
  return CV_OK;
nomem:
  free(area);
  cv_tracer_destroy(tr);
  return cv_err_set(err, CV_ERR_NOMEM, "out of memory building vertex fans");
}

const cv_rt *cv_tracer_rt(const cv_tracer *tr) { return tr->rt; }

int cv_tracer_set_spread(cv_tracer *tr, float spread) {
  if (!(spread >= 0.0f && spread <= 1.0f)) return CV_ERR_RANGE;
  tr->spread = spread;
  return CV_OK;
}

float cv_tracer_spread(const cv_tracer *tr) { return tr->spread; }

void cv_tracer_set_window_sampling(cv_tracer *tr, int on) { tr->window_mis = !!on; }
int cv_tracer_window_sampling(const cv_tracer *tr) { return tr->window_mis && tr->nwin > 0; }

const cv_mesh *cv_tracer_mesh(const cv_tracer *tr) { return tr->m; }

size_t cv_tracer_vertex_count(const cv_tracer *tr) { return tr->m->nv; }

uint32_t cv_tracer_bake_vertex(const cv_tracer *tr, size_t i) { return (uint32_t)i; }

int cv_tracer_fan_size(const cv_tracer *tr, uint32_t v) {
  return (int)(tr->fan_off[v + 1] - tr->fan_off[v]);
}

int cv_tracer_sample(const cv_tracer *tr, uint32_t v, uint32_t j, uint32_t seed, float org[3],
                     float dir[3], uint32_t *tri) {
  if (tr->fan_off[v + 1] == tr->fan_off[v]) return 0;
  vseq q;
  vseq_init(&q, seed, v);
  uint32_t t = sample_ray(tr, v, j, &q, org, dir);
  if (tri) *tri = t;
  return 1;
}

/* The bounce pass's sums (bake.c) take AVX2 + F16C when asked for and the
 * CPU has both. */
int cv_tracer_set_simd(cv_tracer *tr, int on) {
#ifdef CV_BAKE_X86_SIMD
  tr->simd = on && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("f16c");
#else
  (void)on;
  tr->simd = 0;
#endif
  return tr->simd;
}
