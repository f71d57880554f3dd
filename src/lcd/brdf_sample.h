/* Importance sampling of a tabulated BRDF (brdf.h) with the exact density of
 * what is drawn, and one-sample multiple importance sampling with the
 * cosine lobe (Veach 1997, section 9.2.4, balance heuristic).
 *
 * The sampled density is the table itself, interpolated continuously: for
 * a grid view angle theta_o[k], let Y(theta_i, phi_d) be the luminance of f
 * on the grid, and interpolate it bilinearly in (x, phi_d) with
 * x = sin^2(theta_i) (the projected-solid-angle coordinate: d x d phi =
 * 2 cos(theta_i) d omega).  The density in (x, phi_i) is then g / (2 M) with
 * g that interpolant and M its integral over one azimuth side, so in solid
 * angle
 *     p(w_i) = g(x, phi_d) cos(theta_i) / M,
 * which is f cos(theta_i) / albedo up to the difference between
 * interpolating in theta_i (f, brdf.h) and in sin^2(theta_i) (p): the weight
 * f cos / p = M f / g is nearly constant over the hemisphere.  p is
 * continuous everywhere (no jump at cell edges).
 *
 * A draw from u = (u0, u1) in [0,1)^2 inverts the marginal and conditional
 * of this density exactly (Rosenblatt transform), continuously and
 * monotonically, so the stratification of quasi-random points survives:
 *   - u0 picks the theta_i cell a by the cumulative row masses
 *     M(a) = sum over cells below a of dx (S_a + S_a+1) / 2 (S = the
 *     trapezoid integral of a grid row over phi_d), and the remainder picks
 *     x inside the cell from the linear density (1 - s) S_a + s S_a+1;
 *   - u1 picks the azimuth: |2 u1 - 1| runs from the retro-reflection side
 *     (phi_d = 0) to the mirror side (phi_d = pi, at u1 = 1/2) along the
 *     row interpolated at s (piecewise linear in phi_d, inverted cell by
 *     cell with linear densities); u1 < 1/2 gives phi_i = -phi_d, u1 >= 1/2
 *     phi_i = +phi_d.  The fold sits on the mirror plane, where both sides
 *     meet continuously, so no lobe is cut in two.
 * Each step is inverted in float from float tables; the density returned is
 * the product of the probabilities that the float tables give (row step of
 * M, conditional step, linear densities), so it is that of the samples
 * exactly, whatever the rounding of the cumulative sums.
 *
 * A view angle between grid points theta_o = (k + t) * step uses the mixture
 * (1 - t) Y_k + t Y_k+1 of the two slices (un-normalised, so that it is the
 * trilinear f's own luminance along the view): every table above is linear
 * in Y, so the mixed tables are mixtures of the stored ones, read on the fly
 * (no discrete choice of the slice, which would spend a sample dimension and
 * break the stratification).  p is positive wherever the trilinear f is.
 *
 * Local frame: z = surface normal, w_o in the x-z plane with x >= 0
 * (phi_o = 0); a sample's phi is then phi_i, and phi_d = |phi_i|. */
#ifndef CV_LCD_BRDF_SAMPLE_H
#define CV_LCD_BRDF_SAMPLE_H

#include <math.h>
#include <stdint.h>

#include "core/fast_trig.h"
#include "lcd/brdf.h"

/* Guide-table buckets per CDF (Chen & Asau's cutpoint method): a search
 * starts from the cell that holds u's bucket in the nearest stored row and
 * only walks the few cells where the mixed row differs, instead of a binary
 * search over the whole row (a chain of dependent loads). */
#define CV_BRDF_GUIDE 64

typedef struct cv_brdf_sampler {
  const cv_brdf *brdf; /* borrowed: must outlive the sampler */
  int nt, np;          /* grid points (cells: nt-1 by np-1) */
  float inv_dt, inv_dp, dp;
  float *lum;    /* [nt][nt][np]: luminance of f on the grid (theta_o, theta_i, phi_d) */
  float *ccum;   /* [nt][nt][np]: trapezoid cumulative integral of lum over phi_d along
                    each grid row (ccum[..][0] = 0, [np-1] = the row integral S) */
  float *mcum;   /* [nt][nt]: cumulative one-side mass over theta_i cells (mcum[k][0] = 0) */
  float *xg;     /* [nt]: sin^2 of the grid theta */
  float *dx;     /* [nt-1]: xg[a+1] - xg[a] */
  float *cs_phi; /* [np][2]: cos, sin of the grid phi values */
  float *cs_th;  /* [nt][2]: cos, sin of the grid theta values */
  uint16_t *mguide; /* [nt][CV_BRDF_GUIDE + 1]: largest theta cell with mcum <= g/G of the total */
  uint16_t *cguide; /* [nt][nt][CV_BRDF_GUIDE + 1]: the same over phi cells of each grid row */
  int grey;      /* 1 when R = G = B everywhere: lum is then f itself (a third of the
                    memory traffic per evaluation) */
} cv_brdf_sampler;

/* Builds the tables (2 nt^2 np floats: 12 MB at 1 degree).  *out owned by
 * the caller.  Errors: CV_ERR_NOMEM. */
int cv_brdf_sampler_create(const cv_brdf *b, cv_brdf_sampler **out);
void cv_brdf_sampler_destroy(cv_brdf_sampler *s);

/* The view angle's bins: theta_o (radians) -> k and weight t of slice k + 1. */
static inline void cv_brdf_view_bins(const cv_brdf_sampler *s, float theta_o, int *k, float *t) {
  float x = theta_o * s->inv_dt;
  if (!(x > 0)) x = 0;
  if (x > (float)(s->nt - 1)) x = (float)(s->nt - 1);
  int i = (int)x;
  if (i > s->nt - 2) i = s->nt - 2;
  *k = i;
  *t = x - (float)i;
}

/* Draws w_i (local frame) for view bins (k, t) from u[0..1] in [0,1).
 * Returns the direction (wi[2] = cos(theta_i)), theta_i, phi_d, the
 * solid-angle pdf (1/sr) and, when f_rgb is not NULL, the trilinear f
 * there (as cv_brdf_eval_bins).  Returns 0 when nothing can be drawn
 * (f = 0 over the whole hemisphere for this view, or a zero-density edge). */
int cv_brdf_sample(const cv_brdf_sampler *s, int k, float t, const float u[2], float wi[3],
                   float *theta_i, float *phi_d, float *pdf, float f_rgb[3]);

/* Solid-angle pdf (1/sr) of drawing the local direction with polar angle
 * theta_i (cos_i = cos(theta_i), sin2_i = sin^2(theta_i), both given so
 * that callers holding a direction avoid the trigonometry) and azimuth
 * difference phi_d, for view bins (k, t); 0 below the horizon. */
float cv_brdf_pdf_cs(const cv_brdf_sampler *s, int k, float t, float cos_i, float sin2_i,
                     float theta_i, float phi_d);
/* The same from the angles (radians). */
static inline float cv_brdf_pdf(const cv_brdf_sampler *s, int k, float t, float theta_i,
                                float phi_d) {
  float st = sinf(theta_i);
  return cv_brdf_pdf_cs(s, k, t, cosf(theta_i), st * st, theta_i, phi_d);
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
    const float *q = s->lum + (size_t)k * gslice + (size_t)ii * grow + (size_t)ip;
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
  float r = sqrtf(u[0]), sp, cp;
  cv_fast_sincos2pi(u[1], &sp, &cp); /* 2 pi u[1], within 1e-7 (core/fast_trig.h) */
  wi[0] = r * cp;
  wi[1] = r * sp;
  float z2 = 1 - u[0];
  wi[2] = z2 > 0 ? sqrtf(z2) : 0;
}

#endif
