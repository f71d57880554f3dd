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
          "                   [--lum-res N] [--bg-res N] [--half] [--cull-back] [--all-frames]\n"
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
          "  --half           store transfer vectors as half floats on the GPU\n"
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

int cmd_render(int argc, char **argv) {
  const char *cfg = NULL, *scene = NULL, *outdir = NULL, *weights = NULL;
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  double head[3], gaze[3], dt = 0.1;
  int have_head = 0, have_gaze = 0, frames = 1, size = 0, ss = 0, lum_res = 0, bg_res = 1024;
  int half = 0, all_frames = 0, cull_back = 0, gpu = CV_GPU_AUTO, split = 0, split_grid = 64,
      split_samples = CV_SPLIT_SAMPLES_DEFAULT;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *val = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    }
    if (!strcmp(a, "--no-sun")) {
      spec.extract_sun = 0;
      continue;
    }
    int st = cli_parse_light("render", argc, argv, &i, &spec, &weights);
    if (st < 0) return -st;
    if (st) continue;
    if (!strcmp(a, "--gpu")) {
      if (!val || cv_gpu_parse(val, &gpu))
        return cli_fail("render", 2, "--gpu: expected auto, software or a hardware device index 0..63, got '%s'", val ? val : "(nothing)");
      i++;
    } else if (!strcmp(a, "--half")) {
      half = 1;
    } else if (!strcmp(a, "--cull-back")) {
      cull_back = 1;
    } else if (!strcmp(a, "--all-frames")) {
      all_frames = 1;
    } else if (a[0] != '-') {
      if (cfg) return cli_fail("render", 2, "more than one CAVE config ('%s' and '%s')", cfg, a);
      cfg = a;
    } else if (!val) {
      cli_print_usage(help);
      return cli_fail("render", 2, "unknown or incomplete option '%s'", a);
    } else if (!strcmp(a, "-o")) {
      outdir = argv[++i];
    } else if (!strcmp(a, "--scene")) {
      scene = argv[++i];
    } else if (!strcmp(a, "--head")) {
      if (cli_parse_vec(argv[++i], 3, head)) return cli_fail("render", 2, "--head: expected x,y,z, got '%s'", val);
      have_head = 1;
    } else if (!strcmp(a, "--gaze")) {
      if (cli_parse_vec(argv[++i], 3, gaze) || !(fabs(gaze[0]) + fabs(gaze[1]) + fabs(gaze[2]) > 0))
        return cli_fail("render", 2, "--gaze: expected a non-zero x,y,z, got '%s'", val);
      have_gaze = 1;
    } else if (!strcmp(a, "--frames")) {
      if (cli_parse_int(argv[++i], 1, 1000000, &frames))
        return cli_fail("render", 2, "--frames: expected 1..1000000, got '%s'", val);
    } else if (!strcmp(a, "--dt")) {
      if (cv_parse_seconds(argv[++i], &dt) || dt < 0 || dt > 3600)
        return cli_fail("render", 2, "--dt: expected seconds in [0, 3600] (0.0333 or 1/30), got '%s'", val);
    } else if (!strcmp(a, "--size")) {
      if (cli_parse_int(argv[++i], 1, CV_CAVE_MAX_RES, &size))
        return cli_fail("render", 2, "--size: expected 1..%d pixels, got '%s'", CV_CAVE_MAX_RES, val);
    } else if (!strcmp(a, "--supersample")) {
      if (cli_parse_int(argv[++i], 1, 2, &ss))
        return cli_fail("render", 2, "--supersample: expected 1 or 2, got '%s'", val);
    } else if (!strcmp(a, "--lum-res")) {
      if (cli_parse_int(argv[++i], 1, 4096, &lum_res))
        return cli_fail("render", 2, "--lum-res: expected 1..4096, got '%s'", val);
    } else if (!strcmp(a, "--split")) {
      if (cli_parse_int(argv[++i], 0, 4096, &split))
        return cli_fail("render", 2, "--split: expected 0..4096 lights, got '%s'", val);
    } else if (!strcmp(a, "--split-samples")) {
      if (cli_parse_int(argv[++i], 1, 4096, &split_samples))
        return cli_fail("render", 2, "--split-samples: expected 1..4096, got '%s'", val);
    } else if (!strcmp(a, "--split-grid")) {
      if (cli_parse_int(argv[++i], 4, 1024, &split_grid) || split_grid % 2)
        return cli_fail("render", 2, "--split-grid: expected an even width 4..1024, got '%s'", val);
    } else if (!strcmp(a, "--bg-res")) {
      if (cli_parse_int(argv[++i], 2, 16384, &bg_res))
        return cli_fail("render", 2, "--bg-res: expected 2..16384, got '%s'", val);
    } else {
      cli_print_usage(help);
      return cli_fail("render", 2, "unknown option '%s'", a);
    }
  }
  if (!cfg || !scene || !outdir) {
    cli_print_usage(help);
    return cli_fail("render", 2, "a CAVE config, --scene FILE.prt and -o DIR are required");
  }
  if (spec.kind == CV_LIGHT_NONE)
    return cli_fail("render", 2, "no lighting: give --env, --env-constant or --sky");
  int wst = cli_apply_weights("render", &spec, weights);
  if (wst) return wst;

  cv_err err;
  cv_err_clear(&err);
  cv_cave cave;
  if (cv_cave_load(cfg, &cave, &err)) return cli_fail("render", 1, "%s", err.msg);
  if (have_head) memcpy(cave.head, head, sizeof head);
  if (have_gaze) {
    double n = sqrt(gaze[0] * gaze[0] + gaze[1] * gaze[1] + gaze[2] * gaze[2]);
    for (int k = 0; k < 3; k++) cave.gaze[k] = gaze[k] / n;
  }
  if (ss) cave.supersample = ss;
  if (lum_res) cave.lum_res = lum_res;
  cv_cave_fit_res(&cave, size);
  double eyes[2][3];
  cv_head_eyes(cave.head, cave.gaze, cave.eye_separation, eyes[0], eyes[1]);
  static const char *eye_name[2] = {"L", "R"};
  for (int e = 0; e < 2; e++)
    if (cv_cave_check_eye(&cave, eyes[e], &err))
      return cli_fail("render", 1, "%s: %s eye (%.3f, %.3f, %.3f): %s", cfg, e ? "right" : "left",
                      eyes[e][0], eyes[e][1], eyes[e][2], err.msg);

  int rc = 1;
  cv_prt *prt = NULL;
  cv_scene_light *sl = NULL;
  cv_renderer *r = NULL;
  cv_image *bg = NULL, *lum[MAX_VIEWS] = {0}, *disp[MAX_VIEWS] = {0}, *hdr[MAX_VIEWS] = {0};
  cv_render_view views[MAX_VIEWS];
  const int nviews = 2 * cave.n_walls;
  if (cv_prt_read(scene, &prt, &err)) {
    rc = cli_fail("render", 1, "%s", err.msg);
    goto done;
  }
  if (cv_scene_light_build(&spec, (int)prt->bands, &sl, &err)) {
    rc = cli_fail("render", 1, "%s", err.msg);
    goto done;
  }
  cv_scene_light_print(stdout, sl);
  cv_render_opts ro;
  cv_render_default_opts(&ro);
  ro.half_transfer = half;
  ro.cull_back = cull_back;
  ro.gpu = gpu;
  if (cv_renderer_create(prt, &ro, &r, &err)) {
    rc = cli_fail("render", 1, "%s", err.msg);
    goto done;
  }
  printf("GL: %s\n", cv_renderer_gl_name(r));
  cv_render_tex_info ti;
  if (cv_renderer_textures(r, &ti))
    printf("textures: %d materials, %d x %d texels per layer, %zu vertices added at UV seams\n",
           ti.layers, ti.w, ti.h, ti.split_vertices);
  if (ti.unread)
    printf("warning: %d textures could not be read and show their mean albedo; first: %s\n",
           ti.unread, ti.first_error);
  if (split && (rc = render_split(prt, sl, r, split, split_grid, split_samples)) != 0) goto done;
  rc = 1;
  cv_lighting light = cv_scene_light_sh(sl);
  cv_render_light_stats ls;
  cv_frame_timing lt = {0};
  if (cv_render_background_image(sl, bg_res, &bg) || cv_renderer_set_background(r, bg, &err) ||
      cv_renderer_set_lighting(r, &light, &ls, &lt, &err)) {
    rc = cli_fail("render", 1, "%s", err.msg[0] ? err.msg : "cannot build the background");
    goto done;
  }
  printf("scene: %zu vertices, %zu triangles, %u bands; relit on the GPU in %.1f ms (%llu channels "
         "clamped from negative), sun shadow map %.1f ms%s\n",
         prt->nv, prt->nt, prt->bands, lt.relight_ms, (unsigned long long)ls.clamped, lt.shadow_ms,
         light.has_sun ? "" : " (no sun)");
  for (int i = 0; i < nviews; i++) {
    const cv_wall *w = &cave.walls[i / 2];
    cv_render_view *v = &views[i];
    memset(v, 0, sizeof *v);
    if (cv_offaxis_compute(w->pa, w->pb, w->pc, eyes[i % 2], cave.near, cave.far, &v->proj)) {
      rc = cli_fail("render", 1, "%s: walls '%s': no off-axis projection for the %s eye", cfg,
                    w->name, i % 2 ? "right" : "left");
      goto done;
    }
    memcpy(v->scene_offset, cave.scene_offset, sizeof v->scene_offset);
    v->w = w->res[0], v->h = w->res[1], v->supersample = cave.supersample;
    if (cv_image_create(cave.lum_res, cave.lum_res, 1, &lum[i]) ||
        cv_image_create(v->w, v->h, 3, &disp[i]) || cv_image_create(v->w, v->h, 3, &hdr[i])) {
      rc = cli_fail("render", 1, "out of memory for %dx%d images", v->w, v->h);
      goto done;
    }
  }
  printf("CAVE %s: %d walls x 2 eyes, head (%.3f, %.3f, %.3f), gaze (%.3f, %.3f, %.3f), foveal cone "
         "%.1f deg, luminance pass %dx%d, supersample %d\n",
         cfg, cave.n_walls, cave.head[0], cave.head[1], cave.head[2], cave.gaze[0], cave.gaze[1],
         cave.gaze[2], cave.foveal_deg, cave.lum_res, cave.lum_res, cave.supersample);

  if (mkdir(outdir, 0777) && errno != EEXIST) {
    rc = cli_fail("render", 1, "-o %s: cannot create the folder (%s)", outdir, strerror(errno));
    goto done;
  }
  cv_adapt_params ap;
  cv_adapt_default_params(&ap);
  ap.t0_cone = cave.t0_cone, ap.t0_rod = cave.t0_rod;
  ap.tau_cone = cave.tau_cone, ap.tau_rod = cave.tau_rod;
  cv_adapt_state as;
  memset(&as, 0, sizeof as);
  const double half_angle = 0.5 * cave.foveal_deg * M_PI / 180.0;
  for (int f = 0; f < frames; f++) {
    const int last = f == frames - 1, write = last || all_frames;
    double t_lum = 0, t_shade = 0, t_write = 0;
    /* 1. luminance passes */
    for (int i = 0; i < nviews; i++) {
      double t0 = now_ms();
      if (cv_renderer_luminance(r, &views[i], lum[i], NULL, &err)) {
        rc = cli_fail("render", 1, "wall '%s' %s eye: %s", cave.walls[i / 2].name, eye_name[i % 2],
                      err.msg);
        goto done;
      }
      t_lum += now_ms() - t0;
    }
    /* 2. foveal statistics (both eyes, the walls the cone touches) and Lwmax */
    double t0 = now_ms();
    cv_lumstats acc = {0};
    double lwmax = 0, sum_log_all = 0;
    uint64_t n_all = 0;
    char touched[256] = "";
    for (int i = 0; i < nviews; i++) {
      const cv_wall *w = &cave.walls[i / 2];
      const cv_image *L = lum[i];
      /* Lwmax over every pixel; the log-average of everything only when the
       * adaptation has no state yet (first frame, empty cone). */
      const int need_all = !as.initialised;
      for (int k = 0; k < L->w * L->h; k++) {
        float y = L->px[k];
        if (!(y >= 0) || !isfinite(y)) continue;
        if (y > lwmax) lwmax = y;
        if (need_all) {
          sum_log_all += log(y + CV_LUM_EPS);
          n_all++;
        }
      }
      if (!cv_foveal_touches(w->pa, w->pb, w->pc, eyes[i % 2], cave.gaze, half_angle)) continue;
      cv_lumstats s = {0};
      cv_foveal_accumulate(L->px, L->w, L->h, w->pa, w->pb, w->pc, eyes[i % 2], cave.gaze,
                           half_angle, &s);
      cv_lumstats_merge(&acc, &s);
      if (i % 2 == 0 && strlen(touched) + strlen(w->name) + 2 < sizeof touched) {
        if (touched[0]) strcat(touched, ",");
        strcat(touched, w->name);
      }
    }
    double t_stats = now_ms() - t0;
    /* 3. adaptation */
    double g;
    int have = cv_lumstats_lwa(&acc, &g);
    if (!have && !as.initialised && n_all) {
      g = exp(sum_log_all / (double)n_all);
      have = 1;
      printf("frame %d: foveal cone empty; adaptation starts from the log-average of all walls\n", f);
    }
    if (have) {
      if (cv_adapt_step(&as, &ap, g, f == 0 ? 0.0 : dt)) {
        rc = cli_fail("render", 1, "adaptation step failed (target %g cd/m2, dt %g s)", g, dt);
        goto done;
      }
    } else {
      printf("frame %d: foveal cone empty, adaptation state kept\n", f);
    }
    cv_drago d = {.bias = cave.drago_bias, .ldmax = cave.drago_ldmax, .lwa = cv_adapt_lwa(&as),
                  .lwmax = lwmax};
    cv_drago_consts dc;
    cv_drago_prepare(&d, &dc);
    /* 4. depth + shading passes, outputs */
    cv_frame_timing sum = {0};
    for (int i = 0; i < nviews; i++) {
      cv_frame_timing t = {0};
      double s0 = now_ms();
      if (cv_renderer_shade(r, &views[i], &dc, 1, disp[i], write ? hdr[i] : NULL, &t, &err)) {
        rc = cli_fail("render", 1, "wall '%s' %s eye: %s", cave.walls[i / 2].name, eye_name[i % 2],
                      err.msg);
        goto done;
      }
      t_shade += now_ms() - s0;
      sum.depth_ms += t.depth_ms, sum.shade_ms += t.shade_ms;
      if (!write) continue;
      s0 = now_ms();
      char path[4096], suffix[32] = "";
      if (all_frames) snprintf(suffix, sizeof suffix, "_f%04d", f);
      snprintf(path, sizeof path, "%s/%s_%s%s.exr", outdir, cave.walls[i / 2].name, eye_name[i % 2],
               suffix);
      if (cv_exr_write(path, hdr[i], 0, CV_EXR_ZIP, &err)) {
        rc = cli_fail("render", 1, "%s", err.msg);
        goto done;
      }
      snprintf(path, sizeof path, "%s/%s_%s%s.png", outdir, cave.walls[i / 2].name, eye_name[i % 2],
               suffix);
      if (write_png(path, disp[i], &err)) {
        rc = cli_fail("render", 1, "%s", err.msg);
        goto done;
      }
      t_write += now_ms() - s0;
    }
    printf("frame %d (t = %.3f s): foveal %s on %s (%llu px, %.3g sr), Lwmax %.4g; adapted Lwa %.4g "
           "cd/m2 (cones A %.4g B %.4f, rods A %.4g B %.4f); luminance passes %.1f ms, stats %.3f "
           "ms, depth+shading %.1f ms (%.1f ms per wall-eye)\n",
           f, f * dt, acc.weight > 0 ? "Lwa" : "cone empty",
           touched[0] ? touched : "no wall", (unsigned long long)acc.n_pixels, acc.weight, lwmax,
           cv_adapt_lwa(&as), as.a_cone, as.b_cone, as.a_rod, as.b_rod, t_lum, t_stats, t_shade,
           t_shade / nviews);
    if (acc.weight > 0) printf("          foveal log-average %.4g cd/m2, %llu invalid pixels\n", g,
                               (unsigned long long)acc.n_invalid);
    if (write) {
      char path[4096], suffix[32] = "";
      if (all_frames) snprintf(suffix, sizeof suffix, "_f%04d", f);
      cv_image *left[CV_CAVE_MAX_WALLS];
      for (int w = 0; w < cave.n_walls; w++) left[w] = disp[2 * w];
      snprintf(path, sizeof path, "%s/montage_L%s.png", outdir, suffix);
      if (cv_montage_write(path, &cave, left, &err)) {
        rc = cli_fail("render", 1, "%s", err.msg);
        goto done;
      }
      printf("          wrote %d EXR + %d PNG and %s (%.0f ms)\n", nviews, nviews, path, t_write);
    }
  }
  rc = 0;
done:
  for (int i = 0; i < MAX_VIEWS; i++) {
    cv_image_destroy(lum[i]);
    cv_image_destroy(disp[i]);
    cv_image_destroy(hdr[i]);
  }
  cv_image_destroy(bg);
  cv_renderer_destroy(r);
  cv_scene_light_destroy(sl);
  cv_prt_destroy(prt);
  return rc;
}
