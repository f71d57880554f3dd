/* Importance sampling of a tabulated BRDF (brdf.h) with the exact density of
 * what is drawn, and one-sample multiple importance sampling with the
 * cosine lobe (Veach 1997, section 9.2.4, balance heuristic).
 *
 * For every grid view angle theta_o[k] the sampler holds a piecewise-constant
 * 2D distribution over the table's cells (theta_i cell a = [a, a+1] steps,
 * phi_d cell b = [b, b+1] steps): cell weight = luminance of the exact
 * integral of the interpolated f times cos(theta_i) over the cell
 * (cv_brdf_cell_weights).  A draw picks
 * a cell by a marginal CDF over a and a conditional CDF over b (inversion,
 * so the stratification of quasi-random points survives), then a point
 * uniform in solid angle inside the cell (uniform in cos(theta) and phi), and
 * the azimuth side (phi = +phi_d or -phi_d) with probability 1/2 each.  The
 * density of a direction is therefore P(cell) / (2 * solid angle of the cell),
 * computed from the same float CDF values that the inversion uses, so the pdf
 * is that of the samples exactly.
 *
 * A view angle between grid points theta_o = (k + t) * step uses bin k with
 * probability 1 - t and bin k + 1 with probability t: the pdf is the mixture
 * (1 - t) p_k + t p_{k+1}, which is positive wherever the trilinear f is, so
 * BRDF sampling alone is unbiased too.
 *
 * Local frame: z = surface normal, w_o in the x-z plane with x >= 0
 * (phi_o = 0); a sample's phi is then phi_i, and phi_d = |phi_i|. */
#ifndef CV_LCD_BRDF_SAMPLE_H
#define CV_LCD_BRDF_SAMPLE_H

#include <math.h>
#include <stdint.h>

#include "lcd/brdf.h"

/* Guide-table entries per CDF (Chen & Asau's cutpoint method): the
 * inversion starts at the cell that holds u's bucket and walks a step or
 * two, instead of a binary search, a chain of dependent cache misses. */
#define CV_BRDF_GUIDE 64

typedef struct cv_brdf_sampler {
  const cv_brdf *brdf; /* borrowed: must outlive the sampler */
  int nt, np;          /* grid points (cells: nt-1 by np-1) */
  float inv_dt, inv_dp;
  float *marg;   /* [nt][nt]: CDF over theta_i cells (marg[k][0] = 0, [nt-1] = 1) */
  float *cond;   /* [nt][nt-1][np]: CDF over phi cells per theta_i cell */
  float *pdf;    /* [nt][nt-1][np-1]: solid-angle density of each cell (both sides) */
  float *cos_th; /* [nt]: cos of the grid theta values */
  uint16_t *marg_guide; /* [nt][CV_BRDF_GUIDE]: cell holding u = g / CV_BRDF_GUIDE */
  uint16_t *cond_guide; /* [nt][nt-1][CV_BRDF_GUIDE] */
  float *cs_phi; /* [np][2]: cos, sin of the grid phi values */
  float *grey;   /* NULL, or [nt][nt][np] when R = G = B everywhere (a third of the
                    memory traffic per evaluation) */
  int *fallback; /* [nt]: 1 where f was 0 over the whole hemisphere (cosine-like weights used) */
} cv_brdf_sampler;

/* Builds the tables (about 2 x nt^2 x np floats: 13 MB at 1 degree).  *out
 * owned by the caller.  Errors: CV_ERR_NOMEM. */
int cv_brdf_sampler_create(const cv_brdf *b, cv_brdf_sampler **out);
void cv_brdf_sampler_destroy(cv_brdf_sampler *s);

/* The view angle's bins: theta_o (radians) -> k and weight t of bin k + 1. */
static inline void cv_brdf_view_bins(const cv_brdf_sampler *s, float theta_o, int *k, float *t) {
  float x = theta_o * s->inv_dt;
  if (!(x > 0)) x = 0;
  if (x > (float)(s->nt - 1)) x = (float)(s->nt - 1);
  int i = (int)x;
  if (i > s->nt - 2) i = s->nt - 2;
  *k = i;
  *t = x - (float)i;
}

/* Draws w_i (local frame) for view bins (k, t) from u[0..2] in [0,1):
 * u[0], u[1] pick the cell and the point, u[2] picks the bin.  Returns the
 * direction, its cos(theta_i), theta_i and phi_d, and the mixture pdf
 * (1/sr).  Returns 0 when nothing could be drawn (never for valid tables). */
int cv_brdf_sample(const cv_brdf_sampler *s, int k, float t, const float u[3], float wi[3],
                   float *theta_i, float *phi_d, float *pdf);

/* Mixture pdf (1/sr) of drawing local direction angles (theta_i, phi_d) for
 * view bins (k, t); 0 below the horizon. */
static inline float cv_brdf_pdf(const cv_brdf_sampler *s, int k, float t, float theta_i,
                                float phi_d) {
  int a = (int)(theta_i * s->inv_dt), b = (int)(phi_d * s->inv_dp);
  if (a < 0) a = 0;
  if (a > s->nt - 2) a = s->nt - 2;
  if (b < 0) b = 0;
  if (b > s->np - 2) b = s->np - 2;
  size_t slice = (size_t)(s->nt - 1) * (size_t)(s->np - 1);
  size_t c = (size_t)a * (size_t)(s->np - 1) + (size_t)b;
  float p = (1 - t) * s->pdf[(size_t)k * slice + c];
  if (t > 0) p += t * s->pdf[(size_t)(k + 1) * slice + c];
  return p;
}

/* Trilinear f (RGB) for view bins (k, t) at (theta_i, phi_d), radians;
 * equals cv_brdf_eval at theta_o = (k + t) * step. */
static inline void cv_brdf_eval_bins(const cv_brdf_sampler *s, int k, float t, float theta_i,
                                     float phi_d, float rgb[3]) {
  float xi = theta_i * s->inv_dt, xp = phi_d * s->inv_dp;
  if (!(xi > 0)) xi = 0;
  if (!(xp > 0)) xp = 0;
  int ii = (int)xi, ip = (int)xp;
  if (ii > s->nt - 2) ii = s->nt - 2;
  if (ip > s->np - 2) ip = s->np - 2;
  float fi = xi - (float)ii, fp = xp - (float)ip;
  if (fi > 1) fi = 1;
  if (fp > 1) fp = 1;
  const size_t row = (size_t)s->np * 3, slice = (size_t)s->nt * row;
  float w00 = (1 - fi) * (1 - fp), w01 = (1 - fi) * fp, w10 = fi * (1 - fp), w11 = fi * fp;
  if (s->grey) {
    const size_t grow = (size_t)s->np, gslice = (size_t)s->nt * grow;
    const float *q = s->grey + (size_t)k * gslice + (size_t)ii * grow + (size_t)ip;
    float v = w00 * q[0] + w01 * q[1] + w10 * q[grow] + w11 * q[grow + 1];
    if (t > 0) {
      q += gslice;
      v = (1 - t) * v + t * (w00 * q[0] + w01 * q[1] + w10 * q[grow] + w11 * q[grow + 1]);
    }
    rgb[0] = rgb[1] = rgb[2] = v;
    return;
  }
  const float *e = s->brdf->f + (size_t)k * slice + (size_t)ii * row + (size_t)ip * 3;
  for (int c = 0; c < 3; c++)
    rgb[c] = w00 * e[c] + w01 * e[3 + c] + w10 * e[row + c] + w11 * e[row + 3 + c];
  if (t > 0) {
    e += slice;
    for (int c = 0; c < 3; c++)
      rgb[c] = (1 - t) * rgb[c] +
               t * (w00 * e[c] + w01 * e[3 + c] + w10 * e[row + c] + w11 * e[row + 3 + c]);
  }
}

/* Cosine-weighted hemisphere direction from u[0..1]; pdf = cos/pi. */
static inline void cv_cosine_sample(const float u[2], float wi[3]) {
  float r = sqrtf(u[0]), ph = 6.28318530717958647692f * u[1];
  wi[0] = r * cosf(ph);
  wi[1] = r * sinf(ph);
  float z2 = 1 - u[0];
  wi[2] = z2 > 0 ? sqrtf(z2) : 0;
}

#endif
