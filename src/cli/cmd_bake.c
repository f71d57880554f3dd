/* `cave bake`: scene (config or mesh file) -> cleaned mesh -> PRT file.
 * Skips the work when the output already holds a bake of the same inputs. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <omp.h>

#include "cli/cli.h"
#include "lcd/lcd_config.h"
#include "prt/auto_view.h"
#include "prt/auto.h"
#include "prt/bake.h"
#include "prt/scene_light.h"

static void help(FILE *f) {
  fprintf(f,
          "usage: cave bake <scene.json | mesh.obj|.ply|.gltf|.glb | default> -o scene.prt\n"
          "                 [--bands N|auto] [--rays N|auto] [--bounces N] [--seed S]\n"
          "                 [--budget E] [--spread F] [--cosine-only] [--tail on|off] [--tess N]\n"
          "                 [--threads N] [--force] [--quiet] [--view-budget E] [LIGHT]\n"
          "                 [--units U] [--up y|z] [--model-scale S] [--rotate X,Y,Z]\n"
          "                 [--translate X,Y,Z]\n\n"
          "Precomputes per-vertex radiance transfer (Dmitriev et al. 2004, section 4.1):\n"
          "cosine-weighted Owen-scrambled Sobol rays from stochastic points in each vertex's\n"
          "triangles; only rays that leave through a window see the sky (directions drawn\n"
          "by MIS of the cosine lobe and the window openings); N bounces.\n"
          "'default' bakes the built-in cabin.  Options override the scene config.\n\n"
          "  --bands N|auto  SH bands 2..8 (N*N coefficients; config default 8)\n"
          "  --rays N|auto   rays per vertex per pass (default 1024)\n"
          "  --bounces N     interreflection bounces 0..16 (default 2)\n"
          "  --budget E      relative error budget for auto (default 0.05)\n"
          "  --seed S        sampling seed (same seed, same bytes)\n"
          "  --cosine-only   direct pass without window importance sampling\n"
          "  --view-budget E pick the SH bands (and a --split K for shade/render) whose\n"
          "                  median per-pixel error of the direct light in the driver's\n"
          "                  view is <= E (p90 <= 3E) at the lowest cost, estimated before\n"
          "                  the bake against its all-frequency value (needs LIGHT; prints\n"
          "                  every candidate; docs/reference.md)\n"
          "  LIGHT           --env FILE[,FILE...] | --env-constant R,G,B | --sky T,ELEV,AZIM\n"
          "                  (as cave shade): overrides the config's lighting.  It does not\n"
          "                  change the transfer: it steers the auto picks (--bands/--rays\n"
          "                  auto, --view-budget) and is reported.  With --env also:\n"
          "  --weights W1,W2,...  the maps' blend weights (default: equal)\n"
          "  --scale S       radiance multiplier of the map(s) (default 1)\n"
          CLI_ILLUMINANCE_HELP
          "  --no-sun        keep a sun found in the map(s) in the SH lighting instead of\n"
          "                  splitting it out (also for a config whose lighting is \"env\")\n"
          "  --yaw/--pitch/--roll DEG  the car's orientation under the lighting (also on\n"
          "                  the config's lighting; needs one of the two)\n"
          "  --tail on|off   add the bounces after the last as a geometric series (the\n"
          "                  last bounce x r/(1-r), r = ratio of the last two; default on)\n"
          "  --spread F      fraction 0..1 of each vertex's triangles that ray origins\n"
          "                  cover (1 = the paper's whole fan; default 0.5)\n"
          "  --tess N        built-in cabin subdivision (1..64; scene default 2, ~38K triangles)\n"
          "  --threads N     OpenMP threads (default: all cores)\n"
          "  --force         bake even if the output already matches the inputs\n"
          "  --quiet         no progress bar\n"
          CLI_PLACE_HELP
          "The bake prints the model's bounding box in metres and warns when it is\n"
          "implausible for a car (largest extent under 0.5 m or over 20 m).\n\n"
          "Mesh files are imported by assimp in a child process under limits (environment):\n"
          "  CAVE_IMPORT_TIMEOUT=S     wall-clock seconds (default 600; 0 = none)\n"
          "  CAVE_IMPORT_MEMORY_MB=M   MB of address space the import may add (default 8192\n"
          "                            or 3/4 of the RAM, whichever is less; 0 = none);\n"
          "                            raise both for big CAD\n"
          "  CAVE_IMPORT_VERBOSE=1     show what assimp printed (otherwise dropped)\n\n"
          "examples:\n"
          "  cave bake configs/scenes/default.json -o cabin.prt\n"
          "  cave bake regr01.obj --units cm --up z --rays 64 -o house.prt\n");
}

/* cave bake's command line, as given. */
typedef struct bake_opts {
  const char *in, *out;
  const char *bands_s, *rays_s, *bounces_s, *seed_s, *budget_s, *tess_s;
  int force, quiet, threads, cosine_only, tail, no_sun;
  const char *env_only;   /* the first of --scale/--illuminance given (they need --env) */
  const char *pose;       /* the first of --yaw/--pitch/--roll given */
  int pose_given;         /* bits: 1 --yaw, 2 --pitch, 4 --roll */
  int have_light;         /* --env, --env-constant or --sky given */
  double view_budget, spread;
  cv_light_spec lspec;
  const char *weights;
  cli_place_opts place;
} bake_opts;

/* Reads argv into o.  Returns -1 to go on, else the exit status (0 after
 * --help; 2 with the message printed for a bad option). */
static int parse_opts(int argc, char **argv, bake_opts *o) {
  memset(o, 0, sizeof *o);
  o->cosine_only = o->tail = -1;
  o->spread = -1;
  cv_light_spec_default(&o->lspec);
  o->place.given = 0;
  cv_placement_default(&o->place.p);
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
    int pr, prc = 0;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    } else if ((pr = cli_place_option("bake", argv, argc, &i, &o->place, &prc)) != 0) {
      if (pr < 0) return prc;
    } else if (!strcmp(a, "--force")) {
      o->force = 1;
    } else if (!strcmp(a, "--quiet")) {
      o->quiet = 1;
    } else if (!strcmp(a, "--cosine-only")) {
      o->cosine_only = 1;
    } else if (!strcmp(a, "--no-sun")) {
      o->no_sun = 1;
    } else if (!strcmp(a, "-o") && v) {
      o->out = argv[++i];
    } else if (!strcmp(a, "--bands") && v) {
      o->bands_s = argv[++i];
    } else if (!strcmp(a, "--rays") && v) {
      o->rays_s = argv[++i];
    } else if ((pr = cli_parse_light("bake", argc, argv, &i, &o->lspec, &o->weights)) != 0) {
      if (pr < 0) return -pr;
      if (!strcmp(a, "--scale") || !strcmp(a, "--illuminance")) {
        if (!o->env_only) o->env_only = a;
      } else if (!strcmp(a, "--yaw") || !strcmp(a, "--pitch") || !strcmp(a, "--roll")) {
        if (!o->pose) o->pose = a;
        o->pose_given |= a[2] == 'y' ? 1 : a[2] == 'p' ? 2 : 4;
      } else if (strcmp(a, "--weights")) {
        o->have_light = 1;
      }
    } else if (!strcmp(a, "--view-budget") && v) {
      if (cli_parse_double(argv[++i], &o->view_budget) || !(o->view_budget > 0) || o->view_budget > 1)
        return cli_fail("bake", 2, "--view-budget: expected a relative error in (0, 1], got '%s'", v);
    } else if (!strcmp(a, "--tail") && v) {
      if (!strcmp(v, "on")) o->tail = 1;
      else if (!strcmp(v, "off")) o->tail = 0;
      else return cli_fail("bake", 2, "--tail: expected on or off, got '%s'", v);
      i++;
    } else if (!strcmp(a, "--bounces") && v) {
      o->bounces_s = argv[++i];
    } else if (!strcmp(a, "--spread") && v) {
      if (cli_parse_double(argv[++i], &o->spread) || o->spread < 0 || o->spread > 1)
        return cli_fail("bake", 2, "--spread: expected 0..1, got '%s'", v);
    } else if (!strcmp(a, "--seed") && v) {
      o->seed_s = argv[++i];
    } else if (!strcmp(a, "--budget") && v) {
      o->budget_s = argv[++i];
    } else if (!strcmp(a, "--tess") && v) {
      o->tess_s = argv[++i];
    } else if (!strcmp(a, "--threads") && v) {
      if (cli_parse_int(argv[++i], 1, 1024, &o->threads))
        return cli_fail("bake", 2, "--threads: expected 1..1024, got '%s'", v);
    } else if (a[0] == '-' && a[1]) {
      static const char *const value_opts[] = {
          "-o", "--bands", "--rays", "--view-budget", "--tail", "--bounces", "--spread", "--seed",
          "--budget", "--tess", "--threads", "--units", "--up", "--model-scale", "--rotate",
          "--translate", NULL};
      return cli_value_missing("bake", help, a, value_opts);
    } else if (!o->in) {
      o->in = a;
    } else {
      return cli_fail("bake", 2, "more than one input ('%s' and '%s')", o->in, a);
    }
  }
  return -1;
}

/* The scene config's "lcd" block next to the .prt (<out>.lcd.json,
 * lcd_config.h), so that `cave lcd out.prt` and `cave run --scene out.prt`
 * use the scene's panels; without a block, a sidecar of an earlier bake is
 * removed.  Returns the exit status (message printed). */
static int bake_lcd_block(const char *in, const char *out, uint64_t hash) {
  cv_err err;
  cv_err_clear(&err);
  int written, removed;
  char side[CV_PATH_MAX + 16];
  cv_lcd_sidecar_path(out, side, sizeof side);
  if (cv_lcd_sidecar_write(cli_has_ext(in, ".json") ? in : NULL, out, hash, &written, &removed, &err))
    return cli_fail("bake", 1, "%s", err.msg);
  if (written)
    printf("wrote %s (the scene config's lcd block: cave lcd and cave run use its panels with %s)\n",
           side, out);
  else
    printf("lcd: %s has no lcd block%s: cave lcd and cave run use one default panel on the lcd "
           "triangles (docs/readability.md)\n", strcmp(in, "default") ? in : "the built-in scene",
           removed ? " (removed the earlier bake's lcd block)" : "");
  return 0;
}

/* What one bake holds: the scene config, its mesh, tracer and lighting,
 * the bake parameters and the baked transfer. */
typedef struct bake_job {
  cv_scene_config cfg;
  cv_mesh *m;
  cv_tracer *tr;
  cv_scene_light *sl;
  cv_prt *prt;
  cv_bake_params bp;
  float est_error;
} bake_job;

/* The output before any work: a .prt file, not the input, not a folder.
 * Returns 0 or the exit code. */
static int check_output(const bake_opts *o) {
  if (!o->out[0]) return cli_fail("bake", 2, "-o: expected a file name");
  if (strcmp(o->in, "default") && cli_same_file(o->in, o->out))
    return cli_fail("bake", 2, "-o: %s: is the input; expected a new .prt path", o->out);
  if (!cli_has_ext(o->out, ".prt"))
    return cli_fail("bake", 2, "-o: expected a .prt path, got '%s'", o->out);
  if (cli_check_output("bake", "-o", o->out)) return 1; /* a folder, a missing folder */
  return 0;
}

/* The scene config of the input: the built-in scene, a scene .json or a
 * mesh file.  Returns 0 or the exit code. */
static int load_config(const char *in, cv_scene_config *cfg) {
  cv_err err;
  cv_err_clear(&err);
  if (!strcmp(in, "default")) {
    cv_scene_config_default(cfg);
  } else if (cli_has_ext(in, ".json")) {
    if (cv_scene_config_load(in, cfg, &err)) return cli_fail("bake", 1, "%s", err.msg);
  } else {
    cv_scene_config_default(cfg);
    cfg->mesh_is_cabin = 0;
    snprintf(cfg->mesh_path, sizeof cfg->mesh_path, "%s", in);
    snprintf(cfg->source, sizeof cfg->source, "%s", in);
  }
  return 0;
}

/* --bands, --rays, --bounces, --seed, --budget, --tess into cfg.  Returns 0
 * or the exit code. */
static int apply_sampling_options(const bake_opts *o, cv_scene_config *cfg) {
  if (o->bands_s) {
    if (!strcmp(o->bands_s, "auto")) cfg->bands = 0;
    else if (cli_parse_int(o->bands_s, 2, 8, &cfg->bands))
      return cli_fail("bake", 2, "--bands: expected 2..8 or auto, got '%s'", o->bands_s);
  }
  if (o->rays_s) {
    if (!strcmp(o->rays_s, "auto")) cfg->rays = 0;
    else if (cli_parse_int(o->rays_s, 1, 1 << 24, &cfg->rays))
      return cli_fail("bake", 2, "--rays: expected 1..16777216 or auto, got '%s'", o->rays_s);
  }
  if (o->bounces_s && cli_parse_int(o->bounces_s, 0, 16, &cfg->bounces))
    return cli_fail("bake", 2, "--bounces: expected 0..16, got '%s'", o->bounces_s);
  if (o->seed_s) {
    int s;
    if (cli_parse_int(o->seed_s, 0, 2147483647, &s))
      return cli_fail("bake", 2, "--seed: expected 0..2147483647, got '%s'", o->seed_s);
    cfg->seed = (uint32_t)s;
  }
  if (o->budget_s && (cli_parse_double(o->budget_s, &cfg->error_budget) || cfg->error_budget <= 0 ||
                      cfg->error_budget > 1))
    return cli_fail("bake", 2, "--budget: expected a relative error in (0, 1], got '%s'", o->budget_s);
  if (o->tess_s && cli_parse_int(o->tess_s, 1, 64, &cfg->cabin_tess))
    return cli_fail("bake", 2, "--tess: expected 1..64, got '%s'", o->tess_s);
  return 0;
}

/* The lighting options: the command line's lighting, or the car's pose
 * under the config's; --no-sun; what --view-budget needs.  Returns 0 or the
 * exit code. */
static int apply_light_options(const bake_opts *o, cv_scene_config *cfg) {
  if (o->have_light) {
    cfg->light = o->lspec;
  } else if (o->pose) { /* the car's orientation under the config's lighting */
    if (cfg->light.kind == CV_LIGHT_NONE)
      return cli_fail("bake", 2, "%s needs the lighting: --env, --env-constant or --sky (or the "
                      "config's \"lighting\")", o->pose);
    if (o->pose_given & 1) cfg->light.yaw_deg = o->lspec.yaw_deg;
    if (o->pose_given & 2) cfg->light.pitch_deg = o->lspec.pitch_deg;
    if (o->pose_given & 4) cfg->light.roll_deg = o->lspec.roll_deg;
  }
  if (o->no_sun) {
    if (cfg->light.kind != CV_LIGHT_ENV)
      /* only a map's sun can stay in the SH: the sky's is always a separate light */
      return cli_fail("bake", 2, "--no-sun: applies to env maps (--env, or the config's \"env\" "
                      "lighting)%s", cfg->light.kind == CV_LIGHT_NONE ? "; no lighting is given"
                      : cfg->light.kind == CV_LIGHT_SKY ? ", not to --sky: its sun is always split out"
                      : ", not to --env-constant: it has no sun");
    cfg->light.extract_sun = 0;
  }
  if (o->view_budget > 0 && cfg->light.kind == CV_LIGHT_NONE)
    return cli_fail("bake", 2, "--view-budget: needs the lighting (--env, --env-constant or --sky, "
                    "or the config's lighting)");
  return 0;
}

/* Every option into the job's config: the mesh checks, sampling, placement,
 * threads and the lighting.  Returns 0 or the exit code. */
static int apply_options(const bake_opts *o, bake_job *J) {
  cv_scene_config *cfg = &J->cfg;
  if (!cfg->mesh_is_cabin && cli_same_file(cfg->mesh_path, o->out))
    return cli_fail("bake", 2, "-o: %s: is the scene's mesh; expected a new .prt path", o->out);
  if (o->tess_s && !cfg->mesh_is_cabin)
    return cli_fail("bake", 2, "--tess: applies to the built-in cabin, not to a mesh file (%s)",
                    cfg->mesh_path);
  int rc = apply_sampling_options(o, cfg);
  if (!rc) rc = cli_place_apply("bake", &o->place, cfg);
  if (rc) return rc;
  if (o->threads > 0) omp_set_num_threads(o->threads);
  if (o->spread >= 0) cfg->spread = o->spread;
  if (o->cosine_only >= 0) cfg->window_sampling = !o->cosine_only;
  if (o->tail >= 0) cfg->tail = o->tail;
  return apply_light_options(o, cfg);
}

/* The job's tracer (built once), with the bake's spread and sampling.
 * Returns 0 or the exit code. */
static int job_tracer(bake_job *J) {
  cv_err err;
  if (!J->tr && cv_tracer_create(J->m, &J->tr, &err)) return cli_fail("bake", 1, "%s", err.msg);
  cv_tracer_set_spread(J->tr, J->bp.spread);
  cv_tracer_set_window_sampling(J->tr, !J->bp.cosine_only);
  return 0;
}

/* --view-budget: bands and split picked in the driver's view
 * (prt/auto_view.h), printed.  Returns 0 or the exit code. */
static int pick_in_view(const bake_opts *o, bake_job *J) {
  cv_err err;
  int rc = job_tracer(J);
  if (rc) return rc;
  cv_view_cam cam;
  cv_view_cam_driver(&cam);
  cv_view_auto va;
  if (cv_auto_view_select(J->tr, J->sl, &cam, o->view_budget, 1024, J->cfg.seed,
                          o->bands_s ? J->cfg.bands : 0, -1, &va, &err))
    return cli_fail("bake", 1, "%s", err.msg);
  printf("view auto: driver's view %dx%d (%d pixels on geometry, %d pilot vertices), %.2f s; "
         "per-pixel error of the direct light against its all-frequency estimate:\n",
         cam.w, cam.h, va.pixels, va.pilot_vertices, va.seconds);
  for (int k = 0; k < va.n_cand; k++)
    printf("  %d bands, split %2d: median %.1f%%, p90 %.1f%%, mean ratio %.3f\n", va.cand[k].bands,
           va.cand[k].split, 100 * va.cand[k].median, 100 * va.cand[k].p90, va.cand[k].mean_ratio);
  printf("view auto: picked %d bands with --split %d: median %.1f%%, p90 %.1f%%, mean ratio %.3f "
         "(budget: median %.1f%%, p90 %.1f%%)%s\n", va.bands, va.split, 100 * va.median,
         100 * va.p90, va.mean_ratio, 100 * o->view_budget, 300 * o->view_budget,
         va.met_budget ? "" : " -- budget NOT met, the lowest median used");
  if (va.split > 0)
    printf("view auto: relight with `cave shade --split %d` / `cave render --split %d` for this "
           "error\n", va.split, va.split);
  J->bp.bands = va.bands;
  if (J->cfg.rays == 0) J->bp.rays = 1024;
  return 0;
}

/* --bands auto / --rays auto: picked by the per-vertex error budget
 * (prt/auto.h), printed.  Returns 0 or the exit code. */
static int pick_auto(bake_job *J) {
  int rc = job_tracer(J);
  if (rc) return rc;
  cv_lighting lt, *lp = NULL;
  if (J->sl) {
    lt = cv_scene_light_sh(J->sl);
    lp = &lt;
  }
  cv_auto_result ar;
  if (cv_prt_auto_select(J->tr, lp, J->cfg.error_budget, J->cfg.seed, J->cfg.bands, J->cfg.rays, &ar))
    return cli_fail("bake", 1, "auto: the scene has no surface to sample");
  printf("auto: %d pilot vertices, %d candidates in %.2f s under %s\n", ar.pilot_vertices,
         ar.n_cand, ar.seconds, lp ? "the scene's lighting (sun split out)" : "a CIE overcast sky");
  printf("auto: picked %d bands, %d rays: estimated error %.2f%% (budget %.2f%%)%s\n", ar.bands,
         ar.rays, 100 * ar.est_error, 100 * J->cfg.error_budget,
         ar.met_budget ? "" : " -- budget NOT met, most accurate candidate used");
  J->bp.bands = ar.bands;
  J->bp.rays = ar.rays;
  J->est_error = (float)ar.est_error;
  return 0;
}

/* The bake itself with its progress lines, then the .prt written.
 * Returns 0 or the exit code. */
static int bake_and_write(const bake_opts *o, bake_job *J) {
  cv_err err;
  const cv_bake_params *bp = &J->bp;
  int rc = job_tracer(J);
  if (rc) return rc;
  printf("bake: %zu vertices, %d bands, %d rays, %d bounces%s, spread %g, seed %u, %s, %d threads\n",
         J->m->nv, bp->bands, bp->rays, bp->bounces, bp->tail && bp->bounces ? " + tail" : "",
         (double)bp->spread, bp->seed,
         cv_tracer_window_sampling(J->tr) ? "window importance sampling" : "cosine sampling",
         omp_get_max_threads());
  fflush(stdout);
  cv_bake_stats bs;
  if (cv_prt_bake_tracer(J->tr, bp, &J->prt, &bs, &err)) return cli_fail("bake", 1, "%s", err.msg);
  J->prt->meta.est_error = J->est_error;
  for (int b = 0; b <= bp->bounces; b++)
    printf("  pass %d (%s): %.2f s, %.2f Mrays/s\n", b, b ? "bounce" : "direct", bs.seconds[b],
           bs.seconds[b] > 0 ? bs.rays[b] / bs.seconds[b] / 1e6 : 0.0);
  if (bp->tail && bp->bounces > 0)
    printf("  tail: bounce ratio %.4f %.4f %.4f (RGB), last bounce x r/(1-r) added%s\n",
           bs.tail_ratio[0], bs.tail_ratio[1], bs.tail_ratio[2],
           bs.tail_clamped ? " (a ratio was clamped to 0..0.9)" : "");
  printf("bake: %.2f s, %llu rays, %.2f Mrays/s; %llu vertices only on window openings (no transfer)\n",
         bs.total_seconds, (unsigned long long)bs.total_rays,
         bs.total_seconds > 0 ? bs.total_rays / bs.total_seconds / 1e6 : 0.0,
         (unsigned long long)bs.empty_fans);
  if (cv_prt_write(o->out, J->prt, &err)) return cli_fail("bake", 1, "%s", err.msg);
  printf("wrote %s (input hash %016llx)\n", o->out, (unsigned long long)J->prt->meta.input_hash);
  return bake_lcd_block(o->in, o->out, J->prt->meta.input_hash);
}

/* Loads the mesh and the lighting, picks what auto asks for, then bakes
 * unless the .prt is up to date.  Returns 0 or the exit code. */
static int run_bake(const bake_opts *o, bake_job *J) {
  cv_err err;
  cv_scene_config *cfg = &J->cfg;
  if (cv_scene_mesh_load(cfg, stdout, &J->m, &err)) return cli_fail("bake", 1, "%s", err.msg);
  J->bp = (cv_bake_params){.bands = cfg->bands, .rays = cfg->rays, .bounces = cfg->bounces,
                           .seed = cfg->seed, .spread = (float)cfg->spread,
                           .cosine_only = !cfg->window_sampling, .tail = cfg->tail, .quiet = o->quiet};
  J->est_error = -1.0f;
  if (cfg->light.kind != CV_LIGHT_NONE) {
    /* The scene's lighting (8 bands: the auto modes need them): reported
     * here (sun found or not, its energy) and used by auto to judge SH
     * truncation. */
    if (cv_scene_light_build(&cfg->light, 8, &J->sl, &err)) return cli_fail("bake", 1, "%s", err.msg);
    cv_scene_light_print(stdout, J->sl);
  }
  int rc = 0;
  if (o->view_budget > 0)
    rc = pick_in_view(o, J);
  else if (cfg->bands == 0 || cfg->rays == 0)
    rc = pick_auto(J); /* the tracer is needed for it anyway: built first */
  if (rc) return rc;
  uint64_t want = cv_prt_input_hash(J->m, &J->bp), have;
  if (!o->force && cv_prt_read_input_hash(o->out, &have, NULL) == CV_OK && have == want) {
    printf("%s is up to date (input hash %016llx); use --force to bake again\n", o->out,
           (unsigned long long)want);
    return bake_lcd_block(o->in, o->out, want);
  }
  return bake_and_write(o, J);
}

int cmd_bake(int argc, char **argv) {
  bake_opts o;
  const int parsed = parse_opts(argc, argv, &o);
  if (parsed >= 0) return parsed;
  if (!o.in || !o.out) {
    cli_print_usage(help);
    return cli_fail("bake", 2, "an input and -o FILE.prt are required");
  }
  int rc = check_output(&o);
  if (rc) return rc;
  /* The lighting modifiers that only act on the command line's --env maps. */
  if (o.env_only && o.lspec.kind != CV_LIGHT_ENV) return cli_fail("bake", 2, "%s needs --env", o.env_only);
  if (o.weights && (rc = cli_apply_weights("bake", &o.lspec, o.weights)) != 0) return rc;
  bake_job J = {0};
  if ((rc = load_config(o.in, &J.cfg)) != 0) return rc;
  rc = apply_options(&o, &J);
  if (!rc) rc = run_bake(&o, &J);
  cv_prt_destroy(J.prt);
  cv_tracer_destroy(J.tr);
  cv_scene_light_destroy(J.sl);
  cv_mesh_destroy(J.m);
  cv_scene_config_free(&J.cfg);
  return rc;
}
