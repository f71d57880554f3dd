/* Benchmark of a lighting change of the wall-eye renderer (src/render) on
 * the 571K-triangle cabin (tess 8, the cache of bench_render), and of the
 * sun's shadow error against Embree-traced visibility at the same pixels.
 *
 * Variants of the sun's shadow map and relight (renderer options), each its own
 * renderer, timed alternately in the same run (lighting changes cycling
 * over the suns, so no map is reused unless the variant says so):
 * relight, sun split and shadow map per lighting change, in CPU ms of the
 * whole process (every llvmpipe thread) and in wall ms.
 *
 * Shadow error: the 10 wall-eyes of configs/caves/cave5.json (default
 * head) at SIZE^2 (default 360), HDR output.  Per pixel the CPU traces the
 * eye's ray through the pixel centre (Embree, as tests/render), takes the
 * hit triangle's winding normal n_t and interpolated albedo, and the
 * reference visibility V_ref = cv_rt_reaches_env from the hit towards the
 * sun (what the CPU renderer's cv_sun_direct uses).  The GPU's sun term is
 * its HDR pixel minus the CPU's vertex radiance without the direct sun
 * (cv_prt_relight) interpolated at the hit; V_gpu = that / (E/pi albedo
 * n_t . s) in luminance.  Pixels counted: n_t . s > 0.05 and the full sun
 * term above 25% of the pixel (where the sun's shadow is what one sees);
 * pixels where V_gpu is outside [-0.25, 1.25] are silhouettes where the two
 * rasterisers picked different surfaces and are left out (counted).  A
 * pixel differs when (V_gpu > 0.5) != V_ref; "where": the distance in
 * pixels to the nearest counted pixel of the other reference state (an
 * edge of the reference shadow): <= 1, <= 3, farther.  Then, per sun, the
 * extents across the sun's beam (the shadow map's x, y axes) of all
 * vertices, of the triangles the rays hit and of those of counted pixels,
 * and the map resolution that keeps the 2048^2 map's texel when the map is
 * fitted to the counted ones (what a frustum fitted to the seen receivers
 * could save; nothing in the renderer does this).
 *
 * --share: shared lighting instead (render_share.c, `cave run
 * --share-lighting`): three renderers with the wall-eyes' options, timed
 * alternately over the same lighting changes (the suns cycling: every map
 * redrawn): one computes (cv_renderer_set_lighting), the leader computes
 * and exports into a buffer, the importer uploads that buffer
 * (cv_renderer_lighting_import); process CPU ms and wall ms around each
 * call, and what a host of 10 wall-eyes spends per change (10 computing vs
 * the leader + 9 importers).  The importer's images are checked bit-equal
 * to the computing renderer's at the end (one 360^2 view).
 *
 * usage (from the repository root): bench_shadow [--reps N (5)] [--size S (360)]
 *   [--suns K (4)] [--no-error] [--no-time] [--share] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_cabin.h"
#include "bench_util.h"
#include "mesh/cabin.h"
#include "prt/bake.h"
#include "prt/relight.h"
#include "prt/scene_light.h"
#include "render/renderer.h"
#include "rt/rt.h"
#include "view/cave.h"
#include "view/offaxis.h"

#define MAXR 32

static double cpu_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}
#define MAXSUN 8


/* stats: the clamp count is read back (as before: always); same_sun: every
 * change repeats the previous sun (the map and split are kept) */
typedef struct variant {
  const char *name;
  int res, cull, stats, same_sun;
  double casters; /* opts.shadow_casters (m; 0: the mesh itself) */
  int feedback;   /* 1: relight by transform feedback (opts.relight_cpu 0) */
  int half;       /* opts.half_transfer (-1: the default's choice; a half-float variant's
                     images are compared with the float transfer's) */
} variant;

static const variant VARIANTS[] = {
    {"2048^2, all triangles of the mesh, clamp count read back, feedback relight (before issue 16)", 2048, 0, 1, 0, 0, 1, 0},
    {"2048^2, the mesh, facing away only, feedback relight (the default before this change)", 2048, 1, 0, 0, 0, 1, 0},
    {"2048^2, the mesh, facing away only", 2048, 1, 0, 0, 0, 0, 0},
    {"1024^2, the mesh, facing away only", 1024, 1, 0, 0, 0, 0, 0},
    {"2048^2, casters within 0.25 mm, facing away only", 2048, 1, 0, 0, 0.00025, 0, 0},
    {"2048^2, casters within 0.5 mm, facing away only", 2048, 1, 0, 0, 0.0005, 0, 0},
    {"2048^2, casters within 1 mm, facing away only, float transfer (the default before the fitted map)", 2048, 1, 0, 0, 0.001, 0, 0},
    {"2048^2, casters within 1 mm, facing away only (default: half-float transfer with a software GL)", 2048, 1, 0, 0, 0.001, 0, -1},
    {"2048^2, casters within 1 mm, all (not culled)", 2048, 0, 0, 0, 0.001, 0, 0},
    {"2048^2, casters within 2 mm, facing away only", 2048, 1, 0, 0, 0.002, 0, 0},
    {"1024^2, casters within 1 mm, facing away only, float transfer", 1024, 1, 0, 0, 0.001, 0, 0},
    {"2048^2, casters within 1 mm, sun unchanged (map kept; the default transfer)", 2048, 1, 0, 1, 0.001, 0, -1},
};
#define NVAR (int)(sizeof VARIANTS / sizeof VARIANTS[0])

/* The CPU reference of one view: per pixel the hit (tri < 0: none), the
 * full sun term's luminance, the pixel's luminance without the direct sun,
 * the reference visibility. */
typedef struct ref_view {
  int *tri;
  float *sun_y, *base_y;
  unsigned char *vis, *counted;
} ref_view;

static double lum3(const float *c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

static void trace_view(const cv_prt *prt, const cv_rt *rt, const float *rad0, const float *alb,
                       const cv_wall *w, const double eye[3], const double off[3], int S,
                       const double s[3], const double E[3], ref_view *rv) {
  const float sf[3] = {(float)s[0], (float)s[1], (float)s[2]};
#pragma omp parallel for schedule(dynamic, 4)
  for (int y = 0; y < S; y++) {
    cv_rt_thread_init();
    for (int x = 0; x < S; x++) {
      const size_t i = (size_t)y * S + x;
      rv->tri[i] = -1, rv->counted[i] = 0, rv->vis[i] = 0;
      double fx = (x + 0.5) / S, fy = 1 - (y + 0.5) / S, dl = 0;
      float o[3], d[3];
      for (int j = 0; j < 3; j++) {
        double q = w->pa[j] + fx * (w->pb[j] - w->pa[j]) + fy * (w->pc[j] - w->pa[j]);
        d[j] = (float)(q - eye[j]);
        dl += (double)d[j] * d[j];
        o[j] = (float)(eye[j] + off[j]);
      }
      for (int j = 0; j < 3; j++) d[j] = (float)(d[j] / sqrt(dl));
      cv_hit h;
      if (!cv_rt_intersect(rt, o, d, 0, INFINITY, &h)) continue;
      const uint32_t *t = prt->tri + 3 * h.tri;
      const float *a = prt->pos + 3 * t[0], *b = prt->pos + 3 * t[1], *c = prt->pos + 3 * t[2];
      double e1[3], e2[3];
      for (int j = 0; j < 3; j++) e1[j] = (double)b[j] - a[j], e2[j] = (double)c[j] - a[j];
      double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                     e1[0] * e2[1] - e1[1] * e2[0]};
      const double nl = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      if (!(nl > 0)) continue;
      const double cs = (n[0] * s[0] + n[1] * s[1] + n[2] * s[2]) / nl;
      const float w0 = 1 - h.u - h.v;
      float base[3], sun[3];
      for (int k = 0; k < 3; k++) {
        base[k] = w0 * rad0[3 * t[0] + k] + h.u * rad0[3 * t[1] + k] + h.v * rad0[3 * t[2] + k];
        const float al = w0 * alb[3 * t[0] + k] + h.u * alb[3 * t[1] + k] + h.v * alb[3 * t[2] + k];
        sun[k] = (float)(E[k] / M_PI * al * (cs > 0 ? cs : 0));
      }
      rv->tri[i] = (int)h.tri;
      rv->sun_y[i] = (float)lum3(sun);
      rv->base_y[i] = (float)lum3(base);
      if (cs > 0.05 && rv->sun_y[i] > 0.25 * (rv->sun_y[i] + rv->base_y[i])) rv->counted[i] = 1;
      if (cs > 0) {
        float p[3], org[3], ng[3] = {(float)(n[0] / nl), (float)(n[1] / nl), (float)(n[2] / nl)};
        for (int j = 0; j < 3; j++) p[j] = o[j] + h.t * d[j];
        cv_rt_offset_origin(p, ng, org);
        rv->vis[i] = (unsigned char)cv_rt_reaches_env(rt, org, sf, 0.0f);
      }
    }
  }
}


/* Option 2 of issue 16 target 2 (a light frustum fitted to what is seen):
 * the extents across the sun's beam (the axes of cvr_sun_matrices) of all
 * vertices and of the vertices of the triangles hit by the views' rays,
 * all of them or only those of counted pixels (the shadow that matters). */
typedef struct beam_ext {
  double lo[3][2], hi[3][2]; /* [all, seen, counted][x, y] */
} beam_ext;

static void sun_axes(const double s[3], double ax[2][3]) {
  double up[3] = {0, 1, 0};
  if (fabs(s[1]) > 0.99) up[0] = 1, up[1] = 0;
  double x[3] = {up[1] * s[2] - up[2] * s[1], up[2] * s[0] - up[0] * s[2], up[0] * s[1] - up[1] * s[0]};
  const double xl = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
  for (int j = 0; j < 3; j++) ax[0][j] = x[j] / xl;
  ax[1][0] = s[1] * ax[0][2] - s[2] * ax[0][1];
  ax[1][1] = s[2] * ax[0][0] - s[0] * ax[0][2];
  ax[1][2] = s[0] * ax[0][1] - s[1] * ax[0][0];
}

static void beam_add(beam_ext *b, int set, const double ax[2][3], const float *p) {
  for (int a = 0; a < 2; a++) {
    const double d = ax[a][0] * p[0] + ax[a][1] * p[1] + ax[a][2] * p[2];
    b->lo[set][a] = fmin(b->lo[set][a], d), b->hi[set][a] = fmax(b->hi[set][a], d);
  }
}

static void beam_view(const cv_prt *prt, const ref_view *rv, int S, const double ax[2][3], beam_ext *b) {
  for (size_t i = 0; i < (size_t)S * S; i++) {
    if (rv->tri[i] < 0) continue;
    const uint32_t *t = prt->tri + 3 * (size_t)rv->tri[i];
    for (int k = 0; k < 3; k++) {
      beam_add(b, 1, ax, prt->pos + 3 * t[k]);
      if (rv->counted[i]) beam_add(b, 2, ax, prt->pos + 3 * t[k]);
    }
  }
}

typedef struct err_acc {
  long counted, silhouette, differ, leak, dark, near1, near3, far;
} err_acc;

/* Distance (Chebyshev, pixels, up to 8) from pixel i to the nearest counted
 * pixel whose reference state is not `state`; 99 when none within 8. */
static int edge_dist(const ref_view *rv, int S, int x, int y, int state) {
  for (int r = 1; r <= 8; r++)
    for (int dy = -r; dy <= r; dy++)
      for (int dx = -r; dx <= r; dx++) {
        if (abs(dx) != r && abs(dy) != r) continue;
        const int xx = x + dx, yy = y + dy;
        if (xx < 0 || yy < 0 || xx >= S || yy >= S) continue;
        const size_t j = (size_t)yy * S + xx;
        if (rv->tri[j] >= 0 && rv->vis[j] != state) return r;
      }
  return 99;
}

static void compare_view(const ref_view *rv, const cv_image *hdr, int S, err_acc *e) {
  for (int y = 0; y < S; y++)
    for (int x = 0; x < S; x++) {
      const size_t i = (size_t)y * S + x;
      if (!rv->counted[i]) continue;
      const double g = lum3(hdr->px + 3 * i) - rv->base_y[i];
      const double v = g / rv->sun_y[i];
      if (!(v >= -0.25 && v <= 1.25)) {
        e->silhouette++;
        continue;
      }
      e->counted++;
      const int lit = v > 0.5;
      if (lit == rv->vis[i]) continue;
      e->differ++;
      if (lit) e->leak++;
      else e->dark++;
      const int dd = edge_dist(rv, S, x, y, rv->vis[i]);
      if (dd <= 1) e->near1++;
      else if (dd <= 3) e->near3++;
      else e->far++;
    }
}

static int bench_share(cv_prt *prt, const cv_lighting *L, int nsun, int reps, const cv_cave *cave);

int main(int argc, char **argv) {
  int reps = 5, S = 360, nsun = 4, do_err = 1, do_time = 1, share = 0;
  const char *only = NULL; /* --only TEXT: the variants whose name contains it */
  const char *cave_path = "configs/caves/cave5.json";
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--size") && i + 1 < argc) S = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--suns") && i + 1 < argc) nsun = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--no-error")) do_err = 0;
    else if (!strcmp(argv[i], "--no-time")) do_time = 0;
    else if (!strcmp(argv[i], "--share")) share = 1;
    else if (!strcmp(argv[i], "--only") && i + 1 < argc) only = argv[++i];
    else if (!strcmp(argv[i], "--help")) {
      printf("usage: bench_shadow [--reps N] [--size S] [--suns K] [--no-error] [--no-time] [--share] [--only TEXT]\n"
           "  --only TEXT: only the variants whose name contains TEXT\n");
      return 0;
    } else {
      fprintf(stderr, "bench_shadow: unknown option '%s' (see --help)\n", argv[i]);
      return 2;
    }
  }
  if (reps < 1 || reps > MAXR || S < 16 || S > 4096 || nsun < 1 || nsun > MAXSUN) {
    fprintf(stderr, "bench_shadow: --reps 1..%d, --size 16..4096, --suns 1..%d\n", MAXR, MAXSUN);
    return 2;
  }
  cv_err err;
  cv_cave cave;
  if (cv_cave_load(cave_path, &cave, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  cv_prt *prt = bench_cabin_t8();
  if (!prt) return 1;
  /* suns: elevation / azimuth (degrees) of a Preetham sky, turbidity 3 */
  const double sun_ea[MAXSUN][2] = {{35, 30}, {20, 100}, {55, 200}, {12, 290},
                                    {45, 150}, {25, 340}, {65, 60}, {8, 180}};
  cv_lighting L[MAXSUN];
  for (int k = 0; k < nsun; k++) {
    cv_light_spec spec;
    cv_light_spec_default(&spec);
    spec.kind = CV_LIGHT_SKY;
    spec.turbidity = 3, spec.sun_elevation_deg = sun_ea[k][0], spec.sun_azimuth_deg = sun_ea[k][1];
    cv_scene_light *sl;
    if (cv_scene_light_build(&spec, (int)prt->bands, &sl, &err)) {
      fprintf(stderr, "lighting: %s\n", err.msg);
      return 1;
    }
    L[k] = cv_scene_light_sh(sl);
    cv_scene_light_destroy(sl);
    if (!L[k].has_sun) {
      fprintf(stderr, "sun %d: the sky has no sun\n", k);
      return 1;
    }
  }
  if (share) return bench_share(prt, L, nsun, reps, &cave);
  cv_renderer *R[NVAR];
  for (int v = 0; v < NVAR; v++) {
    R[v] = NULL;
    if (only && !strstr(VARIANTS[v].name, only)) continue;
    cv_render_opts ro;
    cv_render_default_opts(&ro);
    ro.cull_back = 1;
    ro.timing = 2; /* CPU ms; wall ms measured around the call */
    ro.shadow_res = VARIANTS[v].res;
    ro.shadow_cull = VARIANTS[v].cull;
    ro.shadow_reuse = VARIANTS[v].same_sun ? 0.5 : 0;
    ro.shadow_casters = VARIANTS[v].casters;
    ro.relight_cpu = VARIANTS[v].feedback ? 0 : -1;
    ro.half_transfer = VARIANTS[v].half;
    if (cv_renderer_create(prt, &ro, &R[v], &err)) {
      fprintf(stderr, "%s\n", err.msg);
      return 1;
    }
  }
  int v0 = 0;
  while (v0 < NVAR && !R[v0]) v0++;
  if (v0 == NVAR) {
    fprintf(stderr, "bench_shadow: no variant's name contains '%s'\n", only);
    return 2;
  }
  /* The first lighting builds each renderer's shadow casters (once): out of the timing. */
  for (int v = 0; v < NVAR; v++) if (R[v])
    if (cv_renderer_set_lighting(R[v], &L[nsun - 1], NULL, NULL, &err)) {
      fprintf(stderr, "%s\n", err.msg);
      return 1;
    }
  const char *lp = getenv("LP_NUM_THREADS");
  printf("GL: %s; LP_NUM_THREADS=%s\n", cv_renderer_gl_name(R[v0]), lp ? lp : "(unset: all cores)");
  printf("Shadow casters (opts.shadow_casters; built once, on the first map):\n\n");
  printf("| variant | tolerance mm | caster triangles (of the mesh's) | simplifier's error mm | "
         "closure defects | culled | triangles in the last map | build wall ms |\n|---|---|---|---|---|---|---|---|\n");
  for (int v = 0; v < NVAR; v++) if (R[v]) {
    cv_shadow_casters sc;
    cv_renderer_shadow_casters(R[v], &sc);
    if (!sc.built) continue;
    printf("| %s | %.2f | %zu (%zu) | %.3f | %zu | %s | %zu | %.0f |\n", VARIANTS[v].name,
           1e3 * sc.tolerance_m, sc.triangles, sc.mesh_triangles, 1e3 * sc.error_m, sc.defects,
           sc.culled ? "yes" : "no", sc.drawn, sc.build_ms);
  }
  printf("\n");
  printf("scene: %zu triangles, %zu vertices, %u bands, closed and consistently wound: %s; %d suns "
         "of a Preetham sky\n\n", prt->nt, prt->nv, prt->bands,
         cv_renderer_mesh_closed(R[v0]) ? "yes" : "no", nsun);
  if (do_time) {
    static double T[NVAR][4][MAXR * MAXSUN];
    int n = 0;
    for (int rep = 0; rep < reps; rep++)
      for (int k = 0; k < nsun; k++, n++)
        for (int v = 0; v < NVAR; v++) if (R[v]) {
          cv_frame_timing t = {0};
          cv_render_light_stats ls;
          const cv_lighting *lk = &L[(k + rep) % nsun];
          if (VARIANTS[v].same_sun && cv_renderer_set_lighting(R[v], lk, NULL, NULL, &err)) {
            fprintf(stderr, "%s\n", err.msg);
            return 1;
          }
          double w0 = bench_now_ms();
          if (cv_renderer_set_lighting(R[v], lk, VARIANTS[v].stats ? &ls : NULL, &t, &err)) {
            fprintf(stderr, "%s\n", err.msg);
            return 1;
          }
          T[v][0][n] = t.relight_ms, T[v][1][n] = t.split_ms, T[v][2][n] = t.shadow_ms;
          T[v][3][n] = bench_now_ms() - w0;
        }
    printf("Per lighting change (%d changes per variant, alternated; medians, [min, max]):\n\n", n);
    printf("| shadow map | relight CPU ms | split CPU ms | shadow map CPU ms | lighting change CPU ms | wall ms |\n");
    printf("|---|---|---|---|---|---|\n");
    for (int v = 0; v < NVAR; v++) if (R[v]) {
      double tot[MAXR * MAXSUN], lo = INFINITY, hi = 0;
      for (int i = 0; i < n; i++) {
        tot[i] = T[v][0][i] + T[v][1][i] + T[v][2][i];
        lo = fmin(lo, tot[i]), hi = fmax(hi, tot[i]);
      }
      double m[4];
      for (int k = 0; k < 4; k++) m[k] = bench_median(T[v][k], n);
      printf("| %s | %.1f | %.1f | %.1f | %.1f [%.1f, %.1f] | %.1f |\n", VARIANTS[v].name, m[0], m[1],
             m[2], bench_median(tot, n), lo, hi, m[3]);
    }
    printf("\n");
  }
  if (!do_err) return 0;

  cv_mesh *pm;
  cv_tracer *tr;
  if (cv_prt_to_mesh(prt, &pm) || cv_tracer_create(pm, &tr, &err)) {
    fprintf(stderr, "tracer: %s\n", err.msg);
    return 1;
  }
  cv_mesh_destroy(pm);
  const cv_rt *rt = cv_tracer_rt(tr);
  float *rad0 = malloc(3 * prt->nv * sizeof *rad0), *alb = malloc(3 * prt->nv * sizeof *alb);
  if (!rad0 || !alb || cv_prt_untextured_scale(prt, alb)) return 1;
  for (size_t i = 0; i < 3 * prt->nv; i++) alb[i] *= prt->albedo[i];
  double eyes[2][3];
  cv_head_eyes(cave.head, cave.gaze, cave.eye_separation, eyes[0], eyes[1]);
  const int nviews = 2 * cave.n_walls;
  ref_view rv;
  const size_t np = (size_t)S * S;
  rv.tri = malloc(np * sizeof *rv.tri);
  rv.sun_y = malloc(np * sizeof *rv.sun_y);
  rv.base_y = malloc(np * sizeof *rv.base_y);
  rv.vis = malloc(np), rv.counted = malloc(np);
  cv_image *hdr;
  if (!rv.tri || !rv.sun_y || !rv.base_y || !rv.vis || !rv.counted || cv_image_create(S, S, 3, &hdr))
    return 1;
  err_acc acc[NVAR][MAXSUN];
  memset(acc, 0, sizeof acc);
  /* the half-float variant's pixels against the float transfer's (otherwise
   * the same): relative luminance differences */
  int v_def = -1, v_half = -1; /* the float-transfer row and the half-float one after it */
  for (int v = 0; v < NVAR; v++) if (R[v]) {
    if (strstr(VARIANTS[v].name, "float transfer (")) v_def = v;
    if (cv_renderer_half_transfer(R[v]) && v_half < 0) v_half = v;
  }
  cv_image *hdr_def;
  double *hrel = malloc((size_t)nsun * nviews * np * sizeof *hrel);
  size_t nhrel = 0;
  double hmax_y = 0, hmax_rel = -1, hmax_ymean = 0; /* the largest difference's pixel: its
                                                        float luminance, its view's mean */
  if (!hrel || cv_image_create(S, S, 3, &hdr_def)) return 1;
  beam_ext bx[MAXSUN];
  for (int k = 0; k < nsun; k++) {
    double sn = 0, sk[3], ax[2][3];
    for (int j = 0; j < 3; j++) sn += L[k].sun_dir[j] * L[k].sun_dir[j];
    for (int j = 0; j < 3; j++) sk[j] = L[k].sun_dir[j] / sqrt(sn);
    sun_axes(sk, ax);
    for (int e = 0; e < 3; e++)
      for (int a = 0; a < 2; a++) bx[k].lo[e][a] = INFINITY, bx[k].hi[e][a] = -INFINITY;
    for (size_t v = 0; v < prt->nv; v++) beam_add(&bx[k], 0, ax, prt->pos + 3 * v);
    if (cv_prt_relight(prt, &L[k], NULL, 0, rad0, NULL)) return 1;
    for (int v = 0; v < NVAR; v++) if (R[v])
      if (cv_renderer_set_lighting(R[v], &L[k], NULL, NULL, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
      }
    for (int i = 0; i < nviews; i++) {
      const cv_wall *w = &cave.walls[i / 2];
      trace_view(prt, rt, rad0, alb, w, eyes[i % 2], cave.scene_offset, S, L[k].sun_dir, L[k].sun_E, &rv);
      beam_view(prt, &rv, S, ax, &bx[k]);
      cv_render_view view;
      memset(&view, 0, sizeof view);
      cv_offaxis_compute(w->pa, w->pb, w->pc, eyes[i % 2], cave.near, cave.far, &view.proj);
      memcpy(view.scene_offset, cave.scene_offset, sizeof view.scene_offset);
      view.w = view.h = S, view.supersample = 1;
      for (int v = 0; v < NVAR; v++) if (R[v]) {
        if (VARIANTS[v].same_sun) continue; /* the map of its row above */
        if (cv_renderer_shade(R[v], &view, NULL, 0, NULL, hdr, NULL, &err)) {
          fprintf(stderr, "%s\n", err.msg);
          return 1;
        }
        compare_view(&rv, hdr, S, &acc[v][k]);
        if (v == v_def) memcpy(hdr_def->px, hdr->px, 3 * np * sizeof *hdr->px);
        if (v == v_half && v_def >= 0 && v_def < v_half)
          for (size_t q = 0; q < np; q++) {
            const float *a = hdr->px + 3 * q, *b = hdr_def->px + 3 * q;
            const double ya = lum3(a), yb = lum3(b);
            if (rv.tri[q] >= 0 && yb > 0) {
              hrel[nhrel++] = fabs(ya - yb) / yb;
              if (hrel[nhrel - 1] > hmax_rel) {
                double ym = 0;
                for (size_t u = 0; u < np; u++) ym += lum3(hdr_def->px + 3 * u) / (double)np;
                hmax_rel = hrel[nhrel - 1], hmax_y = yb, hmax_ymean = ym;
              }
            }
          }
      }
    }
  }
  printf("Shadow error against Embree sun visibility, %d wall-eyes at %d^2, %d suns (pixels where "
         "the sun is over 25%% of the pixel and n.s > 0.05):\n\n", nviews, S, nsun);
  printf("| shadow map | pixels counted | silhouette (left out) | differ | of which too lit / too dark | "
         "within 1 px of a shadow edge | 2-3 px | farther | worst sun |\n");
  printf("|---|---|---|---|---|---|---|---|---|\n");
  for (int v = 0; v < NVAR; v++) if (R[v]) {
    if (VARIANTS[v].same_sun) continue;
    err_acc t = {0};
    double worst = 0;
    for (int k = 0; k < nsun; k++) {
      const err_acc *a = &acc[v][k];
      t.counted += a->counted, t.silhouette += a->silhouette, t.differ += a->differ;
      t.leak += a->leak, t.dark += a->dark, t.near1 += a->near1, t.near3 += a->near3, t.far += a->far;
      if (a->counted) worst = fmax(worst, (double)a->differ / a->counted);
    }
    const double c = t.counted ? (double)t.counted : 1;
    printf("| %s | %ld | %ld | %.3f%% | %.3f%% / %.3f%% | %.3f%% | %.3f%% | %.3f%% | %.3f%% |\n",
           VARIANTS[v].name, t.counted, t.silhouette, 100 * t.differ / c, 100 * t.leak / c,
           100 * t.dark / c, 100 * t.near1 / c, 100 * t.near3 / c, 100 * t.far / c, 100 * worst);
  }
  if (nhrel) {
    qsort(hrel, nhrel, sizeof *hrel, bench_cmp_double);
    printf("\nHalf-float transfer against float (the same renderer otherwise), relative luminance "
           "difference over %zu pixels that see the cabin: median %.2e, p90 %.2e, p99 %.2e, "
           "p99.9 %.2e, max %.2e (at a pixel of float luminance %.3g, %.2g of its view's mean)\n",
           nhrel, hrel[nhrel / 2], hrel[(size_t)(0.9 * nhrel)], hrel[(size_t)(0.99 * nhrel)],
           hrel[(size_t)(0.999 * nhrel)], hrel[nhrel - 1], hmax_y, hmax_y / hmax_ymean);
  }
  free(hrel);
  cv_image_destroy(hdr_def);
  printf("\nAcross the sun's beam (metres, x by y; the map's texel is the larger over its resolution):"
         " all vertices / vertices of the triangles seen / of the counted pixels' triangles; the "
         "resolution that keeps the 2048^2 map's texel when fitted to the counted ones:\n\n");
  printf("| sun | all | seen | counted | same texel at |\n|---|---|---|---|---|\n");
  for (int k = 0; k < nsun; k++) {
    double ex[3][2];
    for (int e = 0; e < 3; e++)
      for (int a = 0; a < 2; a++) ex[e][a] = bx[k].hi[e][a] - bx[k].lo[e][a];
    const double full = fmax(ex[0][0], ex[0][1]), fit = fmax(ex[2][0], ex[2][1]);
    printf("| %d | %.2f x %.2f | %.2f x %.2f | %.2f x %.2f | %.0f^2 |\n", k, ex[0][0], ex[0][1], ex[1][0],
           ex[1][1], ex[2][0], ex[2][1], ceil(2048 * fit / full));
  }
  free(rv.tri), free(rv.sun_y), free(rv.base_y), free(rv.vis), free(rv.counted);
  free(rad0), free(alb);
  cv_image_destroy(hdr);
  cv_tracer_destroy(tr);
  for (int v = 0; v < NVAR; v++) if (R[v]) cv_renderer_destroy(R[v]);
  cv_prt_destroy(prt);
  return 0;
}

/* --share (see the top). */
static int bench_share(cv_prt *prt, const cv_lighting *L, int nsun, int reps, const cv_cave *cave) {
  cv_err err;
  cv_renderer *R[3]; /* computing, leader, importer */
  for (int v = 0; v < 3; v++) {
    cv_render_opts ro;
    cv_render_default_opts(&ro);
    ro.cull_back = -1; /* as cluster/walleye.c */
    ro.timing = 1;     /* glFinish after the passes (as the wall-eyes): the work is done in the call */
    if (cv_renderer_create(prt, &ro, &R[v], &err)) {
      fprintf(stderr, "%s\n", err.msg);
      return 1;
    }
  }
  const size_t cap = cv_renderer_lighting_bytes(R[1]);
  unsigned char *buf = calloc(cap, 1);
  if (!buf) return 1;
  const char *lp = getenv("LP_NUM_THREADS");
  printf("GL: %s; LP_NUM_THREADS=%s\n", cv_renderer_gl_name(R[0]), lp ? lp : "(unset: all cores)");
  printf("scene: %zu triangles, %zu vertices; export buffer %.1f MB\n\n", prt->nt, prt->nv, cap / 1048576.0);
  static double C[3][MAXR * MAXSUN], W[3][MAXR * MAXSUN], P[3][MAXR * MAXSUN];
  int n = 0;
  for (int rep = 0; rep < reps; rep++)
    for (int k = 0; k < nsun; k++, n++) {
      const cv_lighting *lk = &L[(k + rep) % nsun];
      for (int v = 0; v < 3; v++) {
        const double c0 = cpu_ms(), w0 = bench_now_ms();
        cv_frame_timing tm;
        memset(&tm, 0, sizeof tm);
        int st = v < 2 ? cv_renderer_set_lighting(R[v], lk, NULL, NULL, &err) : cv_renderer_lighting_import(R[2], buf, cap, &tm, &err);
        if (v == 2) P[0][n] = tm.relight_ms, P[1][n] = tm.split_ms, P[2][n] = tm.shadow_ms;
        if (!st && v == 1) st = cv_renderer_lighting_export(R[1], buf, cap, &err);
        if (st) {
          fprintf(stderr, "%s\n", err.msg);
          return 1;
        }
        C[v][n] = cpu_ms() - c0, W[v][n] = bench_now_ms() - w0;
      }
    }
  static const char *names[3] = {"computed (cv_renderer_set_lighting)", "leader (computed + export)",
                                 "importer (cv_renderer_lighting_import)"};
  double mc[3], mw[3];
  printf("Per lighting change (%d changes, each sun new: every map redrawn; alternated; medians [min, max]):\n\n", n);
  printf("| wall-eye | CPU ms | wall ms |\n|---|---|---|\n");
  for (int v = 0; v < 3; v++) {
    double lo = INFINITY, hi = 0;
    for (int i = 0; i < n; i++) lo = fmin(lo, C[v][i]), hi = fmax(hi, C[v][i]);
    mc[v] = bench_median(C[v], n), mw[v] = bench_median(W[v], n);
    printf("| %s | %.1f [%.1f, %.1f] | %.1f |\n", names[v], mc[v], lo, hi, mw[v]);
  }
  printf("\nThe importer's parts (wall ms between glFinish calls, medians): relight buffer %.1f, sun split %.1f, "
         "shadow map %.1f\n", bench_median(P[0], n), bench_median(P[1], n), bench_median(P[2], n));
  printf("\nA host of 10 wall-eyes per lighting change: %.1f CPU ms computing each, %.1f CPU ms shared "
         "(leader + 9 importers): %.2fx less; importer / computed %.3f\n\n", 10 * mc[0], mc[1] + 9 * mc[2],
         10 * mc[0] / (mc[1] + 9 * mc[2]), mc[2] / mc[0]);
  /* the importer's image against the computing renderer's: bit-equal */
  double eyes[2][3];
  cv_head_eyes(cave->head, cave->gaze, cave->eye_separation, eyes[0], eyes[1]);
  cv_render_view v;
  memset(&v, 0, sizeof v);
  const cv_wall *w = &cave->walls[0];
  if (cv_offaxis_compute(w->pa, w->pb, w->pc, eyes[0], cave->near, cave->far, &v.proj)) return 1;
  memcpy(v.scene_offset, cave->scene_offset, sizeof v.scene_offset);
  v.w = v.h = 360, v.supersample = 1;
  cv_image *a, *b;
  if (cv_image_create(360, 360, 3, &a) || cv_image_create(360, 360, 3, &b)) return 1;
  if (cv_renderer_shade(R[0], &v, NULL, 0, NULL, a, NULL, &err) || cv_renderer_shade(R[2], &v, NULL, 0, NULL, b, NULL, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  const int same = !memcmp(a->px, b->px, 3 * 360 * 360 * sizeof(float));
  printf("importer's 360^2 HDR image of wall %s %s the computing renderer's\n", w->name, same ? "bit-equal to" : "DIFFERS from");
  cv_image_destroy(a), cv_image_destroy(b);
  free(buf);
  for (int k = 0; k < 3; k++) cv_renderer_destroy(R[k]);
  return same ? 0 : 1;
}
