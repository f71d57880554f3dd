/* Final gather on the dashboard LCD panel (Dmitriev et al. 2004, section
 * 4.3): for each texel of the panel, the eye ray from the tracked head
 * position gives the view direction; reflected rays are drawn by the
 * tabulated BRDF (brdf_sample.h) and traced ONE bounce: a ray leaving
 * through a window reads the environment (car frame), any other hit reads
 * the PRT exit radiance interpolated from the hit triangle's vertices.  The
 * sun is a uniform disc of the real solar angle (CV_LCD_SUN_HALF_ANGLE_DEG,
 * irradiance sun_E at normal incidence) evaluated on the panel itself
 * (next-event estimation: one shadow ray per texel and round towards a
 * direction drawn uniformly in the disc, from the round's first sample
 * position, its term added to every sample of the round), so it is removed
 * from the environment the rays read.  With next-event estimation off
 * (params.sun = 0, for comparisons) the rays that leave through a window
 * inside the disc read its radiance instead: the plain estimators then find
 * the sun only by chance (clamp: at least pi f_max L_sun to stay unbiased).  The PRT radiance read at
 * interior hits already holds the sun's direct light with ray-traced
 * visibility (cv_prt_relight with a tracer), computed once per lighting
 * state.
 *
 * Three sampling strategies, each with its own Owen-scrambled Sobol
 * sequence per texel, and a fixed number of samples of each per round
 * (multi-sample MIS with the balance heuristic, Veach 1997 sec. 9.2):
 *   b: the BRDF table (brdf_sample.h), n_b samples;
 *   c: the cosine lobe, n_c samples;
 *   w: the window openings (only when the mesh has windows), n_w samples:
 *      cosine-weighted directions restricted to one rectangle per opening
 *      in the panel's projected (Nusselt) disk, the rectangle bounding the
 *      opening's vertices as seen from the texel's block; p_w is exact for
 *      any direction (rectangle membership), so no window crossing is needed
 *      to weigh a sample.
 *   e: the environment map by luminance (light sampling, light/env_sample.h:
 *      a marginal and conditional CDF over the car-frame table, uniform in
 *      each cell, restricted to the cells in front of the panel, rebuilt
 *      from the light's tables in each call that uses it), n_e samples.
 *      With windows, each of 4 x 3 regions of the panel has its own table:
 *      every cell's probability times (V + 0.01) times the luminance of
 *      f cos for the view from the region's centre, V the share of probe
 *      rays from the region that reach the sky through a window in that
 *      cell, softened: half its own value plus half the largest of its
 *      3 x 3 cells (the region's other texels see the sky through gaps
 *      shifted by parallax),
 *      so that the strategy draws about the product L f cos V (12 tables
 *      of 256 x 128 cells a round; the probe rays, 16 per cell of 128 x 64
 *      from 4 points of the region, are traced once per gather by
 *      cv_lcd_gather_create).  p_e is exact
 *      for any direction (the block's region table), and a sample counts
 *      only when its ray leaves through a window.
 *   i: the interior by its exit radiance (interior_fraction): a triangle by
 *      area x mean luminance of vrad x a view factor to the panel centre x
 *      the share of 5 panel points that see its centroid (alias table per
 *      call; the view factors once per gather, by cv_lcd_gather_create),
 *      a point uniform on it; the sample counts only
 *      when that point is the ray's first hit; n_i samples; p_i of a ray
 *      that first hits triangle t at distance r is p_area(t) r^2 / |cos_t|.
 * with n_w = round(window_fraction spp), n_e = round(env_fraction spp),
 * n_i = round(interior_fraction spp) (n_w + n_e + n_i <= spp - 1: n_i, then
 * n_e are cut first), n_b = round(brdf_fraction (spp - n_w - n_e - n_i)),
 * n_c = the rest, and c_s = n_s / spp.  The incident light is split
 * into what the interior returns and what the environment sends through a
 * window, and each part is its own MIS integral: the environment part over
 * b, c, w, e, the interior part over b, c, i (each strategy's weight is 0
 * in the other part, so its samples there add nothing):
 *   L = f cos L_int / (c_b p_b + c_c p_c + c_i p_i)              (interior hit)
 *     = f cos L_env / (c_b p_b + c_c p_c + c_w p_w + c_e p_e)    (through a window)
 *     + f(s, w_o) cos(theta_s) L_sun Omega_sun V(s), s in the disc   (sun, every sample)
 * The sun is a delta light: only next-event estimation can reach it, so it
 * takes no MIS weight.
 * The window and environment strategies put samples where the sky is,
 * which dominates the error under BRDF sampling (the diffuse and haze lobes
 * see it through the windows); the default is e = 0.5 and no window
 * samples (the environment tables already hold the windows' visibility:
 * docs/benchmarks.md, issue 12); BRDF sampling alone is brdf_fraction 1,
 * window_fraction = env_fraction = 0.
 *
 * Determinism: sample j of round r of texel (x, y) is sample j - (first
 * index of its strategy in the round) + r n_s of its strategy's sequence,
 * seeded by (seed, texel, strategy); its value depends on nothing else, and
 * values are summed in fixed point (accum.h), so rounds may be rendered by
 * any contributor in any order.  Each strategy's samples over rounds
 * 0..R-1 are the first R n_s points of its sequence.
 *
 * Tracing: the rays of 16 x 16 texel blocks (aligned to the panel's texel
 * grid) are sorted by direction and traced in coherent packets of 16
 * (cv_rt_intersect_packet); a tile that cuts a block still traces the whole
 * block, so every packet, and hence every texel, is the same whatever the
 * tiling, split or thread count.
 * The view direction is taken at the texel centre (the eye moves less than
 * 0.05 degrees across a 0.5 mm texel seen from 0.6 m); sample positions are
 * jittered over the texel.
 *
 * Nothing here prints; nothing here includes MPI. */
#ifndef CV_LCD_GATHER_H
#define CV_LCD_GATHER_H

#include <stddef.h>
#include <stdint.h>

#include "core/image.h"
#include "core/sobol.h"
#include "io/scene_config.h"
#include "lcd/accum.h"
#include "lcd/brdf_sample.h"
#include "light/env_sample.h"
#include "light/envmap.h"
#include "mesh/mesh.h"
#include "prt/bake.h"
#include "prt/scene_light.h"
#include "rt/rt.h"

/* The panel rectangle: centre, unit axes u (width, towards +X for the
 * cabin), v (height, up) and normal = u x v (towards the occupants). */
typedef struct cv_lcd_panel {
  float center[3], u[3], v[3], normal[3];
  float size[2]; /* metres along u, v */
} cv_lcd_panel;

/* The panel frame from the mesh's CV_MAT_LCD triangles: normal = their
 * area-weighted normal, u = normalize(+Y x normal) (or +X when the panel
 * faces straight up or down), v = normal x u, the rectangle = their bounds
 * in (u, v), centred on the plane through their area-weighted centroid.
 * Errors: CV_ERR_NOT_FOUND (no LCD triangle), CV_ERR_INVALID (degenerate). */
int cv_lcd_panel_from_mesh(const cv_mesh *m, cv_lcd_panel *out, cv_err *err);

/* The lighting state the gather reads, in the car frame. */
typedef struct cv_lcd_light {
  cv_envmap *env;     /* background radiance (sun removed when it is a separate light); owned */
  int has_sun;
  float sun_dir[3];   /* unit, towards the sun */
  float sun_E[3];     /* RGB irradiance at normal incidence */
  float *vrad;        /* 3*nv exit radiance per vertex; owned */
  size_t nv;
  double max_radiance;/* largest env or vertex radiance channel */
  uint64_t vrad_fixed;/* vertex radiance channels that were NaN/Inf or negative, set to 0 */
  uint64_t hash;      /* FNV-1a of env, sun and vrad: the lighting-state key */
  char sun_source[64];/* "sky", "extracted from the environment", "none", ... */
  cv_env_sampler *env_smp; /* luminance sampling tables of env (environment strategy); owned */
} cv_lcd_light;

/* From explicit data (copied): env_car is the car-frame background, vrad
 * 3*nv values (NULL: all zero).  NaN/Inf or negative vrad values are set
 * to 0 and counted (vrad_fixed).
 * Errors: CV_ERR_INVALID, CV_ERR_NONFINITE (sun), CV_ERR_NOMEM. */
int cv_lcd_light_create(const cv_envmap *env_car, const float *vrad, size_t nv, int has_sun,
                        const double sun_dir[3], const double sun_E[3], cv_lcd_light **out);

/* From a scene's lighting: the background is tabulated in the car frame at
 * env_w x env_w/2 from cv_scene_light_background.  For environment maps
 * with a sun split out (spec->kind == CV_LIGHT_ENV, extract_sun) the sun is
 * still in that background: it is extracted again from the table
 * (light/sun.h) so that the table and the directional sun add up to the
 * background exactly; when the table shows no sun, none is used.  For the
 * sky the background has no sun disc and the sky's sun is used as is.  The
 * per-vertex radiance comes from cv_prt_relight(p, tr, sun_samples) (sun
 * direct with ray-traced visibility when tr is non-NULL).  *out owned by the
 * caller.  Errors: CV_ERR_INVALID, CV_ERR_NOMEM, relight errors. */
int cv_lcd_light_from_scene(const cv_scene_light *sl, const cv_light_spec *spec, const cv_prt *p,
                            const cv_tracer *tr, int sun_samples, int env_w, cv_lcd_light **out,
                            cv_err *err);
void cv_lcd_light_destroy(cv_lcd_light *l);

typedef struct cv_lcd_gather cv_lcd_gather;

/* The immutable part: ray tracer (borrowed: built from m, must outlive the
 * gather), the mesh's triangles (copied), the panel frame, the BRDF
 * (borrowed) and its sampling tables (built here, ~13 MB), and the
 * geometry tables of the environment and interior strategies (about 1 M
 * probe rays on all OpenMP threads, 0.1-0.2 s of CPU on the default
 * cabin).  *out owned by
 * the caller.  Errors: CV_ERR_INVALID, CV_ERR_NOMEM. */
int cv_lcd_gather_create(const cv_rt *rt, const cv_mesh *m, const cv_lcd_panel *panel,
                         const cv_brdf *brdf, cv_lcd_gather **out, cv_err *err);
void cv_lcd_gather_destroy(cv_lcd_gather *g);
const cv_brdf_sampler *cv_lcd_gather_sampler(const cv_lcd_gather *g);
const cv_lcd_panel *cv_lcd_gather_panel(const cv_lcd_gather *g);

typedef struct cv_lcd_params {
  int w, h;              /* texels of the whole panel (default 400 x 300) */
  int x0, y0;            /* the accumulation buffer holds the tile of acc->w x acc->h
                            texels starting here (default 0, 0 with a w x h buffer);
                            a tile's texels equal the whole panel's bit for bit */
  int spp;               /* samples per texel per round (default 40) */
  float eye[3];          /* eye position, car frame (from cv_lcd_key_eye) */
  double brdf_fraction;  /* share of the non-window samples drawn from the BRDF table, the rest
                            cosine-weighted (default 0.9; 1 = BRDF sampling, 0 = cosine) */
  double window_fraction;/* share of the samples drawn towards the window openings, in [0, 1)
                            (default CV_LCD_WINDOW_FRACTION; ignored without windows) */
  double env_fraction;   /* share of the samples drawn from the environment map by luminance,
                            in [0, 1), window_fraction + env_fraction < 1 (default
                            CV_LCD_ENV_FRACTION; ignored for a black map) */
  double interior_fraction; /* share of the samples drawn towards the interior by its
                            exit radiance (points on triangles chosen by area x luminance of
                            the PRT radiance), in [0, 1), with window_fraction and env_fraction
                            below 1 (default CV_LCD_INTERIOR_FRACTION; ignored for a black
                            interior) */
  uint32_t seed;         /* sequence seed (default 1) */
  int sun;               /* 1: sun next-event estimation (default 1); 0: the rays read the
                            solar disc (no light sampling of the sun) */
  int threads;           /* OpenMP threads, 0 = OpenMP's default */
  /* Benchmark hook: when non-NULL, the gather ray of sample j of round 0's
   * buffer texel (x, y) is stored at ray_log[6*((y*acc->w + x)*spp + j)]
   * (origin, direction); holds 6*acc->w*acc->h*spp floats. */
  float *ray_log;
  /* Benchmark hook: when non-NULL, the thread CPU seconds of each phase of
   * the round (enum cv_lcd_phase, summed over threads) are ADDED to
   * phase_seconds[0 .. CV_LCD_PHASES-1]; the values the round writes are the
   * same with or without it. */
  double *phase_seconds;
} cv_lcd_params;

/* The phases of a round, as cv_lcd_params.phase_seconds splits its time. */
enum cv_lcd_phase {
  CV_LCD_PHASE_SETUP,    /* per-texel state of each block and the sun's shadow rays */
  CV_LCD_PHASE_GENERATE, /* sample points, directions, densities, sort keys */
  CV_LCD_PHASE_ORDER,    /* the sort by direction and the permutation into that order */
  CV_LCD_PHASE_CLOSEST,  /* closest-hit packets (and copying their hits out) */
  CV_LCD_PHASE_WINDOWS,  /* window-crossing packets of the rays that escaped */
  CV_LCD_PHASE_SHADE,    /* MIS weights, radiance reads, fixed-point sums */
  CV_LCD_PHASES
};

/* The environment strategy's visibility tables made softer and wider, in
 * place: n tables of w x h lat-long cells (row-major, rows from the zenith),
 * each cell set to half its own value plus half the largest value of its
 * 3 x 3 neighbourhood (azimuth wraps around, the rows at the poles do not).
 * A cell keeps its value where it is its neighbourhood's largest, and a
 * cell next to a visible one gets at least half of it.  Used by
 * cv_lcd_gather_create on its probe tables; exposed for tests.
 * Errors: CV_ERR_INVALID (NULL, w or h < 1, n < 0), CV_ERR_NOMEM. */
int cv_lcd_soften_visibility(float *vis, int w, int h, int n);

/* Default window_fraction (measured on the default cabin: docs/benchmarks.md). */
#define CV_LCD_WINDOW_FRACTION 0.0
/* Default env_fraction (measured on the default cabin: docs/benchmarks.md). */
#define CV_LCD_ENV_FRACTION 0.5
/* Default interior_fraction (measured on the default cabin: docs/benchmarks.md). */
#define CV_LCD_INTERIOR_FRACTION 0.0
/* Angular radius of the solar disc (degrees; the sun's mean apparent
 * diameter is 0.533 degrees). */
#define CV_LCD_SUN_HALF_ANGLE_DEG 0.2666
/* Openings (window materials) the window strategy aims at. */
#define CV_LCD_MAX_OPENINGS 16

void cv_lcd_params_default(cv_lcd_params *p);

/* Default clamp of sample values for a lighting state and BRDF: 1e4 x the
 * largest radiance the rays can read, and at least 10 x the largest sun
 * term f_max E_sun (deterministic, never a firefly); 1 for a black scene. */
double cv_lcd_default_clamp(const cv_lcd_light *l, const cv_brdf *b);

/* Fingerprint of what the samples depend on besides eye and lighting. */
uint64_t cv_lcd_setup_hash(const cv_lcd_gather *g, const cv_lcd_params *p, double clamp,
                           double tolerance, uint64_t scene_hash);

/* Renders round `round` (samples round*spp .. round*spp + spp - 1 of every
 * texel of the tile p->x0, p->y0, acc->w x acc->h) and ADDS it to acc (its
 * clamp and unit apply).  A pure function of (g, l, p, round, tile): any
 * split of rounds over calls, threads or processes sums to the same
 * integers.  Errors: CV_ERR_INVALID (sizes, tile outside the panel,
 * spp < 1, light for another mesh, brdf_fraction outside [0, 1],
 * window_fraction or env_fraction outside [0, 1), or their sum >= 1),
 * CV_ERR_RANGE (the buffer would exceed CV_LCD_MAX_SPP or the sample index
 * 2^32). */
int cv_lcd_render_round(const cv_lcd_gather *g, const cv_lcd_light *l, const cv_lcd_params *p,
                        uint32_t round, cv_lcd_accum *acc);

/* --- what the eye sees (for the glare integral, lcd/readability.h) -------- */

/* RGB radiance the eye at `eye` sees along unit `dir`: the environment when
 * the ray leaves through a window (or, in a mesh without windows, escapes),
 * the PRT exit radiance interpolated at the first interior hit, black when
 * it escapes without crossing a window.  Returns 1, with black, when the
 * ray meets the panel rectangle first (the task, which is not glare), else
 * 0.  Thread-safe. */
int cv_lcd_eye_radiance(const cv_lcd_gather *g, const cv_lcd_light *l, const float eye[3],
                        const float dir[3], float rgb[3]);

/* 1 when the light has a sun and the eye sees it (the ray towards it
 * reaches the environment), else 0. */
int cv_lcd_sun_visible(const cv_lcd_gather *g, const cv_lcd_light *l, const float eye[3]);

/* --- panel content ------------------------------------------------------ */

/* The panel's emitted radiance: w x h x 3 linear RGB, content value v in
 * [0, 1] shown as black + v (white - black) cd/m^2 (content white has
 * luminance `white`, content black `black`, the panel's own black level).
 * From an image file (.png: sRGB decoded; .exr: linear, scaled so that its
 * maximum luminance maps to white), box-filtered to w x h and placed with
 * its own aspect on a panel of aspect panel_aspect (width / height in
 * metres; as large as fits, centred, black around it: never stretched;
 * panel_aspect <= 0: filling the panel); or the built-in test pattern (path
 * NULL or ""): a black screen with white text-like bars and a coloured
 * gauge.  Errors name the file. */
int cv_lcd_content_load(const char *path, int w, int h, double panel_aspect, double white,
                        double black, cv_image **out, cv_err *err);

#endif
