/* The PRT bake (Dmitriev et al. 2004, section 4.1, equation 6).
 *
 * Sampling: for vertex v and sample j, an Owen-scrambled Sobol point picks a
 * triangle of v's fan (probability proportional to area) and a point p in it
 * with density proportional to v's barycentric weight (the "hat" function of
 * v), then a cosine-weighted direction about that triangle's normal.  This
 * is the paper's section 4.1.1: rays start at stochastic points inside the
 * triangles and each sample counts for a vertex by its distance weight, so a
 * vertex slightly covered by an overlapping triangle does not go black.
 * Sampling the hat density instead of weighting uniform points gives every
 * vertex exactly `rays` rays and makes each vertex's result depend only on
 * its own samples: deterministic for any thread count.
 *
 * Pass 0 (direct): V = 1 iff the ray leaves through a window (rt.h).  When
 * the scene has windows, directions are drawn by multiple importance
 * sampling of the cosine lobe and the window area (balance heuristic).
 * Pass b >= 1: the ray's closest opaque hit q reads the bounce b-1 exit
 * transfer interpolated from q's triangle vertices (RGB, albedo applied). */
#ifndef CV_PRT_BAKE_H
#define CV_PRT_BAKE_H

#include <stdint.h>

#include "mesh/mesh.h"
#include "prt/prt.h"
#include "rt/rt.h"

#include "prt/tracer.h"

/* Largest per-channel ratio of successive bounces the tail estimate accepts
 * (a tail of r / (1 - r) = 9 times the last bounce). */
#define CV_BAKE_TAIL_MAX_RATIO 0.9

typedef struct cv_bake_params {
  int bands;      /* SH bands, 2..8 */
  int rays;       /* rays per vertex per pass, >= 1 */
  int bounces;    /* interreflection bounces, 0..16 */
  uint32_t seed;
  float spread;   /* 0..1, see CV_BAKE_DEFAULT_SPREAD */
  int cosine_only;/* 1: direct pass without window importance sampling */
  int tail;       /* 1: add the geometric tail of the bounces after the last one
                     (cv_prt_tail_ratio); no effect with bounces = 0 */
  int quiet;      /* 1: no progress bar */
} cv_bake_params;

typedef struct cv_bake_stats {
  double seconds[17];   /* per pass: 0 = direct, b = bounce b */
  uint64_t rays[17];    /* rays traced per pass (direct counts 1 or 2 queries as 1 ray) */
  double total_seconds;
  uint64_t total_rays;
  uint64_t empty_fans;  /* vertices with no opaque triangle (transfer 0) */
  double tail_ratio[3]; /* with tail: the per-channel ratio r used (else 0) */
  int tail_clamped;     /* with tail: 1 if a ratio was clamped to [0, CV_BAKE_TAIL_MAX_RATIO] */
} cv_bake_stats;

/* Direct (visibility) transfer of the listed vertices: out[k*n*n + i].
 * Used by the auto mode and the benchmark on vertex subsets. */
int cv_bake_direct_subset(const cv_tracer *tr, int bands, int rays, uint32_t seed,
                          const uint32_t *verts, size_t count, float *out);

/* The previous bounce's exit transfer as the bounce passes read it: per
 * vertex 3*n*n values stored as half floats relative to a float scale (the
 * record's largest |value|), i.e. rounded to 2^-12 of that value; 3 cache
 * lines per 25-coefficient record instead of 5-6 (docs/benchmarks.md). */
typedef struct cv_bounce_records cv_bounce_records;
/* Zeroed records for nv vertices of `bands` bands; CV_ERR_RANGE / NOMEM. */
int cv_bounce_records_create(int bands, size_t nv, cv_bounce_records **out);
void cv_bounce_records_destroy(cv_bounce_records *r);
/* Stores / reads back vertex v's 3*n*n values (layout [c][i]; finite). */
void cv_bounce_records_set(cv_bounce_records *r, size_t v, const float *val);
void cv_bounce_records_get(const cv_bounce_records *r, size_t v, float *val);

/* One bounce pass of the listed vertices from the previous bounce's records
 * (all vertices): out[k*3*n*n + c*n*n + i], as the full pass computes it
 * (without a texture's albedo split).  Used by the benchmark. */
int cv_bake_bounce_subset(const cv_tracer *tr, int bands, int rays, uint32_t seed,
                          const cv_bounce_records *prev, const uint32_t *verts, size_t count,
                          float *out);

/* Radiance arriving from unit direction d (car frame), RGB; called from
 * several threads at once. */
typedef struct cv_radiance_fn {
  void (*fn)(const void *ctx, const float d[3], float rgb[3]);
  const void *ctx;
} cv_radiance_fn;

/* The direct pass's estimator on the listed vertices, with the same rays
 * giving both the SH transfer td (count x bands^2, as cv_bake_direct_subset)
 * and, for rf's radiance, rgb (3 per vertex) = (1/pi) integral L V cos dw:
 * the all-frequency direct light that td's SH lighting approximates (the
 * two share their Monte Carlo noise).  alb_out (3 per vertex): the fan's
 * hat-weighted material albedo. */
int cv_bake_direct_radiance_subset(const cv_tracer *tr, int bands, int rays, uint32_t seed,
                                   const cv_radiance_fn *rf, const uint32_t *verts, size_t count,
                                   float *td, float *rgb, float *alb_out);

/* Full bake; *out owned by the caller.  With cv_prt_bake_tracer the
 * tracer's spread must equal p->spread.  meta.input_hash is set from
 * cv_prt_input_hash.  Prints a progress bar to stderr unless p->quiet. */
int cv_prt_bake(const cv_mesh *m, const cv_bake_params *p, cv_prt **out, cv_bake_stats *stats,
                cv_err *err);
/* Same on an existing tracer (the mesh it was built from). */
int cv_prt_bake_tracer(const cv_tracer *tr, const cv_bake_params *p, cv_prt **out,
                       cv_bake_stats *stats, cv_err *err);

/* Interreflection passes from a given bounce-0 exit transfer prev
 * ([v][c][i], RGB, albedo applied; overwritten with the last bounce) into ti
 * (same layout, accumulated: ti += bounces 1..B); bounces read the previous
 * one through cv_bounce_records (half floats).  The bake calls this after
 * its direct pass; tests seed it with a known transfer (furnace). */
int cv_prt_propagate(const cv_tracer *tr, int bands, int rays, uint32_t seed, int bounces,
                     int quiet, float *prev, float *ti, cv_bake_stats *stats);

/* The bounces a bake leaves out, estimated as a geometric series: with
 * `before` and `last` the exit transfers of the last two bounces ([v][c][i],
 * albedo applied), ratio[c] = sum_v A_v last[v][c][0] / sum_v A_v before[v][c][0]
 * (A_v a third of v's opaque fan area; DC coefficients = the response to a
 * constant sky), clamped to [0, CV_BAKE_TAIL_MAX_RATIO]; bounce B + k is
 * taken as ratio^k times bounce B, so the tail is last * r / (1 - r).
 * Returns 1 if a ratio was clamped. */
int cv_prt_tail_ratio(const cv_tracer *tr, int bands, const float *before, const float *last,
                      double ratio[3]);

/* Fingerprint of everything a bake depends on: mesh geometry, materials,
 * parameters and the format version. */
uint64_t cv_prt_input_hash(const cv_mesh *m, const cv_bake_params *p);

/* Checks bake parameters; err names the offending field. */
int cv_bake_params_validate(const cv_bake_params *p, cv_err *err);

/* Direct sun light at every vertex with exact (ray-traced) visibility through
 * the windows: out_rgb[3v+c] += E_c/pi * mean over `samples` fan points of
 * albedo_c(t) * max(0, n_t.s) * V(p, s).  sun_dir points towards the sun in
 * the car frame; E is the sun's RGB irradiance at normal incidence. */
int cv_sun_direct(const cv_tracer *tr, const double sun_dir[3], const double E[3], int samples,
                  uint32_t seed, float *out_rgb);

/* cv_sun_direct on the listed vertices only: out_rgb[3k+c] += vertex
 * verts[k]'s direct light (same samples and result as the full call). */
int cv_sun_direct_subset(const cv_tracer *tr, const double sun_dir[3], const double E[3],
                         int samples, uint32_t seed, const uint32_t *verts, size_t count,
                         float *out_rgb);

#endif
