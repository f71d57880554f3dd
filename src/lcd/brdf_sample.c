/* Sampling tables of a tabulated BRDF (see brdf_sample.h). */
#include "lcd/brdf_sample.h"

#include <stdlib.h>
#include <string.h>

void cv_brdf_sampler_destroy(cv_brdf_sampler *s) {
  if (!s) return;
  free(s->marg);
  free(s->cond);
  free(s->pdf);
  free(s->cos_th);
  free(s->fallback);
  free(s->marg_guide);
  free(s->cond_guide);
  free(s->grey);
  free(s->cs_phi);
  free(s);
}

/* guide[g] = the cell i with cdf[i] <= g/G < cdf[i+1] (n entries, n-1 cells). */
static void build_guide(const float *cdf, int n, uint16_t *guide) {
  int i = 0;
  for (int g = 0; g < CV_BRDF_GUIDE; g++) {
    float u = (float)g / CV_BRDF_GUIDE;
    while (i < n - 2 && cdf[i + 1] <= u) i++;
    guide[g] = (uint16_t)i;
  }
}

int cv_brdf_sampler_create(const cv_brdf *b, cv_brdf_sampler **out) {
  *out = NULL;
  const int nt = b->n_theta, np = b->n_phi, na = nt - 1, nb = np - 1;
  cv_brdf_sampler *s = calloc(1, sizeof *s);
  double *w = malloc((size_t)na * nb * sizeof(double)), *rows = malloc((size_t)na * sizeof(double));
  double *cint = malloc(2 * (size_t)na * sizeof(double));
  if (!s || !w || !rows || !cint) goto nomem;
  s->brdf = b;
  s->nt = nt;
  s->np = np;
  s->inv_dt = (float)(1 / b->d_theta);
  s->inv_dp = (float)(1 / b->d_phi);
  s->marg = malloc((size_t)nt * nt * sizeof(float));
  s->cond = malloc((size_t)nt * na * np * sizeof(float));
  s->pdf = malloc((size_t)nt * na * nb * sizeof(float));
  s->cos_th = malloc((size_t)nt * sizeof(float));
  s->fallback = calloc((size_t)nt, sizeof(int));
  s->marg_guide = malloc((size_t)nt * CV_BRDF_GUIDE * sizeof(uint16_t));
  s->cond_guide = malloc((size_t)nt * na * CV_BRDF_GUIDE * sizeof(uint16_t));
  if (!s->marg || !s->cond || !s->pdf || !s->cos_th || !s->fallback || !s->marg_guide ||
      !s->cond_guide)
    goto nomem;
  for (int a = 0; a < nt; a++) s->cos_th[a] = (float)cos(a * b->d_theta);
  s->cos_th[nt - 1] = 0.0f; /* cos(pi/2) exactly: no sample below the horizon */
  for (int a = 0; a < na; a++) {
    /* exact integral of the interpolant times cos over a cell (one side) */
    cv_brdf_cell_weights(b->d_theta, a, &cint[2 * a], &cint[2 * a + 1]);
    cint[2 * a] *= b->d_phi * 0.5;
    cint[2 * a + 1] *= b->d_phi * 0.5;
  }
  for (int k = 0; k < nt; k++) {
    double total = 0;
    for (int a = 0; a < na; a++) {
      double rs = 0;
      for (int c = 0; c < nb; c++) {
        const float *e00 = cv_brdf_at(b, k, a, c), *e01 = cv_brdf_at(b, k, a, c + 1);
        const float *e10 = cv_brdf_at(b, k, a + 1, c), *e11 = cv_brdf_at(b, k, a + 1, c + 1);
        double m[3];
        for (int ch = 0; ch < 3; ch++)
          m[ch] = cint[2 * a] * ((double)e00[ch] + e01[ch]) +
                  cint[2 * a + 1] * ((double)e10[ch] + e11[ch]);
        double y = 0.2126 * m[0] + 0.7152 * m[1] + 0.0722 * m[2];
        w[(size_t)a * nb + c] = y;
        rs += y;
      }
      rows[a] = rs;
      total += rs;
    }
    if (!(total > 0)) {
      /* f = 0 for this view: cosine-like weights keep a valid distribution */
      s->fallback[k] = 1;
      total = 0;
      for (int a = 0; a < na; a++) {
        double ci = cint[2 * a] + cint[2 * a + 1];
        for (int c = 0; c < nb; c++) w[(size_t)a * nb + c] = ci;
        rows[a] = ci * nb;
        total += rows[a];
      }
    }
    float *mg = s->marg + (size_t)k * nt;
    double acc = 0;
    mg[0] = 0;
    for (int a = 0; a < na; a++) {
      acc += rows[a];
      mg[a + 1] = (float)(acc / total);
    }
    mg[na] = 1.0f;
    for (int a = 0; a < na; a++) {
      float *cd = s->cond + ((size_t)k * na + a) * np;
      cd[0] = 0;
      if (rows[a] > 0) {
        double ca = 0;
        for (int c = 0; c < nb; c++) {
          ca += w[(size_t)a * nb + c];
          cd[c + 1] = (float)(ca / rows[a]);
        }
      } else {
        for (int c = 0; c < nb; c++) cd[c + 1] = (float)((c + 1.0) / nb);
      }
      cd[nb] = 1.0f;
      /* density from the very float CDF steps the inversion walks */
      double pa = (double)mg[a + 1] - (double)mg[a];
      double omega = b->d_phi * ((double)s->cos_th[a] - (double)s->cos_th[a + 1]); /* one side */
      for (int c = 0; c < nb; c++) {
        double pc = (double)cd[c + 1] - (double)cd[c];
        s->pdf[((size_t)k * na + a) * nb + c] = omega > 0 ? (float)(pa * pc / (2 * omega)) : 0.0f;
      }
    }
  }
  s->cs_phi = malloc(2 * (size_t)np * sizeof(float));
  if (!s->cs_phi) goto nomem;
  for (int c = 0; c < np; c++) {
    s->cs_phi[2 * c] = (float)cos(c * b->d_phi);
    s->cs_phi[2 * c + 1] = (float)sin(c * b->d_phi);
  }
  size_t ne = (size_t)nt * nt * np;
  int grey = 1;
  for (size_t i = 0; i < ne && grey; i++) grey = b->f[3 * i] == b->f[3 * i + 1] && b->f[3 * i] == b->f[3 * i + 2];
  if (grey) {
    s->grey = malloc(ne * sizeof(float));
    if (!s->grey) goto nomem;
    for (size_t i = 0; i < ne; i++) s->grey[i] = b->f[3 * i];
  }
  for (int k = 0; k < nt; k++) {
    build_guide(s->marg + (size_t)k * nt, nt, s->marg_guide + (size_t)k * CV_BRDF_GUIDE);
    for (int a = 0; a < na; a++)
      build_guide(s->cond + ((size_t)k * na + a) * np, np,
                  s->cond_guide + ((size_t)k * na + a) * CV_BRDF_GUIDE);
  }
  free(w);
  free(rows);
  free(cint);
  *out = s;
  return CV_OK;
nomem:
  free(w);
  free(rows);
  free(cint);
  cv_brdf_sampler_destroy(s);
  return CV_ERR_NOMEM;
}

/* Index i with cdf[i] <= u < cdf[i+1] over n entries (cdf[0] = 0 <= u <
 * cdf[n-1] = 1), from the guide table's cell for u's bucket (never past
 * the answer, since cdf is non-decreasing). */
static inline int find_interval(const float *cdf, int n, const uint16_t *guide, float u) {
  int i = guide[(int)(u * CV_BRDF_GUIDE)];
  while (i < n - 2 && cdf[i + 1] <= u) i++;
  return i;
}

int cv_brdf_sample(const cv_brdf_sampler *s, int k, float t, const float u[3], float wi[3],
                   float *theta_i, float *phi_d, float *pdf) {
  const int nt = s->nt, np = s->np, na = nt - 1, nb = np - 1;
  int kb = (t > 0 && u[2] < t) ? k + 1 : k;
  const float *mg = s->marg + (size_t)kb * nt;
  int a = find_interval(mg, nt, s->marg_guide + (size_t)kb * CV_BRDF_GUIDE, u[0]);
  float da = mg[a + 1] - mg[a];
  if (!(da > 0)) return 0;
  float r = (u[0] - mg[a]) / da;
  if (r >= 1) r = 0x1.fffffep-1f;
  const float *cd = s->cond + ((size_t)kb * na + a) * np;
  int c = find_interval(cd, np, s->cond_guide + ((size_t)kb * na + a) * CV_BRDF_GUIDE, u[1]);
  float dc = cd[c + 1] - cd[c];
  if (!(dc > 0)) return 0;
  float r2 = (u[1] - cd[c]) / dc;
  if (r2 >= 1) r2 = 0x1.fffffep-1f;
  float side = r2 >= 0.5f ? -1.0f : 1.0f;
  r2 = r2 >= 0.5f ? 2 * r2 - 1 : 2 * r2;
  float ct = s->cos_th[a] - r * (s->cos_th[a] - s->cos_th[a + 1]);
  float st2 = 1 - ct * ct, st = st2 > 0 ? sqrtf(st2) : 0;
  /* phi = phi_c + e, e < one step: angle addition with short series for e
   * (|error| < 1e-9 for steps up to 1 degree) instead of sincosf */
  float e = r2 / s->inv_dp, e2 = e * e;
  float ce = 1 - e2 * (0.5f - e2 * (1.0f / 24)), se = e * (1 - e2 * (1.0f / 6));
  const float *cp = s->cs_phi + 2 * c;
  float ph = ((float)c + r2) / s->inv_dp;
  wi[0] = st * (cp[0] * ce - cp[1] * se);
  wi[1] = side * st * (cp[1] * ce + cp[0] * se);
  wi[2] = ct;
  *theta_i = acosf(ct);
  *phi_d = ph;
  size_t slice = (size_t)na * nb, cell = (size_t)a * nb + (size_t)c;
  float p = (1 - t) * s->pdf[(size_t)k * slice + cell];
  if (t > 0) p += t * s->pdf[(size_t)(k + 1) * slice + cell];
  *pdf = p;
  return p > 0;
}
