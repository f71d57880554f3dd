/* `cave lcd`: what the driver sees on the dashboard LCD panel under the
 * current daylight from the tracked head position (Dmitriev et al. 2004,
 * section 4.3): the panel's emitted content plus its reflection of the car
 * interior (PRT radiance) and the sky through the windows, final-gathered
 * with one bounce through a tabulated BRDF, progressively in fixed point
 * (src/lcd).  Writes the panel image (EXR), a sidecar JSON with its sample
 * count and error estimate, and optionally a tone-mapped PNG. */
#include <math.h>
#include <omp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/cli.h"
#include "core/outfile.h"
#include "core/progress.h"
#include "io/exr.h"
#include "io/tonemap_simple.h"
#include "lcd/gather.h"
#include "lcd/lcd_config.h"
#include "prt/bake.h"
#include "prt/scene_light.h"

static void help(FILE *f) {
  fprintf(f,
          "usage: cave lcd <scene.prt | scene.json> --eye x,y,z LIGHT [--yaw DEG] [--pitch DEG]\n"
          "                [--roll DEG] [--spp N] [--rounds R] [--size WxH] [--brdf FILE]\n"
          "                [--sampling brdf|cosine|mis] [--content FILE] [--luminance CD]\n"
          "                [--lcd-config FILE] [--prt FILE] [--seed S] [--threads N]\n"
          "                -o panel.exr [--png]\n\n"
          "Final gather on the LCD panel (the scene's triangles tagged lcd): for every texel the\n"
          "eye ray from --eye gives the view direction; reflected rays are drawn from the\n"
          "panel's BRDF and traced one bounce: through a window they read the environment,\n"
          "elsewhere the PRT radiance of the hit triangle; the sun is added where it reaches the\n"
          "panel.  The panel's content (--content image, --luminance cd/m^2 for white) is added.\n"
          "Rounds of --spp samples per texel accumulate in fixed point (same result for any split).\n\n"
          "LIGHT is one of --env FILE[,FILE...] [--weights w,..] [--scale S |\n"
          "--illuminance LUX|auto] [--no-sun],\n"
          "--env-constant R,G,B, --sky TURBIDITY,ELEVATION,AZIMUTH (as cave shade); a\n"
          "scene.json's own lighting is used when none is given.\n\n"
          "  --eye x,y,z       driver's eye, car frame, metres (quantised by lcd.eye_tolerance)\n"
          "  --spp N           samples per texel per round (default 40)\n"
          "  --rounds R        rounds (default 1)\n"
          "  --size WxH        panel texels (default 400x300)\n"
          "  --brdf FILE       BRDF table (docs/brdf-format.md), MERL .binary, or\n"
          "                    builtin:antiglare (default)\n"
          "  --sampling S      brdf, cosine, or mis (default: mis: half the samples towards\n"
          "                    the windows, the rest 90%% BRDF / 10%% cosine)\n"
          "  --content FILE    .png (sRGB) or .exr shown on the panel (default: a test pattern)\n"
          "  --luminance CD    content white luminance in cd/m^2 (default 250)\n"
          "  --lcd-config FILE JSON {\"lcd\": {...}} with these settings (see lcd_config.h)\n"
          "  --prt FILE        with a scene.json: the baked PRT to use (else baked here)\n"
          "  --png             also write a tone-mapped PNG next to the EXR\n"
          "Outputs: panel.exr (linear RGB radiance), panel.exr.json (samples, error estimate).\n"
          "\nexamples:\n"
          "  cave lcd scene.prt --eye -0.37,1.1,0.3 --env forest.exr --illuminance auto -o panel.exr --png\n"
          "  cave lcd configs/scenes/default.json --eye -0.37,1.1,0.3 --rounds 4 -o panel.exr\n");
}

static int parse_light(const char *a, char **argv, int *i, cv_light_spec *spec, int *have,
                       const char **weights) {
  const char *val = argv[*i + 1];
  cv_err err;
  if (!strcmp(a, "--env")) {
    char buf[8192];
    snprintf(buf, sizeof buf, "%s", argv[++*i]);
    char *save = NULL;
    spec->kind = CV_LIGHT_ENV;
    spec->n_env = 0;
    for (char *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
      if (spec->n_env == CV_MAX_ENV_MAPS) return cli_fail("lcd", 2, "--env: at most %d maps", CV_MAX_ENV_MAPS);
      if (cv_resolve_env_path(tok, NULL, spec->env[spec->n_env], &err))
        return cli_fail("lcd", 1, "--env: %s", err.msg);
      spec->n_env++;
    }
    for (int k = 0; k < spec->n_env; k++) spec->weight[k] = 1.0 / spec->n_env;
  } else if (!strcmp(a, "--weights")) {
    *weights = argv[++*i];
  } else if (!strcmp(a, "--scale")) {
    if (cli_parse_double(argv[++*i], &spec->scale) || spec->scale < 0)
      return cli_fail("lcd", 2, "--scale: expected a non-negative number, got '%s'", val);
  } else if (!strcmp(a, "--illuminance")) {
    if (cli_parse_illuminance(argv[++*i], &spec->illuminance))
      return cli_fail("lcd", 2, "--illuminance: expected lux (0, 1e7] or auto, got '%s'", val);
  } else if (!strcmp(a, "--env-constant")) {
    spec->kind = CV_LIGHT_CONSTANT;
    if (cli_parse_vec(argv[++*i], 3, spec->constant) || spec->constant[0] < 0 ||
        spec->constant[1] < 0 || spec->constant[2] < 0)
      return cli_fail("lcd", 2, "--env-constant: expected R,G,B >= 0, got '%s'", val);
  } else if (!strcmp(a, "--sky")) {
    double s[3];
    spec->kind = CV_LIGHT_SKY;
    if (cli_parse_vec(argv[++*i], 3, s) || s[0] < 2 || s[0] > 10 || s[1] < -10 || s[1] > 90)
      return cli_fail("lcd", 2, "--sky: expected TURBIDITY(2..10),ELEVATION(-10..90),AZIMUTH, got '%s'", val);
    spec->turbidity = s[0];
    spec->sun_elevation_deg = s[1];
    spec->sun_azimuth_deg = s[2];
  } else {
    double d;
    if (cli_parse_double(argv[++*i], &d)) return cli_fail("lcd", 2, "%s: expected degrees, got '%s'", a, val);
    if (!strcmp(a, "--yaw")) spec->yaw_deg = d;
    else if (!strcmp(a, "--pitch")) spec->pitch_deg = d;
    else spec->roll_deg = d;
    return -1; /* orientation only: not a lighting source */
  }
  *have = 1;
  return -1;
}

static int write_sidecar(const char *path, const cv_lcd_accum *acc, const cv_lcd_error *e,
                         const cv_lcd_key *key, double seconds, const char *brdf, cv_err *err) {
  cv_outfile o;
  int st = cv_outfile_open(&o, path, 1, err);
  if (st) return st;
  const int64_t *d = acc->data;
  fprintf(o.f,
          "{\n  \"width\": %d, \"height\": %d,\n  \"samples_per_texel\": %lld, \"rounds\": %lld,\n"
          "  \"estimated_relative_rms_error\": %.6g,\n  \"mean_reflected_luminance\": %.6g,\n"
          "  \"clamped_values\": %lld, \"nonfinite_values\": %lld,\n"
          "  \"rays\": {\"interior\": %lld, \"environment\": %lld, \"lost\": %lld, \"sun_shadow\": %lld, \"sun_unblocked\": %lld},\n"
          "  \"key\": {\"eye_q\": [%d, %d, %d], \"light_hash\": \"%016llx\", \"setup_hash\": \"%016llx\"},\n"
          "  \"brdf\": \"%s\", \"seconds\": %.3f\n}\n",
          acc->w, acc->h, (long long)d[CV_LCD_ACC_SPP], (long long)d[CV_LCD_ACC_ROUNDS], e->rel_rms,
          e->mean_luminance, (long long)d[CV_LCD_ACC_CLAMPED], (long long)d[CV_LCD_ACC_NONFINITE],
          (long long)d[CV_LCD_ACC_HITS], (long long)d[CV_LCD_ACC_ENV], (long long)d[CV_LCD_ACC_LOST],
          (long long)d[CV_LCD_ACC_SHADOW], (long long)d[CV_LCD_ACC_SUNLIT], key->eye_q[0],
          key->eye_q[1], key->eye_q[2], (unsigned long long)key->light_hash,
          (unsigned long long)key->setup_hash, brdf, seconds);
  return cv_outfile_commit(&o, err);
}

int cmd_lcd(int argc, char **argv) {
  const char *in = NULL, *out = NULL, *weights = NULL, *prt_path = NULL, *cfg_path = NULL;
  const char *brdf_s = NULL, *content_s = NULL, *sampling = NULL, *size_s = NULL;
  int png = 0, have_light = 0, have_eye = 0, threads = 0, spp = -1, rounds = -1;
  double lum = -1, eye[3] = {0, 0, 0};
  long long seed = -1;
  cv_light_spec spec;
  cv_light_spec_default(&spec);
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *val = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    } else if (!strcmp(a, "--png")) {
      png = 1;
    } else if (!strcmp(a, "--no-sun")) {
      spec.extract_sun = 0;
    } else if (a[0] == '-' && !val) {
      cli_print_usage(help);
      return cli_fail("lcd", 2, "option '%s' needs a value", a);
    } else if (!strcmp(a, "--env") || !strcmp(a, "--weights") || !strcmp(a, "--scale") || !strcmp(a, "--illuminance") ||
               !strcmp(a, "--env-constant") || !strcmp(a, "--sky") || !strcmp(a, "--yaw") ||
               !strcmp(a, "--pitch") || !strcmp(a, "--roll")) {
      int rc = parse_light(a, argv, &i, &spec, &have_light, &weights);
      if (rc >= 0) return rc;
    } else if (!strcmp(a, "-o")) {
      out = argv[++i];
    } else if (!strcmp(a, "--eye")) {
      if (cli_parse_vec(argv[++i], 3, eye)) return cli_fail("lcd", 2, "--eye: expected x,y,z, got '%s'", val);
      have_eye = 1;
    } else if (!strcmp(a, "--spp")) {
      if (cli_parse_int(argv[++i], 1, 65536, &spp)) return cli_fail("lcd", 2, "--spp: expected 1..65536, got '%s'", val);
    } else if (!strcmp(a, "--rounds")) {
      if (cli_parse_int(argv[++i], 1, 100000, &rounds)) return cli_fail("lcd", 2, "--rounds: expected 1..100000, got '%s'", val);
    } else if (!strcmp(a, "--size")) {
      size_s = argv[++i];
    } else if (!strcmp(a, "--brdf")) {
      brdf_s = argv[++i];
    } else if (!strcmp(a, "--sampling")) {
      sampling = argv[++i];
      if (strcmp(sampling, "brdf") && strcmp(sampling, "cosine") && strcmp(sampling, "mis"))
        return cli_fail("lcd", 2, "--sampling: expected brdf, cosine or mis, got '%s'", sampling);
    } else if (!strcmp(a, "--content")) {
      content_s = argv[++i];
    } else if (!strcmp(a, "--luminance")) {
      if (cli_parse_double(argv[++i], &lum) || lum < 0) return cli_fail("lcd", 2, "--luminance: expected cd/m^2 >= 0, got '%s'", val);
    } else if (!strcmp(a, "--lcd-config")) {
      cfg_path = argv[++i];
    } else if (!strcmp(a, "--prt")) {
      prt_path = argv[++i];
    } else if (!strcmp(a, "--seed")) {
      int s;
      if (cli_parse_int(argv[++i], 0, 2147483647, &s)) return cli_fail("lcd", 2, "--seed: expected 0..2147483647, got '%s'", val);
      seed = s;
    } else if (!strcmp(a, "--threads")) {
      if (cli_parse_int(argv[++i], 1, 1024, &threads)) return cli_fail("lcd", 2, "--threads: expected 1..1024, got '%s'", val);
    } else if (a[0] == '-') {
      cli_print_usage(help);
      return cli_fail("lcd", 2, "unknown option '%s'", a);
    } else {
      if (in) return cli_fail("lcd", 2, "more than one input ('%s' and '%s')", in, a);
      in = a;
    }
  }
  if (!in || !out || !have_eye) {
    cli_print_usage(help);
    return cli_fail("lcd", 2, "an input (.prt or .json), --eye x,y,z and -o FILE.exr are required");
  }
  if (!cli_has_ext(out, ".exr")) return cli_fail("lcd", 2, "-o: the panel is written as .exr, got '%s'", out);
  cv_err err;
  cv_err_clear(&err);
  cv_lcd_config lc;
  cv_lcd_config_default(&lc);
  if (cfg_path && cv_lcd_config_load(cfg_path, &lc, &err)) return cli_fail("lcd", 1, "%s", err.msg);
  if (spp > 0) lc.spp = spp;
  if (rounds > 0) lc.rounds = rounds;
  if (size_s && (sscanf(size_s, "%dx%d", &lc.width, &lc.height) != 2 || lc.width < 1 ||
                 lc.height < 1 || lc.width > 16384 || lc.height > 16384))
    return cli_fail("lcd", 2, "--size: expected WxH (1..16384), got '%s'", size_s);
  if (brdf_s) snprintf(lc.brdf, sizeof lc.brdf, "%s", brdf_s);
  if (content_s) snprintf(lc.content, sizeof lc.content, "%s", content_s);
  if (lum >= 0) lc.content_luminance = lum;
  if (seed >= 0) lc.seed = (uint32_t)seed;
  if (sampling) lc.brdf_fraction = !strcmp(sampling, "brdf") ? 1.0 : !strcmp(sampling, "cosine") ? 0.0 : 0.9;
  if (threads > 0) omp_set_num_threads(threads);

  int rc = 1;
  cv_scene_config cfg;
  cv_scene_config_default(&cfg);
  cv_prt *p = NULL;
  cv_mesh *m = NULL;
  cv_tracer *tr = NULL;
  cv_scene_light *sl = NULL;
  cv_lcd_light *light = NULL;
  cv_brdf *brdf = NULL;
  cv_lcd_gather *g = NULL;
  cv_lcd_accum *acc = NULL, *round_buf = NULL;
  cv_lcd_progress prog;
  memset(&prog, 0, sizeof prog);
  cv_image *content = NULL, *img = NULL;
  if (weights) {
    if (spec.kind != CV_LIGHT_ENV) return cli_fail("lcd", 2, "--weights needs --env");
    double w[CV_MAX_ENV_MAPS], sum = 0;
    if (cli_parse_vec(weights, spec.n_env, w))
      return cli_fail("lcd", 2, "--weights: expected %d comma-separated numbers, got '%s'", spec.n_env, weights);
    for (int k = 0; k < spec.n_env; k++) {
      if (w[k] < 0) return cli_fail("lcd", 2, "--weights: negative weight %g", w[k]);
      spec.weight[k] = w[k];
      sum += w[k];
    }
    if (!(sum > 0)) return cli_fail("lcd", 2, "--weights: the weights sum to 0");
  }
  /* The BRDF first: a bad file fails before any long work. */
  cv_brdf_report brep;
  if (cv_brdf_load(lc.brdf, &brdf, &brep, &err)) {
    rc = cli_fail("lcd", 1, "%s", err.msg);
    goto done;
  }
  printf("brdf: %s, %dx%dx%d grid; directional albedo max %.4f at %.0f deg", brdf->source,
         brdf->n_theta, brdf->n_theta, brdf->n_phi, brep.albedo_max, brep.albedo_max_deg);
  if (brep.merl_missing)
    printf("; MERL: %llu missing samples read as 0 (%llu grid points on them)",
           (unsigned long long)brep.merl_missing, (unsigned long long)brep.merl_missing_used);
  printf("\n");
  if (brep.albedo_violations)
    printf("warning: brdf: directional albedo above 1 at %d view angles (from %.0f deg): the "
           "table reflects more light than it receives\n",
           brep.albedo_violations, brep.first_violation_deg);
  if (cli_has_ext(in, ".json")) {
    if (cv_scene_config_load(in, &cfg, &err)) {
      rc = cli_fail("lcd", 1, "%s", err.msg);
      goto done;
    }
    if (!have_light && cfg.light.kind != CV_LIGHT_NONE) {
      double y = spec.yaw_deg, pi = spec.pitch_deg, r = spec.roll_deg;
      spec = cfg.light;
      if (y != 0) spec.yaw_deg = y;
      if (pi != 0) spec.pitch_deg = pi;
      if (r != 0) spec.roll_deg = r;
      have_light = 1;
    }
    if (prt_path) {
      if (cv_prt_read(prt_path, &p, &err)) {
        rc = cli_fail("lcd", 1, "%s", err.msg);
        goto done;
      }
    } else {
      if (cli_load_scene_mesh(&cfg, stdout, &m, &err) || cv_tracer_create(m, &tr, &err)) {
        rc = cli_fail("lcd", 1, "%s", err.msg);
        goto done;
      }
      cv_bake_params bp = {.bands = cfg.bands ? cfg.bands : 5, .rays = cfg.rays ? cfg.rays : 1024,
                           .bounces = cfg.bounces, .seed = cfg.seed, .spread = (float)cfg.spread,
                           .cosine_only = !cfg.window_sampling, .quiet = 1};
      printf("bake: %d bands, %d rays, %d bounces (use --prt FILE from `cave bake` to skip this)\n",
             bp.bands, bp.rays, bp.bounces);
      fflush(stdout);
      cv_tracer_set_spread(tr, bp.spread);
      cv_tracer_set_window_sampling(tr, !bp.cosine_only);
      if (cv_prt_bake_tracer(tr, &bp, &p, NULL, &err)) {
        rc = cli_fail("lcd", 1, "%s", err.msg);
        goto done;
      }
      cv_tracer_destroy(tr);
      tr = NULL;
      cv_mesh_destroy(m);
      m = NULL;
    }
  } else if (cv_prt_read(in, &p, &err)) {
    rc = cli_fail("lcd", 1, "%s", err.msg);
    goto done;
  }
  if (!have_light || spec.kind == CV_LIGHT_NONE) {
    rc = cli_fail("lcd", 2, "no lighting: give --env, --env-constant or --sky");
    goto done;
  }
  double t0 = cv_now_seconds();
  if (cv_prt_to_mesh(p, &m) || cv_tracer_create(m, &tr, &err)) {
    rc = cli_fail("lcd", 1, "%s: %s", in, err.msg[0] ? err.msg : "out of memory");
    goto done;
  }
  if (cv_scene_light_build(&spec, (int)p->bands, &sl, &err) ||
      cv_lcd_light_from_scene(sl, &spec, p, tr, lc.sun_samples, lc.env_width, &light, &err)) {
    rc = cli_fail("lcd", 1, "%s", err.msg);
    goto done;
  }
  cv_scene_light_print(stdout, sl);
  printf("lcd sun: %s; %llu vertex radiance values were not finite or negative (set to 0)\n",
         light->sun_source, (unsigned long long)light->vrad_fixed);
  cv_lcd_panel panel;
  if (cv_lcd_panel_from_mesh(m, &panel, &err) ||
      cv_lcd_gather_create(cv_tracer_rt(tr), m, &panel, brdf, &g, &err)) {
    rc = cli_fail("lcd", 1, "%s: %s", in, err.msg);
    goto done;
  }
  printf("panel: %.0f x %.0f mm at %.3f %.3f %.3f, normal %.3f %.3f %.3f; %dx%d texels\n",
         1000 * panel.size[0], 1000 * panel.size[1], panel.center[0], panel.center[1],
         panel.center[2], panel.normal[0], panel.normal[1], panel.normal[2], lc.width, lc.height);
  cv_lcd_params par;
  cv_lcd_params_default(&par);
  par.w = lc.width;
  par.h = lc.height;
  par.spp = lc.spp;
  par.brdf_fraction = lc.brdf_fraction;
  /* brdf / cosine alone: no window samples (mis: the default share) */
  if (sampling && strcmp(sampling, "mis")) par.window_fraction = 0;
  par.seed = lc.seed;
  double clamp = lc.clamp > 0 ? lc.clamp : cv_lcd_default_clamp(light, brdf);
  const float ef[3] = {(float)eye[0], (float)eye[1], (float)eye[2]};
  cv_lcd_key key;
  uint64_t setup = cv_lcd_setup_hash(g, &par, clamp, lc.eye_tolerance, p->meta.input_hash);
  if (cv_lcd_key_make(ef, lc.eye_tolerance, light->hash, setup, &key)) {
    rc = cli_fail("lcd", 2, "--eye: %g,%g,%g is not representable with tolerance %g", eye[0],
                  eye[1], eye[2], lc.eye_tolerance);
    goto done;
  }
  cv_lcd_key_eye(&key, lc.eye_tolerance, par.eye);
  if (cv_lcd_accum_create(par.w, par.h, clamp, &round_buf)) {
    rc = cli_fail("lcd", 1, "cannot allocate a %dx%d panel", par.w, par.h);
    goto done;
  }
  double setup_s = cv_now_seconds() - t0;
  t0 = cv_now_seconds();
  for (int r = 0; r < lc.rounds; r++) {
    cv_lcd_accum_clear(round_buf);
    int st = cv_lcd_render_round(g, light, &par, (uint32_t)r, round_buf);
    if (!st) st = cv_lcd_progress_submit(&prog, &key, round_buf, NULL);
    if (st) {
      rc = cli_fail("lcd", 1, "round %d: %s", r, cv_status_str(st));
      goto done;
    }
  }
  double render_s = cv_now_seconds() - t0;
  acc = prog.acc;
  cv_lcd_error e;
  cv_lcd_accum_error(acc, &e);
  if (cv_lcd_content_load(lc.content, par.w, par.h, lc.content_luminance, &content, &err)) {
    rc = cli_fail("lcd", 1, "%s", err.msg);
    goto done;
  }
  if (cv_lcd_accum_to_image(acc, content, &img) || cv_exr_write(out, img, 0, CV_EXR_ZIP, &err)) {
    rc = cli_fail("lcd", 1, "%s", err.msg[0] ? err.msg : "cannot make the image");
    goto done;
  }
  const int64_t *d = acc->data;
  int64_t rays = d[CV_LCD_ACC_HITS] + d[CV_LCD_ACC_ENV] + d[CV_LCD_ACC_LOST];
  printf("lcd: %d round(s) x %d samples per texel in %.2f s (setup %.2f s) on %d threads: %.2f M "
         "rays/s; eye %.4f %.4f %.4f\n",
         lc.rounds, par.spp, render_s, setup_s, omp_get_max_threads(),
         render_s > 0 ? rays / render_s / 1e6 : 0.0, par.eye[0], par.eye[1], par.eye[2]);
  printf("lcd: %lld samples per texel; estimated relative RMS error of the reflection %.2f%%; "
         "rays: %.1f%% interior, %.1f%% environment, %.2f%% lost; sun reached %lld of %lld texel "
         "rounds; clamped %lld, non-finite %lld, behind the panel %lld\n",
         (long long)d[CV_LCD_ACC_SPP], 100 * e.rel_rms, rays ? 100.0 * d[CV_LCD_ACC_HITS] / rays : 0.0,
         rays ? 100.0 * d[CV_LCD_ACC_ENV] / rays : 0.0, rays ? 100.0 * d[CV_LCD_ACC_LOST] / rays : 0.0,
         (long long)d[CV_LCD_ACC_SUNLIT], (long long)d[CV_LCD_ACC_SHADOW],
         (long long)d[CV_LCD_ACC_CLAMPED], (long long)d[CV_LCD_ACC_NONFINITE],
         (long long)d[CV_LCD_ACC_BEHIND]);
  double white = lc.content_luminance, black = 0.002 * white;
  printf("lcd: mean reflected luminance %.4g; content white %.4g, black %.4g: ambient contrast "
         "ratio %.1f:1\n",
         e.mean_luminance, white, black,
         black + e.mean_luminance > 0 ? (white + e.mean_luminance) / (black + e.mean_luminance) : 0.0);
  char side[CV_PATH_MAX + 8];
  snprintf(side, sizeof side, "%s.json", out);
  if (write_sidecar(side, acc, &e, &key, render_s, brdf->source, &err)) {
    rc = cli_fail("lcd", 1, "%s", err.msg);
    goto done;
  }
  if (png) {
    char pngp[CV_PATH_MAX];
    snprintf(pngp, sizeof pngp, "%.*s.png", (int)(strlen(out) - 4), out);
    cv_preview_stats ps;
    if (cv_preview_write_png(pngp, img, 0, &ps, &err)) {
      rc = cli_fail("lcd", 1, "%s", err.msg);
      goto done;
    }
    printf("wrote %s (exposure %.4g)\n", pngp, ps.exposure);
  }
  printf("wrote %s and %s\n", out, side);
  rc = 0;
done:
  cv_image_destroy(img);
  cv_image_destroy(content);
  cv_lcd_progress_free(&prog);
  cv_lcd_accum_destroy(round_buf);
  cv_lcd_gather_destroy(g);
  cv_brdf_destroy(brdf);
  cv_lcd_light_destroy(light);
  cv_scene_light_destroy(sl);
  cv_tracer_destroy(tr);
  cv_mesh_destroy(m);
  cv_prt_destroy(p);
  cv_scene_config_free(&cfg);
  return rc;
}
