/* Image-space choice of SH bands and split window lights (see auto_view.h). */
#include "prt/auto_view.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/pinhole.h"
#include "core/progress.h"

#define NB 8
#define NCOEF (NB * NB)
#define SPLIT_GRID 64
#define SPLIT_SAMPLES 16

void cv_view_cam_driver(cv_view_cam *c) {
  const cv_view_cam d = {{-0.37, 1.02, 0}, {-0.15, 0.65, -1.0}, {0, 1, 0}, 60, 48, 36};
  *c = d;
}

static double lum3(const double *p) { return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]; }

static int cmp_dbl(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

static void residual_fn(const void *ctx, const float d[3], float rgb[3]) {
  cv_scene_light_residual((const cv_scene_light *)ctx, d, rgb);
}

/* Camera rays through the pixel centres (as `cave shade --view`): hit
 * triangle (or UINT32_MAX) and barycentrics per pixel. */
static void cast_pixels(const cv_tracer *tr, const cv_view_cam *c, uint32_t *tri, float *bary) {
  cv_pinhole cam;
  cv_pinhole_init(&cam, c->eye, c->look, c->up, c->fov_deg, c->w, c->h);
  const cv_rt *rt = cv_tracer_rt(tr);
  cv_rt_thread_init();
  for (int y = 0; y < c->h; y++)
    for (int x = 0; x < c->w; x++) {
      const int i = y * c->w + x;
      float d[3], o[3];
      cv_pinhole_ray(&cam, x, y, o, d);
      cv_hit h;
      tri[i] = UINT32_MAX;
      if (cv_rt_intersect(rt, o, d, 0, INFINITY, &h)) {
        tri[i] = h.tri;
        bary[2 * i] = h.u;
        bary[2 * i + 1] = h.v;
      }
    }
}

/* Per-pixel errors of one candidate: prt and truth per pilot vertex (RGB),
 * interpolated at the pixels. */
static void pixel_errors(const cv_mesh *m, const uint32_t *tri, const float *bary, int npx,
                         const int *slot, const double *prt, const double *truth, double *err,
                         cv_view_cand *c) {
  int n = 0;
  double sp = 0, st = 0;
  for (int i = 0; i < npx; i++) {
    if (tri[i] == UINT32_MAX) continue;
    const uint32_t *t = m->tri + 3 * tri[i];
    const double w[3] = {1.0 - bary[2 * i] - bary[2 * i + 1], bary[2 * i], bary[2 * i + 1]};
    double P[3] = {0, 0, 0}, T[3] = {0, 0, 0};
    for (int k = 0; k < 3; k++)
      for (int ch = 0; ch < 3; ch++) {
        P[ch] += w[k] * prt[3 * slot[t[k]] + ch];
        T[ch] += w[k] * truth[3 * slot[t[k]] + ch];
      }
    const double yp = lum3(P), yt = lum3(T);
    if (!(yt > 0)) continue;
    sp += yp, st += yt;
    err[n++] = fabs(yp - yt) / yt;
  }
  qsort(err, (size_t)n, sizeof *err, cmp_dbl);
  c->median = n ? err[n / 2] : NAN;
  c->p90 = n ? err[(int)(0.9 * (n - 1) + 0.5)] : NAN;
  c->mean_ratio = st > 0 ? sp / st : NAN;
}

int cv_auto_view_select(const cv_tracer *tr, cv_scene_light *sl, const cv_view_cam *cam,
                        double budget, int rays, uint32_t seed, int fixed_bands, int fixed_split,
                        cv_view_auto *res, cv_err *err) {
  memset(res, 0, sizeof *res);
  const double t0 = cv_now_seconds();
  if (cam->w < 1 || cam->h < 1 || cam->w * cam->h > 1 << 20 || rays < 1 || !(budget > 0))
    return cv_err_set(err, CV_ERR_RANGE, "auto view: grid %dx%d, %d rays, budget %g", cam->w,
                      cam->h, rays, budget);
  const cv_mesh *m = NULL;
  const size_t nv = cv_tracer_vertex_count(tr);
  const int npx = cam->w * cam->h;
  uint32_t *tri = malloc((size_t)npx * sizeof *tri), *verts = malloc(3 * (size_t)npx * sizeof *verts);
  float *bary = malloc(2 * (size_t)npx * sizeof *bary);
  int *slot = malloc(nv * sizeof *slot);
  float *td = NULL, *frgb = NULL, *alb = NULL, *sun = NULL, *spl = NULL;
  double *truth = NULL, *prt = NULL, *perr = NULL;
  int st = CV_OK;
  if (!tri || !verts || !bary || !slot) goto nomem;
  cast_pixels(tr, cam, tri, bary);
  m = cv_tracer_mesh(tr);
  for (size_t v = 0; v < nv; v++) slot[v] = -1;
  size_t np = 0;
  for (int i = 0; i < npx; i++) {
    if (tri[i] == UINT32_MAX) continue;
    res->pixels++;
    for (int k = 0; k < 3; k++) {
      const uint32_t v = m->tri[3 * tri[i] + k];
      if (slot[v] < 0) {
        slot[v] = (int)np;
        verts[np++] = v;
      }
    }
  }
  if (np == 0) {
    st = cv_err_set(err, CV_ERR_EMPTY, "auto view: no pixel of the view sees geometry");
    goto done;
  }
  res->pilot_vertices = (int)np;
  td = malloc(np * NCOEF * sizeof *td);
  frgb = malloc(3 * np * sizeof *frgb);
  alb = malloc(3 * np * sizeof *alb);
  sun = calloc(3 * np, sizeof *sun);
  spl = malloc(3 * np * sizeof *spl);
  truth = malloc(3 * np * sizeof *truth);
  prt = malloc(3 * np * sizeof *prt);
  perr = malloc((size_t)npx * sizeof *perr);
  if (!td || !frgb || !alb || !sun || !spl || !truth || !prt || !perr) goto nomem;
  const cv_radiance_fn rf = {residual_fn, sl};
  cv_bake_direct_radiance_subset(tr, NB, rays, seed, &rf, verts, np, td, frgb, alb);
  cv_lighting l = cv_scene_light_sh(sl);
  if (l.has_sun && cv_sun_direct_subset(tr, l.sun_dir, l.sun_E, SPLIT_SAMPLES, seed, verts, np, sun))
    goto nomem;
  for (size_t k = 0; k < np; k++)
    for (int c = 0; c < 3; c++) truth[3 * k + c] = (double)alb[3 * k + c] * frgb[3 * k + c] + sun[3 * k + c];
  static const int splits[] = {0, 16, 64};
  int best = -1, lowest = -1;
  for (size_t s = 0; s < sizeof splits / sizeof splits[0]; s++) {
    const int K = fixed_split >= 0 ? fixed_split : splits[s];
    if ((st = cv_scene_light_split(sl, tr, K, SPLIT_GRID, err))) goto done;
    l = cv_scene_light_sh(sl);
    if (l.bands < NB) {
      st = cv_err_set(err, CV_ERR_RANGE, "auto view: the lighting has %d bands, needs %d", l.bands, NB);
      goto done;
    }
    const cv_dir_light *ex;
    const int n_ex = cv_scene_light_extra(sl, &ex);
    memset(spl, 0, 3 * np * sizeof *spl);
    for (int e = 0; e < n_ex; e++)
      if (cv_sun_direct_subset(tr, ex[e].dir, ex[e].E, SPLIT_SAMPLES, seed + 1u + (uint32_t)e, verts,
                               np, spl))
        goto nomem;
    for (int n = 2; n <= NB; n++) {
      if (fixed_bands > 0 && n != fixed_bands) continue;
      if (res->n_cand >= CV_AUTO_VIEW_MAX_CAND) break;
      for (size_t k = 0; k < np; k++)
        for (int c = 0; c < 3; c++) {
          double d = 0;
          for (int i = 0; i < n * n; i++) d += l.sh[3 * i + c] * td[k * NCOEF + i];
          prt[3 * k + c] = alb[3 * k + c] * d + spl[3 * k + c] + sun[3 * k + c];
        }
      cv_view_cand *cd = &res->cand[res->n_cand];
      cd->bands = n;
      cd->split = n_ex;
      cd->cost = 1.0 + 0.03 * n * n + 0.02 * n_ex;
      pixel_errors(m, tri, bary, npx, slot, prt, truth, perr, cd);
      if (cd->median <= budget && cd->p90 <= 3 * budget && (best < 0 || cd->cost < res->cand[best].cost))
        best = res->n_cand;
      if (lowest < 0 || cd->median < res->cand[lowest].median) lowest = res->n_cand;
      res->n_cand++;
    }
    if (fixed_split >= 0) break;
  }
  res->met_budget = best >= 0;
  const cv_view_cand *pick = &res->cand[best >= 0 ? best : lowest];
  res->bands = pick->bands;
  res->split = pick->split;
  res->median = pick->median;
  res->p90 = pick->p90;
  res->mean_ratio = pick->mean_ratio;
  /* Leave sl split as picked. */
  if ((st = cv_scene_light_split(sl, tr, pick->split, SPLIT_GRID, err))) goto done;
  res->seconds = cv_now_seconds() - t0;
  goto done;
nomem:
  st = cv_err_set(err, CV_ERR_NOMEM, "auto view: out of memory");
done:
  free(tri), free(verts), free(bary), free(slot), free(td), free(frgb), free(alb), free(sun);
  free(spl), free(truth), free(prt), free(perr);
  return st;
}
