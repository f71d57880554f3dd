/* Benchmark of the LCD panel final gather (issue 5; Dmitriev et al. 2004,
 * section 4.3) on the default cabin under blender-data's forest.exr.
 *
 *   bench_lcd [--tess N] [--env NAME | --sky ELEV,AZIMUTH] [--crop WxH] [--ref-spp N]
 *             [--max-spp N] [--reps N] [--dat FILE] [--speed] [--seed K]
 *
 * --sky: the Preetham sky (turbidity 3) with its sun at that elevation and
 * azimuth (degrees, clockwise from ahead) instead of the map.  Strategies:
 * the gather's mixes (gather.h: BRDF, cosine, window, environment and
 * interior fractions, the sun next-event estimated) and plain cosine
 * sampling (params.sun = 0: no light sampling, the rays find the solar
 * disc; its clamp raised above the disc's f L pi so that it stays
 * unbiased).  With a sun, the samples plain cosine sampling needs to 1%
 * are also computed from the sun term (the disc is too small for a run).
 *
 * 1. Speed: one 400 x 300 round of 40 samples per texel on ONE thread, for
 *    each sampling strategy (median and range of --reps runs, alternating
 *    with the bare loops; thread CPU time, which a loaded machine inflates
 *    less than wall time, and wall time), and the default on all threads.
 * 2. Rays/s next to two bare Embree closest-hit loops over the very rays the
 *    default strategy traced in that round (recorded through the ray_log
 *    hook), one thread: cv_rt_intersect one ray at a time in texel order,
 *    and cv_rt_intersect_packet over the same rays grouped and sorted as the
 *    gather does (16 x 16 texel blocks, by the same direction key, coherent
 *    packets of 16; the sort itself not timed).  Then the default round's
 *    time by phase (gather.h, cv_lcd_params.phase_seconds, in rounds of
 *    their own) and the bound the tracing alone puts on the ratio to the
 *    bare packet loop: the gather's closest-hit and window-crossing packets
 *    against the bare loop, as if everything else took no time.
 * 3. Error: relative RMSE against a reference of --ref-spp samples per
 *    texel (the default strategy, another seed) on a centred crop of the
 *    panel (texels of the full 400 x 300 panel, bit-identical to a full
 *    render), as a function of samples per texel, for each strategy; time =
 *    samples x the per-sample CPU time of step 1 on the whole panel (one
 *    core); samples and time to 1% RMSE.  Defaults: a 16 x 12 crop and
 *    262144 samples per texel: the 16384-sample reference would
 *    itself be about 1% off on this scene (the sky seen through the windows
 *    by the haze and diffuse lobes dominates the variance), too coarse to
 *    measure 1%.
 * --seed K adds K to the seeds of the reference (777) and of the strategies'
 * runs (1): another realisation of every estimate, to see the spread of
 * the ratios.
 * Prints markdown tables; --dat writes gnuplot-ready blocks (one per
 * strategy: spp, seconds, rmse).  --speed: steps 1 and 2 only, for the
 * library's default and the two MIS mixes that were the default before
 * (window 0.5; window 0.25 + env 0.25), then exit (for before/after timing
 * of two builds, alternated). */
#include <math.h>
#include <omp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_util.h"
#include "core/hash.h"
#include "core/progress.h"
#include "lcd/gather.h"
#include "mesh/cabin.h"
#include "mesh/clean.h"
#include "prt/bake.h"
#include "prt/scene_light.h"

#include <time.h>

typedef struct {
  const char *name;
  double c, w, e; /* brdf_fraction, window_fraction, env_fraction */
  int sun;        /* params.sun: 1 next-event estimation, 0 the rays find the solar disc */
  double i;       /* interior_fraction */
} strategy;

#define NSTRAT 12
#define COSINE_STRAT 1
#define PLAIN_COSINE_STRAT 6
static const strategy strategies[NSTRAT] = {
    {"BRDF sampling", 1.0, 0.0, 0.0, 1, 0.0},
    {"cosine sampling", 0.0, 0.0, 0.0, 1, 0.0},
    {"MIS BRDF + cosine (c = 0.9)", 0.9, 0.0, 0.0, 1, 0.0},
    {"MIS BRDF + cosine + window (c = 0.9, w = 0.5)", 0.9, 0.5, 0.0, 1, 0.0},
    {"MIS BRDF + cosine + env (c = 0.9, e = 0.25)", 0.9, 0.0, 0.25, 1, 0.0},
    {"MIS BRDF + cosine + window + env (c = 0.9, w = 0.25, e = 0.25)", 0.9, 0.25, 0.25, 1, 0.0},
    {"plain cosine sampling (no light sampling: the rays find the solar disc)", 0.0, 0.0, 0.0, 0, 0.0},
    {"MIS BRDF + cosine + window + interior (c = 0.9, w = 0.25, i = 0.5)", 0.9, 0.25, 0.0, 1, 0.5},
    {"MIS BRDF + cosine + window + env + interior (c = 0.9, w = 0.2, e = 0.2, i = 0.4)", 0.9, 0.2, 0.2, 1, 0.4},
    {"MIS BRDF + cosine + env (c = 0.9, e = 0.5)", 0.9, 0.0, 0.5, 1, 0.0},
    {"MIS BRDF + window + env (c = 1, w = 0.3, e = 0.4)", 1.0, 0.3, 0.4, 1, 0.0},
    {"MIS BRDF + cosine + env (c = 0.9, e = 0.6)", 0.9, 0.0, 0.6, 1, 0.0}};

/* The row of the library's defaults (cv_lcd_params_default). */
static int default_strategy(void) {
  cv_lcd_params d;
  cv_lcd_params_default(&d);
  for (int s = 0; s < NSTRAT; s++)
    if (strategies[s].c == d.brdf_fraction && strategies[s].w == d.window_fraction &&
        strategies[s].e == d.env_fraction && strategies[s].sun == d.sun &&
        strategies[s].i == d.interior_fraction)
      return s;
  return -1;
}

/* Where the default round's time goes, and the bound that puts on the
 * ratio to the bare packet loop: the gather traces its closest hits and
 * its escaped rays' window crossings whatever its sampling costs. */
static void print_phases(const double *ph, double sum, double t_round, double t_pack, int reps) {
  static const char *names[CV_LCD_PHASES] = {
      "setup (texel state, sun shadow rays)",
      "generate (sample points, directions, densities, sort keys)",
      "order (sort by direction, permutation)",
      "closest-hit packets",
      "window-crossing packets of the escaped rays",
      "shade (MIS weights, radiance reads, fixed-point sums)"};
  printf("### Where the default round's time goes (thread CPU seconds, median of %d rounds timed by "
         "the phase_seconds hook)\n\n| phase | CPU seconds | share |\n|---|---|---|\n",
         reps);
  for (int k = 0; k < CV_LCD_PHASES; k++)
    printf("| %s | %.3f | %.1f%% |\n", names[k], ph[k], 100 * ph[k] / sum);
  printf("| sum of the phases (the round without the hook: %.3f) | %.3f | 100%% |\n\n", t_round, sum);
  const double tr = ph[CV_LCD_PHASE_CLOSEST] + ph[CV_LCD_PHASE_WINDOWS];
  printf("bound on the gather / bare packet loop ratio if setup, generation, ordering and shading "
         "cost nothing: bare packet loop / (closest-hit + window-crossing packets) = %.3f / %.3f = "
         "%.2f; with the window crossings free as well: %.2f\n\n",
         t_pack, tr, t_pack / tr, t_pack / ph[CV_LCD_PHASE_CLOSEST]);
}

/* The strategies step 1 times: all, or with --speed the default and the
 * two MIS mixes that were or are the default (rows 3 and 5). */
static int timed(int s, int default_strat, int speed_only) {
  return !speed_only || s == default_strat || s == 3 || s == 5;
}

static void set_strategy(cv_lcd_params *p, int s) {
  p->brdf_fraction = strategies[s].c;
  p->window_fraction = strategies[s].w;
  p->env_fraction = strategies[s].e;
  p->sun = strategies[s].sun;
  p->interior_fraction = strategies[s].i;
}

/* CPU time of the calling thread (a loaded machine inflates it less than
 * wall time: descheduled time does not count). */
static double cpu_seconds(void) {
  struct timespec t;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static double bare_loop(const cv_rt *rt, const float *org, const float *dir, size_t n,
                        uint64_t *hits) {
  uint64_t h = 0;
  cv_rt_thread_init();
  double t0 = cpu_seconds();
  for (size_t i = 0; i < n; i++) {
    cv_hit hit;
    h += (uint64_t)cv_rt_intersect(rt, org + 3 * i, dir + 3 * i, 0, INFINITY, &hit);
  }
  *hits = h;
  return cpu_seconds() - t0;
}

static double bare_packets(const cv_rt *rt, const float *org, const float *dir, size_t n,
                           uint64_t *hits) {
  uint64_t h = 0;
  cv_hit hit[CV_RT_PACKET_MAX];
  uint8_t found[CV_RT_PACKET_MAX];
  cv_rt_thread_init();
  double t0 = cpu_seconds();
  for (size_t i = 0; i < n; i += CV_RT_PACKET_MAX) {
    int m = n - i < CV_RT_PACKET_MAX ? (int)(n - i) : CV_RT_PACKET_MAX;
    h += (uint64_t)cv_rt_intersect_packet(rt, m, org + 3 * i, dir + 3 * i, NULL, 0, INFINITY, 1,
                                          hit, found);
  }
  *hits = h;
  return cpu_seconds() - t0;
}

/* The gather's direction key (src/lcd/gather.c): octahedral coordinates
 * quantised to 8 bits each, Morton order. */
static uint16_t dir_key(const float d[3]) {
  float s = fabsf(d[0]) + fabsf(d[1]) + fabsf(d[2]);
  float x = d[0] / s, y = d[1] / s;
  if (d[2] < 0) {
    float ox = x;
    x = (1 - fabsf(y)) * (x >= 0 ? 1.0f : -1.0f);
    y = (1 - fabsf(ox)) * (y >= 0 ? 1.0f : -1.0f);
  }
  uint32_t qx = (uint32_t)((x * 0.5f + 0.5f) * 255.0f + 0.5f) & 255;
  uint32_t qy = (uint32_t)((y * 0.5f + 0.5f) * 255.0f + 0.5f) & 255;
  uint32_t k = 0;
  for (int b = 0; b < 8; b++) k |= ((qx >> b) & 1u) << (2 * b) | ((qy >> b) & 1u) << (2 * b + 1);
  return (uint16_t)k;
}

typedef struct {
  uint16_t key;
  uint32_t i;
} keyed;

static int keyed_cmp(const void *a, const void *b) {
  const keyed *x = a, *y = b;
  if (x->key != y->key) return x->key < y->key ? -1 : 1;
  return x->i < y->i ? -1 : x->i > y->i;
}

/* Reorders the logged rays (texel-major, spp per texel, NaN = none) as the
 * gather traces them: per 16 x 16 texel block, stably sorted by key.
 * Writes org/dir (3 floats each) and returns the count. */
static size_t gather_order(const float *log, int W, int H, int S, float *org, float *dir) {
  const int B = 16;
  keyed *k = malloc((size_t)B * B * S * sizeof *k);
  size_t o = 0;
  for (int by = 0; by < H; by += B)
    for (int bx = 0; bx < W; bx += B) {
      size_t n = 0;
      for (int y = by; y < by + B && y < H; y++)
        for (int x = bx; x < bx + B && x < W; x++)
          for (int j = 0; j < S; j++) {
            size_t i = ((size_t)y * W + x) * S + j;
            if (isnan(log[6 * i])) continue;
            k[n].key = dir_key(log + 6 * i + 3);
            k[n++].i = (uint32_t)i;
          }
      qsort(k, n, sizeof *k, keyed_cmp);
      for (size_t q = 0; q < n; q++, o++) {
        memcpy(org + 3 * o, log + 6 * (size_t)k[q].i, 3 * sizeof(float));
        memcpy(dir + 3 * o, log + 6 * (size_t)k[q].i + 3, 3 * sizeof(float));
      }
    }
  free(k);
  return o;
}

static void range(const double *v, int n, double *lo, double *hi) {
  *lo = *hi = v[0];
  for (int i = 1; i < n; i++) *lo = fmin(*lo, v[i]), *hi = fmax(*hi, v[i]);
}

static double rel_rmse(const cv_image *a, const cv_image *ref) {
  double e2 = 0, s = 0;
  size_t n = (size_t)a->w * a->h * 3;
  for (size_t i = 0; i < n; i++) {
    double d = (double)a->px[i] - ref->px[i];
    e2 += d * d;
    s += ref->px[i];
  }
  return s > 0 ? sqrt(e2 / n) / (s / n) : 0;
}

/* Samples per texel where the curve crosses `target` (log-log interpolation;
 * extrapolated with the slope of the last two points when never reached:
 * *extrap = 1). */
static double spp_at(const int *spp, const double *err, int n, double target, int *extrap) {
  *extrap = 0;
  for (int i = 0; i < n; i++)
    if (err[i] <= target) {
      if (i == 0) return spp[0];
      double a = log(err[i - 1]), b = log(err[i]), t = (log(target) - a) / (b - a);
      return exp(log(spp[i - 1]) + t * (log(spp[i]) - log(spp[i - 1])));
    }
  *extrap = 1;
  double slope = (log(err[n - 1]) - log(err[n - 2])) / (log(spp[n - 1]) - log(spp[n - 2]));
  if (!(slope < 0)) return INFINITY;
  return exp(log(spp[n - 1]) + (log(target) - log(err[n - 1])) / slope);
}

int main(int argc, char **argv) {
  int tess = 2, cw = 16, ch = 12, ref_spp = 262144, max_spp = 16384, reps = 3;
  const char *env = "forest.exr", *dat = NULL;
  int speed_only = 0; /* --speed: step 1-2 for the two MIS defaults only, then exit */
  int seed_add = 0;   /* --seed K: added to the reference's and the runs' seeds */
  double sky_el = -1000, sky_az = 0; /* --sky: analytic sky instead of the map */
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--tess") && i + 1 < argc) tess = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--env") && i + 1 < argc) env = argv[++i];
    else if (!strcmp(argv[i], "--sky") && i + 1 < argc) {
      if (sscanf(argv[++i], "%lf,%lf", &sky_el, &sky_az) != 2) cw = 0;
    }
    else if (!strcmp(argv[i], "--crop") && i + 1 < argc) {
      if (sscanf(argv[++i], "%dx%d", &cw, &ch) != 2) cw = 0;
    } else if (!strcmp(argv[i], "--ref-spp") && i + 1 < argc) ref_spp = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--max-spp") && i + 1 < argc) max_spp = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--dat") && i + 1 < argc) dat = argv[++i];
    else if (!strcmp(argv[i], "--speed")) speed_only = 1;
    else if (!strcmp(argv[i], "--seed") && i + 1 < argc) {
      char *end;
      const long v = strtol(argv[++i], &end, 10);
      seed_add = *end || end == argv[i] || v < 0 || v > 1000000 ? -1 : (int)v;
    }
    else {
      fprintf(stderr, "usage: bench_lcd [--tess N] [--env NAME | --sky ELEV,AZIMUTH] [--crop WxH] "
                      "[--ref-spp N] [--max-spp N] [--reps N] [--dat FILE] [--speed] [--seed K]\n");
      return strcmp(argv[i], "--help") ? 2 : 0;
    }
  }
  if (cw < 1 || ch < 1 || cw > 400 || ch > 300 || reps < 1 || reps > 15 || max_spp < 8 ||
      ref_spp < 256 || seed_add < 0 || seed_add > 1000000) {
    fprintf(stderr, "bench_lcd: bad option value\n");
    return 2;
  }
  cv_err err;
  cv_cabin_params cp;
  cv_cabin_default_params(&cp);
  cp.tess = tess;
  cv_cabin_info info;
  cv_mesh *m;
  if (cv_cabin_generate_ex(&cp, &m, &info, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  cv_clean_params clp;
  cv_clean_default_params(&clp);
  cv_clean_report crep;
  if (cv_mesh_clean(m, &clp, &crep, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  cv_tracer *tr;
  if (cv_tracer_create(m, &tr, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  /* The PRT only supplies the radiance rays read at interior hits: a quick
   * bake is enough for timing and error measurements. */
  cv_bake_params bp = {.bands = 3, .rays = 64, .bounces = 1, .seed = 1,
                       .spread = cv_tracer_spread(tr), .quiet = 1};
  cv_prt *prt;
  double t0 = cv_now_seconds();
  if (cv_prt_bake_tracer(tr, &bp, &prt, NULL, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  double t_bake = cv_now_seconds() - t0;
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  if (sky_el > -1000) { /* the Preetham sky with its sun where --sky puts it */
    spec.kind = CV_LIGHT_SKY;
    spec.sun_elevation_deg = sky_el;
    spec.sun_azimuth_deg = sky_az;
  } else {
    spec.kind = CV_LIGHT_ENV;
    spec.n_env = 1;
    spec.weight[0] = 1;
  }
  cv_scene_light *sl;
  cv_lcd_light *light;
  if ((spec.kind == CV_LIGHT_ENV && cv_resolve_env_path(env, NULL, spec.env[0], &err)) ||
      cv_scene_light_build(&spec, (int)prt->bands, &sl, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  t0 = cv_now_seconds();
  if (cv_lcd_light_from_scene(sl, &spec, prt, tr, 16, 1024, &light, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  double t_light = cv_now_seconds() - t0;
  cv_brdf *brdf;
  cv_brdf_report brep;
  cv_lcd_panel panel;
  cv_lcd_gather *g;
  t0 = cv_now_seconds();
  if (cv_brdf_load(CV_BRDF_BUILTIN_ANTIGLARE, &brdf, &brep, &err) ||
      cv_lcd_panel_from_mesh(m, &panel, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  const clock_t c0 = clock(); /* process CPU time: the create traces on all threads */
  const double t1 = cv_now_seconds();
  if (cv_lcd_gather_create(cv_tracer_rt(tr), m, &panel, brdf, &g, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  const double t_create = cv_now_seconds() - t1, c_create = (double)(clock() - c0) / CLOCKS_PER_SEC;
  double t_setup = cv_now_seconds() - t0;
  cv_lcd_params p;
  cv_lcd_params_default(&p);
  memcpy(p.eye, info.eye, sizeof p.eye);
  const double clamp = cv_lcd_default_clamp(light, brdf);
  const int DEFAULT_STRAT = default_strategy();
  if (DEFAULT_STRAT < 0) {
    fprintf(stderr, "bench_lcd: the library's default fractions are not in the strategy list\n");
    return 1;
  }
  const int W = p.w, H = p.h, S = p.spp;

  printf("# LCD panel final gather benchmark\n\n");
  printf("cabin tess %d: %zu triangles, %zu vertices (PRT: %d bands, %d rays, %d bounce, %.1f s); "
         "lighting %s, sun %s; eye %.3f %.3f %.3f; panel %dx%d texels of %.0fx%.0f mm; "
         "built-in anti-glare BRDF (albedo max %.3f); %d threads available\n\n",
         tess, m->nt, m->nv, bp.bands, bp.rays, bp.bounces, t_bake, spec.kind == CV_LIGHT_SKY ? "Preetham sky" : env, light->sun_source,
         p.eye[0], p.eye[1], p.eye[2], W, H, 1000 * panel.size[0], 1000 * panel.size[1],
         brep.albedo_max, omp_get_max_threads());
  printf("per lighting state: relight + background table %.2f s; BRDF table + sampler %.2f s "
         "(of which cv_lcd_gather_create %.2f s wall, %.2f s CPU of all threads: the BRDF sampling "
         "tables and the probe-ray tables)\n\n",
         t_light, t_setup, t_create, c_create);
  /* Where the sun is against the panel: the mirror direction of the eye
   * ray at the panel centre (the coating's haze lobe is around it), in the
   * sky's angles (elevation, azimuth clockwise from ahead, -Z). */
  double clamp_plain = clamp; /* the rays that find the disc must not be clamped */
  {
    float wo[3], r[3];
    for (int k = 0; k < 3; k++) wo[k] = p.eye[k] - panel.center[k];
    float wl = sqrtf(wo[0] * wo[0] + wo[1] * wo[1] + wo[2] * wo[2]);
    for (int k = 0; k < 3; k++) wo[k] /= wl;
    const float c = wo[0] * panel.normal[0] + wo[1] * panel.normal[1] + wo[2] * panel.normal[2];
    for (int k = 0; k < 3; k++) r[k] = 2 * c * panel.normal[k] - wo[k];
    printf("panel centre's mirror direction: elevation %.1f, azimuth %.1f deg", asin(r[1]) * 180 / M_PI,
           atan2(r[0], -r[2]) * 180 / M_PI);
    if (light->has_sun) {
      const float *sd = light->sun_dir;
      const double cs = sd[0] * panel.normal[0] + sd[1] * panel.normal[1] + sd[2] * panel.normal[2];
      const double cm = sd[0] * r[0] + sd[1] * r[1] + sd[2] * r[2];
      const double sa = sin(CV_LCD_SUN_HALF_ANGLE_DEG * M_PI / 180);
      double fmx = 0, lsun = 0;
      for (size_t i = 0; i < (size_t)brdf->n_theta * brdf->n_theta * brdf->n_phi * 3; i++)
        fmx = fmax(fmx, brdf->f[i]);
      for (int k = 0; k < 3; k++) lsun = fmax(lsun, light->sun_E[k] / (M_PI * sa * sa));
      clamp_plain = fmax(clamp, 2 * M_PI * fmx * lsun);
      printf("; sun elevation %.1f, azimuth %.1f deg, %.1f deg from the mirror direction, cos to "
             "the panel normal %.3f, luminance of its E %.4g (disc radiance %.4g)",
             asin(sd[1]) * 180 / M_PI, atan2(sd[0], -sd[2]) * 180 / M_PI,
             acos(fmin(1, fmax(-1, cm))) * 180 / M_PI, cs,
             cv_luminance(light->sun_E[0], light->sun_E[1], light->sun_E[2]), lsun);
    }
    printf("\n\n");
  }

  /* 1 + 2. Speed, and the bare loops over the rays of the default round. */
  cv_lcd_accum *acc;
  if (cv_lcd_accum_create(W, H, clamp, &acc)) return 1;
  size_t nlog = (size_t)W * H * S;
  float *rays = malloc(6 * nlog * sizeof(float));
  float *org = malloc(3 * nlog * sizeof(float)), *dir = malloc(3 * nlog * sizeof(float));
  float *porg = malloc(3 * nlog * sizeof(float)), *pdir = malloc(3 * nlog * sizeof(float));
  if (!rays || !org || !dir || !porg || !pdir) return 1;
  for (size_t i = 0; i < 6 * nlog; i++) rays[i] = NAN;
  p.threads = 1;
  set_strategy(&p, DEFAULT_STRAT);
  p.ray_log = rays;
  cv_lcd_render_round(g, light, &p, 0, acc); /* records the rays; also a warm-up */
  p.ray_log = NULL;
  size_t nvalid = 0;
  for (size_t i = 0; i < nlog; i++)
    if (!isnan(rays[6 * i])) {
      memcpy(org + 3 * nvalid, rays + 6 * i, 3 * sizeof(float));
      memcpy(dir + 3 * nvalid++, rays + 6 * i + 3, 3 * sizeof(float));
    }
  size_t npk = gather_order(rays, W, H, S, porg, pdir);
  free(rays);
  const cv_rt *rt = cv_tracer_rt(tr);
  double t_gather[NSTRAT][15], w_gather[NSTRAT][15], t_bare[15], t_pack[15];
  int64_t cnt[NSTRAT][CV_LCD_ACC_HEADER];
  uint64_t bare_hits = 0, pack_hits = 0, digest[NSTRAT][15];
  for (int r = 0; r < reps; r++) {
    t_bare[r] = bare_loop(rt, org, dir, nvalid, &bare_hits);
    t_pack[r] = bare_packets(rt, porg, pdir, npk, &pack_hits);
    for (int s = 0; s < NSTRAT; s++) {
      if (!timed(s, DEFAULT_STRAT, speed_only)) continue;
      set_strategy(&p, s);
      cv_lcd_accum_clear(acc);
      double w0 = cv_now_seconds();
      t0 = cpu_seconds();
      cv_lcd_render_round(g, light, &p, (uint32_t)r, acc);
      t_gather[s][r] = cpu_seconds() - t0;
      w_gather[s][r] = cv_now_seconds() - w0;
      memcpy(cnt[s], acc->data, sizeof cnt[s]);
      digest[s][r] = cv_hash64(acc->data, acc->n * sizeof(int64_t));
    }
  }
  double tb_lo, tb_hi, tp_lo, tp_hi, tg_lo[NSTRAT], tg_hi[NSTRAT];
  range(t_bare, reps, &tb_lo, &tb_hi);
  range(t_pack, reps, &tp_lo, &tp_hi);
  const double tb = bench_median(t_bare, reps), tpk = bench_median(t_pack, reps);
  double tg[NSTRAT], wg[NSTRAT];
  for (int s = 0; s < NSTRAT; s++) {
    if (!timed(s, DEFAULT_STRAT, speed_only)) {
      tg[s] = wg[s] = tg_lo[s] = tg_hi[s] = 0;
      continue;
    }
    range(t_gather[s], reps, &tg_lo[s], &tg_hi[s]);
    tg[s] = bench_median(t_gather[s], reps);
    wg[s] = bench_median(w_gather[s], reps);
  }
  set_strategy(&p, DEFAULT_STRAT);
  p.threads = 0;
  double t_all[15];
  for (int r = 0; r < reps; r++) {
    cv_lcd_accum_clear(acc);
    t0 = cv_now_seconds();
    cv_lcd_render_round(g, light, &p, (uint32_t)r, acc);
    t_all[r] = cv_now_seconds() - t0;
  }
  double tall = bench_median(t_all, reps);
  /* the default round's phases, in rounds of their own (the hook's clock
   * reads are not in the timed rounds above) */
  double ph_run[CV_LCD_PHASES][15], ph_med[CV_LCD_PHASES], ph_sum = 0;
  p.threads = 1;
  for (int r = 0; r < reps; r++) {
    double ph[CV_LCD_PHASES] = {0};
    cv_lcd_accum_clear(acc);
    p.phase_seconds = ph;
    cv_lcd_render_round(g, light, &p, (uint32_t)r, acc);
    p.phase_seconds = NULL;
    for (int k = 0; k < CV_LCD_PHASES; k++) ph_run[k][r] = ph[k];
  }
  for (int k = 0; k < CV_LCD_PHASES; k++) ph_sum += ph_med[k] = bench_median(ph_run[k], reps);
  const double samples = (double)W * H * S;
  printf("## One %dx%d rough image, %d samples per texel (median [range] of %d; thread CPU "
         "seconds, wall in parentheses)\n\n",
         W, H, S, reps);
  printf("| strategy | threads | CPU seconds | M samples/s | closest-hit rays | + window / shadow "
         "queries | closest-hit M rays/s | vs bare single-ray loop | vs bare packet loop "
         "|\n|---|---|---|---|---|---|---|---|---|\n");
  for (int s = 0; s < NSTRAT; s++) {
    if (!timed(s, DEFAULT_STRAT, speed_only)) continue;
    double nr = (double)(cnt[s][CV_LCD_ACC_HITS] + cnt[s][CV_LCD_ACC_ENV] + cnt[s][CV_LCD_ACC_LOST]);
    double nq = (double)(cnt[s][CV_LCD_ACC_ENV] + cnt[s][CV_LCD_ACC_LOST]) +
                (double)cnt[s][CV_LCD_ACC_SHADOW];
    printf("| %s | 1 | %.3f [%.3f, %.3f] (%.3f) | %.2f | %.0f | %.0f | %.2f | %.2f | %.2f |\n",
           strategies[s].name, tg[s], tg_lo[s], tg_hi[s], wg[s], samples / tg[s] / 1e6, nr, nq,
           nr / tg[s] / 1e6, (nr / tg[s]) / (nvalid / tb), (nr / tg[s]) / (npk / tpk));
  }
  printf("| %s | %d | (%.3f wall) | %.2f | | | | | |\n", strategies[DEFAULT_STRAT].name,
         omp_get_max_threads(), tall, samples / tall / 1e6);
  printf("| bare single-ray loop (cv_rt_intersect, the default round's %zu rays, texel order) | 1 "
         "| %.3f [%.3f, %.3f] | | %zu | | %.2f | 1.00 | |\n",
         nvalid, tb, tb_lo, tb_hi, nvalid, nvalid / tb / 1e6);
  printf("| bare packet loop (cv_rt_intersect_packet, the same rays sorted as the gather sorts "
         "them, coherent packets of %d) | 1 | %.3f [%.3f, %.3f] | | %zu | | %.2f | %.2f | 1.00 "
         "|\n\n",
         CV_RT_PACKET_MAX, tpk, tp_lo, tp_hi, npk, npk / tpk / 1e6, tb / tpk);
  print_phases(ph_med, ph_sum, tg[DEFAULT_STRAT], tpk, reps);
  /* the buffers' FNV-1a digests: two builds that must agree bit for bit
   * print the same */
  printf("buffer digests (round: FNV-1a of the accumulation buffer):");
  for (int s = 0; s < NSTRAT; s++)
    if (timed(s, DEFAULT_STRAT, speed_only))
      for (int r = 0; r < reps && r < 2; r++)
        printf(" s%d r%d %016llx", s, r, (unsigned long long)digest[s][r]);
  printf("\n\n");
  const int64_t *cd = cnt[DEFAULT_STRAT];
  printf("default round: %.1f%% of gather rays hit the interior, %.1f%% left through a window, "
         "%.2f%% lost; sun shadow rays %lld (%lld unblocked); clamped channel values %lld; bare "
         "loops found %llu and %llu hits\n\n",
         100.0 * cd[CV_LCD_ACC_HITS] / nvalid, 100.0 * cd[CV_LCD_ACC_ENV] / nvalid,
         100.0 * cd[CV_LCD_ACC_LOST] / nvalid, (long long)cd[CV_LCD_ACC_SHADOW],
         (long long)cd[CV_LCD_ACC_SUNLIT], (long long)cd[CV_LCD_ACC_CLAMPED],
         (unsigned long long)bare_hits, (unsigned long long)pack_hits);
  free(org);
  free(dir);
  free(porg);
  free(pdir);
  cv_lcd_accum_destroy(acc);
  if (speed_only) return 0;

  /* Where the environment-light samples go, from the panel centre: behind
   * the panel, onto the car body, or out through a window (what limits
   * light sampling here); shares of the samples and of the environment's
   * luminance x solid angle they carry (sum of Y / pdf). */
  {
    enum { NV = 1 << 16 };
    const cv_env_sampler *es = light->env_smp;
    float o[3];
    cv_rt_offset_origin(panel.center, panel.normal, o);
    double cnt_c[3] = {0, 0, 0}, pow_c[3] = {0, 0, 0};
    cv_rt_thread_init();
    for (int i = 0; i < NV && es->total > 0; i++) {
      float u[2] = {((float)i + 0.5f) / NV, 0}, d[3], pdf, rgb[3];
      /* a 2D Hammersley set: the second coordinate by bit reversal */
      uint32_t r = (uint32_t)i;
      r = (r << 16) | (r >> 16);
      r = ((r & 0x00ff00ffu) << 8) | ((r & 0xff00ff00u) >> 8);
      r = ((r & 0x0f0f0f0fu) << 4) | ((r & 0xf0f0f0f0u) >> 4);
      r = ((r & 0x33333333u) << 2) | ((r & 0xccccccccu) >> 2);
      r = ((r & 0x55555555u) << 1) | ((r & 0xaaaaaaaau) >> 1);
      u[1] = (float)(r >> 8) * 0x1p-24f;
      if (!cv_env_sampler_sample(es, u, d, &pdf)) break;
      cv_envmap_lookup(light->env, d, rgb);
      const double y = cv_luminance(rgb[0], rgb[1], rgb[2]) / pdf;
      const int c = d[0] * panel.normal[0] + d[1] * panel.normal[1] + d[2] * panel.normal[2] <= 0
                        ? 0
                        : (cv_rt_reaches_env(rt, o, d, 0) ? 2 : 1);
      cnt_c[c] += 1;
      pow_c[c] += y;
    }
    const double pt = pow_c[0] + pow_c[1] + pow_c[2];
    printf("environment-light samples from the panel centre (%d, %dx%d cells of %dx%d pixels): "
           "%.1f%% behind the panel (%.1f%% of the map's luminance x solid angle), %.1f%% onto the "
           "car body (%.1f%%), %.1f%% out through a window (%.1f%%)\n\n",
           NV, es->w, es->h, es->f, es->f, 100 * cnt_c[0] / NV, 100 * pow_c[0] / pt,
           100 * cnt_c[1] / NV, 100 * pow_c[1] / pt, 100 * cnt_c[2] / NV, 100 * pow_c[2] / pt);
  }

  /* 3. Error against the reference on the crop. */
  cv_lcd_params q = p;
  q.x0 = (W - cw) / 2;
  q.y0 = (H - ch) / 2;
  q.threads = 0;
  set_strategy(&q, DEFAULT_STRAT);
  q.seed = 777 + (uint32_t)seed_add;
  q.spp = 256;
  cv_lcd_accum *ra;
  cv_image *ref;
  if (cv_lcd_accum_create(cw, ch, clamp, &ra)) return 1;
  t0 = cv_now_seconds();
  for (int r = 0; r < ref_spp / q.spp; r++) cv_lcd_render_round(g, light, &q, (uint32_t)r, ra);
  double t_ref = cv_now_seconds() - t0;
  cv_lcd_error rerr;
  cv_lcd_accum_error(ra, &rerr);
  if (cv_lcd_accum_to_image(ra, NULL, &ref)) return 1;
  printf("## Relative RMSE against a reference (crop %dx%d at texel %d,%d; %lld samples per "
         "texel, the default strategy, seed %u: %.1f s on %d threads; its own estimated error "
         "%.3f%%; the strategies' runs seed %u)\n\n",
         cw, ch, q.x0, q.y0, (long long)ra->data[CV_LCD_ACC_SPP], q.seed, t_ref, omp_get_max_threads(),
         100 * rerr.rel_rms, 1 + (unsigned)seed_add);
  printf("RMSE = sqrt(mean over texels and RGB of (L - L_ref)^2) / mean(L_ref); mean reflected "
         "luminance of the crop %.4g; rounds of 16 samples per texel; seconds = samples x the "
         "one-core CPU time per sample of the whole 400x300 panel above.\n\n",
         rerr.mean_luminance);
  enum { MAXP = 32 };
  int spp_pts[NSTRAT][MAXP], npts[NSTRAT] = {0};
  double err_pts[NSTRAT][MAXP];
  FILE *df = dat ? fopen(dat, "w") : NULL;
  if (df)
    fprintf(df, "# bench_lcd: relative RMSE vs samples per texel and one-core seconds for the "
                "400x300 panel\n# columns: spp seconds rmse; one block per strategy\n");
  const int round_spp = 16;
  for (int s = 0; s < NSTRAT; s++) {
    cv_lcd_params e = q;
    e.seed = 1 + (uint32_t)seed_add;
    e.spp = round_spp;
    set_strategy(&e, s);
    cv_lcd_accum *a;
    cv_lcd_accum_create(cw, ch, strategies[s].sun ? clamp : clamp_plain, &a);
    int next = round_spp;
    if (df) fprintf(df, "# %s\n", strategies[s].name);
    for (int r = 0; (r + 1) * round_spp <= max_spp; r++) {
      cv_lcd_render_round(g, light, &e, (uint32_t)r, a);
      int n = (r + 1) * round_spp;
      if (n == next) {
        cv_image *img;
        cv_lcd_accum_to_image(a, NULL, &img);
        double er = rel_rmse(img, ref);
        cv_image_destroy(img);
        spp_pts[s][npts[s]] = n;
        err_pts[s][npts[s]++] = er;
        if (df) fprintf(df, "%d %.6g %.6g\n", n, n * tg[s] / S, er);
        next *= 2;
      }
    }
    if (df) fprintf(df, "\n\n");
    cv_lcd_accum_destroy(a);
  }
  if (df) fclose(df);
  printf("| samples per texel |");
  for (int s = 0; s < NSTRAT; s++) printf(" %s RMSE | seconds |", strategies[s].name);
  printf("\n|---|");
  for (int s = 0; s < NSTRAT; s++) printf("---|---|");
  printf("\n");
  for (int i = 0; i < npts[0]; i++) {
    printf("| %d |", spp_pts[0][i]);
    for (int s = 0; s < NSTRAT; s++)
      printf(" %.3f%% | %.3f |", 100 * err_pts[s][i], spp_pts[s][i] * tg[s] / S);
    printf("\n");
  }
  printf("\n## Time to 1%% RMSE on the default panel (400x300, one core)\n\n");
  printf("| strategy | samples per texel | CPU seconds |\n|---|---|---|\n");
  double n1[NSTRAT];
  for (int s = 0; s < NSTRAT; s++) {
    int ex;
    n1[s] = spp_at(spp_pts[s], err_pts[s], npts[s], 0.01, &ex);
    printf("| %s | %.0f%s | %.2f%s |\n", strategies[s].name, n1[s], ex ? " (extrapolated)" : "",
           n1[s] * tg[s] / S, ex ? " (extrapolated)" : "");
  }
  printf("\n## Samples to 1%% RMSE: cosine sampling's count over each strategy's (same run)\n\n"
         "| strategy | cosine (sun NEE) samples / its samples | plain cosine samples / its samples "
         "|\n|---|---|---|\n");
  for (int s = 0; s < NSTRAT; s++)
    printf("| %s%s | %.2f | %.2f |\n", strategies[s].name, s == DEFAULT_STRAT ? " (default)" : "",
           n1[COSINE_STRAT] / n1[s], n1[PLAIN_COSINE_STRAT] / n1[s]);
  {
    const int d = DEFAULT_STRAT;
    const double nr = (double)(cnt[d][CV_LCD_ACC_HITS] + cnt[d][CV_LCD_ACC_ENV] + cnt[d][CV_LCD_ACC_LOST]);
    printf("\n## The issue's targets, default strategy (%s), this run\n\n"
           "| figure | measured | target |\n|---|---|---|\n"
           "| one %dx%d x %d spp rough image, one core, CPU s | %.3f | <= 1 |\n"
           "| gather closest-hit rays/s over a bare packet loop's, same rays | %.2f | >= 0.7 |\n"
           "| gather closest-hit rays/s over a bare single-ray loop's, same rays | %.2f | |\n"
           "| cosine samples (sun NEE) / default samples to 1%% RMSE | %.2f | |\n"
           "| plain cosine samples (no light sampling) / default samples to 1%% RMSE | %.2f | >= 10 |\n",
           strategies[d].name, W, H, S, tg[d], (nr / tg[d]) / ((double)npk / tpk),
           (nr / tg[d]) / ((double)nvalid / tb), n1[COSINE_STRAT] / n1[d],
           n1[PLAIN_COSINE_STRAT] / n1[d]);
  }
  if (light->has_sun) {
    /* Plain cosine sampling and the solar disc: per texel of the crop, the
     * sun term S_t (next-event estimate, the default strategy, a light with
     * the sun alone) is what a cosine ray finds with probability
     * p = Omega cos(theta_s) / pi when the sun is visible, so the disc alone
     * adds the per-sample variance S_t^2 (1 - p) / p: samples to 1% RMSE
     * >= mean_t(S_t^2 (1 - p) / p) / (0.01 mean(L_ref))^2, a count no
     * run reaches (the measured curve stays at the sun's share). */
    cv_envmap *black;
    cv_lcd_light *ls;
    float *zero = calloc(3 * m->nv + 1, sizeof(float));
    const double sd[3] = {light->sun_dir[0], light->sun_dir[1], light->sun_dir[2]};
    const double sE[3] = {light->sun_E[0], light->sun_E[1], light->sun_E[2]};
    if (!zero || cv_envmap_clone(light->env, &black)) return 1;
    memset(black->img->px, 0, (size_t)black->img->w * black->img->h * 3 * sizeof(float));
    if (cv_lcd_light_create(black, zero, m->nv, 1, sd, sE, &ls)) return 1;
    cv_lcd_accum *sa;
    cv_image *simg;
    cv_lcd_params e = q;
    e.seed = 5;
    set_strategy(&e, DEFAULT_STRAT);
    if (cv_lcd_accum_create(cw, ch, clamp, &sa)) return 1;
    for (int r = 0; r < 16; r++) cv_lcd_render_round(g, ls, &e, (uint32_t)r, sa);
    if (cv_lcd_accum_to_image(sa, NULL, &simg)) return 1;
    const double al = CV_LCD_SUN_HALF_ANGLE_DEG * M_PI / 180, om = 2 * M_PI * (1 - cos(al));
    const double cs = sd[0] * panel.normal[0] + sd[1] * panel.normal[1] + sd[2] * panel.normal[2];
    const double pp = om * cs / M_PI;
    double mu = 0, sm = 0, var = 0;
    const size_t nn = (size_t)cw * ch * 3;
    for (size_t i = 0; i < nn; i++) {
      mu += ref->px[i] / nn;
      sm += simg->px[i] / nn;
      var += pp > 0 ? (double)simg->px[i] * simg->px[i] * (1 - pp) / pp / nn : 0;
    }
    const double n_disc = var / (0.01 * mu) / (0.01 * mu);
    printf("\n## Plain cosine sampling and the solar disc (computed)\n\nsun term %.1f%% of the crop's "
           "mean (%lld of %lld shadow rays unblocked); a cosine ray finds the disc with p = %.3g; "
           "from the disc alone plain cosine sampling needs %.3g samples per texel to 1%% RMSE: "
           "%.3g x the default strategy's %.0f\n",
           mu > 0 ? 100 * sm / mu : 0, (long long)sa->data[CV_LCD_ACC_SUNLIT],
           (long long)sa->data[CV_LCD_ACC_SHADOW], pp, n_disc, n_disc / n1[DEFAULT_STRAT],
           n1[DEFAULT_STRAT]);
    cv_image_destroy(simg);
    cv_lcd_accum_destroy(sa);
    cv_lcd_light_destroy(ls);
    cv_envmap_destroy(black);
    free(zero);
  }
  cv_image_destroy(ref);
  cv_lcd_accum_destroy(ra);
  cv_lcd_gather_destroy(g);
  cv_brdf_destroy(brdf);
  cv_lcd_light_destroy(light);
  cv_scene_light_destroy(sl);
  cv_prt_destroy(prt);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
  return 0;
}
