/* Automatic choice of SH bands and ray count (see auto.h). */
#include "prt/auto.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/progress.h"
#include "sh/sh.h"

void cv_lighting_cie_overcast(int bands, cv_lighting *l) {
  memset(l, 0, sizeof *l);
  l->bands = bands;
  /* Midpoint quadrature in (cos theta, phi); the integrand is smooth apart
   * from the horizon cut, which 512 rows resolve to ~1e-6. */
  const int nt = 512, np = 64;
  double acc[64] = {0};
  for (int a = 0; a < nt; a++) {
    double ct = (a + 0.5) / nt, st = sqrt(1 - ct * ct); /* upper hemisphere only */
    double L = (1 + 2 * ct) / 3, w = 2 * M_PI / ((double)nt * np);
    for (int b = 0; b < np; b++) {
      double ph = 2 * M_PI * (b + 0.5) / np, d[3] = {st * cos(ph), ct, st * sin(ph)}, y[64];
      cv_sh_eval_d(bands, d, y);
      for (int i = 0; i < bands * bands; i++) acc[i] += L * y[i] * w;
    }
  }
  for (int i = 0; i < bands * bands; i++)
    for (int c = 0; c < 3; c++) l->sh[3 * i + c] = acc[i];
}

/* Luminance of the lighting's coefficient i. */
static double lum(const cv_lighting *l, int i) {
  return 0.2126 * l->sh[3 * i] + 0.7152 * l->sh[3 * i + 1] + 0.0722 * l->sh[3 * i + 2];
}

int cv_prt_auto_select(const cv_tracer *tr, const cv_lighting *l, double budget, uint32_t seed,
                       int fixed_bands, int fixed_rays, cv_auto_result *res) {
  memset(res, 0, sizeof *res);
  double t0 = cv_now_seconds();
  cv_lighting sky;
  if (!l || l->bands < 8) {
    cv_lighting_cie_overcast(8, &sky);
    if (l) { /* keep the scene's low bands, fill the rest from nothing */
      memset(sky.sh, 0, sizeof sky.sh);
      memcpy(sky.sh, l->sh, 3 * (size_t)l->bands * l->bands * sizeof(double));
      sky.bands = 8;
    }
    l = &sky;
  }
  /* Pilot vertices: a deterministic spread over those with geometry
   * (a multiplicative stride visits vertices all over the index range). */
  const size_t nv = cv_tracer_vertex_count(tr);
  const size_t want = 256;
  uint32_t *verts = malloc(want * sizeof(uint32_t));
  if (!verts) return CV_ERR_NOMEM;
  size_t np = 0;
  const uint64_t stride = 2654435761ull; /* odd: a permutation mod 2^k, spreads mod nv */
  for (size_t k = 0; k < nv && np < want; k++) {
    uint32_t v = (uint32_t)(((uint64_t)k * stride) % nv);
    if (cv_tracer_fan_size(tr, v) > 0) {
      int dup = 0;
      for (size_t q = 0; q < np; q++) dup |= verts[q] == v;
      if (!dup) verts[np++] = v;
    }
  }
  if (np == 0) {
    free(verts);
    return CV_ERR_EMPTY;
  }
  const int NB = 8, NC = 64, REF_RAYS = 16384;
  float *ref = malloc(np * NC * sizeof(float)), *cur = malloc(np * NC * sizeof(float));
  double *Lref = malloc(np * sizeof(double));
  if (!ref || !cur || !Lref) {
    free(verts);
    free(ref);
    free(cur);
    free(Lref);
    return CV_ERR_NOMEM;
  }
  cv_bake_direct_subset(tr, NB, REF_RAYS, seed ^ 0xA5A5u, verts, np, ref);
  double ref2 = 0;
  for (size_t k = 0; k < np; k++) {
    double s = 0;
    for (int i = 0; i < NC; i++) s += lum(l, i) * ref[k * NC + i];
    Lref[k] = s;
    ref2 += s * s;
  }
  static const int ray_set[] = {64, 128, 256, 512, 1024, 2048, 4096};
  res->pilot_vertices = (int)np;
  int best = -1, most_accurate = -1;
  for (size_t r = 0; r < sizeof ray_set / sizeof ray_set[0]; r++) {
    int R = fixed_rays > 0 ? fixed_rays : ray_set[r];
    cv_bake_direct_subset(tr, NB, R, seed, verts, np, cur);
    for (int n = 2; n <= NB; n++) {
      if (fixed_bands > 0 && n != fixed_bands) continue;
      double e2 = 0;
      for (size_t k = 0; k < np; k++) {
        double s = 0;
        for (int i = 0; i < n * n; i++) s += lum(l, i) * cur[k * NC + i];
        e2 += (s - Lref[k]) * (s - Lref[k]);
      }
      if (res->n_cand >= CV_AUTO_MAX_CAND) break;
      cv_auto_candidate *c = &res->cand[res->n_cand];
      c->bands = n;
      c->rays = R;
      c->error = ref2 > 0 ? sqrt(e2 / ref2) : 0.0;
      c->cost = R * (1.0 + 0.03 * n * n);
      if (c->error <= budget && (best < 0 || c->cost < res->cand[best].cost)) best = res->n_cand;
      if (most_accurate < 0 || c->error < res->cand[most_accurate].error)
        most_accurate = res->n_cand;
      res->n_cand++;
    }
    if (fixed_rays > 0) break;
  }
  res->met_budget = best >= 0;
  int pick = best >= 0 ? best : most_accurate;
  res->bands = res->cand[pick].bands;
  res->rays = res->cand[pick].rays;
  res->est_error = res->cand[pick].error;
  res->seconds = cv_now_seconds() - t0;
  free(verts);
  free(ref);
  free(cur);
  free(Lref);
  return CV_OK;
}
