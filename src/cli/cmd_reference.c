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
  return cv_scene_mesh_load(&cfg, stdout, m, err);
}

/* The command line of cave reference. */
typedef struct ref_opts {
  const char *in, *out, *err_out, *png_out, *ids_out;
  light_opts lo;
  cv_ref_camera cam;
  cv_ref_params rp;
  int have_view, have_look, threads, tess, png;
  double exposure;
  const char *eye_s, *look_s, *up_s;
  char png_path[4096];
} ref_opts;

/* One option with a value (argv[*i], value val) into o; 1 when it is not
 * one of these, else 0 or minus the exit code. */
static int parse_value_opt(char **argv, int *i, ref_opts *o) {
  const char *a = argv[*i], *val = argv[*i + 1];
  cv_ref_camera *cam = &o->cam;
  cv_ref_params *rp = &o->rp;
  if (!strcmp(a, "-o")) {
    o->out = argv[++*i];
  } else if (!strcmp(a, "--error")) {
    o->err_out = argv[++*i];
  } else if (!strcmp(a, "--ids")) {
    o->ids_out = argv[++*i];
  } else if (!strcmp(a, "--view") || !strcmp(a, "--look") || !strcmp(a, "--view-up")) {
    double *dst = !strcmp(a, "--view") ? cam->eye : !strcmp(a, "--look") ? cam->look : cam->up;
    if (cli_parse_vec(argv[++*i], 3, dst))
      return -cli_fail("reference", 2, "%s: expected x,y,z, got '%s'", a, val);
    o->have_view |= !strcmp(a, "--view");
    o->have_look |= !strcmp(a, "--look");
    if (!strcmp(a, "--view")) o->eye_s = val;
    else if (!strcmp(a, "--look")) o->look_s = val;
    else o->up_s = val;
  } else if (!strcmp(a, "--fov")) {
    if (cli_parse_double(argv[++*i], &cam->fov_deg) || cam->fov_deg <= 1 || cam->fov_deg >= 179)
      return -cli_fail("reference", 2, "--fov: expected degrees in (1, 179), got '%s'", val);
  } else if (!strcmp(a, "--size")) {
    if (cli_parse_size(argv[++*i], 16384, &cam->w, &cam->h))
      return -cli_fail("reference", 2, "--size: expected WxH (1..16384), got '%s'", val);
  } else if (!strcmp(a, "--spp")) {
    if (cli_parse_int(argv[++*i], 1, 1 << 20, &rp->spp))
      return -cli_fail("reference", 2, "--spp: expected 1..1048576, got '%s'", val);
  } else if (!strcmp(a, "--pass")) {
    if (cli_parse_int(argv[++*i], 1, 1 << 20, &rp->pass_spp))
      return -cli_fail("reference", 2, "--pass: expected 1..1048576, got '%s'", val);
  } else if (!strcmp(a, "--bounces")) {
    if (cli_parse_int(argv[++*i], 0, 1000, &rp->bounces))
      return -cli_fail("reference", 2, "--bounces: expected 0..1000, got '%s'", val);
  } else if (!strcmp(a, "--seed")) {
    int s;
    if (cli_parse_int(argv[++*i], 0, 2147483647, &s))
      return -cli_fail("reference", 2, "--seed: expected 0..2147483647, got '%s'", val);
    rp->seed = (uint32_t)s;
  } else if (!strcmp(a, "--tess")) {
    if (cli_parse_int(argv[++*i], 1, 64, &o->tess))
      return -cli_fail("reference", 2, "--tess: expected 1..64, got '%s'", val);
  } else if (!strcmp(a, "--threads")) {
    if (cli_parse_int(argv[++*i], 1, 1024, &o->threads))
      return -cli_fail("reference", 2, "--threads: expected 1..1024, got '%s'", val);
  } else if (!strcmp(a, "--exposure")) {
    if (cli_parse_double(argv[++*i], &o->exposure) || o->exposure <= 0)
      return -cli_fail("reference", 2, "--exposure: expected a positive number, got '%s'", val);
  } else {
    return 1;
  }
  return 0;
}

/* argv into o.  Returns -1 to go on, else the exit code. */
static int parse_args(int argc, char **argv, ref_opts *o) {
  static const char *const value_opts[] = {"-o", "--error", "--ids", "--view", "--look",
                                           "--view-up", "--fov", "--size", "--spp", "--pass",
                                           "--bounces", "--seed", "--tess", "--threads",
                                           "--exposure", NULL};
  memset(o, 0, sizeof *o);
  cv_light_spec_default(&o->lo.spec);
  o->cam = (cv_ref_camera){.up = {0, 1, 0}, .fov_deg = 70, .w = 640, .h = 480};
  cv_ref_params_default(&o->rp);
  o->eye_s = "";
  o->look_s = "";
  o->up_s = "0,1,0 (the default)";
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *val = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    }
    if (!strcmp(a, "--quiet")) {
      o->rp.quiet = 1;
      continue;
    }
    if (!strcmp(a, "--png")) {
      /* a flag, as in cave lcd; the old form --png FILE.png gets a hint */
      if (val && val[0] != '-' && cli_has_ext(val, ".png"))
        return cli_fail("reference", 2, "--png: a flag (the preview goes next to -o, view.exr: "
                                        "view.png), got a file '%s'", val);
      o->png = 1;
      continue;
    }
    if (!strcmp(a, "--no-sun"))
      return cli_fail("reference", 2, "--no-sun: not taken: cave reference always keeps a map's "
                                      "sun in the map and samples it from there (no extraction)");
    if (!strcmp(a, "--up"))
      return cli_fail("reference", 2, "--up: the camera's up vector is --view-up x,y,z (--up y|z "
                                      "is a mesh file's up axis, in cave bake and materials)");
    int pl = cli_parse_light("reference", argc, argv, &i, &o->lo.spec, &o->lo.weights);
    if (pl < 0) return -pl;
    if (pl) continue;
    if (a[0] == '-' && a[1] && !val) return cli_value_missing("reference", help, a, value_opts);
    if (val) {
      const int st = parse_value_opt(argv, &i, o);
      if (st < 0) return -st;
      if (st == 0) continue;
    }
    if (a[0] == '-' && a[1]) {
      cli_print_usage(help);
      return cli_fail("reference", 2, "unknown option '%s'", a);
    } else if (!o->in) {
      o->in = a;
    } else {
      return cli_fail("reference", 2, "more than one input ('%s' and '%s')", o->in, a);
    }
  }
  return -1;
}

/* The outputs' names, the camera, the lighting and every output's folder,
 * before minutes of path tracing.  Returns 0 or the exit code. */
static int check_args(ref_opts *o) {
  if (!o->in || !o->out) {
    cli_print_usage(help);
    return cli_fail("reference", 2, "an input scene and -o FILE.exr are required");
  }
  if (!cli_has_ext(o->out, ".exr"))
    return cli_fail("reference", 2, "-o: the view is written as linear .exr, got '%s'", o->out);
  if (o->err_out && !cli_has_ext(o->err_out, ".exr"))
    return cli_fail("reference", 2, "--error: expected an .exr path, got '%s'", o->err_out);
  if (o->ids_out && !cli_has_ext(o->ids_out, ".exr"))
    return cli_fail("reference", 2, "--ids: expected an .exr path, got '%s'", o->ids_out);
  if (o->png) {
    if (strlen(o->out) - 4 + 5 > sizeof o->png_path)
      return cli_fail("reference", 2, "-o: path too long for --png, got '%s'", o->out);
    snprintf(o->png_path, sizeof o->png_path, "%.*s.png", (int)strlen(o->out) - 4, o->out);
    o->png_out = o->png_path;
  }
  if (!o->have_view || !o->have_look)
    return cli_fail("reference", 2, "--view x,y,z and --look x,y,z are required");
  cli_camera_arg ca = {o->cam.eye, o->cam.look, o->cam.up, o->eye_s, o->look_s, o->up_s};
  if (cli_check_camera("reference", &ca)) return 2;
  if (finish_light(&o->lo)) return 2;
  const char *outs[4][2] = {{"-o", o->out}, {"--error", o->err_out}, {"--ids", o->ids_out},
                            {"--png", o->png_out}};
  for (int k = 0; k < 4; k++) {
    if (!outs[k][1]) continue;
    int cst = cli_check_output("reference", outs[k][0], outs[k][1]);
    if (cst) return cst;
    for (int j = 0; j < k; j++)
      if (outs[j][1] && !strcmp(outs[j][1], outs[k][1]))
        return cli_fail("reference", 2, "%s: '%s' is also the %s output", outs[k][0], outs[k][1],
                        outs[j][0]);
  }
  return 0;
}

/* What one reference render holds. */
typedef struct ref_job {
  cv_mesh *m;
  cv_ref_scene *sc;
  cv_ref_light *light;
  cv_image *img, *se, *ids;
} ref_job;

/* The scene, its lighting and the path-traced view with its standard
 * error, printed.  Returns 0 or the exit code. */
static int render_view(const ref_opts *o, ref_job *J) {
  cv_err err;
  cv_err_clear(&err);
  const cv_ref_camera *cam = &o->cam;
  const cv_ref_params *rp = &o->rp;
  if (load_mesh(o->in, o->tess, &J->m, &err)) return cli_fail("reference", 1, "%s", err.msg);
  if (cv_ref_scene_create(J->m, &J->sc, &err)) return cli_fail("reference", 1, "%s: %s", o->in, err.msg);
  if (cv_ref_light_build(&o->lo.spec, &J->light, &err)) return cli_fail("reference", 1, "%s", err.msg);
  cv_ref_light_print(stdout, J->light);
  if (cv_image_create(cam->w, cam->h, 3, &J->img) || cv_image_create(cam->w, cam->h, 3, &J->se))
    return cli_fail("reference", 1, "cannot allocate a %dx%d image", cam->w, cam->h);
  cv_ref_stats st;
  if (cv_ref_render(J->sc, J->light, cam, rp, J->img, J->se, &st, &err))
    return cli_fail("reference", 1, "%s", err.msg);
  printf("reference: %dx%d, %d spp, bounces %s, seed %u: %.2f s, %.3g paths/s, %.2f vertices "
         "per path\n",
         cam->w, cam->h, rp->spp, rp->bounces < 0 ? "until roulette" : "limited", rp->seed, st.seconds,
         st.paths / (st.seconds > 0 ? st.seconds : 1), (double)st.vertices / (double)st.paths);
  printf("reference: relative standard error of pixel luminance: median %.2f%%, p90 %.2f%%; "
         "%llu samples non-finite (set to 0); %llu pixels saw neither geometry nor a window\n",
         100 * st.median_rel_se, 100 * st.p90_rel_se, (unsigned long long)st.nonfinite,
         (unsigned long long)st.blocked_view);
  return 0;
}

/* The view, then the asked-for error, ids and preview files.  ZIP:
 * cv_exr_write guards against OpenEXR issue #2306 (a chunk whose deflated
 * size equals its raw size was stored wrongly; noisy images hit it).  Each
 * file is written whole (temp + rename); when one fails, those written
 * before it are removed: an error leaves nothing behind.  Returns 0 or the
 * exit code. */
static int write_outputs(const ref_opts *o, ref_job *J) {
  cv_err err;
  cv_err_clear(&err);
  const char *written[4];
  int n_written = 0, rc = 0;
  if (cv_exr_write(o->out, J->img, 0, CV_EXR_ZIP, &err)) return cli_fail("reference", 1, "%s", err.msg);
  written[n_written++] = o->out;
  if (o->err_out) {
    if (cv_exr_write(o->err_out, J->se, 0, CV_EXR_ZIP, &err))
      rc = cli_fail("reference", 1, "--error: %s", err.msg);
    else
      written[n_written++] = o->err_out;
  }
  if (!rc && o->ids_out) {
    if (cv_image_create(o->cam.w, o->cam.h, 1, &J->ids) ||
        cv_ref_material_ids(J->sc, &o->cam, J->ids, &err) ||
        cv_exr_write(o->ids_out, J->ids, 0, CV_EXR_NONE, &err))
      rc = cli_fail("reference", 1, "--ids: %s", err.msg[0] ? err.msg : "out of memory");
    else
      written[n_written++] = o->ids_out;
  }
  cv_preview_stats ps;
  if (!rc && o->png_out) {
    if (cv_preview_write_png(o->png_out, J->img, o->exposure, &ps, &err))
      rc = cli_fail("reference", 1, "--png: %s", err.msg);
    else
      written[n_written++] = o->png_out;
  }
  if (rc) {
    for (int k = 0; k < n_written; k++) remove(written[k]);
    return rc;
  }
  if (o->ids_out)
    for (size_t k = 0; k < J->m->nm; k++)
      printf("material %zu: %s (albedo %.3g %.3g %.3g)\n", k, J->m->mats[k].name,
             (double)J->m->mats[k].albedo[0], (double)J->m->mats[k].albedo[1],
             (double)J->m->mats[k].albedo[2]);
  if (o->png_out) printf("preview: %s, exposure %.4g\n", o->png_out, ps.exposure);
  printf("wrote");
  for (int k = 0; k < n_written; k++) printf("%s %s", k ? "," : "", written[k]);
  printf("\n");
  return 0;
}

int cmd_reference(int argc, char **argv) {
  ref_opts o;
  int rc = parse_args(argc, argv, &o);
  if (rc >= 0) return rc;
  if ((rc = check_args(&o)) != 0) return rc;
  if (o.threads) omp_set_num_threads(o.threads);
  ref_job J = {0};
  rc = render_view(&o, &J);
  if (!rc) rc = write_outputs(&o, &J);
  cv_image_destroy(J.img);
  cv_image_destroy(J.se);
  cv_image_destroy(J.ids);
  cv_ref_light_destroy(J.light);
  cv_ref_scene_destroy(J.sc);
  cv_mesh_destroy(J.m);
  return rc;
}
