/* `cave render`: every wall-eye of a CAVE configuration rendered with the
 * GPU PRT renderer (src/render) in one process, one after the other, with one
 * shared adaptation state, as the MPI service will do across ranks
 * (Dmitriev et al. 2004, sections 4.2 and 5.4).  Per frame:
 *   1. the low-resolution luminance pass of every wall-eye;
 *   2. foveal statistics: the cone of cave.foveal_deg around the gaze from
 *      each eye, on the walls cv_foveal_touches picks, merged over walls and
 *      both eyes (solid-angle weights); Lwmax = the maximum luminance of all
 *      low-resolution frames (the paper's "maximum displayed luminance on
 *      all displays");
 *   3. Pattanaik adaptation stepped by --dt towards the foveal log-average
 *      (an empty cone keeps the previous state; on the first frame it falls
 *      back to the log-average of all luminance frames);
 *   4. the depth and shading passes of every wall-eye with Drago at the
 *      adapted luminance.
 * Writes per wall-eye a linear EXR and a tone-mapped PNG (last frame, or
 * every frame with --all-frames) and a montage of the left eye's walls
 * (an unfolded cube when the walls are named front/left/right/floor/ceiling
 * (/back) and share one size, else side by side). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "cli/cli.h"
#include "core/parse.h"
#include "io/exr.h"
#include "io/png.h"
#include "prt/scene_light.h"
#include "render/renderer.h"
#include "tonemap/adapt.h"
#include "tonemap/drago.h"
#include "tonemap/foveal.h"
#include "view/cave.h"
#include "view/montage.h"
#include "view/offaxis.h"

static void help(FILE *f) {
  fprintf(f,
          "usage: cave render <cave.json> --scene scene.prt LIGHT [--head x,y,z --gaze x,y,z]\n"
          "                   [--frames N] [--dt S] [--size N] [--supersample 1|2]\n"
          "                   [--lum-res N] [--bg-res N] [--transfer T] [--cull-back] [--all-frames]\n"
          "                   [--gpu auto|software|N] [--split K [--split-grid W] [--split-samples N]]\n"
          "                   -o DIR\n\n"
          "Renders every wall and eye of the CAVE configuration with the EGL/OpenGL PRT\n"
          "renderer: per frame the luminance passes of all wall-eyes, the foveal adaptation\n"
          "statistics, one Pattanaik adaptation step of --dt seconds, then the shading\n"
          "passes tone-mapped with Drago at the adapted luminance.\n\n"
          "LIGHT is one of (as in `cave shade`)\n"
          "  --env FILE[,FILE...] [--weights w1,w2,...] [--scale S | --illuminance LUX|auto]\n"
          "                       [--no-sun]\n"
          CLI_ILLUMINANCE_HELP
          "  --env-constant R,G,B\n"
          "  --sky T,ELEV,AZIM    Preetham sky: turbidity 2..10, sun elevation, azimuth (deg)\n"
          "  [--yaw DEG] [--pitch DEG] [--roll DEG]   car orientation\n\n"
          "  --head x,y,z     tracked head position, CAVE coordinates (default: the config's)\n"
          "  --gaze x,y,z     gaze direction (default: the config's)\n"
          "  --split K        cut the K brightest window-visible cells of a W x W/2 grid\n"
          "                   (--split-grid, default 64) out of the map as directional lights\n"
          "                   with ray-traced visibility, as `cave shade --split` (their direct\n"
          "                   light per vertex on the CPU, --split-samples fan points per\n"
          "                   vertex, 1..4096, default 4; docs/reference.md).  The sun's\n"
          "                   direct light is per pixel (shadow map), as `cave shade\n"
          "                   --pixel-lights sun`\n"
          "  --frames N       frames to simulate (default 1)\n"
          "  --dt S           seconds per frame for the adaptation, 0.0333 or 1/30 (default 0.1)\n"
          "  --size N         render every wall at N pixels on its longer side (default: the\n"
          "                   config's resolution)\n"
          "  --supersample K  1 or 2 (default: the config's)\n"
          "  --lum-res N      luminance pass size (default: the config's, 128)\n"
          "  --bg-res N       width of the background lat-long texture (default 1024)\n"
          "  --transfer T     how the transfer vectors are stored: auto (default: half floats\n"
          "                   when the relight runs on the CPU, i.e. llvmpipe; floats on a\n"
          "                   GPU), float or half (relative pixel difference half/float:\n"
          "                   median 1.5e-4, p99 1.4e-3); --half = --transfer half\n"
          "  --cull-back      cull back faces (faster; only for closed, consistently wound\n"
          "                   meshes such as the built-in cabin)\n"
          "  --all-frames     write the images of every frame (default: the last one)\n"
          "  --gpu G          auto (default: the first hardware EGL device, else llvmpipe,\n"
          "                   said so), software (llvmpipe) or hardware device N (0..63);\n"
          "                   a device asked for and missing is an error, as in cave run\n"
          "  -o DIR           output folder (created if missing)\n\n"
          "Writes DIR/<wall>_<L|R>.exr (linear radiance), DIR/<wall>_<L|R>.png (Drago +\n"
          "Rec.709 transfer) and DIR/montage_L.png; with --all-frames the frame number is\n"
          "appended (<wall>_<eye>_f0003.png).  Prints the adaptation state per frame.\n\n"
          "Adaptation: the foveal cone (the config's foveal_deg around the gaze, from each\n"
          "eye) on the walls it touches gives the target log-average luminance; the first\n"
          "frame starts adapted to it (steady state), each later frame steps the Pattanaik\n"
          "model by --dt.  An empty cone keeps the state.  Drago's Lwmax is the maximum\n"
          "luminance of all walls' luminance passes.\n"
          "Textures of a textured .prt multiply each pixel's radiance (docs/prt-format.md);\n"
          "one that cannot be read is a warning and shows its mean albedo.\n"
          "\nexamples:\n"
          "  cave render configs/caves/cave5.json --scene scene.prt --env forest.exr --illuminance auto -o out\n"
          "  cave render configs/caves/cave5.json --scene scene.prt --sky 3,35,0 --frames 30 --dt 1/30 -o out\n");
}

static double now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/* Display values in [0, 1] to 8-bit RGB (rounded). */
static void to_rgb8(const cv_image *img, uint8_t *dst) {
  size_t n = (size_t)img->w * img->h * 3;
  for (size_t i = 0; i < n; i++) {
    float v = img->px[i];
    v = v > 0 ? (v < 1 ? v : 1) : 0;
    dst[i] = (uint8_t)lrintf(v * 255.0f);
  }
}

static int write_png(const char *path, const cv_image *img, cv_err *err) {
  uint8_t *px = malloc((size_t)img->w * img->h * 3);
  if (!px) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  to_rgb8(img, px);
  int st = cv_png_write(path, img->w, img->h, 3, px, err);
  free(px);
  return st;
}

/* --split: the window light split out of the map (cv_scene_light_split, on
 * a tracer of the PRT's mesh) and handed to the renderer with its direct
 * light per vertex (`samples` fan points, as `cave shade --split-samples`).  Returns 0 or the exit
 * status after printing the error. */
static int render_split(const cv_prt *prt, cv_scene_light *sl, cv_renderer *r, int k, int grid,
                        int samples) {
  cv_err err;
  cv_err_clear(&err);
  cv_mesh *m = NULL;
  cv_tracer *tr = NULL;
  float *direct = NULL;
  int rc = 1;
  const cv_dir_light *ex;
  if (cv_prt_to_mesh(prt, &m) || cv_tracer_create(m, &tr, &err)) {
    rc = cli_fail("render", 1, "--split: %s", err.msg[0] ? err.msg : "out of memory");
    goto out;
  }
  double t0 = now_ms();
  if (cv_scene_light_split(sl, tr, k, grid, &err)) {
    rc = cli_fail("render", 1, "--split: %s", err.msg);
    goto out;
  }
  const int n = cv_scene_light_extra(sl, &ex);
  if (!(direct = calloc(3 * prt->nv + 1, sizeof *direct)) ||
      cv_split_direct(prt, tr, ex, n, samples, direct)) {
    rc = cli_fail("render", 1, "--split: out of memory for the split lights' direct light");
    goto out;
  }
  if (cv_renderer_set_split(r, ex, n, direct, &err)) {
    rc = cli_fail("render", 1, "--split: %s", err.msg);
    goto out;
  }
  printf("split: %d window lights of a %d x %d grid, direct light traced per vertex in %.1f s\n",
         n, grid, grid / 2, (now_ms() - t0) / 1000.0);
  rc = 0;
out:
  free(direct);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
  return rc;
}

#define MAX_VIEWS (2 * CV_CAVE_MAX_WALLS)

/* The command line. */
typedef struct render_args {
  const char *cfg, *scene, *outdir, *weights;
  cv_light_spec spec;
  double head[3], gaze[3], dt;
  int have_head, have_gaze, frames, size, ss, lum_res, bg_res;
  int half, all_frames, cull_back, gpu, split, split_grid, split_samples;
} render_args;

#define PARSED (-1) /* parse_args: go on */

/* Reads the options into *a: PARSED, or the exit status (0 after --help). */
static int parse_args(int argc, char **argv, render_args *a) {
  memset(a, 0, sizeof *a);
  cv_light_spec_default(&a->spec);
  a->dt = 0.1, a->frames = 1, a->bg_res = 1024, a->gpu = CV_GPU_AUTO, a->half = -1;
  a->split_grid = 64, a->split_samples = CV_SPLIT_SAMPLES_DEFAULT;
  for (int i = 1; i < argc; i++) {
    const char *o = argv[i], *val = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(o, "--help") || !strcmp(o, "-h")) {
      help(stdout);
      return 0;
    }
    if (!strcmp(o, "--no-sun")) {
      a->spec.extract_sun = 0;
      continue;
    }
    int st = cli_parse_light("render", argc, argv, &i, &a->spec, &a->weights);
    if (st < 0) return -st;
    if (st) continue;
    if (!strcmp(o, "--gpu")) {
      if (!val || cv_gpu_parse(val, &a->gpu))
        return cli_fail("render", 2, "--gpu: expected auto, software or a hardware device index 0..63, got '%s'", val ? val : "(nothing)");
      i++;
    } else if (!strcmp(o, "--transfer")) {
      if (!val || cv_render_transfer_parse(val, &a->half))
        return cli_fail("render", 2, "--transfer: expected auto, float or half, got '%s'", val ? val : "(nothing)");
      i++;
    } else if (!strcmp(o, "--half")) {
      a->half = 1;
    } else if (!strcmp(o, "--cull-back")) {
      a->cull_back = 1;
    } else if (!strcmp(o, "--all-frames")) {
      a->all_frames = 1;
    } else if (o[0] != '-') {
      if (a->cfg) return cli_fail("render", 2, "more than one CAVE config ('%s' and '%s')", a->cfg, o);
      a->cfg = o;
    } else if (!val) {
      static const char *const value_opts[] = {
          "-o", "--scene", "--head", "--gaze", "--frames", "--dt", "--size", "--supersample",
          "--lum-res", "--split", "--split-samples", "--split-grid", "--bg-res", "--gpu",
          "--transfer", NULL};
      return cli_value_missing("render", help, o, value_opts);
    } else if (!strcmp(o, "-o")) {
      a->outdir = argv[++i];
    } else if (!strcmp(o, "--scene")) {
      a->scene = argv[++i];
    } else if (!strcmp(o, "--head")) {
      if (cli_parse_vec(argv[++i], 3, a->head)) return cli_fail("render", 2, "--head: expected x,y,z, got '%s'", val);
      a->have_head = 1;
    } else if (!strcmp(o, "--gaze")) {
      const double *g = a->gaze;
      if (cli_parse_vec(argv[++i], 3, a->gaze) || !(fabs(g[0]) + fabs(g[1]) + fabs(g[2]) > 0))
        return cli_fail("render", 2, "--gaze: expected a non-zero x,y,z, got '%s'", val);
      a->have_gaze = 1;
    } else if (!strcmp(o, "--frames")) {
      if (cli_parse_int(argv[++i], 1, 1000000, &a->frames))
        return cli_fail("render", 2, "--frames: expected 1..1000000, got '%s'", val);
    } else if (!strcmp(o, "--dt")) {
      if (cv_parse_seconds(argv[++i], &a->dt) || a->dt < 0 || a->dt > 3600)
        return cli_fail("render", 2, "--dt: expected seconds in [0, 3600] (0.0333 or 1/30), got '%s'", val);
    } else if (!strcmp(o, "--size")) {
      if (cli_parse_int(argv[++i], 1, CV_CAVE_MAX_RES, &a->size))
        return cli_fail("render", 2, "--size: expected 1..%d pixels, got '%s'", CV_CAVE_MAX_RES, val);
    } else if (!strcmp(o, "--supersample")) {
      if (cli_parse_int(argv[++i], 1, 2, &a->ss))
        return cli_fail("render", 2, "--supersample: expected 1 or 2, got '%s'", val);
    } else if (!strcmp(o, "--lum-res")) {
      if (cli_parse_int(argv[++i], 1, 4096, &a->lum_res))
        return cli_fail("render", 2, "--lum-res: expected 1..4096, got '%s'", val);
    } else if (!strcmp(o, "--split")) {
      if (cli_parse_int(argv[++i], 0, 4096, &a->split))
        return cli_fail("render", 2, "--split: expected 0..4096 lights, got '%s'", val);
    } else if (!strcmp(o, "--split-samples")) {
      if (cli_parse_int(argv[++i], 1, 4096, &a->split_samples))
        return cli_fail("render", 2, "--split-samples: expected 1..4096, got '%s'", val);
    } else if (!strcmp(o, "--split-grid")) {
      if (cli_parse_int(argv[++i], 4, 1024, &a->split_grid) || a->split_grid % 2)
        return cli_fail("render", 2, "--split-grid: expected an even width 4..1024, got '%s'", val);
    } else if (!strcmp(o, "--bg-res")) {
      if (cli_parse_int(argv[++i], 2, 16384, &a->bg_res))
        return cli_fail("render", 2, "--bg-res: expected 2..16384, got '%s'", val);
    } else {
      cli_print_usage(help);
      return cli_fail("render", 2, "unknown option '%s'", o);
    }
  }
  if (!a->cfg || !a->scene || !a->outdir) {
    cli_print_usage(help);
    return cli_fail("render", 2, "a CAVE config, --scene FILE.prt and -o DIR are required");
  }
  if (a->spec.kind == CV_LIGHT_NONE)
    return cli_fail("render", 2, "no lighting: give --env, --env-constant or --sky");
  int wst = cli_apply_weights("render", &a->spec, a->weights);
  return wst ? wst : PARSED;
}

static const char *const EYE_NAME[2] = {"L", "R"};

/* The CAVE config with the command line's head, gaze, sizes applied, and
 * the two eyes: 0 or the exit status (printed). */
static int load_cave(const render_args *a, cv_cave *cave, double eyes[2][3]) {
  cv_err err;
  cv_err_clear(&err);
  if (cv_cave_load(a->cfg, cave, &err)) return cli_fail("render", 1, "%s", err.msg);
  if (a->have_head) memcpy(cave->head, a->head, sizeof a->head);
  if (a->have_gaze) {
    const double *g = a->gaze, n = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
    for (int k = 0; k < 3; k++) cave->gaze[k] = g[k] / n;
  }
  if (a->ss) cave->supersample = a->ss;
  if (a->lum_res) cave->lum_res = a->lum_res;
  cv_cave_fit_res(cave, a->size);
  cv_head_eyes(cave->head, cave->gaze, cave->eye_separation, eyes[0], eyes[1]);
  for (int e = 0; e < 2; e++)
    if (cv_cave_check_eye(cave, eyes[e], &err))
      return cli_fail("render", 1, "%s: %s eye (%.3f, %.3f, %.3f): %s", a->cfg, e ? "right" : "left",
                      eyes[e][0], eyes[e][1], eyes[e][2], err.msg);
  return 0;
}

/* What a render holds: the scene, its light and renderer, the views and
 * their images, the shared adaptation state. */
typedef struct render_job {
  const render_args *a;
  cv_cave cave;
  double eyes[2][3];
  cv_prt *prt;
  cv_scene_light *sl;
  cv_renderer *r;
  cv_image *bg, *lum[MAX_VIEWS], *disp[MAX_VIEWS], *hdr[MAX_VIEWS];
  cv_render_view views[MAX_VIEWS];
  int nviews;
  cv_adapt_params ap;
  cv_adapt_feed adf; /* the adaptation (the master's policy) */
} render_job;

/* The renderer on the scene, its textures reported, the split lights
 * (--split): 0 or the exit status (printed). */
static int start_renderer(render_job *j) {
  const render_args *a = j->a;
  cv_err err;
  cv_err_clear(&err);
  if (cv_prt_read(a->scene, &j->prt, &err) ||
      cv_scene_light_build(&a->spec, (int)j->prt->bands, &j->sl, &err))
    return cli_fail("render", 1, "%s", err.msg);
  cv_scene_light_print(stdout, j->sl);
  cv_render_opts ro;
  cv_render_default_opts(&ro);
  ro.half_transfer = a->half;
  ro.cull_back = a->cull_back;
  ro.gpu = a->gpu;
  if (cv_renderer_create(j->prt, &ro, &j->r, &err)) return cli_fail("render", 1, "%s", err.msg);
  printf("GL: %s\n", cv_renderer_gl_name(j->r));
  cv_render_tex_info ti;
  if (cv_renderer_textures(j->r, &ti))
    printf("textures: %d materials, %d x %d texels per layer, %zu vertices added at UV seams\n",
           ti.layers, ti.w, ti.h, ti.split_vertices);
  if (ti.unread)
    printf("warning: %d textures could not be read and show their mean albedo; first: %s\n",
           ti.unread, ti.first_error);
  if (a->split) return render_split(j->prt, j->sl, j->r, a->split, a->split_grid, a->split_samples);
  return 0;
}

/* The lighting: background, relight, the sun's split and shadow map, and
 * the line that says what they cost and what was used: 0 or the exit
 * status (printed). */
static int light_scene(render_job *j) {
  cv_err err;
  cv_err_clear(&err);
  cv_lighting light = cv_scene_light_sh(j->sl);
  cv_render_light_stats ls;
  cv_frame_timing lt = {0};
  if (cv_render_background_image(j->sl, j->a->bg_res, &j->bg) ||
      cv_renderer_set_background(j->r, j->bg, &err) ||
      cv_renderer_set_lighting(j->r, &light, &ls, &lt, &err))
    return cli_fail("render", 1, "%s", err.msg[0] ? err.msg : "cannot build the background");
  cv_shadow_casters sc;
  cv_renderer_shadow_casters(j->r, &sc);
  char casters[224] = "";
  if (sc.built)
    snprintf(casters, sizeof casters, " of %zu shadow casters (the mesh's %zu opaque triangles "
             "simplified within %.3f mm%s; built in %.0f ms, counted in the map's time)",
             sc.triangles, sc.mesh_triangles, 1e3 * sc.error_m,
             sc.culled ? ", those facing away from the sun" : "", sc.build_ms);
  printf("scene: %zu vertices, %zu triangles, %u bands; relit %s from %s transfer in %.1f ms (%llu channels "
         "clamped from negative), sun shadow map%s %.1f ms%s\n",
         j->prt->nv, j->prt->nt, j->prt->bands,
         cv_renderer_relight_on_cpu(j->r) ? "on the CPU" : "on the GPU",
         cv_renderer_half_transfer(j->r) ? "half-float" : "float", lt.relight_ms,
         (unsigned long long)ls.clamped, casters, lt.shadow_ms, light.has_sun ? "" : " (no sun)");
  return 0;
}

/* Every wall-eye's off-axis view and its images: 0 or the exit status. */
static int make_views(render_job *j) {
  const cv_cave *cave = &j->cave;
  j->nviews = 2 * cave->n_walls;
  for (int i = 0; i < j->nviews; i++) {
    const cv_wall *w = &cave->walls[i / 2];
    cv_render_view *v = &j->views[i];
    memset(v, 0, sizeof *v);
    if (cv_offaxis_compute(w->pa, w->pb, w->pc, j->eyes[i % 2], cave->near, cave->far, &v->proj))
      return cli_fail("render", 1, "%s: walls '%s': no off-axis projection for the %s eye",
                      j->a->cfg, w->name, i % 2 ? "right" : "left");
    memcpy(v->scene_offset, cave->scene_offset, sizeof v->scene_offset);
    v->w = w->res[0], v->h = w->res[1], v->supersample = cave->supersample;
    if (cv_image_create(cave->lum_res, cave->lum_res, 1, &j->lum[i]) ||
        cv_image_create(v->w, v->h, 3, &j->disp[i]) || cv_image_create(v->w, v->h, 3, &j->hdr[i]))
      return cli_fail("render", 1, "out of memory for %dx%d images", v->w, v->h);
  }
  printf("CAVE %s: %d walls x 2 eyes, head (%.3f, %.3f, %.3f), gaze (%.3f, %.3f, %.3f), foveal cone "
         "%.1f deg, luminance pass %dx%d, supersample %d\n",
         j->a->cfg, cave->n_walls, cave->head[0], cave->head[1], cave->head[2], cave->gaze[0],
         cave->gaze[1], cave->gaze[2], cave->foveal_deg, cave->lum_res, cave->lum_res,
         cave->supersample);
  return 0;
}

/* One frame's foveal statistics (step 2 of the file's comment). */
typedef struct frame_stats {
  cv_lumstats acc;   /* the foveal cone over the walls it touches, both eyes */
  double lwmax;
  char touched[256]; /* the walls the cone touches */
} frame_stats;

static void foveal_stats(const render_job *j, frame_stats *fs) {
  memset(fs, 0, sizeof *fs);
  const cv_cave *cave = &j->cave;
  const double half_angle = 0.5 * cave->foveal_deg * M_PI / 180.0;
  for (int i = 0; i < j->nviews; i++) {
    const cv_wall *w = &cave->walls[i / 2];
    const cv_image *L = j->lum[i];
    /* Lwmax over every pixel */
    for (int k = 0; k < L->w * L->h; k++) {
      float y = L->px[k];
      if (!(y >= 0) || !isfinite(y)) continue;
      if (y > fs->lwmax) fs->lwmax = y;
    }
    if (!cv_foveal_touches(w->pa, w->pb, w->pc, j->eyes[i % 2], cave->gaze, half_angle)) continue;
    cv_lumstats s = {0};
    cv_foveal_accumulate(L->px, L->w, L->h, w->pa, w->pb, w->pc, j->eyes[i % 2], cave->gaze,
                         half_angle, &s);
    cv_lumstats_merge(&fs->acc, &s);
    if (i % 2 == 0 && strlen(fs->touched) + strlen(w->name) + 2 < sizeof fs->touched) {
      if (fs->touched[0]) strcat(fs->touched, ",");
      strcat(fs->touched, w->name);
    }
  }
}

/* Step 3: the adaptation towards the cone's log-average *g (set here), by
 * the policy cave run's master uses (cv_adapt_feed_frame: frame 0 starts in
 * steady state at its own foveal luminance, an empty cone keeps the state
 * and its time waits): 0 or the exit status. */
static int adapt(render_job *j, const frame_stats *fs, int f, double *g) {
  const int have = cv_lumstats_lwa(&fs->acc, g) == 1;
  if (!have)
    printf("frame %d: foveal cone empty, adaptation state kept%s\n", f,
           j->adf.s.initialised ? "" : " (1 cd/m2 until the cone sees a wall)");
  if (cv_adapt_feed_frame(&j->adf, &j->ap, f == 0 ? 0.0 : j->a->dt, have, have ? *g : 0) < 0)
    return cli_fail("render", 1, "adaptation step failed (target %g cd/m2, dt %g s)", *g, j->a->dt);
  return 0;
}

/* View i's EXR and PNG of frame f: 0 or the exit status. */
static int write_view(const render_job *j, int i, int f) {
  cv_err err;
  cv_err_clear(&err);
  char path[4096], suffix[32] = "";
  if (j->a->all_frames) snprintf(suffix, sizeof suffix, "_f%04d", f);
  const char *wall = j->cave.walls[i / 2].name;
  snprintf(path, sizeof path, "%s/%s_%s%s.exr", j->a->outdir, wall, EYE_NAME[i % 2], suffix);
  if (cv_exr_write(path, j->hdr[i], 0, CV_EXR_ZIP, &err)) return cli_fail("render", 1, "%s", err.msg);
  snprintf(path, sizeof path, "%s/%s_%s%s.png", j->a->outdir, wall, EYE_NAME[i % 2], suffix);
  if (write_png(path, j->disp[i], &err)) return cli_fail("render", 1, "%s", err.msg);
  return 0;
}

/* One frame in the phases of the file's comment: 0 or the exit status. */
static int render_frame(render_job *j, int f) {
  const render_args *a = j->a;
  const int write = f == a->frames - 1 || a->all_frames;
  double t_lum = 0, t_shade = 0, t_write = 0;
  cv_err err;
  cv_err_clear(&err);
  /* 1. luminance passes */
  for (int i = 0; i < j->nviews; i++) {
    double t0 = now_ms();
    if (cv_renderer_luminance(j->r, &j->views[i], j->lum[i], NULL, &err))
      return cli_fail("render", 1, "wall '%s' %s eye: %s", j->cave.walls[i / 2].name,
                      EYE_NAME[i % 2], err.msg);
    t_lum += now_ms() - t0;
  }
  /* 2. foveal statistics (both eyes, the walls the cone touches) and Lwmax */
  double t0 = now_ms();
  frame_stats fs;
  foveal_stats(j, &fs);
  double t_stats = now_ms() - t0;
  /* 3. adaptation */
  double g = 0;
  int st = adapt(j, &fs, f, &g);
  if (st) return st;
  cv_drago d = {.bias = j->cave.drago_bias, .ldmax = j->cave.drago_ldmax,
                .lwa = cv_adapt_lwa(&j->adf.s), .lwmax = fs.lwmax};
  cv_drago_consts dc;
  cv_drago_prepare(&d, &dc);
  /* 4. depth + shading passes, outputs */
  for (int i = 0; i < j->nviews; i++) {
    double s0 = now_ms();
    if (cv_renderer_shade(j->r, &j->views[i], &dc, 1, j->disp[i], write ? j->hdr[i] : NULL, NULL,
                          &err))
      return cli_fail("render", 1, "wall '%s' %s eye: %s", j->cave.walls[i / 2].name,
                      EYE_NAME[i % 2], err.msg);
    t_shade += now_ms() - s0;
    if (!write) continue;
    s0 = now_ms();
    if ((st = write_view(j, i, f))) return st;
    t_write += now_ms() - s0;
  }
  const cv_adapt_state *as = &j->adf.s;
  printf("frame %d (t = %.3f s): foveal %s on %s (%llu px, %.3g sr), Lwmax %.4g; adapted Lwa %.4g "
         "cd/m2 (cones A %.4g B %.4f, rods A %.4g B %.4f); luminance passes %.1f ms, stats %.3f "
         "ms, depth+shading %.1f ms (%.1f ms per wall-eye)\n",
         f, f * a->dt, fs.acc.weight > 0 ? "Lwa" : "cone empty",
         fs.touched[0] ? fs.touched : "no wall", (unsigned long long)fs.acc.n_pixels,
         fs.acc.weight, fs.lwmax, cv_adapt_lwa(as), as->a_cone, as->b_cone, as->a_rod, as->b_rod,
         t_lum, t_stats, t_shade, t_shade / j->nviews);
  if (fs.acc.weight > 0) printf("          foveal log-average %.4g cd/m2, %llu invalid pixels\n", g,
                                (unsigned long long)fs.acc.n_invalid);
  if (!write) return 0;
  char path[4096], suffix[32] = "";
  if (a->all_frames) snprintf(suffix, sizeof suffix, "_f%04d", f);
  cv_image *left[CV_CAVE_MAX_WALLS];
  for (int w = 0; w < j->cave.n_walls; w++) left[w] = j->disp[2 * w];
  snprintf(path, sizeof path, "%s/montage_L%s.png", a->outdir, suffix);
  if (cv_montage_write(path, &j->cave, left, &err)) return cli_fail("render", 1, "%s", err.msg);
  printf("          wrote %d EXR + %d PNG and %s (%.0f ms)\n", j->nviews, j->nviews, path, t_write);
  return 0;
}

static void render_job_free(render_job *j) {
  for (int i = 0; i < MAX_VIEWS; i++) {
    cv_image_destroy(j->lum[i]);
    cv_image_destroy(j->disp[i]);
    cv_image_destroy(j->hdr[i]);
  }
  cv_image_destroy(j->bg);
  cv_renderer_destroy(j->r);
  cv_scene_light_destroy(j->sl);
  cv_prt_destroy(j->prt);
}

int cmd_render(int argc, char **argv) {
  render_args a;
  int rc = parse_args(argc, argv, &a);
  if (rc != PARSED) return rc;
  render_job *j = calloc(1, sizeof *j);
  if (!j) return cli_fail("render", 1, "out of memory");
  j->a = &a;
  if (!(rc = load_cave(&a, &j->cave, j->eyes)) && !(rc = start_renderer(j)) &&
      !(rc = light_scene(j)) && !(rc = make_views(j))) {
    if (mkdir(a.outdir, 0777) && errno != EEXIST) {
      rc = cli_fail("render", 1, "-o %s: cannot create the folder (%s)", a.outdir, strerror(errno));
    } else {
      cv_adapt_default_params(&j->ap);
      j->ap.t0_cone = j->cave.t0_cone, j->ap.t0_rod = j->cave.t0_rod;
      j->ap.tau_cone = j->cave.tau_cone, j->ap.tau_rod = j->cave.tau_rod;
      for (int f = 0; f < a.frames && !rc; f++) rc = render_frame(j, f);
    }
  }
  render_job_free(j);
  free(j);
  return rc;
}
