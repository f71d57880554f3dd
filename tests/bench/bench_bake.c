/* Benchmark of the PRT bake on the default cabin (speed against error).
 *
 *   bench_bake [--tess N] [--subset V] [--bake-rays R] [--bounces B] [--skip-full]
 *              [--skip-error] [--skip-direct] [--portable] [--csv FILE]
 *
 * --portable: the bounce pass sums hits without AVX2 / F16C (same bits).
 *
 * 1. Throughput: the bake's direct and bounce passes on a vertex subset, next
 *    to a bare Embree loop tracing the SAME rays (pre-generated, so the bare
 *    loop pays only for rtcOccluded1 / rtcIntersect1), measured in this run;
 *    likewise a bounce pass (runs of neighbouring vertices, as the full bake
 *    visits them) next to a bare rtcIntersect1 loop over its very rays.
 * 2. The full bake (25 coefficients, R rays, B bounces) of the whole cabin.
 * 3. Error: direct transfer of the subset for SH bands 2..6 and 256..4096
 *    rays against a 16384-ray bake of the same vertices (mean over vertices
 *    of |T - T_ref| / |T_ref|, L2 over the coefficients), and the relit
 *    radiance under blender-data's forest.exr (sun split out, as the renderer
 *    does), mean relative error over lit vertices.
 * Prints markdown tables (docs/benchmarks.md). */
#include <math.h>

#include "bench_util.h"
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "core/progress.h"
#include "mesh/cabin.h"
#include "mesh/clean.h"
#include "prt/bake.h"
#include "prt/scene_light.h"

static double bare_loop(const cv_tracer *tr, const float *org, const float *dir, size_t n,
                        int intersect, uint64_t *hits) {
  const cv_rt *rt = cv_tracer_rt(tr);
  uint64_t h = 0;
  double t0 = cv_now_seconds();
#pragma omp parallel reduction(+ : h)
  {
    cv_rt_thread_init();
#pragma omp for schedule(dynamic, 4096)
    for (size_t i = 0; i < n; i++) {
      if (intersect) {
        cv_hit hit;
        h += (uint64_t)cv_rt_intersect(rt, org + 3 * i, dir + 3 * i, 0, INFINITY, &hit);
      } else {
        h += (uint64_t)cv_rt_reaches_env(rt, org + 3 * i, dir + 3 * i, 0);
      }
    }
  }
  *hits = h;
  return cv_now_seconds() - t0;
}

/* Relative errors of cur against ref over the first nco of NC coefficients
 * per vertex: mean of the per-vertex relative L2 (vertices with a non-zero
 * reference) and the energy-weighted sqrt(sum |d|^2 / sum |ref|^2). */
static void transfer_error(const float *cur, const float *ref, size_t ns, int NC, int nco,
                           double *per_vertex, double *global) {
  double sum = 0, ge2 = 0, gr2 = 0;
  size_t cnt = 0;
  for (size_t k = 0; k < ns; k++) {
    double e2 = 0, r2 = 0;
    for (int i = 0; i < nco; i++) {
      double d = cur[k * NC + i] - ref[k * NC + i];
      e2 += d * d;
      r2 += (double)ref[k * NC + i] * ref[k * NC + i];
    }
    ge2 += e2;
    gr2 += r2;
    if (r2 > 1e-12) {
      sum += sqrt(e2 / r2);
      cnt++;
    }
  }
  *per_vertex = cnt ? sum / cnt : 0.0;
  *global = gr2 > 0 ? sqrt(ge2 / gr2) : 0.0;
}

/* The bare loop with rays j0..j0+15 of each vertex (R per vertex) as one
 * rtcIntersect16 packet, the packets the bounce pass traces. */
static double bare_packet_loop(const cv_tracer *tr, const float *org, const float *dir, size_t nverts,
                               int R) {
  const cv_rt *rt = cv_tracer_rt(tr);
  double t0 = cv_now_seconds();
#pragma omp parallel
  {
    cv_rt_thread_init();
#pragma omp for schedule(dynamic, 1)
    for (size_t k = 0; k < nverts; k++)
      for (int j0 = 0; j0 < R; j0 += 16) {
        cv_hit hit[16];
        uint8_t found[16];
        size_t i = k * (size_t)R + (size_t)j0;
        cv_rt_intersect_packet(rt, R - j0 < 16 ? R - j0 : 16, org + 3 * i, dir + 3 * i, NULL, 0,
                               INFINITY, 0, hit, found);
      }
  }
  return cv_now_seconds() - t0;
}

/* CPU seconds used by the whole process (all threads). */
static double cpu_seconds(void) {
  struct timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* Bounce pass (25 coefficients, RGB) against a bare closest-hit loop over the
 * very same rays, alternated run by run REPS times in this run.  The vertices
 * are runs of RUN neighbours in the bake's visiting order spread over the
 * mesh, so the previous bounce's records are read with the locality of the
 * full pass; the previous bounce is synthetic (its values do not change the
 * work).  Wall and CPU-second ratios: the machine is shared, and CPU seconds
 * are what the load does not stretch. */
static void bounce_throughput(const cv_tracer *tr, const cv_mesh *m, int subset, int R) {
  enum { REPS = 5, RUN = 256, BANDS = 5, REC = 3 * BANDS * BANDS };
  const size_t nv = cv_tracer_vertex_count(tr);
  size_t runs = (size_t)subset / RUN > 0 ? (size_t)subset / RUN : 1, ns = 0;
  uint32_t *verts = malloc(runs * RUN * sizeof(uint32_t));
  size_t *run_at = calloc(runs + 1, sizeof(size_t)); /* first index in verts of each run */
  for (size_t r = 0; r < runs; r++) {
    size_t first = nv > RUN ? (nv - RUN) * r / (runs > 1 ? runs - 1 : 1) : 0;
    run_at[r] = ns;
    for (size_t i = first; i < first + RUN && i < nv; i++) {
      uint32_t v = cv_tracer_bake_vertex(tr, i);
      if (cv_tracer_fan_size(tr, v) > 0) verts[ns++] = v;
    }
  }
  run_at[runs] = ns;
  size_t nr = ns * (size_t)R;
  float *org = malloc(3 * nr * sizeof(float)), *dir = malloc(3 * nr * sizeof(float));
  uint32_t *from = malloc(nr * sizeof(uint32_t));
  float *prev = malloc(nv * REC * sizeof(float)), *out = malloc(ns * REC * sizeof(float));
  uint32_t x = 12345u;
  for (size_t i = 0; i < nv * REC; i++) {
    x ^= x << 13, x ^= x >> 17, x ^= x << 5;
    prev[i] = (float)(x >> 8) * (0.5f / 16777216.0f);
  }
  cv_bounce_records *recs;
  if (cv_bounce_records_create(BANDS, nv, &recs)) {
    fprintf(stderr, "out of memory\n");
    exit(1);
  }
  for (size_t v = 0; v < nv; v++) cv_bounce_records_set(recs, v, prev + v * REC);
  for (size_t k = 0; k < ns; k++)
    for (int j = 0; j < R; j++)
      cv_tracer_sample(tr, verts[k], (uint32_t)j, 1, org + 3 * (k * R + j), dir + 3 * (k * R + j),
                       from + k * R + j);
  uint64_t hits = 0, h;
  double bare[REPS], bounce[REPS], bare_cpu[REPS], bounce_cpu[REPS], packet[REPS];
  cv_bake_bounce_subset(tr, BANDS, R / 8 > 0 ? R / 8 : 1, 1, recs, verts, ns, out); /* warm up */
  for (int k = 0; k < REPS; k++) {
    bare[k] = bounce[k] = bare_cpu[k] = bounce_cpu[k] = packet[k] = 0;
    hits = 0;
    for (size_t r = 0; r < runs; r++) {
      size_t a = run_at[r], n = run_at[r + 1] - a;
      double c0 = cpu_seconds();
      bare[k] += bare_loop(tr, org + 3 * a * R, dir + 3 * a * R, n * R, 1, &h);
      double c1 = cpu_seconds(), t0 = cv_now_seconds();
      hits += h;
      cv_bake_bounce_subset(tr, BANDS, R, 1, recs, verts + a, n, out + a * REC);
      bounce[k] += cv_now_seconds() - t0;
      bounce_cpu[k] += cpu_seconds() - c1;
      bare_cpu[k] += c1 - c0;
      packet[k] += bare_packet_loop(tr, org + 3 * a * R, dir + 3 * a * R, n, R);
    }
  }
  double check = 0;
  for (size_t i = 0; i < ns * REC; i++) check += out[i];
  /* Brute force from the float values over the same rays: the error of the
   * bake's records (and a check of its pipelined pass). */
  double e2 = 0, r2 = 0, worst = 0;
  for (size_t k = 0; k < ns; k++) {
    double ref[REC] = {0}, ve2 = 0, vr2 = 0;
    for (int j = 0; j < R; j++) {
      cv_hit hit;
      size_t i = k * R + j;
      if (!cv_rt_intersect(cv_tracer_rt(tr), org + 3 * i, dir + 3 * i, 0, INFINITY, &hit)) continue;
      const uint32_t *tv = m->tri + 3 * hit.tri;
      const float *al = m->mats[m->tri_mat[from[i]]].albedo;
      double w[3] = {1.0 - hit.u - hit.v, hit.u, hit.v};
      for (int c = 0; c < 3; c++)
        for (int q = 0; q < REC / 3; q++) {
          double s = 0;
          for (int t = 0; t < 3; t++) s += w[t] * prev[(size_t)tv[t] * REC + c * (REC / 3) + q];
          ref[c * (REC / 3) + q] += al[c] * s / R;
        }
    }
    for (int i = 0; i < REC; i++) {
      double d = out[k * REC + i] - ref[i];
      ve2 += d * d;
      vr2 += ref[i] * ref[i];
    }
    e2 += ve2;
    r2 += vr2;
    if (vr2 > 0 && sqrt(ve2 / vr2) > worst) worst = sqrt(ve2 / vr2);
  }
  double ratio[REPS], ratio_cpu[REPS];
  for (int k = 0; k < REPS; k++) {
    ratio[k] = bare[k] / bounce[k];
    ratio_cpu[k] = bare_cpu[k] / bounce_cpu[k];
  }
  printf("## Bounce pass, %zu vertices (%zu runs of %d neighbours) x %d rays = %.1f M rays, %.1f%% hit "
         "(same rays in both; median of %d alternating runs)\n\n", ns, runs, RUN, R, nr / 1e6,
         100.0 * hits / nr, REPS);
  printf("| loop | seconds | M rays/s | ratio to bare |\n|---|---|---|---|\n");
  double tb = bench_median(bare, REPS), tp = bench_median(bounce, REPS),
         tk = bench_median(packet, REPS);
  printf("| bare Embree closest hit (rtcIntersect1) | %.3f | %.2f | 1.00 |\n", tb, nr / tb / 1e6);
  printf("| bare Embree closest hit, the bounce pass's rtcIntersect16 packets | %.3f | %.2f | %.2f |\n",
         tk, nr / tk / 1e6, tb / tk);
  printf("| bake bounce pass (sampling, rtcIntersect16 packets of a vertex's rays, %d-value half records of 3 vertices, RGB sums) | %.3f | "
         "%.2f | **%.2f** |\n\n", REC, tp, nr / tp / 1e6, tb / tp);
  printf("bounce ratio per run (bare / bounce), wall:");
  for (int k = 0; k < REPS; k++) printf(" %.2f", ratio[k]);
  printf("; CPU seconds:");
  for (int k = 0; k < REPS; k++) printf(" %.2f", ratio_cpu[k]);
  printf(", median %.2f; checksum of the bounce output %.9e\n\n", bench_median(ratio_cpu, REPS), check);
  printf("bounce output against a brute-force float sum over the same rays: relative L2 %.2e, "
         "worst vertex %.2e\n\n", r2 > 0 ? sqrt(e2 / r2) : 0.0, worst);
  free(org);
  free(dir);
  free(prev);
  free(from);
  cv_bounce_records_destroy(recs);
  free(out);
  free(verts);
  free(run_at);
}

int main(int argc, char **argv) {
  int tess = 8, subset = 4000, bake_rays = 1024, bounces = 2, skip_full = 0, skip_error = 0,
      skip_direct = 0, portable = 0;
  const char *csv_path = NULL;
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--tess") && i + 1 < argc) tess = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--subset") && i + 1 < argc) subset = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--bake-rays") && i + 1 < argc) bake_rays = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--bounces") && i + 1 < argc) bounces = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--skip-full")) skip_full = 1;
    else if (!strcmp(argv[i], "--skip-error")) skip_error = 1;
    else if (!strcmp(argv[i], "--skip-direct")) skip_direct = 1;
    else if (!strcmp(argv[i], "--portable")) portable = 1;
    else if (!strcmp(argv[i], "--csv") && i + 1 < argc) csv_path = argv[++i];
    else {
      fprintf(stderr,
              "usage: bench_bake [--tess N] [--subset V] [--bake-rays R] [--bounces B] [--skip-full]\n"
              "                  [--skip-error] [--skip-direct] [--portable] [--csv FILE]\n");
      return strcmp(argv[i], "--help") ? 2 : 0;
    }
  }
  cv_cabin_params cp;
  cv_cabin_default_params(&cp);
  cp.tess = tess;
  cv_mesh *m;
  cv_err err;
  if (cv_cabin_generate(&cp, &m, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  cv_clean_params clp;
  cv_clean_default_params(&clp);
  cv_clean_report rep;
  cv_mesh_clean(m, &clp, &rep, &err);
  printf("# PRT bake benchmark\n\ncabin tess %d: %zu triangles, %zu vertices; %d threads\n\n", tess,
         m->nt, m->nv, omp_get_max_threads());
  double t0 = cv_now_seconds();
  cv_tracer *tr;
  if (cv_tracer_create(m, &tr, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  printf("BVH build + fans: %.2f s; bounce sums: %s\n\n", cv_now_seconds() - t0,
         cv_tracer_set_simd(tr, !portable) ? "AVX2 + F16C" : "portable");

  /* Subset: every k-th vertex with geometry. */
  size_t nv = m->nv, ns = 0;
  uint32_t *verts = malloc(nv * sizeof(uint32_t));
  size_t step = nv / (size_t)subset > 0 ? nv / (size_t)subset : 1;
  for (size_t v = 0; v < nv && ns < (size_t)subset; v += step)
    if (cv_tracer_fan_size(tr, (uint32_t)v) > 0) verts[ns++] = (uint32_t)v;

  /* 1. Throughput against the bare loop, same rays. */
  const int R = bake_rays;
  size_t nr = ns * (size_t)R;
  double t_bare_isect = 0;
  float *out = malloc(ns * 64 * sizeof(float));
  if (!skip_direct) {
    float *org = malloc(3 * nr * sizeof(float)), *dir = malloc(3 * nr * sizeof(float));
    for (size_t k = 0; k < ns; k++)
      for (int j = 0; j < R; j++)
        cv_tracer_sample(tr, verts[k], (uint32_t)j, 1, org + 3 * (k * R + j), dir + 3 * (k * R + j), NULL);
    /* Alternate the loops REPS times and keep medians: the machine is shared. */
    enum { REPS = 5 };
    uint64_t hits;
    bare_loop(tr, org, dir, nr / 8, 0, &hits); /* warm up */
    double occ[REPS], isect[REPS], direct[REPS];
    double mis_t[REPS];
    for (int k = 0; k < REPS; k++) {
      occ[k] = bare_loop(tr, org, dir, nr, 0, &hits);
      cv_tracer_set_window_sampling(tr, 0); /* the very rays of the bare loop */
      t0 = cv_now_seconds();
      cv_bake_direct_subset(tr, 5, R, 1, verts, ns, out);
      direct[k] = cv_now_seconds() - t0;
      cv_tracer_set_window_sampling(tr, 1);
      t0 = cv_now_seconds();
      cv_bake_direct_subset(tr, 5, R, 1, verts, ns, out);
      mis_t[k] = cv_now_seconds() - t0;
      isect[k] = bare_loop(tr, org, dir, nr, 1, &hits);
    }
    double t_mis = bench_median(mis_t, REPS);
    bare_loop(tr, org, dir, nr, 0, &hits);
    double esc = (double)hits / nr;
    double t_bare_occ = bench_median(occ, REPS), t_direct = bench_median(direct, REPS);
    t_bare_isect = bench_median(isect, REPS);
    printf("## Throughput, %zu vertices x %d rays = %.1f M rays (same rays in both; median of %d "
           "alternating runs)\n\n", ns, R, nr / 1e6, REPS);
    printf("| loop | seconds | M rays/s | ratio to bare |\n|---|---|---|---|\n");
    printf("| bare Embree occlusion (window rule: 1-2 rtcOccluded1 per ray, %.1f%% escape) | %.3f | %.2f | 1.00 |\n",
           100 * esc, t_bare_occ, nr / t_bare_occ / 1e6);
    printf("| bake direct pass, cosine sampling (sampling + SH 25 + window rule) | %.3f | %.2f | %.2f |\n",
           t_direct, nr / t_direct / 1e6, t_bare_occ / t_direct);
    printf("| bake direct pass, window MIS (default; +32 pilot rays per vertex, more rays escape) | %.3f | %.2f | %.2f |\n",
           t_mis, nr / t_mis / 1e6, t_bare_occ / t_mis);
    printf("| bare Embree closest hit (rtcIntersect1) | %.3f | %.2f | - |\n\n", t_bare_isect,
           nr / t_bare_isect / 1e6);
    free(org);
    free(dir);
  }
  bounce_throughput(tr, m, subset, R);

  /* 2. Full bake. */
  if (!skip_full) {
    cv_bake_params bp = {.bands = 5, .rays = R, .bounces = bounces, .seed = 1, .spread = cv_tracer_spread(tr), .quiet = 1};
    cv_bake_stats bs;
    cv_prt *prt;
    if (cv_prt_bake_tracer(tr, &bp, &prt, &bs, &err)) {
      fprintf(stderr, "%s\n", err.msg);
      return 1;
    }
    printf("## Full bake: 25 coefficients, %d rays, %d bounces\n\n", R, bounces);
    printf("| pass | seconds | M rays/s |\n|---|---|---|\n");
    for (int b = 0; b <= bounces; b++)
      printf("| %s %d | %.2f | %.2f |\n", b ? "bounce" : "direct", b, bs.seconds[b],
             bs.rays[b] / bs.seconds[b] / 1e6);
    printf("| total | %.2f | %.2f |\n\n", bs.total_seconds, bs.total_rays / bs.total_seconds / 1e6);
    if (t_bare_isect > 0 && bounces > 0)
      printf("bounce 1 of the full bake over the direct section's bare closest-hit rate (minutes "
             "apart): %.2f\n\n", (bs.rays[1] / bs.seconds[1]) / (nr / t_bare_isect));
    cv_prt_destroy(prt);
  }

  if (skip_error) {
    free(out);
    free(verts);
    cv_tracer_destroy(tr);
    cv_mesh_destroy(m);
    return 0;
  }
  /* 3. Error against a 16384-ray reference. */
  const int NB = 6, NC = 36, REF = 16384;
  float *ref = malloc(ns * NC * sizeof(float)), *cur = malloc(ns * NC * sizeof(float));
  t0 = cv_now_seconds();
  cv_bake_direct_subset(tr, NB, REF, 777, verts, ns, ref);
  printf("reference: %zu vertices x %d rays in %.1f s\n\n", ns, REF, cv_now_seconds() - t0);
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  spec.kind = CV_LIGHT_ENV;
  spec.n_env = 1;
  spec.weight[0] = 1;
  int have_forest = cv_resolve_env_path("forest.exr", NULL, spec.env[0], &err) == CV_OK;
  cv_scene_light *sl = NULL;
  cv_lighting l;
  if (have_forest && cv_scene_light_build(&spec, NB, &sl, &err) == CV_OK) l = cv_scene_light_sh(sl);
  else have_forest = 0;
  static const int rays[] = {256, 512, 1024, 2048, 4096};
  /* Cosine-only at the same ray counts, 5 bands, against the same reference. */
  printf("## Cosine sampling against window MIS, 5 bands (per-vertex mean / energy-weighted)\n\n");
  printf("| rays | cosine: seconds | cosine: error | MIS: seconds | MIS: error |\n|---|---|---|---|---|\n");
  for (size_t r = 0; r < sizeof rays / sizeof rays[0]; r++) {
    double secs[2], pv[2], gl[2];
    for (int mode = 0; mode < 2; mode++) {
      cv_tracer_set_window_sampling(tr, mode);
      t0 = cv_now_seconds();
      cv_bake_direct_subset(tr, NB, rays[r], 1, verts, ns, cur);
      secs[mode] = cv_now_seconds() - t0;
      transfer_error(cur, ref, ns, NC, 25, &pv[mode], &gl[mode]);
    }
    printf("| %d | %.2f | %.2f%% / %.2f%% | %.2f | %.2f%% / %.2f%% |\n", rays[r], secs[0],
           100 * pv[0], 100 * gl[0], secs[1], 100 * pv[1], 100 * gl[1]);
  }
  printf("\n");
  cv_tracer_set_window_sampling(tr, 1);
  FILE *csv = csv_path ? fopen(csv_path, "w") : NULL;
  if (csv) fprintf(csv, "rays,bands,seconds,per_vertex_mean,global_l2\n");
  printf("## Direct transfer error against %d rays, window MIS (the default)\n\n", REF);
  printf("Each cell: mean over vertices of the per-vertex relative L2 / energy-weighted relative L2\n"
         "(sqrt(sum |dT|^2 / sum |T_ref|^2) over all vertices).  Last column: radiance under\n"
         "forest.exr (sun split out), 5 bands: mean per-vertex relative error over lit vertices\n"
         "(radiance > 1%% of the mean) / mean |dL| over mean L.\n\n");
  printf("| rays | seconds | bands 2 | bands 3 | bands 4 | bands 5 | bands 6 | forest.exr radiance, 5 bands |\n");
  printf("|---|---|---|---|---|---|---|---|\n");
  for (size_t r = 0; r < sizeof rays / sizeof rays[0]; r++) {
    t0 = cv_now_seconds();
    cv_bake_direct_subset(tr, NB, rays[r], 1, verts, ns, cur);
    double secs = cv_now_seconds() - t0;
    printf("| %d | %.2f |", rays[r], secs);
    for (int n = 2; n <= NB; n++) {
      double pv, gl;
      transfer_error(cur, ref, ns, NC, n * n, &pv, &gl);
      printf(" %.2f%% / %.2f%% |", 100 * pv, 100 * gl);
      if (csv) fprintf(csv, "%d,%d,%.4f,%.6f,%.6f\n", rays[r], n, secs, pv, gl);
    }
    if (have_forest) {
      double mean_ref = 0;
      for (size_t k = 0; k < ns; k++) {
        double s = 0;
        for (int i = 0; i < 25; i++) s += l.sh[3 * i + 1] * ref[k * NC + i];
        mean_ref += s / ns;
      }
      double sum = 0, abs_sum = 0, ref_sum = 0;
      size_t cnt = 0;
      for (size_t k = 0; k < ns; k++) {
        double a = 0, b = 0;
        for (int i = 0; i < 25; i++) {
          a += l.sh[3 * i + 1] * cur[k * NC + i];
          b += l.sh[3 * i + 1] * ref[k * NC + i];
        }
        abs_sum += fabs(a - b);
        ref_sum += fabs(b);
        if (b > 0.01 * mean_ref) { /* lit vertices */
          sum += fabs(a - b) / b;
          cnt++;
        }
      }
      printf(" %.2f%% / %.2f%% |", cnt ? 100 * sum / cnt : 0.0, ref_sum > 0 ? 100 * abs_sum / ref_sum : 0.0);
    } else {
      printf(" (forest.exr missing) |");
    }
    printf("\n");
  }
  if (csv) fclose(csv);
  cv_scene_light_destroy(sl);
  free(ref);
  free(cur);
  free(out);
  free(verts);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
  return 0;
}
