/* "Model only what the scene needs": picks the SH band count and the rays
 * per vertex that meet a relative error budget at the lowest cost.
 *
 * A pilot bakes the direct transfer of up to 256 vertices spread over the
 * scene at 8 bands with a 16384-ray reference and at 64..4096 rays with
 * another seed, then relights both under the scene's sky (sun split out; a
 * CIE overcast sky when the scene names no lighting).  For each candidate
 * (bands n, rays R) the error is the relative L2 over the pilot vertices of
 * the radiance from n bands and R rays against the 8-band reference: SH
 * truncation and Monte Carlo noise together.  Cost model: R * (1 + 0.03 n^2)
 * (ray cost plus basis evaluation, measured ratio on the default cabin). */
#ifndef CV_PRT_AUTO_H
#define CV_PRT_AUTO_H

#include "prt/bake.h"
#include "prt/relight.h"

#define CV_AUTO_MAX_CAND 64

typedef struct cv_auto_candidate {
  int bands, rays;
  double error, cost;
} cv_auto_candidate;

typedef struct cv_auto_result {
  int bands, rays;          /* the pick */
  double est_error;         /* its estimated relative error */
  int met_budget;           /* 0: nothing met the budget; the most accurate was picked */
  int pilot_vertices;
  int n_cand;
  cv_auto_candidate cand[CV_AUTO_MAX_CAND];
  double seconds;
} cv_auto_result;

/* l may be NULL (CIE overcast sky).  fixed_bands / fixed_rays > 0 pin that
 * parameter.  Returns CV_ERR_EMPTY when no vertex has geometry to sample. */
int cv_prt_auto_select(const cv_tracer *tr, const cv_lighting *l, double budget, uint32_t seed,
                       int fixed_bands, int fixed_rays, cv_auto_result *res);

/* SH of the CIE standard overcast sky L(theta) = (1 + 2 cos theta) / 3
 * (zenith radiance 1, up = +Y, black below the horizon), `bands` bands. */
void cv_lighting_cie_overcast(int bands, cv_lighting *l);

#endif
