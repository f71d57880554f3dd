/* `cave shade`: CPU relighting of a baked PRT, the reference path the GPU
 * renderer is checked against.  Writes per-vertex exit radiance as PLY, or a
 * pinhole view (Embree primary rays, radiance interpolated from the hit
 * triangle's vertices, the environment through the windows) as EXR or PNG. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/cli.h"
#include "io/exr.h"
#include "io/ply.h"
#include "io/texture.h"
#include "io/tonemap_simple.h"
#include "prt/shade_view.h"
#include "prt/relight.h"
#include "prt/scene_light.h"

static void help(FILE *f) {
  fprintf(f,
          "usage: cave shade <scene.prt> LIGHT [--yaw DEG] [--pitch DEG] [--roll DEG]\n"
          "                  [--sun-samples N] [--split K [--split-grid W] [--split-samples N]]\n"
          "                  -o out.ply [--ascii]\n"
          "       cave shade <scene.prt> LIGHT --view x,y,z --look x,y,z [--view-up x,y,z]\n"
          "                  [--fov DEG] [--size WxH] [--exposure E] [--pixel-lights sun|all|none]\n"
          "                  [same --sun-samples/--split options] -o view.exr|view.png\n\n"
          "LIGHT is one of\n"
          "  --env FILE[,FILE...] [--weights w1,w2,...] [--scale S | --illuminance LUX|auto]\n"
          "                       [--no-sun]\n"
          "                       lat-long HDR maps (blended); a bare name such as forest.exr\n"
          "                       is looked up in blender-data's studio lights\n"
          CLI_ILLUMINANCE_HELP
          "  --env-constant R,G,B constant environment radiance\n"
          "  --sky T,ELEV,AZIM    Preetham sky: turbidity 2..10, sun elevation and azimuth\n"
          "                       (degrees, azimuth clockwise from straight ahead)\n\n"
          "A sun found in a map (or the sky's sun) is split out of the SH lighting and\n"
          "added as a directional light with ray-traced visibility through the windows.\n"
          "The PLY holds float x y z and float red green blue = linear exit radiance.\n"
          "A view looks from --view towards --look (metres, within +-1e6); --view-up is\n"
          "the camera's up vector (default 0,1,0; give another, e.g. 0,0,-1, to look\n"
          "straight down or up); --fov the vertical field of view (default 70),\n"
          "--size the picture (default 640x480, each side 1..16384).\n"
          "--split K cuts the K brightest window-visible cells of a W x W/2 grid (default\n"
          "W 64) out of the map as extra directional lights treated like the sun (an\n"
          "all-frequency answer to window light; docs/reference.md).\n"
          "--sun-samples N      fan points per vertex for the sun's per-vertex shadow rays\n"
          "                     (1..4096, default 16)\n"
          "--split-samples N    the same for each split light (1..4096, default 4)\n"
          "--pixel-lights M     a view only: whose direct light is evaluated per pixel, with\n"
          "                     one shadow ray from the pixel's surface point, instead of\n"
          "                     interpolated from the vertices: sun (default; as the GPU's\n"
          "                     shadow-mapped sun), all (the sun and every split light) or\n"
          "                     none (all per vertex, as the PLY).  Sharp shadow edges;\n"
          "                     SH ringing below 0 is then clamped per pixel, after it.\n"
          "PNG views use a simple global tone map (log-average to 0.18, Reinhard, sRGB).\n"
          "A view multiplies each pixel on a textured material by its texture (the PNG\n"
          "or JPEG named in the .prt, bilinear, sRGB decoded; one that cannot be read is\n"
          "a warning and shows its mean albedo); the PLY shows the mean albedo.\n"
          "\nexamples:\n"
          "  cave shade scene.prt --env forest.exr --illuminance auto -o lit.ply\n"
          "  cave shade scene.prt --env forest.exr --split 64 --view -0.37,1.02,0 \\\n"
          "             --look -0.15,0.65,-1.0 --fov 60 -o driver.exr\n"
          "  cave shade scene.prt --sky 3,35,0 --view -0.37,1.1,0.3 --look -0.37,0,0.3 \\\n"
          "             --view-up 0,0,-1 -o floor.png\n"
          "  cave shade scene.prt --sky 3,35,0 --view -0.37,1.1,0.3 --look 0,1,-1 -o view.png\n");
}

typedef struct {
  double eye[3], look[3], up[3], fov;
  int w, h;
} view_opts;

enum { PIXEL_NONE, PIXEL_SUN, PIXEL_ALL };

static void background(const void *ctx, const float d[3], float rgb[3]) {
  cv_scene_light_background(ctx, d, rgb);
}

/* The pixel lights of --pixel-lights: the sun (when there is one), and with
 * `all` the split lights after it, in lights[] (room for 1 + n_extra). */
static int pixel_lights(int mode, const cv_lighting *l, const cv_dir_light *extra, int n_extra,
                        cv_dir_light *lights) {
  int n = 0;
  if (mode != PIXEL_NONE && l->has_sun) {
    for (int k = 0; k < 3; k++) {
      lights[n].dir[k] = l->sun_dir[k];
      lights[n].E[k] = l->sun_E[k];
    }
    n++;
  }
  for (int k = 0; mode == PIXEL_ALL && k < n_extra; k++) lights[n++] = extra[k];
  return n;
}

/* The command line of cave shade. */
typedef struct shade_opts {
  const char *in, *out, *weights;
  cv_light_spec spec;
  int ascii, have_view, have_look, split, split_grid, pixel_mode;
  cv_relight_opts ro;
  double exposure;
  view_opts v;
  const char *eye_s, *look_s, *up_s;
} shade_opts;

/* One option with a value (argv[*i], value argv[*i + 1]) into o; 1 when
 * it is not one of these, else 0 or minus the exit code. */
static int parse_value_opt(int argc, char **argv, int *i, shade_opts *o) {
  const char *a = argv[*i], *val = argv[*i + 1];
  view_opts *v = &o->v;
  int st;
  if (!strcmp(a, "-o")) {
    o->out = argv[++*i];
  } else if ((st = cli_parse_light("shade", argc, argv, i, &o->spec, &o->weights)) != 0) {
    if (st < 0) return st;
  } else if (!strcmp(a, "--sun-samples")) {
    if (cli_parse_int(argv[++*i], 1, 4096, &o->ro.sun_samples))
      return -cli_fail("shade", 2, "--sun-samples: expected 1..4096, got '%s'", val);
  } else if (!strcmp(a, "--split-samples")) {
    if (cli_parse_int(argv[++*i], 1, 4096, &o->ro.split_samples))
      return -cli_fail("shade", 2, "--split-samples: expected 1..4096, got '%s'", val);
  } else if (!strcmp(a, "--pixel-lights")) {
    ++*i;
    if (!strcmp(val, "sun")) o->pixel_mode = PIXEL_SUN;
    else if (!strcmp(val, "all")) o->pixel_mode = PIXEL_ALL;
    else if (!strcmp(val, "none")) o->pixel_mode = PIXEL_NONE;
    else return -cli_fail("shade", 2, "--pixel-lights: expected sun, all or none, got '%s'", val);
  } else if (!strcmp(a, "--split")) {
    if (cli_parse_int(argv[++*i], 0, 4096, &o->split))
      return -cli_fail("shade", 2, "--split: expected 0..4096 lights, got '%s'", val);
  } else if (!strcmp(a, "--split-grid")) {
    if (cli_parse_int(argv[++*i], 4, 1024, &o->split_grid) || o->split_grid % 2)
      return -cli_fail("shade", 2, "--split-grid: expected an even width 4..1024, got '%s'", val);
  } else if (!strcmp(a, "--view")) {
    if (cli_parse_vec(argv[++*i], 3, v->eye)) return -cli_fail("shade", 2, "--view: expected x,y,z, got '%s'", val);
    o->have_view = 1;
    o->eye_s = val;
  } else if (!strcmp(a, "--look")) {
    if (cli_parse_vec(argv[++*i], 3, v->look)) return -cli_fail("shade", 2, "--look: expected x,y,z, got '%s'", val);
    o->have_look = 1;
    o->look_s = val;
  } else if (!strcmp(a, "--view-up")) {
    if (cli_parse_vec(argv[++*i], 3, v->up)) return -cli_fail("shade", 2, "--view-up: expected x,y,z, got '%s'", val);
    o->up_s = val;
  } else if (!strcmp(a, "--fov")) {
    if (cli_parse_double(argv[++*i], &v->fov) || v->fov <= 1 || v->fov >= 179)
      return -cli_fail("shade", 2, "--fov: expected degrees in (1, 179), got '%s'", val);
  } else if (!strcmp(a, "--size")) {
    if (cli_parse_size(argv[++*i], 16384, &v->w, &v->h))
      return -cli_fail("shade", 2, "--size: expected WxH (1..16384), got '%s'", val);
  } else if (!strcmp(a, "--exposure")) {
    if (cli_parse_double(argv[++*i], &o->exposure) || o->exposure <= 0)
      return -cli_fail("shade", 2, "--exposure: expected a positive number, got '%s'", val);
  } else {
    return 1;
  }
  return 0;
}

/* argv into o.  Returns -1 to go on, else the exit code. */
static int parse_args(int argc, char **argv, shade_opts *o) {
  static const char *const value_opts[] = {"-o", "--sun-samples", "--split-samples",
                                           "--pixel-lights", "--split", "--split-grid", "--view",
                                           "--look", "--view-up", "--fov", "--size",
                                           "--exposure", NULL};
  *o = (shade_opts){.split_grid = 64, .pixel_mode = PIXEL_SUN,
                    .v = {.up = {0, 1, 0}, .fov = 70, .w = 640, .h = 480},
                    .eye_s = "", .look_s = "", .up_s = "0,1,0 (the default)"};
  cv_light_spec_default(&o->spec);
  cv_relight_opts_default(&o->ro);
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *val = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    } else if (!strcmp(a, "--ascii")) {
      o->ascii = 1;
    } else if (!strcmp(a, "--no-sun")) {
      o->spec.extract_sun = 0;
    } else if (!strcmp(a, "--up")) {
      return cli_fail("shade", 2, "--up: the camera's up vector is --view-up x,y,z (--up y|z is a "
                                  "mesh file's up axis, in cave bake and materials)");
    } else if (!val) {
      if (a[0] == '-' && a[1]) return cli_value_missing("shade", help, a, value_opts);
      if (o->in) return cli_fail("shade", 2, "more than one input ('%s' and '%s')", o->in, a);
      o->in = a;
    } else {
      const int st = parse_value_opt(argc, argv, &i, o);
      if (st < 0) return -st;
      if (st == 0) continue;
      if (a[0] == '-') {
        cli_print_usage(help);
        return cli_fail("shade", 2, "unknown option '%s'", a);
      }
      if (o->in) return cli_fail("shade", 2, "more than one input ('%s' and '%s')", o->in, a);
      o->in = a;
    }
  }
  return -1;
}

/* What the options need of each other, before any work.  Returns 0 or the
 * exit code. */
static int check_args(shade_opts *o) {
  if (!o->in || !o->out) {
    cli_print_usage(help);
    return cli_fail("shade", 2, "a .prt input and -o FILE are required");
  }
  int st = cli_check_output("shade", "-o", o->out);
  if (st) return st;
  if (o->spec.kind == CV_LIGHT_NONE)
    return cli_fail("shade", 2, "no lighting: give --env, --env-constant or --sky");
  if ((st = cli_apply_weights("shade", &o->spec, o->weights)) != 0) return st;
  if (o->have_view != o->have_look) return cli_fail("shade", 2, "--view and --look go together");
  if (o->have_view && !cli_has_ext(o->out, ".exr") && !cli_has_ext(o->out, ".png"))
    return cli_fail("shade", 2, "-o: a view is written as .exr or .png, got '%s'", o->out);
  if (!o->have_view && !cli_has_ext(o->out, ".ply"))
    return cli_fail("shade", 2, "-o: per-vertex output is a .ply (or add --view for an image), got '%s'", o->out);
  if (o->have_view) {
    cli_camera_arg ca = {o->v.eye, o->v.look, o->v.up, o->eye_s, o->look_s, o->up_s};
    if (cli_check_camera("shade", &ca)) return 2;
  }
  return 0;
}

/* What one shade holds. */
typedef struct shade_job {
  cv_prt *p;
  cv_mesh *m;
  cv_tracer *tr;
  cv_scene_light *sl;
  float *rad;
  cv_dir_light *lights;
  cv_image *img;
  cv_image **tex; /* per material, NULL where untextured */
} shade_job;

/* The .prt, its lighting (split when asked), its tracer; the lighting
 * printed.  Returns 0 or the exit code. */
static int load_scene(const shade_opts *o, shade_job *J) {
  cv_err err;
  cv_err_clear(&err);
  if (cv_prt_read(o->in, &J->p, &err)) return cli_fail("shade", 1, "%s", err.msg);
  if (cv_scene_light_build(&o->spec, (int)J->p->bands, &J->sl, &err))
    return cli_fail("shade", 1, "%s", err.msg);
  if (cv_prt_to_mesh(J->p, &J->m) || cv_tracer_create(J->m, &J->tr, &err))
    return cli_fail("shade", 1, "%s: %s", o->in, err.msg[0] ? err.msg : "out of memory");
  if (o->split && cv_scene_light_split(J->sl, J->tr, o->split, o->split_grid, &err))
    return cli_fail("shade", 1, "--split: %s", err.msg);
  cv_scene_light_print(stdout, J->sl);
  return 0;
}

/* The albedo textures of a textured .prt into J->tex: a texture that cannot
 * be read shows the material's stored albedo (its mean) as a 1 x 1
 * texture, as the renderer does, counted.  Returns 0 or the exit code. */
static int load_textures(shade_job *J) {
  const cv_prt *p = J->p;
  cv_err err;
  if (!(J->tex = calloc(p->nm + 1, sizeof *J->tex))) return cli_fail("shade", 1, "out of memory");
  size_t unread = 0;
  for (size_t i = 0; i < p->nm; i++) {
    if (!cv_prt_mat_textured(p, i)) continue;
    if (cv_texture_load(p->mat_tex[i], &J->tex[i], &err)) {
      if (!unread++) printf("warning: material '%s' texture: %s\n", p->mats[i].name, err.msg);
      if (cv_image_create(1, 1, 3, &J->tex[i])) return cli_fail("shade", 1, "out of memory");
      memcpy(J->tex[i]->px, p->mats[i].albedo, 3 * sizeof(float));
      continue;
    }
    cv_texture_match_mean(J->tex[i], p->mats[i].albedo); /* the colour factor */
    printf("texture: material '%s': %s (%d x %d)\n", p->mats[i].name, p->mat_tex[i],
           J->tex[i]->w, J->tex[i]->h);
  }
  if (unread) printf("warning: %zu textures could not be read and show their mean albedo\n", unread);
  return 0;
}

/* The view from the camera (vertex radiance plus the pixel lights), written
 * as EXR or PNG.  Returns 0 or the exit code. */
static int write_view(const shade_opts *o, const cv_lighting *l, const cv_dir_light *extra,
                      int n_extra, shade_job *J) {
  const view_opts *v = &o->v;
  cv_err err;
  if (cv_image_create(v->w, v->h, 3, &J->img))
    return cli_fail("shade", 1, "cannot allocate a %dx%d image", v->w, v->h);
  int rc = (J->p->flags & CV_PRT_TEXTURED) ? load_textures(J) : 0;
  if (rc) return rc;
  cv_shade_view_params vp = {.rad = J->rad, .lights = J->lights, .tex = J->tex,
                             .background = background, .bg_ctx = J->sl};
  vp.n_lights = pixel_lights(o->pixel_mode, l, extra, n_extra, J->lights);
  cv_pinhole_init(&vp.cam, v->eye, v->look, v->up, v->fov, v->w, v->h);
  cv_shade_view_stats vs;
  cv_shade_view(J->p, cv_tracer_rt(J->tr), &vp, J->img, &vs);
  printf("view: %d lights per pixel (--pixel-lights %s); %llu pixel channels clamped from "
         "negative, %llu non-finite\n", vp.n_lights,
         o->pixel_mode == PIXEL_ALL ? "all" : o->pixel_mode == PIXEL_SUN ? "sun" : "none",
         (unsigned long long)vs.clamped_negative, (unsigned long long)vs.nonfinite);
  if (vs.escaped)
    printf("view: %llu pixels saw neither geometry nor a window (black)\n",
           (unsigned long long)vs.escaped);
  if (cli_has_ext(o->out, ".exr")) {
    if (cv_exr_write(o->out, J->img, 0, CV_EXR_ZIP, &err)) return cli_fail("shade", 1, "%s", err.msg);
    return 0;
  }
  cv_preview_stats ps;
  if (cv_preview_write_png(o->out, J->img, o->exposure, &ps, &err))
    return cli_fail("shade", 1, "%s", err.msg);
  printf("view: exposure %.4g (log-average luminance %.4g), %llu channels clamped\n",
         ps.exposure, ps.log_avg_luminance, (unsigned long long)ps.clamped_channels);
  return 0;
}

/* Relights every vertex (the direct light of what --pixel-lights leaves to
 * the vertices), then writes the vertices as PLY or the view.  Returns 0 or
 * the exit code. */
static int relight_and_write(shade_opts *o, shade_job *J) {
  cv_err err;
  cv_prt *p = J->p;
  cv_lighting l = cv_scene_light_sh(J->sl);
  const cv_dir_light *extra = NULL;
  int n_extra = cv_scene_light_extra(J->sl, &extra);
  if (!o->have_view) o->pixel_mode = PIXEL_NONE; /* per-vertex output: all direct light per vertex */
  cv_relight_opts *ro = &o->ro;
  ro->sun_direct = o->pixel_mode == PIXEL_NONE;
  ro->extra_direct = o->pixel_mode != PIXEL_ALL;
  ro->clamp = o->pixel_mode == PIXEL_NONE; /* else clamped per pixel, after the pixel lights */
  J->rad = malloc(3 * p->nv * sizeof(float) + 1);
  J->lights = malloc((1 + (size_t)n_extra) * sizeof *J->lights);
  cv_relight_stats rs;
  if (!J->rad || !J->lights || cv_prt_relight_opt(p, &l, extra, n_extra, J->tr, ro, J->rad, &rs))
    return cli_fail("shade", 1, "relighting failed");
  printf("relit %zu vertices (%u bands); %llu channels %s (SH ringing), %llu non-finite\n",
         p->nv, p->bands, (unsigned long long)rs.clamped_negative,
         ro->clamp ? "clamped from negative" : "negative (kept: clamped per pixel after the pixel lights)",
         (unsigned long long)rs.nonfinite);
  if (o->have_view) {
    int rc = write_view(o, &l, extra, n_extra, J);
    if (rc) return rc;
  } else {
    if (cv_prt_fold_texture_means(p, J->rad)) return cli_fail("shade", 1, "out of memory");
    if (cv_ply_write_points(o->out, p->nv, p->pos, J->rad, p->tri, p->nt, !o->ascii, &err))
      return cli_fail("shade", 1, "%s", err.msg);
  }
  printf("wrote %s\n", o->out);
  return 0;
}

int cmd_shade(int argc, char **argv) {
  shade_opts o;
  int rc = parse_args(argc, argv, &o);
  if (rc >= 0) return rc;
  if ((rc = check_args(&o)) != 0) return rc;
  shade_job J = {0};
  rc = load_scene(&o, &J);
  if (!rc) rc = relight_and_write(&o, &J);
  for (size_t i = 0; J.tex && i < J.p->nm; i++) cv_image_destroy(J.tex[i]);
  free(J.tex);
  cv_image_destroy(J.img);
  free(J.rad);
  free(J.lights);
  cv_tracer_destroy(J.tr);
  cv_mesh_destroy(J.m);
  cv_scene_light_destroy(J.sl);
  cv_prt_destroy(J.p);
  return rc;
}
