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

int cmd_shade(int argc, char **argv) {
  const char *in = NULL, *out = NULL;
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  int ascii = 0, have_view = 0, have_look = 0, split = 0, split_grid = 64, pixel_mode = PIXEL_SUN;
  cv_relight_opts ro;
  cv_relight_opts_default(&ro);
  double exposure = 0;
  view_opts v = {.up = {0, 1, 0}, .fov = 70, .w = 640, .h = 480};
  const char *eye_s = "", *look_s = "", *up_s = "0,1,0 (the default)";
  static const char *const value_opts[] = {"-o", "--sun-samples", "--split-samples",
                                           "--pixel-lights", "--split", "--split-grid", "--view",
                                           "--look", "--view-up", "--fov", "--size",
                                           "--exposure", NULL};
  const char *weights = NULL;
  cv_err err;
  cv_err_clear(&err);
  for (int i = 1, st; i < argc; i++) {
    const char *a = argv[i], *val = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    } else if (!strcmp(a, "--ascii")) {
      ascii = 1;
    } else if (!strcmp(a, "--no-sun")) {
      spec.extract_sun = 0;
    } else if (!strcmp(a, "--up")) {
      return cli_fail("shade", 2, "--up: the camera's up vector is --view-up x,y,z (--up y|z is a "
                                  "mesh file's up axis, in cave bake and materials)");
    } else if (!val) {
      if (a[0] == '-' && a[1]) return cli_value_missing("shade", help, a, value_opts);
      if (in) return cli_fail("shade", 2, "more than one input ('%s' and '%s')", in, a);
      in = a;
    } else if (!strcmp(a, "-o")) {
      out = argv[++i];
    } else if ((st = cli_parse_light("shade", argc, argv, &i, &spec, &weights)) != 0) {
      if (st < 0) return -st;
    } else if (!strcmp(a, "--sun-samples")) {
      if (cli_parse_int(argv[++i], 1, 4096, &ro.sun_samples))
        return cli_fail("shade", 2, "--sun-samples: expected 1..4096, got '%s'", val);
    } else if (!strcmp(a, "--split-samples")) {
      if (cli_parse_int(argv[++i], 1, 4096, &ro.split_samples))
        return cli_fail("shade", 2, "--split-samples: expected 1..4096, got '%s'", val);
    } else if (!strcmp(a, "--pixel-lights")) {
      ++i;
      if (!strcmp(val, "sun")) pixel_mode = PIXEL_SUN;
      else if (!strcmp(val, "all")) pixel_mode = PIXEL_ALL;
      else if (!strcmp(val, "none")) pixel_mode = PIXEL_NONE;
      else return cli_fail("shade", 2, "--pixel-lights: expected sun, all or none, got '%s'", val);
    } else if (!strcmp(a, "--split")) {
      if (cli_parse_int(argv[++i], 0, 4096, &split))
        return cli_fail("shade", 2, "--split: expected 0..4096 lights, got '%s'", val);
    } else if (!strcmp(a, "--split-grid")) {
      if (cli_parse_int(argv[++i], 4, 1024, &split_grid) || split_grid % 2)
        return cli_fail("shade", 2, "--split-grid: expected an even width 4..1024, got '%s'", val);
    } else if (!strcmp(a, "--view")) {
      if (cli_parse_vec(argv[++i], 3, v.eye)) return cli_fail("shade", 2, "--view: expected x,y,z, got '%s'", val);
      have_view = 1;
      eye_s = val;
    } else if (!strcmp(a, "--look")) {
      if (cli_parse_vec(argv[++i], 3, v.look)) return cli_fail("shade", 2, "--look: expected x,y,z, got '%s'", val);
      have_look = 1;
      look_s = val;
    } else if (!strcmp(a, "--view-up")) {
      if (cli_parse_vec(argv[++i], 3, v.up)) return cli_fail("shade", 2, "--view-up: expected x,y,z, got '%s'", val);
      up_s = val;
    } else if (!strcmp(a, "--fov")) {
      if (cli_parse_double(argv[++i], &v.fov) || v.fov <= 1 || v.fov >= 179)
        return cli_fail("shade", 2, "--fov: expected degrees in (1, 179), got '%s'", val);
    } else if (!strcmp(a, "--size")) {
      if (cli_parse_size(argv[++i], 16384, &v.w, &v.h))
        return cli_fail("shade", 2, "--size: expected WxH (1..16384), got '%s'", val);
    } else if (!strcmp(a, "--exposure")) {
      if (cli_parse_double(argv[++i], &exposure) || exposure <= 0)
        return cli_fail("shade", 2, "--exposure: expected a positive number, got '%s'", val);
    } else if (a[0] == '-') {
      cli_print_usage(help);
      return cli_fail("shade", 2, "unknown option '%s'", a);
    } else {
      if (in) return cli_fail("shade", 2, "more than one input ('%s' and '%s')", in, a);
      in = a;
    }
  }
  if (!in || !out) {
    cli_print_usage(help);
    return cli_fail("shade", 2, "a .prt input and -o FILE are required");
  }
  int cst = cli_check_output("shade", "-o", out);
  if (cst) return cst;
  if (spec.kind == CV_LIGHT_NONE)
    return cli_fail("shade", 2, "no lighting: give --env, --env-constant or --sky");
  int wst = cli_apply_weights("shade", &spec, weights);
  if (wst) return wst;
  if (have_view != have_look) return cli_fail("shade", 2, "--view and --look go together");
  int is_view = have_view;
  if (is_view && !cli_has_ext(out, ".exr") && !cli_has_ext(out, ".png"))
    return cli_fail("shade", 2, "-o: a view is written as .exr or .png, got '%s'", out);
  if (!is_view && !cli_has_ext(out, ".ply"))
    return cli_fail("shade", 2, "-o: per-vertex output is a .ply (or add --view for an image), got '%s'", out);
  if (is_view) {
    cli_camera_arg ca = {v.eye, v.look, v.up, eye_s, look_s, up_s};
    if (cli_check_camera("shade", &ca)) return 2;
  }

  int rc = 1;
  cv_prt *p = NULL;
  cv_mesh *m = NULL;
  cv_tracer *tr = NULL;
  cv_scene_light *sl = NULL;
  float *rad = NULL;
  cv_dir_light *lights = NULL;
  cv_image *img = NULL;
  cv_image **tex = NULL; /* per material, NULL where untextured */
  if (cv_prt_read(in, &p, &err)) {
    rc = cli_fail("shade", 1, "%s", err.msg);
    goto done;
  }
  if (cv_scene_light_build(&spec, (int)p->bands, &sl, &err)) {
    rc = cli_fail("shade", 1, "%s", err.msg);
    goto done;
  }
  if (cv_prt_to_mesh(p, &m) || cv_tracer_create(m, &tr, &err)) {
    rc = cli_fail("shade", 1, "%s: %s", in, err.msg[0] ? err.msg : "out of memory");
    goto done;
  }
  if (split && cv_scene_light_split(sl, tr, split, split_grid, &err)) {
    rc = cli_fail("shade", 1, "--split: %s", err.msg);
    goto done;
  }
  cv_scene_light_print(stdout, sl);
  cv_lighting l = cv_scene_light_sh(sl);
  const cv_dir_light *extra = NULL;
  int n_extra = cv_scene_light_extra(sl, &extra);
  if (!is_view) pixel_mode = PIXEL_NONE; /* per-vertex output: all direct light per vertex */
  ro.sun_direct = pixel_mode == PIXEL_NONE;
  ro.extra_direct = pixel_mode != PIXEL_ALL;
  ro.clamp = pixel_mode == PIXEL_NONE; /* else clamped per pixel, after the pixel lights */
  rad = malloc(3 * p->nv * sizeof(float) + 1);
  lights = malloc((1 + (size_t)n_extra) * sizeof *lights);
  cv_relight_stats rs;
  if (!rad || !lights || cv_prt_relight_opt(p, &l, extra, n_extra, tr, &ro, rad, &rs)) {
    rc = cli_fail("shade", 1, "relighting failed");
    goto done;
  }
  printf("relit %zu vertices (%u bands); %llu channels %s (SH ringing), %llu non-finite\n",
         p->nv, p->bands, (unsigned long long)rs.clamped_negative,
         ro.clamp ? "clamped from negative" : "negative (kept: clamped per pixel after the pixel lights)",
         (unsigned long long)rs.nonfinite);
  if (!is_view) {
    if (cv_prt_fold_texture_means(p, rad)) {
      rc = cli_fail("shade", 1, "out of memory");
      goto done;
    }
    if (cv_ply_write_points(out, p->nv, p->pos, rad, p->tri, p->nt, !ascii, &err)) {
      rc = cli_fail("shade", 1, "%s", err.msg);
      goto done;
    }
  } else {
    if (cv_image_create(v.w, v.h, 3, &img)) {
      rc = cli_fail("shade", 1, "cannot allocate a %dx%d image", v.w, v.h);
      goto done;
    }
    if (p->flags & CV_PRT_TEXTURED) {
      if (!(tex = calloc(p->nm + 1, sizeof *tex))) {
        rc = cli_fail("shade", 1, "out of memory");
        goto done;
      }
      size_t unread = 0;
      for (size_t i = 0; i < p->nm; i++) {
        if (!cv_prt_mat_textured(p, i)) continue;
        if (cv_texture_load(p->mat_tex[i], &tex[i], &err)) {
          /* as the renderer does: the material's stored albedo (the
           * texture's mean) as a 1 x 1 texture, counted */
          if (!unread++) printf("warning: material '%s' texture: %s\n", p->mats[i].name, err.msg);
          if (cv_image_create(1, 1, 3, &tex[i])) {
            rc = cli_fail("shade", 1, "out of memory");
            goto done;
          }
          memcpy(tex[i]->px, p->mats[i].albedo, 3 * sizeof(float));
          continue;
        }
        cv_texture_match_mean(tex[i], p->mats[i].albedo); /* the colour factor */
        printf("texture: material '%s': %s (%d x %d)\n", p->mats[i].name, p->mat_tex[i],
               tex[i]->w, tex[i]->h);
      }
      if (unread)
        printf("warning: %zu textures could not be read and show their mean albedo\n", unread);
    }
    cv_shade_view_params vp = {.rad = rad, .lights = lights, .tex = tex,
                               .background = background, .bg_ctx = sl};
    vp.n_lights = pixel_lights(pixel_mode, &l, extra, n_extra, lights);
    cv_pinhole_init(&vp.cam, v.eye, v.look, v.up, v.fov, v.w, v.h);
    cv_shade_view_stats vs;
    cv_shade_view(p, cv_tracer_rt(tr), &vp, img, &vs);
    printf("view: %d lights per pixel (--pixel-lights %s); %llu pixel channels clamped from "
           "negative, %llu non-finite\n", vp.n_lights,
           pixel_mode == PIXEL_ALL ? "all" : pixel_mode == PIXEL_SUN ? "sun" : "none",
           (unsigned long long)vs.clamped_negative, (unsigned long long)vs.nonfinite);
    if (vs.escaped)
      printf("view: %llu pixels saw neither geometry nor a window (black)\n",
             (unsigned long long)vs.escaped);
    if (cli_has_ext(out, ".exr")) {
      if (cv_exr_write(out, img, 0, CV_EXR_ZIP, &err)) {
        rc = cli_fail("shade", 1, "%s", err.msg);
        goto done;
      }
    } else {
      cv_preview_stats ps;
      if (cv_preview_write_png(out, img, exposure, &ps, &err)) {
        rc = cli_fail("shade", 1, "%s", err.msg);
        goto done;
      }
      printf("view: exposure %.4g (log-average luminance %.4g), %llu channels clamped\n",
             ps.exposure, ps.log_avg_luminance, (unsigned long long)ps.clamped_channels);
    }
  }
  printf("wrote %s\n", out);
  rc = 0;
done:
  for (size_t i = 0; tex && i < p->nm; i++) cv_image_destroy(tex[i]);
  free(tex);
  cv_image_destroy(img);
  free(rad);
  free(lights);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
  cv_scene_light_destroy(sl);
  cv_prt_destroy(p);
  return rc;
}
