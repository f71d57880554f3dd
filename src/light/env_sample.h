/* Importance sampling of a lat-long environment map by luminance (light
 * sampling for the LCD final gather, lcd/gather.h; Pharr, Jakob, Humphreys,
 * PBRT 3rd ed. sec. 13.6.7 and 14.2.4).
 *
 * Cells: blocks of f x f pixels of the map (f the smallest power of two
 * that brings the width to at most CV_ENV_SAMPLE_MAX_W while dividing both
 * sizes: small tables stay in cache), w x h of them (layout of
 * light/envmap.h: u = x / w, v = y / h, theta = pi v from the zenith +Y);
 * cell (x, y) covers u in [x/w, (x+1)/w) and cos(theta) in
 * [cos(pi (y+1)/h), cos(pi y/h)), solid angle
 * Omega_y = (2 pi / w)(cos(pi y/h) - cos(pi (y+1)/h)).  A cell is chosen
 * with probability P(x, y) proportional to the sum over its pixels of
 * Y Omega_pixel (Y the pixel's Rec.709 luminance, negative values counted
 * as 0) by inverting a marginal
 * CDF over rows and a conditional CDF over the row's cells (continuous
 * inversion: a (0,2)-sequence keeps its stratification), and the direction
 * is uniform in (u, cos theta) within the cell: its density is the constant
 * P(x, y) / Omega_y per steradian there, exactly what cv_env_sampler_pdf
 * returns for any direction in the cell.  Cells of zero luminance are never
 * drawn (density 0): an estimator must combine this strategy with one that
 * covers every direction (MIS).
 *
 * The probabilities are the differences of the stored float CDFs, so the
 * sampler and the density agree to float rounding. */
#ifndef CV_LIGHT_ENV_SAMPLE_H
#define CV_LIGHT_ENV_SAMPLE_H

#include <stdint.h>

#include "light/envmap.h"

#define CV_ENV_SAMPLE_MAX_W 256
/* Guide-table buckets per CDF (Chen & Asau 1974): u's bucket brackets the
 * cell, so a draw searches a few cells instead of log2(w) + log2(h)
 * dependent loads over the whole rows. */
#define CV_ENV_GUIDE 64

typedef struct cv_env_sampler {
  int w, h;        /* cells */
  int f;           /* pixels per cell side */
  float *marg;     /* h + 1: CDF over rows, marg[0] = 0, marg[h] = 1 */
  float *cond;     /* h * (w + 1): per-row CDF over its cells */
  float *cos_edge; /* h + 1: cos(pi y / h) */
  float *inv_sa;   /* h: 1 / Omega_y */
  uint16_t *mguide;/* CV_ENV_GUIDE + 1: largest row y with marg[y] <= g / CV_ENV_GUIDE */
  uint16_t *cguide;/* h * (CV_ENV_GUIDE + 1): the same over each row's cond */
  double total;    /* sum of Y Omega over the cells (cd/m^2 sr); 0: a black map */
} cv_env_sampler;

/* Tables for env (read, not kept).  *out owned by the caller.
 * Errors: CV_ERR_INVALID (NULL, w or h < 1 or >= 65536), CV_ERR_NOMEM. */
int cv_env_sampler_create(const cv_envmap *env, cv_env_sampler **out);
void cv_env_sampler_destroy(cv_env_sampler *s);

/* A copy of src restricted to the cells in front of the plane with normal
 * n (a panel's hemisphere): a cell keeps its probability (renormalised) when
 * one of 9 probe directions (corners, edge midpoints, centre) has d.n > 0,
 * else gets 0.  The density stays exact for what is drawn; a cell cut away
 * that reaches the front by a sliver only loses this strategy's samples
 * there (an MIS estimator with a strategy covering every direction stays
 * unbiased).  total = the kept part of src's.  *out owned by the caller.
 * Errors: CV_ERR_INVALID, CV_ERR_NOMEM. */
int cv_env_sampler_restrict(const cv_env_sampler *src, const float n[3], cv_env_sampler **out);

/* A copy of src whose cell probabilities are multiplied by cell_w[y w + x]
 * (w x h weights, >= 0; NaN/Inf/negative count as 0) and renormalised; the
 * density stays exact for what is drawn.  total = src's total x the
 * weighted share (the weights scale it).  *out owned by the caller.
 * Errors: CV_ERR_INVALID, CV_ERR_NOMEM. */
int cv_env_sampler_reweight(const cv_env_sampler *src, const float *cell_w, cv_env_sampler **out);

/* Probability of cell (x, y) (the difference of the stored CDFs). */
double cv_env_sampler_cell_prob(const cv_env_sampler *s, int x, int y);

/* Direction d (unit) from u[0] (across the row: azimuth) and u[1] (over the
 * rows: elevation), both in [0, 1), and its density in 1/sr.  Returns 0
 * (nothing drawn) for a black map. */
int cv_env_sampler_sample(const cv_env_sampler *s, const float u[2], float d[3], float *pdf);

/* Density (1/sr) of direction d (unit) under cv_env_sampler_sample. */
float cv_env_sampler_pdf(const cv_env_sampler *s, const float d[3]);

#endif
