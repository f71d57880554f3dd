/* `cave reference`: the independent judge of the PRT pipeline.  Renders the
 * view of `cave shade --view` with an unbiased path tracer (src/ref/) that
 * shares no transfer code with the bake, and writes a linear EXR, its
 * per-pixel standard error and optionally a PNG preview. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <omp.h>

#include "cli/cli.h"
#include "io/exr.h"
#include "io/tonemap_simple.h"
#include "prt/prt.h"
#include "ref/ref.h"

static void help(FILE *f) {
  fprintf(f,
          "usage: cave reference <scene.prt | scene.json | mesh.obj|.ply|.gltf|.glb | default>\n"
          "                      LIGHT --view x,y,z --look x,y,z [--view-up x,y,z] [--fov DEG]\n"
          "                      [--size WxH] [--spp N] [--pass N] [--bounces N] [--seed S]\n"
          "                      [--tess N] [--threads N] [--error se.exr] [--png]\n"
          "                      [--exposure E] [--ids ids.exr] [--quiet] -o view.exr\n\n"
          "Unbiased Monte Carlo path tracer of the car interior: Lambert surfaces with each\n"
          "triangle's material albedo, the environment seen only through window triangles,\n"
          "next-event estimation of the map (luminance alias table) and of the window\n"
          "openings (area sampling), both MIS-weighted with the cosine lobe, and of the\n"
          "sky's sun; Russian roulette.  Shares no transfer code\n"
          "with the PRT bake: use it to measure `cave shade --view` (same camera, one ray\n"
          "through each pixel centre).  A map's sun stays in the map (no extraction, so\n"
          "no --no-sun).\n\n"
          "LIGHT is one of\n"
          "  --env FILE[,FILE...] [--weights w1,w2,...] [--scale S | --illuminance LUX|auto]\n"
          "                       lat-long HDR maps\n"
          "                       (a bare name such as forest.exr is looked up in blender-data)\n"
          "  --env-constant R,G,B constant environment radiance\n"
          "  --sky T,ELEV,AZIM    Preetham sky and its sun (as cave shade)\n"
          "  [--yaw DEG] [--pitch DEG] [--roll DEG]   car orientation\n\n"
          "  --view x,y,z   the eye, metres (within +-1e6)\n"
          "  --look x,y,z   the point looked at (not the eye)\n"
          "  --view-up x,y,z  the camera's up vector (default 0,1,0; not along the view:\n"
          "                 looking straight down or up needs e.g. 0,0,-1)\n"
          "  --fov DEG      vertical field of view (default 70)\n"
          "  --size WxH     picture size (default 640x480, each side 1..16384)\n"
          "  --spp N        samples per pixel (default 64)\n"
          "  --pass N       samples per progressive pass, one progress line each (default 16)\n"
          "  --bounces N    keep light that bounced at most N times (N = 2 matches a 2-bounce\n"
          "                 bake); default: until Russian roulette ends the path\n"
          "  --seed S       sampling seed (same seed, same image, any thread count)\n"
          "  --tess N       built-in cabin subdivision (default or .json input)\n"
          "  --threads N    OpenMP threads (default: all cores)\n"
          "  --error FILE   EXR of the per-pixel standard error of each channel's mean\n"
          "  --png          also write a tone-mapped preview next to -o (view.exr: view.png;\n"
          "                 log-average to 0.18, Reinhard, sRGB)\n"
          "  --exposure E   fixed exposure for --png instead of the log-average\n"
          "  --ids FILE     EXR (1 channel) of 1 + the material index each pixel sees, 0 for none\n"
          "                 (region masks for the error report; the indices are printed)\n"
          "Input .prt: its cleaned mesh and material albedos (not its per-vertex albedos).\n"
          "Every output's folder is checked before the render; on an error nothing is left.\n"
          "\nexamples:\n"
          "  cave reference scene.prt --env forest.exr --illuminance auto --view -0.37,1.02,0 \\\n"
          "                 --look -0.15,0.65,-1.0 --fov 60 --spp 256 -o ref.exr --error se.exr\n"
          "  cave reference scene.prt --env-constant 1,1,1 --view -0.37,1.1,0.3 \\\n"
          "                 --look -0.37,0,0.3 --view-up 0,0,-1 --ids ids.exr -o floor.exr\n"
          "  cave reference default --sky 3,35,0 --view -0.37,1.1,0.3 --look 0,1,-1 -o v.exr --png\n");
}

typedef struct {
  cv_light_spec spec;
  const char *weights;
} light_opts;

static int finish_light(light_opts *lo) {
  if (lo->spec.kind == CV_LIGHT_NONE)
    return cli_fail("reference", 2, "no lighting: give --env, --env-constant or --sky");
  return cli_apply_weights("reference", &lo->spec, lo->weights);
}

/* The scene's cleaned mesh: from a .prt (as `cave shade` sees it) or built
 * from a config, a mesh file or the default cabin. */
static int load_mesh(const char *in, int tess, cv_mesh **m, cv_err *err) {
  if (cli_has_ext(in, ".prt")) {
    cv_prt *p = NULL;
    int st = cv_prt_read(in, &p, err);
    if (st) return st;
    st = cv_prt_to_mesh(p, m);
    if (!st)
      printf("scene: %s: %zu vertices, %zu triangles, %zu materials\n", in, p->nv, p->nt, p->nm);
    cv_prt_destroy(p);
    if (st) return cv_err_set(err, st, "%s: out of memory", in);
    return CV_OK;
  }
  cv_scene_config cfg;
  if (!strcmp(in, "default")) {
    cv_scene_config_default(&cfg);
  } else if (cli_has_ext(in, ".json")) {
    int st = cv_scene_config_load(in, &cfg, err);
    if (st) return st;
  } else {
    cv_scene_config_default(&cfg);
    cfg.mesh_is_cabin = 0;
    snprintf(cfg.mesh_path, sizeof cfg.mesh_path, "%s", in);
    snprintf(cfg.source, sizeof cfg.source, "%s", in);
  }
  if (tess > 0) cfg.cabin_tess = tess;
  return cli_load_scene_mesh(&cfg, stdout, m, err);
}

int cmd_reference(int argc, char **argv) {
  const char *in = NULL, *out = NULL, *err_out = NULL, *png_out = NULL, *ids_out = NULL;
  light_opts lo = {.weights = NULL};
  cv_light_spec_default(&lo.spec);
  cv_ref_camera cam = {.up = {0, 1, 0}, .fov_deg = 70, .w = 640, .h = 480};
  cv_ref_params rp;
  cv_ref_params_default(&rp);
  int have_view = 0, have_look = 0, threads = 0, tess = 0, png = 0;
  double exposure = 0;
  const char *eye_s = "", *look_s = "", *up_s = "0,1,0 (the default)";
  char png_path[4096];
  static const char *const value_opts[] = {"-o", "--error", "--ids", "--view", "--look",
                                           "--view-up", "--fov", "--size", "--spp", "--pass",
                                           "--bounces", "--seed", "--tess", "--threads",
                                           "--exposure", NULL};
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *val = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    }
    if (!strcmp(a, "--quiet")) {
      rp.quiet = 1;
      continue;
    }
    if (!strcmp(a, "--png")) {
      /* a flag, as in cave lcd; the old form --png FILE.png gets a hint */
      if (val && val[0] != '-' && cli_has_ext(val, ".png"))
        return cli_fail("reference", 2, "--png: a flag (the preview goes next to -o, view.exr: "
                                        "view.png), got a file '%s'", val);
      png = 1;
      continue;
    }
    if (!strcmp(a, "--no-sun"))
      return cli_fail("reference", 2, "--no-sun: not taken: cave reference always keeps a map's "
                                      "sun in the map and samples it from there (no extraction)");
    if (!strcmp(a, "--up"))
      return cli_fail("reference", 2, "--up: the camera's up vector is --view-up x,y,z (--up y|z "
                                      "is a mesh file's up axis, in cave bake and materials)");
    int pl = cli_parse_light("reference", argc, argv, &i, &lo.spec, &lo.weights);
    if (pl < 0) return -pl;
    if (pl) continue;
    if (a[0] == '-' && a[1] && !val) return cli_value_missing("reference", help, a, value_opts);
    if (!strcmp(a, "-o")) {
      out = argv[++i];
    } else if (!strcmp(a, "--error")) {
      err_out = argv[++i];
    } else if (!strcmp(a, "--ids")) {
      ids_out = argv[++i];
    } else if (!strcmp(a, "--view") || !strcmp(a, "--look") || !strcmp(a, "--view-up")) {
      double *dst = !strcmp(a, "--view") ? cam.eye : !strcmp(a, "--look") ? cam.look : cam.up;
      if (cli_parse_vec(argv[++i], 3, dst))
        return cli_fail("reference", 2, "%s: expected x,y,z, got '%s'", a, val);
      have_view |= !strcmp(a, "--view");
      have_look |= !strcmp(a, "--look");
      if (!strcmp(a, "--view")) eye_s = val;
      else if (!strcmp(a, "--look")) look_s = val;
      else up_s = val;
    } else if (!strcmp(a, "--fov")) {
      if (cli_parse_double(argv[++i], &cam.fov_deg) || cam.fov_deg <= 1 || cam.fov_deg >= 179)
        return cli_fail("reference", 2, "--fov: expected degrees in (1, 179), got '%s'", val);
    } else if (!strcmp(a, "--size")) {
      if (cli_parse_size(argv[++i], 16384, &cam.w, &cam.h))
        return cli_fail("reference", 2, "--size: expected WxH (1..16384), got '%s'", val);
    } else if (!strcmp(a, "--spp")) {
      if (cli_parse_int(argv[++i], 1, 1 << 20, &rp.spp))
        return cli_fail("reference", 2, "--spp: expected 1..1048576, got '%s'", val);
    } else if (!strcmp(a, "--pass")) {
      if (cli_parse_int(argv[++i], 1, 1 << 20, &rp.pass_spp))
        return cli_fail("reference", 2, "--pass: expected 1..1048576, got '%s'", val);
    } else if (!strcmp(a, "--bounces")) {
      if (cli_parse_int(argv[++i], 0, 1000, &rp.bounces))
        return cli_fail("reference", 2, "--bounces: expected 0..1000, got '%s'", val);
    } else if (!strcmp(a, "--seed")) {
      int s;
      if (cli_parse_int(argv[++i], 0, 2147483647, &s))
        return cli_fail("reference", 2, "--seed: expected 0..2147483647, got '%s'", val);
      rp.seed = (uint32_t)s;
    } else if (!strcmp(a, "--tess")) {
      if (cli_parse_int(argv[++i], 1, 64, &tess))
        return cli_fail("reference", 2, "--tess: expected 1..64, got '%s'", val);
    } else if (!strcmp(a, "--threads")) {
      if (cli_parse_int(argv[++i], 1, 1024, &threads))
        return cli_fail("reference", 2, "--threads: expected 1..1024, got '%s'", val);
    } else if (!strcmp(a, "--exposure")) {
      if (cli_parse_double(argv[++i], &exposure) || exposure <= 0)
        return cli_fail("reference", 2, "--exposure: expected a positive number, got '%s'", val);
    } else if (a[0] == '-' && a[1]) {
      cli_print_usage(help);
      return cli_fail("reference", 2, "unknown option '%s'", a);
    } else if (!in) {
      in = a;
    } else {
      return cli_fail("reference", 2, "more than one input ('%s' and '%s')", in, a);
    }
  }
  if (!in || !out) {
    cli_print_usage(help);
    return cli_fail("reference", 2, "an input scene and -o FILE.exr are required");
  }
  if (!cli_has_ext(out, ".exr"))
    return cli_fail("reference", 2, "-o: the view is written as linear .exr, got '%s'", out);
  if (err_out && !cli_has_ext(err_out, ".exr"))
    return cli_fail("reference", 2, "--error: expected an .exr path, got '%s'", err_out);
  if (ids_out && !cli_has_ext(ids_out, ".exr"))
    return cli_fail("reference", 2, "--ids: expected an .exr path, got '%s'", ids_out);
  if (png) {
    if (strlen(out) - 4 + 5 > sizeof png_path)
      return cli_fail("reference", 2, "-o: path too long for --png, got '%s'", out);
    snprintf(png_path, sizeof png_path, "%.*s.png", (int)strlen(out) - 4, out);
    png_out = png_path;
  }
  if (!have_view || !have_look)
    return cli_fail("reference", 2, "--view x,y,z and --look x,y,z are required");
  cli_camera_arg ca = {cam.eye, cam.look, cam.up, eye_s, look_s, up_s};
  if (cli_check_camera("reference", &ca)) return 2;
  if (finish_light(&lo)) return 2;
  /* every output's folder before minutes of path tracing */
  const char *outs[4][2] = {{"-o", out}, {"--error", err_out}, {"--ids", ids_out},
                            {"--png", png_out}};
  for (int k = 0; k < 4; k++) {
    if (!outs[k][1]) continue;
    int cst = cli_check_output("reference", outs[k][0], outs[k][1]);
    if (cst) return cst;
    for (int j = 0; j < k; j++)
      if (outs[j][1] && !strcmp(outs[j][1], outs[k][1]))
        return cli_fail("reference", 2, "%s: '%s' is also the %s output", outs[k][0], outs[k][1],
                        outs[j][0]);
  }
  if (threads) omp_set_num_threads(threads);

  int rc = 1;
  cv_err err;
  cv_err_clear(&err);
  cv_mesh *m = NULL;
  cv_ref_scene *sc = NULL;
  cv_ref_light *light = NULL;
  cv_image *img = NULL, *se = NULL, *ids = NULL;
  if (load_mesh(in, tess, &m, &err)) {
    rc = cli_fail("reference", 1, "%s", err.msg);
    goto done;
  }
  if (cv_ref_scene_create(m, &sc, &err)) {
    rc = cli_fail("reference", 1, "%s: %s", in, err.msg);
    goto done;
  }
  if (cv_ref_light_build(&lo.spec, &light, &err)) {
    rc = cli_fail("reference", 1, "%s", err.msg);
    goto done;
  }
  cv_ref_light_print(stdout, light);
  if (cv_image_create(cam.w, cam.h, 3, &img) || cv_image_create(cam.w, cam.h, 3, &se)) {
    rc = cli_fail("reference", 1, "cannot allocate a %dx%d image", cam.w, cam.h);
    goto done;
  }
  cv_ref_stats st;
  if (cv_ref_render(sc, light, &cam, &rp, img, se, &st, &err)) {
    rc = cli_fail("reference", 1, "%s", err.msg);
    goto done;
  }
  printf("reference: %dx%d, %d spp, bounces %s, seed %u: %.2f s, %.3g paths/s, %.2f vertices "
         "per path\n",
         cam.w, cam.h, rp.spp, rp.bounces < 0 ? "until roulette" : "limited", rp.seed, st.seconds,
         st.paths / (st.seconds > 0 ? st.seconds : 1), (double)st.vertices / (double)st.paths);
  printf("reference: relative standard error of pixel luminance: median %.2f%%, p90 %.2f%%; "
         "%llu samples non-finite (set to 0); %llu pixels saw neither geometry nor a window\n",
         100 * st.median_rel_se, 100 * st.p90_rel_se, (unsigned long long)st.nonfinite,
         (unsigned long long)st.blocked_view);
  /* ZIP: cv_exr_write guards against OpenEXR issue #2306 (a chunk whose
   * deflated size equals its raw size was stored wrongly; noisy images hit it).
   * Each file is written whole (temp + rename); when one fails, those
   * written before it are removed: an error leaves nothing behind. */
  const char *written[4];
  int n_written = 0;
  if (cv_exr_write(out, img, 0, CV_EXR_ZIP, &err)) {
    rc = cli_fail("reference", 1, "%s", err.msg);
    goto done;
  }
  written[n_written++] = out;
  if (err_out) {
    if (cv_exr_write(err_out, se, 0, CV_EXR_ZIP, &err)) {
      rc = cli_fail("reference", 1, "--error: %s", err.msg);
      goto unwrite;
    }
    written[n_written++] = err_out;
  }
  if (ids_out) {
    if (cv_image_create(cam.w, cam.h, 1, &ids) || cv_ref_material_ids(sc, &cam, ids, &err) ||
        cv_exr_write(ids_out, ids, 0, CV_EXR_NONE, &err)) {
      rc = cli_fail("reference", 1, "--ids: %s", err.msg[0] ? err.msg : "out of memory");
      goto unwrite;
    }
    written[n_written++] = ids_out;
  }
  cv_preview_stats ps;
  if (png_out) {
    if (cv_preview_write_png(png_out, img, exposure, &ps, &err)) {
      rc = cli_fail("reference", 1, "--png: %s", err.msg);
      goto unwrite;
    }
    written[n_written++] = png_out;
  }
  if (ids_out)
    for (size_t k = 0; k < m->nm; k++)
      printf("material %zu: %s (albedo %.3g %.3g %.3g)\n", k, m->mats[k].name,
             (double)m->mats[k].albedo[0], (double)m->mats[k].albedo[1],
             (double)m->mats[k].albedo[2]);
  if (png_out) printf("preview: %s, exposure %.4g\n", png_out, ps.exposure);
  printf("wrote");
  for (int k = 0; k < n_written; k++) printf("%s %s", k ? "," : "", written[k]);
  printf("\n");
  rc = 0;
  goto done;
unwrite:
  for (int k = 0; k < n_written; k++) remove(written[k]);
done:
  cv_image_destroy(img);
  cv_image_destroy(se);
  cv_image_destroy(ids);
  cv_ref_light_destroy(light);
  cv_ref_scene_destroy(sc);
  cv_mesh_destroy(m);
  return rc;
}
