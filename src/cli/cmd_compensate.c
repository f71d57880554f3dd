/* `cave compensate`: compensation of the light that concave screens scatter
 * onto each other (Bimber et al. 2006).  Images are down-sampled to the
 * display's patches, the wanted radiosity is what each image would show
 * without scattering (T = F M R + E M), a solver finds the projector input I
 * whose displayed radiosity B = D + K B matches T, and the correction is
 * applied at full resolution by the paper's equation 7. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli/cli.h"
#include "compensate/display.h"
#include "compensate/formfactor.h"
#include "compensate/resample.h"
#include "compensate/seam.h"
#include "compensate/solve.h"
#include "core/progress.h"
#include "io/exr.h"
#include "view/cave.h"

#include <cjson/cJSON.h>

#define MAX_IMAGES 64

/* A CAVE config (top-level "walls") rather than a display description
 * ("surfaces"): decided by the keys, so that each loader reports its own
 * problems; anything unreadable goes to the display loader, which says why. */
static int is_cave_config(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) return 0;
  char *text = NULL;
  long n = -1;
  if (!fseek(f, 0, SEEK_END) && (n = ftell(f)) >= 0 && n < (64L << 20) && !fseek(f, 0, SEEK_SET) &&
      (text = malloc((size_t)n + 1)) && fread(text, 1, (size_t)n, f) == (size_t)n)
    text[n] = 0;
  else
    n = -1;
  fclose(f);
  int cave = 0;
  if (n >= 0) {
    cJSON *root = cJSON_Parse(text);
    cave = cJSON_IsObject(root) && cJSON_GetObjectItemCaseSensitive(root, "walls") &&
           !cJSON_GetObjectItemCaseSensitive(root, "surfaces");
    cJSON_Delete(root);
  }
  free(text);
  return cave;
}

/* 1 when the dense form-factor build of n patches would take more than half
 * the physical memory: about 20 bytes per ordered pair at its peak (the
 * upper-triangle lists, the CSR copy and the final matrix). */
static int dense_too_big(size_t n) {
  const long pages = sysconf(_SC_PHYS_PAGES), psize = sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || psize <= 0) return 0;
  return 20.0 * (double)n * (double)n > 0.5 * (double)pages * (double)psize;
}

static void help(FILE *f) {
  fprintf(f,
          "usage: cave compensate --display FILE.json --image R.exr [--image ...]\n"
          "                       [--right R.exr ...] [--solver auto|jacobi|exact|bounded]\n"
          "                       [--levels H] [--time-ms T] [--threshold T] [--drop F]\n"
          "                       [--storage auto|float|half|low-rank|direct] -o I.exr [--report]\n"
          "                       [--seam-budget E|off] [--quiet]\n\n"
          "Computes projector images that cancel the light the screens scatter onto each\n"
          "other, so that every surface shows what its image shows without scattering.\n\n"
          "  --display FILE    display description (configs/displays/*.json), or a CAVE config\n"
          "                    (configs/caves/*.json: its walls and \"screens\")\n"
          "  --image R.exr     one image per surface in surface order, or one atlas with\n"
          "                    the surfaces side by side at equal widths\n"
          "  --right R.exr     the right eye's images (stereo): one solve on (L + R) / 2,\n"
          "                    its correction applied to both eyes\n"
          "  --solver S        auto (exact unless it clips, else bounded; default), exact\n"
          "                    (D = (I - K) R, clipped naively), jacobi (the paper's\n"
          "                    iteration; refused when the spectral radius of K >= 0.5),\n"
          "                    bounded (least displayed error with the projector in [0, 1])\n"
          "  --levels H        jacobi scatter levels (default 2)\n"
          "  --time-ms T       time slot for the iterative solvers (default: none)\n"
          "  --threshold T     jacobi exit: no patch changes by more than T (default 1/255)\n"
          "  --storage S       how K is kept for the products: low-rank (dense near-field and\n"
          "                    low-rank far-field blocks of 8x8-patch tiles, each row within\n"
          "                    1e-3 of its sum), half (half precision, good to about 1e-4),\n"
          "                    float, direct (the low-rank form built from the display\n"
          "                    without the dense form factors: clusters up to whole wall\n"
          "                    quadrants, rows within an estimated 1e-3 of their sum; for\n"
          "                    displays whose dense build does not fit in memory), or auto\n"
          "                    (default: direct when the dense build would take more than\n"
          "                    half the physical memory, else low-rank where it takes at\n"
          "                    most half the bytes, else float); --half = --storage half\n"
          "  --seam-budget E   RMS error of the up-sampled correction allowed within 0.5 m\n"
          "                    of a seam, as estimated from the patch solution (default\n"
          "                    0.01, about the Weber threshold); above it the patches are\n"
          "                    graded towards the seams (up to 3 rounds) and solved again;\n"
          "                    'off' keeps the display's patches\n"
          "  --drop F          form-factor sparsification: share of each row's energy that\n"
          "                    may be dropped (default 1e-3)\n"
          "  -o I.exr          output: atlas in, atlas out; otherwise I_<surface>.exr per\n"
          "                    surface (stereo: _left / _right)\n"
          "  --report          displayed error, luminance compensated overall and within\n"
          "                    0.5 m of a seam, clipping, iterations, spectral radius, time\n"
          "\nexamples:\n"
          "  cave compensate --display configs/caves/cave5.json --image atlas.exr -o I.exr --report\n"
          "  cave compensate --display configs/displays/dome.json --image R.exr -o I.exr\n");
}

/* Input images are display values in [0, 1]: say how many lie outside (an
 * HDR render, not yet tone-mapped?) instead of only reporting a large error. */
static void warn_range(const char *path, const cv_image *im) {
  size_t n = (size_t)im->w * im->h * im->c, out = 0;
  double lo = 0, hi = 1;
  for (size_t i = 0; i < n; i++) {
    double v = im->px[i];
    if (v >= 0 && v <= 1) continue;
    out++;
    if (v < lo) lo = v;
    if (v > hi) hi = v;
  }
  if (out)
    fprintf(stderr,
            "warning: %s: %zu of %zu values outside [0, 1] (min %.4g, max %.4g); the displays "
            "cannot show them (tone-map HDR images first: cave tonemap)\n",
            path, out, n, lo, hi);
}

/* Output path: base without ".exr" + suffix + ".exr". */
static void out_path(const char *o, const char *suffix, char *buf, size_t n) {
  size_t l = strlen(o);
  if (l >= 4 && cli_has_ext(o, ".exr")) l -= 4;
  snprintf(buf, n, "%.*s%s.exr", (int)l, o, suffix);
}

static double lum(const double *c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

typedef struct {
  double rms, max, lum_all, lum_seam;
} display_stats;

/* Displayed radiosity for input I and its error against T. */
static int judge(const cv_scatter_system *s, const float *I, const double *T, double *B,
                 display_stats *st) {
  int iters;
  if (cv_scatter_physics(s, I, B, 1e-9, &iters)) return -1;
  double e2 = 0, mx = 0;
  for (size_t k = 0; k < 3 * s->n; k++) {
    double d = fabs(B[k] - T[k]);
    e2 += d * d;
    mx = d > mx ? d : mx;
  }
  st->rms = sqrt(e2 / (3.0 * s->n));
  st->max = mx;
  return 0;
}

int cmd_compensate(int argc, char **argv) {
  const char *display_path = NULL, *out = NULL;
  const char *img_path[MAX_IMAGES], *right_path[MAX_IMAGES];
  int n_img = 0, n_right = 0, report = 0, quiet = 0, half = 0, compress = 1;
  cv_scatter_opts opts;
  cv_scatter_opts_default(&opts);
  double drop = -1, seam_budget = 0.01;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    } else if (!strcmp(a, "--report")) {
      report = 1;
    } else if (!strcmp(a, "--quiet")) {
      quiet = 1;
    } else if (!strcmp(a, "--half")) {
      half = 1;
    } else if (!strcmp(a, "--seam-budget") && v) {
      i++;
      if (!strcmp(v, "off")) seam_budget = 0;
      else if (cli_parse_double(v, &seam_budget) || !(seam_budget > 0 && seam_budget < 1))
        return cli_fail("compensate", 2, "--seam-budget: expected 0 < E < 1 or off, got '%s'", v);
    } else if (!strcmp(a, "--storage") && v) {
      i++;
      if (!strcmp(v, "auto")) half = 0, compress = 1;
      else if (!strcmp(v, "float")) half = 0, compress = 0;
      else if (!strcmp(v, "half")) half = 1, compress = 0;
      else if (!strcmp(v, "low-rank")) half = 0, compress = 2;
      else if (!strcmp(v, "direct")) half = 0, compress = 3;
      else return cli_fail("compensate", 2, "--storage: expected auto, float, half, low-rank or direct, got '%s'", v);
    } else if (!v) {
      cli_print_usage(help);
      return cli_fail("compensate", 2, "unknown or incomplete option '%s'", a);
    } else if (!strcmp(a, "--display")) {
      display_path = argv[++i];
    } else if (!strcmp(a, "-o")) {
      out = argv[++i];
    } else if (!strcmp(a, "--image") || !strcmp(a, "--right")) {
      int *n = a[2] == 'i' ? &n_img : &n_right;
      const char **list = a[2] == 'i' ? img_path : right_path;
      if (*n == MAX_IMAGES) return cli_fail("compensate", 2, "%s: at most %d images", a, MAX_IMAGES);
      list[(*n)++] = argv[++i];
    } else if (!strcmp(a, "--solver")) {
      const char *s = argv[++i];
      if (!strcmp(s, "auto")) opts.solver = CV_SCATTER_AUTO;
      else if (!strcmp(s, "exact")) opts.solver = CV_SCATTER_EXACT;
      else if (!strcmp(s, "jacobi")) opts.solver = CV_SCATTER_JACOBI;
      else if (!strcmp(s, "bounded")) opts.solver = CV_SCATTER_BOUNDED;
      else return cli_fail("compensate", 2, "--solver: expected auto, exact, jacobi or bounded, got '%s'", s);
    } else if (!strcmp(a, "--levels")) {
      if (cli_parse_int(argv[++i], 1, 64, &opts.levels))
        return cli_fail("compensate", 2, "--levels: expected 1..64, got '%s'", v);
    } else if (!strcmp(a, "--time-ms")) {
      if (cli_parse_double(argv[++i], &opts.time_ms) || opts.time_ms <= 0)
        return cli_fail("compensate", 2, "--time-ms: expected a positive number, got '%s'", v);
    } else if (!strcmp(a, "--threshold")) {
      if (cli_parse_double(argv[++i], &opts.threshold) || opts.threshold <= 0)
        return cli_fail("compensate", 2, "--threshold: expected a positive number, got '%s'", v);
    } else if (!strcmp(a, "--drop")) {
      if (cli_parse_double(argv[++i], &drop) || drop < 0 || drop >= 1)
        return cli_fail("compensate", 2, "--drop: expected 0 <= F < 1, got '%s'", v);
    } else {
      cli_print_usage(help);
      return cli_fail("compensate", 2, "unknown option '%s'", a);
    }
  }
  if (!display_path || !out || n_img == 0) {
    cli_print_usage(help);
    return cli_fail("compensate", 2, "--display, at least one --image and -o are required");
  }
  if (n_right && n_right != n_img)
    return cli_fail("compensate", 2, "--right: %d images for %d --image", n_right, n_img);
  if (!cli_has_ext(out, ".exr")) return cli_fail("compensate", 2, "-o: expected an .exr path, got '%s'", out);
  if (cli_check_output("compensate", "-o", out)) return 1; /* before minutes of work */

  int rc = 1;
  cv_err err;
  cv_err_clear(&err);
  cv_display *d = NULL;
  cv_ffmatrix *F = NULL;
  cv_hmatrix *H = NULL;
  cv_scatter_workspace *ws = NULL;
  cv_image *imgs[2][MAX_IMAGES] = {{0}};
  double *R[2] = {NULL, NULL}, *T = NULL, *B = NULL, *delta = NULL;
  float *I = NULL, *I0 = NULL, *Tf[2] = {NULL, NULL};
  if (is_cave_config(display_path)) {
    /* a CAVE config: the display it describes (its walls and "screens") */
    cv_cave cave;
    if (cv_cave_load(display_path, &cave, &err)) {
      rc = cli_fail("compensate", 1, "%s", err.msg);
      goto done;
    }
    if (cv_display_from_cave(&cave, 0, -1, &d, &err)) {
      rc = cli_fail("compensate", 1, "%s: %s", display_path, err.msg);
      goto done;
    }
  } else if (cv_display_load(display_path, &d, &err)) {
    char buf[8192];
    int np = 0;
    cv_display_validate_all(display_path, buf, sizeof buf, &np);
    if (np > 1) fputs(buf, stderr);
    rc = cli_fail("compensate", 1, "%s", err.msg);
    goto done;
  }
  const size_t ns = cv_display_surface_count(d), n = cv_display_patch_count(d);
  const int atlas = n_img == 1 && ns > 1;
  if (!atlas && (size_t)n_img != ns) {
    rc = cli_fail("compensate", 2, "%s has %zu surfaces: give one --image per surface or one atlas, not %d",
                  display_path, ns, n_img);
    goto done;
  }
  const int eyes = n_right ? 2 : 1;
  for (int e = 0; e < eyes; e++)
    for (int k = 0; k < n_img; k++)
      if (cv_exr_read(e ? right_path[k] : img_path[k], &imgs[e][k], &err)) {
        rc = cli_fail("compensate", 1, "%s", err.msg);
        goto done;
      }
  for (int e = 0; e < eyes; e++)
    for (int k = 0; k < n_img; k++) warn_range(e ? right_path[k] : img_path[k], imgs[e][k]);
  /* Per surface views into the inputs (atlas: equal-width columns). */
  int w0 = imgs[0][0]->w, h0 = imgs[0][0]->h;
  if (atlas && w0 % (int)ns) {
    rc = cli_fail("compensate", 1, "%s: atlas width %d is not a multiple of %zu surfaces",
                  img_path[0], w0, ns);
    goto done;
  }
  /* Seam refinement rounds: patches graded ever more strongly towards the
   * seams while the estimated seam error exceeds the budget. */
  static const double grading[] = {3, 8, 20};
  int refine_round = 0;
  cv_seam_estimate seam_est;
  memset(&seam_est, 0, sizeof seam_est);
refine_again:
  for (int e = 0; e < eyes; e++) {
    R[e] = calloc(3 * n, sizeof(double));
    if (!R[e]) goto nomem;
    for (size_t k = 0; k < ns; k++) {
      const cv_display_surface *S = cv_display_surface_at(d, k);
      cv_image *src = imgs[e][atlas ? 0 : k], *part = src;
      if (atlas) { /* copy the column: the image type has no stride */
        int cw = w0 / (int)ns;
        if (cv_image_create(cw, h0, 3, &part)) goto nomem;
        for (int y = 0; y < h0; y++)
          memcpy(cv_image_at(part, 0, y), cv_image_at(src, (int)k * cw, y), 3 * cw * sizeof(float));
      }
      if (cv_downsample_to_patches(part, S->nu, S->nv, S->edge_u, S->edge_v, R[e] + 3 * S->offset)) goto nomem;
      if (atlas) cv_image_destroy(part);
    }
  }
  /* Form factors and the system. */
  cv_ff_params fp;
  cv_ff_params_default(&fp);
  fp.quiet = quiet;
  if (drop >= 0) fp.drop_budget = drop;
  cv_ff_report frep;
  memset(&frep, 0, sizeof frep);
  const int direct = compress == 3 || (compress == 1 && !half && dense_too_big(n));
  cv_scatter_system sys;
  if (direct) {
    cv_hmatrix_direct_params hp;
    cv_hmatrix_direct_params_default(&hp);
    hp.quiet = quiet;
    const double t_ff = cv_now_seconds();
    if (cv_hmatrix_build_direct(d, &fp, &hp, &H, NULL, &err)) {
      rc = cli_fail("compensate", 1, "%s", err.msg);
      goto done;
    }
    frep.seconds = cv_now_seconds() - t_ff;
    cv_display_scatter_system(d, NULL, &sys);
    sys.H = H;
  } else {
    if (cv_formfactors_build(d, &fp, &F, &frep, &err)) {
      rc = cli_fail("compensate", 1, "%s", err.msg);
      goto done;
    }
    cv_display_scatter_system(d, F, &sys);
  }
  if (cv_scatter_workspace_create_ex(&sys, (half ? CV_SCATTER_WS_HALF : 0) | (compress ? CV_SCATTER_WS_COMPRESS : 0), &ws, &err)) {
    rc = cli_fail("compensate", 1, "%s", err.msg);
    goto done;
  }
  cv_scatter_model model;
  cv_scatter_workspace_get_model(ws, &model);
  if (compress == 2 && strcmp(model.storage, "block low-rank"))
    fprintf(stderr, "cave compensate: --storage low-rank: the compressed form (%.1f MB) does not pay "
            "against %.1f MB plain; using %s\n", model.compressed_bytes / 1e6, model.source_bytes / 1e6,
            model.storage);
  /* Wanted radiosity: what the images show without scattering. */
  for (int e = 0; e < eyes; e++) {
    Tf[e] = malloc(3 * n * sizeof(float));
    if (!Tf[e]) goto nomem;
    for (size_t i = 0; i < n; i++)
      for (int c = 0; c < 3; c++)
        Tf[e][3 * i + c] = (float)(sys.proj[i] * sys.refl[3 * i + c] * R[e][3 * i + c] +
                                   sys.env[3 * i + c] * sys.refl[3 * i + c]);
  }
  I = malloc(3 * n * sizeof(float));
  I0 = malloc(3 * n * sizeof(float));
  T = malloc(3 * n * sizeof(double));
  B = malloc(3 * n * sizeof(double));
  delta = malloc(3 * n * sizeof(double));
  if (!I || !I0 || !T || !B || !delta) goto nomem;
  cv_scatter_stats st;
  int srt = eyes == 2 ? cv_scatter_solve_stereo(ws, Tf[0], Tf[1], &opts, I, &st, &err)
                      : cv_scatter_solve(ws, Tf[0], &opts, I, &st, &err);
  if (srt) {
    rc = cli_fail("compensate", 1, "%s", err.msg);
    goto done;
  }
  /* The (averaged) input and target at patch resolution. */
  for (size_t k = 0; k < 3 * n; k++) {
    double r = eyes == 2 ? 0.5 * (R[0][k] + R[1][k]) : R[0][k];
    I0[k] = (float)r;
    T[k] = eyes == 2 ? 0.5 * ((double)Tf[0][k] + Tf[1][k]) : Tf[0][k];
    delta[k] = r - I[k];
  }
  if (seam_budget > 0 && ns > 1) {
    if (cv_seam_estimate_error(d, delta, 0.5, &seam_est)) goto nomem;
    if (!quiet)
      printf("seam error estimate of the up-sampled correction within 0.5 m of a seam: RMS %.4f, "
             "max %.4f (budget %.4f RMS)%s\n", seam_est.seam_rms, seam_est.seam_max, seam_budget,
             refine_round ? " after grading" : "");
    int nr = 0;
    if (seam_est.seam_rms > seam_budget && refine_round < 3) {
      if (cv_display_refine_seams(d, grading[refine_round], 0.15, &nr)) goto nomem;
      if (nr) {
        if (!quiet)
          printf("  over budget: patches graded towards the seams (strength %g, width 0.15), "
                 "solving again\n", grading[refine_round]);
        refine_round++;
        for (int e = 0; e < 2; e++) {
          free(R[e]);
          free(Tf[e]);
          R[e] = NULL;
          Tf[e] = NULL;
        }
        free(I);
        free(I0);
        free(T);
        free(B);
        free(delta);
        I = I0 = NULL;
        T = B = delta = NULL;
        cv_scatter_workspace_destroy(ws);
        ws = NULL;
        cv_ffmatrix_destroy(F);
        F = NULL;
        cv_hmatrix_destroy(H);
        H = NULL;
        goto refine_again;
      }
    }
  }
  /* Full resolution: equation 7 per surface and eye. */
  uint64_t clamped = 0;
  for (int e = 0; e < eyes; e++) {
    cv_image *res = NULL;
    if (atlas && cv_image_create(w0, h0, 3, &res)) goto nomem;
    for (size_t k = 0; k < ns; k++) {
      const cv_display_surface *S = cv_display_surface_at(d, k);
      cv_image *src = imgs[e][atlas ? 0 : k], *part = src, *o;
      int cw = atlas ? w0 / (int)ns : src->w;
      if (atlas) {
        if (cv_image_create(cw, h0, 3, &part)) goto nomem;
        for (int y = 0; y < h0; y++)
          memcpy(cv_image_at(part, 0, y), cv_image_at(src, (int)k * cw, y), 3 * cw * sizeof(float));
      }
      if (cv_image_create(part->w, part->h, 3, &o)) goto nomem;
      clamped += cv_apply_patch_delta(part, delta + 3 * S->offset, S->nu, S->nv, S->edge_u,
                                      S->edge_v, o);
      if (atlas) {
        for (int y = 0; y < h0; y++)
          memcpy(cv_image_at(res, (int)k * cw, y), cv_image_at(o, 0, y), 3 * cw * sizeof(float));
        cv_image_destroy(part);
      } else {
        char path[1200], suffix[100];
        snprintf(suffix, sizeof suffix, "%s%s%s", ns > 1 ? "_" : "", ns > 1 ? S->name : "",
                 eyes == 2 ? (e ? "_right" : "_left") : "");
        out_path(out, suffix, path, sizeof path);
        if (cv_exr_write(path, o, 1, CV_EXR_ZIP, &err)) {
          cv_image_destroy(o);
          rc = cli_fail("compensate", 1, "%s", err.msg);
          goto done;
        }
        if (!quiet) printf("wrote %s\n", path);
      }
      cv_image_destroy(o);
    }
    if (atlas) {
      char path[1200];
      out_path(out, eyes == 2 ? (e ? "_right" : "_left") : "", path, sizeof path);
      int wst = cv_exr_write(path, res, 1, CV_EXR_ZIP, &err);
      cv_image_destroy(res);
      if (wst) {
        rc = cli_fail("compensate", 1, "%s", err.msg);
        goto done;
      }
      if (!quiet) printf("wrote %s\n", path);
    }
  }
  if (!quiet && direct)
    printf("compensate: %zu patches, form factors built compressed (%.1f MB, %.1f s), solver %s, "
           "%d iterations, %.2f ms; %llu pixel channels clamped by equation 7\n",
           n, model.bytes / 1e6, frep.seconds, cv_scatter_solver_name(st.solver), st.iterations,
           st.ms, (unsigned long long)clamped);
  else if (!quiet)
    printf("compensate: %zu patches, %zu form factors (%.2f%% of the energy dropped), solver %s, "
           "%d iterations, %.2f ms; %llu pixel channels clamped by equation 7\n",
           n, frep.nnz, 100 * frep.dropped_total, cv_scatter_solver_name(st.solver), st.iterations,
           st.ms, (unsigned long long)clamped);
  if (report) {
    display_stats un, co;
    double *Bu = malloc(3 * n * sizeof(double));
    if (!Bu || judge(&sys, I0, T, Bu, &un) || judge(&sys, I, T, B, &co)) {
      free(Bu);
      rc = cli_fail("compensate", 1, "the display physics did not converge");
      goto done;
    }
    /* Luminance compensated = (uncompensated - compensated) / uncompensated,
     * area-weighted, over all patches and over those within 0.5 m of
     * another surface (the seams). */
    double all_u = 0, all_c = 0, seam_u = 0, seam_c = 0, peak = 0;
    size_t seam_n = 0;
    for (size_t i = 0; i < n; i++) {
      const cv_patch *p = cv_display_patch(d, i);
      double a = p->area, yu = a * lum(Bu + 3 * i), yc = a * lum(B + 3 * i);
      all_u += yu;
      all_c += yc;
      if (yu > 0 && (yu - yc) / yu > peak) peak = (yu - yc) / yu;
      int near = 0;
      for (size_t j = 0; j < n && !near; j++) {
        const cv_patch *q = cv_display_patch(d, j);
        if (q->surface == p->surface) continue;
        double dx = p->c[0] - q->c[0], dy = p->c[1] - q->c[1], dz = p->c[2] - q->c[2];
        near = dx * dx + dy * dy + dz * dz < 0.25;
      }
      if (near) {
        seam_u += yu;
        seam_c += yc;
        seam_n++;
      }
    }
    free(Bu);
    printf("report (radiosity units; wanted = what the images show without scattering):\n");
    printf("  %-14s displayed RMS error %.5f, max %.5f\n", "uncompensated", un.rms, un.max);
    printf("  %-14s displayed RMS error %.5f, max %.5f\n", "compensated", co.rms, co.max);
    if (seam_n)
      printf("  luminance compensated: %.2f%% overall, %.2f%% within 0.5 m of a seam (%zu patches), "
             "%.2f%% on the most compensated patch\n",
             all_u > 0 ? 100 * (all_u - all_c) / all_u : 0.0,
             seam_u > 0 ? 100 * (seam_u - seam_c) / seam_u : 0.0, seam_n, 100 * peak);
    else
      printf("  luminance compensated: %.2f%% overall (no seams: a single surface)\n",
             all_u > 0 ? 100 * (all_u - all_c) / all_u : 0.0);
    printf("  solver %s%s, %d iterations, %zu clipped patches (%zu channels), spectral radius %.4f, "
           "%.2f ms\n",
           cv_scatter_solver_name(st.solver), st.stereo ? " (stereo average)" : "", st.iterations,
           st.clipped_patches, st.clipped_channels, st.rho, st.ms);
    if (seam_budget > 0 && ns > 1)
      printf("  seam refinement: %s (estimated seam RMS %.4f, budget %.4f)\n",
             refine_round ? "graded towards the seams" : "not needed", seam_est.seam_rms, seam_budget);
    printf("  storage of K: %s, %.2f MB read per product (plain %.2f MB), product error <= %.2e x max|x|\n",
           model.storage, model.bytes / 1e6, model.source_bytes / 1e6, model.error_bound);
    if (direct)
      printf("  form factors: built compressed from the display (no dense matrix), %.2f s; "
             "row error estimated <= %.2e of the row\n",
             frep.seconds, model.compress_info.max_rel_row_error);
    else
      printf("  form factors: %zu of %zu kept, %.3f%% of the energy dropped (worst row %.3f%%), %.2f s\n",
             frep.nnz, frep.nnz_full, 100 * frep.dropped_total, 100 * frep.dropped_max, frep.seconds);
  }
  rc = 0;
  goto done;
nomem:
  rc = cli_fail("compensate", 1, "out of memory");
done:
  for (int e = 0; e < 2; e++) {
    for (int k = 0; k < MAX_IMAGES; k++) cv_image_destroy(imgs[e][k]);
    free(R[e]);
    free(Tf[e]);
  }
  free(I);
  free(I0);
  free(T);
  free(B);
  free(delta);
  cv_scatter_workspace_destroy(ws);
  cv_ffmatrix_destroy(F);
  cv_hmatrix_destroy(H);
  cv_display_destroy(d);
  return rc;
}
