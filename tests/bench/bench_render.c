/* Benchmark of the wall-eye renderer (src/render) on the default cabin at
 * about 500K triangles (tessellation 8: 570,648 triangles, 293,264
 * vertices, 5 bands), on whatever EGL gives (llvmpipe without a GPU).
 *
 * The bake only feeds raster timing, so it uses 2 rays per vertex and one
 * bounce (the GPU data are the same size as a full bake's) and is cached in
 * $TMPDIR/cave_bench_render_t8.prt.
 *
 * Per wall-eye of configs/caves/cave5.json (5 walls x 2 eyes, default head),
 * at 720x720 and 1440x1440: the luminance pass (128x128, draw + read-back),
 * the depth pre-pass, the PRT shading pass (depth EQUAL, Drago + Rec.709,
 * the sun's shadow map), the background fill, the read-back, and, in the
 * same run, an unlit pass of the same mesh and vertex format after the same
 * depth pre-pass.  Per lighting change: the transform-feedback relight and
 * the sun's shadow map.  Per frame: the adaptation statistics of all 10
 * wall-eyes (foveal cone + Lwmax over the 128x128 luminance images).
 * Medians over the frames; every pass is bracketed by glFinish.
 *
 * usage (from the repository root): bench_render [frames (default 5)] [--transfer auto|float|half]
 *   [--half (= --transfer half)] [--cave FILE]
 *   [--no-cull-back] [--no-frustum] [--float-display] [--only 720|1440|N] [--cpu]
 *   [--tone-exact] [--no-sun-split] [--no-transfer] [--depth-less] [--gpu auto|software|N]
 *   [--loop N]
 * --gpu: the EGL device, as `cave render --gpu` (a device asked for and
 * missing is an error);
 * --loop N: instead of the per-pass table, N back-to-back frames (after 3
 * warm-up frames) per case, timed by the wall clock around each whole frame
 * with no glFinish between passes (opts.timing = 0), as `cave run` renders
 * them: (a) one wall-eye (front L) with the display and HDR images read back
 * (cave run's frame until the luminance statistics moved to the GPU), (b)
 * the display image only, (e) the display image and the luminance
 * statistics (cv_renderer_shade_stats: cave run's frame; reduced on a GPU,
 * or on the CPU from the read-back HDR image with llvmpipe),
 * (c) (e) after a lighting change every frame (the sun turns 0.5 deg:
 * relight + shadow map), (d) all 10 wall-eyes as (e) per CAVE frame, one
 * context (one GPU serving the whole CAVE).  Sizes: 1440 unless --only N;
 * --cpu: every pass timed in CPU ms of the whole process (all llvmpipe
 * threads: the work done, steady on a machine others load) instead of wall
 * ms; --tone-exact / --no-sun-split: the renderer options of those names
 * (opts.tone_exact = 1, opts.sun_split = 0), for before/after tables;
 * --no-transfer: display-linear output without the Rec.709 curve in the
 * shader, as `cave run` renders (its 8-bit codes come from a CPU table);
 * --depth-less: no z pre-pass, one shading pass with depth LESS
 * (opts.depth_less; "depth" is then only the clear).
 * Back faces are culled by default (the cabin is closed and consistently
 * wound; tests/render checks the image does not change). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_cabin.h"
#include "bench_util.h"
#include "mesh/cabin.h"
#include "prt/bake.h"
#include "prt/scene_light.h"
#include "render/renderer.h"
#include "tonemap/drago.h"
#include "tonemap/foveal.h"
#include "view/cave.h"
#include "view/offaxis.h"

#define MAXF 64
#define NV 16
#define MAXLOOP 10000

typedef struct {
  cv_renderer *r;
  cv_cave *cave;
  double eyes[2][3];
  cv_drago_consts dc;
  int bands;
} loop_ctx;

/* View i (wall i / 2, eye i % 2) of the CAVE at S x S. */
static int loop_view(const loop_ctx *c, int i, int S, cv_render_view *v) {
  const cv_wall *w = &c->cave->walls[i / 2];
  memset(v, 0, sizeof *v);
  memcpy(v->scene_offset, c->cave->scene_offset, sizeof v->scene_offset);
  v->w = v->h = S, v->supersample = 1;
  return cv_offaxis_compute(w->pa, w->pb, w->pc, c->eyes[i % 2], c->cave->near, c->cave->far, &v->proj);
}

/* One timed case of --loop: n frames of `views` views (the first `views` of
 * the CAVE), each frame optionally after a lighting change (sun azimuth +0.5
 * deg per frame); prints one table row. */
enum { OUT_DISP = 0, OUT_DISP_HDR = 1, OUT_DISP_STATS = 2 };

static int loop_case(const loop_ctx *c, const char *name, int S, int n, int views, int outs,
                     int light_change, const cv_light_spec *spec0) {
  cv_image *disp, *hdr, *lum;
  cv_image_create(S, S, 3, &disp);
  cv_image_create(S, S, 3, &hdr);
  cv_image_create(c->cave->lum_res, c->cave->lum_res, 1, &lum);
  static double ms[MAXLOOP];
  cv_light_spec spec = *spec0;
  cv_err err;
  int st = 0;
  double t_all = 0;
  for (int f = -3; f < n && !st; f++) {
    /* The sky and its SH are the CPU's (the lighting leader's in cave run),
     * built before the clock starts; the renderer's products are timed. */
    cv_scene_light *sl = NULL;
    if (light_change) {
      spec.sun_azimuth_deg = spec0->sun_azimuth_deg + 0.5 * (f + 4);
      if ((st = cv_scene_light_build(&spec, c->bands, &sl, &err))) break;
    }
    const double t0 = bench_now_ms();
    if (sl) {
      cv_lighting l = cv_scene_light_sh(sl);
      st = cv_renderer_set_lighting(c->r, &l, NULL, NULL, &err);
      cv_scene_light_destroy(sl);
      if (st) break;
    }
    for (int i = 0; i < views && !st; i++) {
      cv_render_view v;
      if (loop_view(c, i, S, &v)) continue;
      double mx;
      uint64_t bad;
      st = cv_renderer_shade_stats(c->r, &v, &c->dc, 0, disp, outs == OUT_DISP_HDR ? hdr : NULL,
                                   outs == OUT_DISP_STATS ? lum : NULL, &mx, &bad, NULL, &err);
    }
    const double dt = bench_now_ms() - t0;
    if (f >= 0) ms[f] = dt, t_all += dt;
  }
  cv_image_destroy(disp);
  cv_image_destroy(hdr);
  cv_image_destroy(lum);
  if (st) {
    fprintf(stderr, "loop %s: %s\n", name, err.msg);
    return st;
  }
  const double mean = t_all / n;
  qsort(ms, (size_t)n, sizeof *ms, bench_cmp_double);
  printf("| %d | %s | %d | %.2f | %.2f | %.2f | **%.1f** |\n", S, name, n, mean, ms[n / 2],
         ms[(size_t)(0.99 * (n - 1) + 0.5)], 1e3 / mean);
  return CV_OK;
}


int main(int argc, char **argv) {
  int frames = 5, half = -1, cull_back = 1, frustum = 1, dfloat = 0, only = 0, cpu = 0, exact = 0, split = 1;
  int transfer = 1, depth_less = 0, gpu = CV_GPU_AUTO, loop = 0;
#ifdef CV_SOURCE_DIR
  const char *cave_path = CV_SOURCE_DIR "/configs/caves/cave5.json";
#else
  const char *cave_path = "configs/caves/cave5.json"; /* run from the repository root */
#endif
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--half")) half = 1;
    else if (!strcmp(argv[i], "--transfer") && i + 1 < argc) {
      if (cv_render_transfer_parse(argv[++i], &half)) {
        fprintf(stderr, "bench_render: --transfer: expected auto, float or half, got '%s'\n", argv[i]);
        return 2;
      }
    }
    else if (!strcmp(argv[i], "--no-cull-back")) cull_back = 0;
    else if (!strcmp(argv[i], "--no-frustum")) frustum = 0;
    else if (!strcmp(argv[i], "--float-display")) dfloat = 1;
    else if (!strcmp(argv[i], "--cpu")) cpu = 1;
    else if (!strcmp(argv[i], "--tone-exact")) exact = 1;
    else if (!strcmp(argv[i], "--no-sun-split")) split = 0;
    else if (!strcmp(argv[i], "--no-transfer")) transfer = 0;
    else if (!strcmp(argv[i], "--depth-less")) depth_less = 1;
    else if (!strcmp(argv[i], "--only") && i + 1 < argc) only = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--cave") && i + 1 < argc) cave_path = argv[++i];
    else if (!strcmp(argv[i], "--gpu") && i + 1 < argc) {
      if (cv_gpu_parse(argv[++i], &gpu)) {
        fprintf(stderr, "bench_render: --gpu: expected auto, software or a hardware device index 0..63, got '%s'\n", argv[i]);
        return 2;
      }
    } else if (!strcmp(argv[i], "--loop") && i + 1 < argc) {
      loop = atoi(argv[++i]);
      if (loop < 1 || loop > MAXLOOP) {
        fprintf(stderr, "bench_render: --loop: expected 1..%d frames, got '%s'\n", MAXLOOP, argv[i]);
        return 2;
      }
    }
    else frames = atoi(argv[i]);
  }
  if (frames < 1 || frames > MAXF) frames = 5;
  cv_err err;
  cv_cave cave;
  if (cv_cave_load(cave_path, &cave, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  cv_prt *prt = bench_cabin_t8();
  if (!prt) return 1;
  cv_render_opts ro;
  cv_render_default_opts(&ro);
  ro.half_transfer = half;
  ro.cull_back = cull_back;
  ro.cull_frustum = frustum;
  ro.display_float = dfloat;
  ro.timing = loop ? 0 : cpu ? 2 : 1;
  ro.gpu = gpu;
  ro.tone_exact = exact;
  ro.sun_split = split;
  ro.shadow_reuse = 0; /* the same sun every change: time the map, do not keep it */
  ro.depth_less = depth_less;
  cv_renderer *r;
  if (cv_renderer_create(prt, &ro, &r, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  spec.kind = CV_LIGHT_SKY;
  spec.turbidity = 3, spec.sun_elevation_deg = 35, spec.sun_azimuth_deg = 30;
  cv_scene_light *sl;
  cv_image *bg;
  if (cv_scene_light_build(&spec, (int)prt->bands, &sl, &err) ||
      cv_render_background_image(sl, 1024, &bg) || cv_renderer_set_background(r, bg, &err)) {
    fprintf(stderr, "lighting: %s\n", err.msg);
    return 1;
  }
  cv_lighting l = cv_scene_light_sh(sl);
  const char *lp = getenv("LP_NUM_THREADS");
  printf("GL: %s (a %s device; %d hardware EGL device(s) here); LP_NUM_THREADS=%s; times in %s ms; tone map %s%s; sun split %s\n",
         cv_renderer_gl_name(r), cv_renderer_is_software(r) ? "software" : "hardware",
         cv_renderer_hw_devices(r), lp ? lp : "(unset: all cores)", cpu ? "CPU (all threads)" : "wall",
         exact ? "log/pow" : "table + polynomial", transfer ? "" : " (no transfer)", split ? "on" : "off");
  printf("scene: %zu triangles, %zu vertices, %u bands, transfer %s (%zu B/vertex on the GPU); "
         "back faces %s, frustum culling %s, display target %s\n",
         prt->nt, prt->nv, prt->bands, cv_renderer_half_transfer(r) ? "half" : "float",
         (size_t)(prt->bands * prt->bands + 1) * (cv_renderer_half_transfer(r) ? 8 : 16), cull_back ? "culled" : "drawn",
         frustum ? "on" : "off", dfloat ? "RGBA32F" : "RGBA8");

  if (loop) {
    loop_ctx c = {.r = r, .cave = &cave, .bands = (int)prt->bands};
    cv_head_eyes(cave.head, cave.gaze, cave.eye_separation, c.eyes[0], c.eyes[1]);
    cv_drago d = {.bias = cave.drago_bias, .ldmax = cave.drago_ldmax, .lwa = 1000, .lwmax = 2e4};
    cv_drago_prepare(&d, &c.dc);
    const int S = only > 0 ? only : 1440, nv = 2 * cave.n_walls;
    if (cv_renderer_set_lighting(r, &l, NULL, NULL, &err)) {
      fprintf(stderr, "%s\n", err.msg);
      return 1;
    }
    char all[64];
    snprintf(all, sizeof all, "(d) all %d wall-eyes as (e)", nv);
    printf("back-to-back frames, wall ms per frame (a CAVE frame in (d)); no glFinish between passes\n\n");
    printf("| size | case | frames | mean ms | p50 ms | p99 ms | frames/s |\n|---|---|---|---|---|---|---|\n");
    int st = loop_case(&c, "(a) front L, display + HDR read back", S, loop, 1, OUT_DISP_HDR, 0, &spec) ||
             loop_case(&c, "(b) front L, display only", S, loop, 1, OUT_DISP, 0, &spec) ||
             loop_case(&c, cv_renderer_lum_stats_on_gpu(r)
                               ? "(e) front L, display + luminance statistics reduced on the GPU (cave run)"
                               : "(e) front L, display + luminance statistics reduced on the CPU (cave run)",
                       S, loop, 1, OUT_DISP_STATS, 0, &spec) ||
             loop_case(&c, "(c) (e) + a lighting change every frame", S, loop, 1, OUT_DISP_STATS, 1, &spec) ||
             loop_case(&c, all, S, loop < 10 ? loop : loop / 10 + 1, nv, OUT_DISP_STATS, 0, &spec);
    cv_image_destroy(bg);
    cv_scene_light_destroy(sl);
    cv_renderer_destroy(r);
    cv_prt_destroy(prt);
    return st ? 1 : 0;
  }

  double relight[MAXF], shadow[MAXF];
  for (int f = 0; f < frames; f++) {
    cv_frame_timing t = {0};
    if (cv_renderer_set_lighting(r, &l, NULL, &t, &err)) {
      fprintf(stderr, "%s\n", err.msg);
      return 1;
    }
    relight[f] = t.relight_ms, shadow[f] = t.split_ms + t.shadow_ms;
  }
  double m_relight = bench_median(relight, frames), m_shadow = bench_median(shadow, frames);
  printf("per lighting change: relight (transform feedback) %.1f ms, sun split + shadow map "
         "2048^2 %.1f ms\n\n",
         m_relight, m_shadow);

  double eyes[2][3];
  cv_head_eyes(cave.head, cave.gaze, cave.eye_separation, eyes[0], eyes[1]);
  loop_ctx views = {.r = r, .cave = &cave}; /* the table's views, as --loop's */
  memcpy(views.eyes, eyes, sizeof eyes);
  const int nviews = 2 * cave.n_walls;
  cv_drago d = {.bias = cave.drago_bias, .ldmax = cave.drago_ldmax, .lwa = 1000, .lwmax = 2e4};
  cv_drago_consts dc;
  cv_drago_prepare(&d, &dc);
  int sizes[2] = {720, 1440};
  if (only > 0 && only != 720 && only != 1440) sizes[0] = only; /* any other size alone */
  cv_image *lum[NV];
  for (int i = 0; i < nviews; i++) cv_image_create(cave.lum_res, cave.lum_res, 1, &lum[i]);
  double stats_ms[MAXF];
  printf("| size | wall-eye | lum 128^2 | lum read | depth | shade | background | read-back | total | unlit | shade/unlit |\n");
  printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (int si = 0; si < 2; si++) {
    const int S = sizes[si];
    if (only && S != only) continue;
    cv_image *disp, *un;
    cv_image_create(S, S, 3, &disp);
    cv_image_create(S, S, 3, &un);
    /* [view][pass][frame] */
    static double T[NV][9][MAXF];
    for (int f = 0; f < frames; f++) {
      for (int i = 0; i < nviews; i++) {
        cv_render_view v;
        loop_view(&views, i, S, &v);
        cv_frame_timing t = {0}, tu = {0};
        if (cv_renderer_luminance(r, &v, lum[i], &t, &err) ||
            cv_renderer_shade(r, &v, &dc, transfer, disp, NULL, &t, &err) ||
            cv_renderer_unlit(r, &v, un, &tu, &err)) {
          fprintf(stderr, "%s\n", err.msg);
          return 1;
        }
        double vals[9] = {t.lum_ms, t.lum_read_ms, t.depth_ms, t.shade_ms, t.background_ms, t.read_ms,
                          t.lum_ms + t.lum_read_ms + t.depth_ms + t.shade_ms + t.background_ms + t.read_ms,
                          tu.unlit_ms, 0};
        for (int k = 0; k < 9; k++) T[i][k][f] = vals[k];
      }
      if (si == 0) {
        /* adaptation statistics of all wall-eyes, as cmd_render.c */
        double t0 = bench_now_ms();
        const double ha = 0.5 * cave.foveal_deg * M_PI / 180;
        cv_lumstats acc = {0};
        double lwmax = 0;
        for (int i = 0; i < nviews; i++) {
          const cv_wall *w = &cave.walls[i / 2];
          for (int k = 0; k < lum[i]->w * lum[i]->h; k++)
            if (lum[i]->px[k] > lwmax && isfinite(lum[i]->px[k])) lwmax = lum[i]->px[k];
          if (!cv_foveal_touches(w->pa, w->pb, w->pc, eyes[i % 2], cave.gaze, ha)) continue;
          cv_lumstats s = {0};
          cv_foveal_accumulate(lum[i]->px, lum[i]->w, lum[i]->h, w->pa, w->pb, w->pc, eyes[i % 2],
                               cave.gaze, ha, &s);
          cv_lumstats_merge(&acc, &s);
        }
        double g;
        cv_lumstats_lwa(&acc, &g);
        stats_ms[f] = bench_now_ms() - t0;
      }
    }
    double mean[9] = {0}, worst_total = 0, worst_ratio = 0;
    for (int i = 0; i < nviews; i++) {
      double m[9];
      for (int k = 0; k < 8; k++) m[k] = bench_median(T[i][k], frames);
      m[8] = m[3] / m[7];
      printf("| %d | %s %s | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.2f |\n", S,
             cave.walls[i / 2].name, i % 2 ? "R" : "L", m[0], m[1], m[2], m[3], m[4], m[5], m[6],
             m[7], m[8]);
      for (int k = 0; k < 9; k++) mean[k] += m[k] / nviews;
      if (m[6] > worst_total) worst_total = m[6];
      if (m[8] > worst_ratio) worst_ratio = m[8];
    }
    printf("| **%d** | **mean of %d** | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | **%.1f** | %.1f | **%.2f** |\n",
           S, nviews, mean[0], mean[1], mean[2], mean[3], mean[4], mean[5], mean[6], mean[7],
           mean[8]);
    printf("| %d | worst wall-eye | | | | | | | %.1f | | %.2f |\n", S, worst_total, worst_ratio);
    printf("| %d | + relight + shadow map (one rank per wall-eye) | | | | | | | %.1f | | |\n", S,
           mean[6] + m_relight + m_shadow);
    cv_image_destroy(disp);
    cv_image_destroy(un);
  }
  printf("\nadaptation statistics, all %d wall-eyes (Lwmax + foveal cone on %dx%d luminance "
         "images): median %.3f ms per frame\n",
         nviews, cave.lum_res, cave.lum_res, bench_median(stats_ms, frames));
  for (int i = 0; i < nviews; i++) cv_image_destroy(lum[i]);
  cv_image_destroy(bg);
  cv_scene_light_destroy(sl);
  cv_renderer_destroy(r);
  cv_prt_destroy(prt);
  return 0;
}
