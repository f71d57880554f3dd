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
#include <sys/stat.h>
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
  double rms, max;
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

/* What the command line asks for. */
typedef struct {
  const char *display_path, *out;
  const char *img_path[MAX_IMAGES], *right_path[MAX_IMAGES];
  int n_img, n_right, report, quiet, half;
  int compress; /* 0 plain, 1 auto, 2 low-rank, 3 direct */
  cv_scatter_opts solve;
  double drop, seam_budget;
} comp_opts;

/* The display and the images to show on it. */
typedef struct {
  cv_display *d;
  size_t ns, n;   /* surfaces, patches */
  int atlas;      /* one image with the surfaces side by side */
  int eyes, w0, h0;
  cv_image *imgs[2][MAX_IMAGES];
} comp_input;

/* One solve of the display as it is patched now. */
typedef struct {
  int direct; /* form factors built compressed, without the dense matrix */
  cv_ffmatrix *F;
  cv_hmatrix *H;
  cv_scatter_system sys;
  cv_scatter_workspace *ws;
  cv_scatter_model model;
  cv_ff_report frep;
  cv_scatter_stats st;
  double *R[2];          /* input per patch and eye */
  float *Tf[2];          /* wanted radiosity per eye */
  float *I, *I0;         /* projector input: solved, uncompensated */
  double *T, *B, *delta; /* averaged target, displayed radiosity, I0 - I */
} comp_solution;

#define COMP_NOMEM() cli_fail("compensate", 1, "out of memory")

/* Returns -1 to go on, else the exit code (0 after --help). */
static int parse_options(int argc, char **argv, comp_opts *o) {
  memset(o, 0, sizeof *o);
  o->compress = 1;
  o->drop = -1;
  o->seam_budget = 0.01;
  cv_scatter_opts_default(&o->solve);
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    } else if (!strcmp(a, "--report")) {
      o->report = 1;
    } else if (!strcmp(a, "--quiet")) {
      o->quiet = 1;
    } else if (!strcmp(a, "--half")) {
      o->half = 1;
    } else if (!strcmp(a, "--seam-budget") && v) {
      i++;
      if (!strcmp(v, "off")) o->seam_budget = 0;
      else if (cli_parse_double(v, &o->seam_budget) || !(o->seam_budget > 0 && o->seam_budget < 1))
        return cli_fail("compensate", 2, "--seam-budget: expected 0 < E < 1 or off, got '%s'", v);
    } else if (!strcmp(a, "--storage") && v) {
      i++;
      if (!strcmp(v, "auto")) o->half = 0, o->compress = 1;
      else if (!strcmp(v, "float")) o->half = 0, o->compress = 0;
      else if (!strcmp(v, "half")) o->half = 1, o->compress = 0;
      else if (!strcmp(v, "low-rank")) o->half = 0, o->compress = 2;
      else if (!strcmp(v, "direct")) o->half = 0, o->compress = 3;
      else return cli_fail("compensate", 2, "--storage: expected auto, float, half, low-rank or direct, got '%s'", v);
    } else if (!v) {
      static const char *const value_opts[] = {
          "-o", "--display", "--image", "--right", "--solver", "--levels", "--time-ms",
          "--threshold", "--drop", "--seam-budget", "--storage", NULL};
      return cli_value_missing("compensate", help, a, value_opts);
    } else if (!strcmp(a, "--display")) {
      o->display_path = argv[++i];
    } else if (!strcmp(a, "-o")) {
      o->out = argv[++i];
    } else if (!strcmp(a, "--image") || !strcmp(a, "--right")) {
      int *n = a[2] == 'i' ? &o->n_img : &o->n_right;
      const char **list = a[2] == 'i' ? o->img_path : o->right_path;
      if (*n == MAX_IMAGES) return cli_fail("compensate", 2, "%s: at most %d images", a, MAX_IMAGES);
      list[(*n)++] = argv[++i];
    } else if (!strcmp(a, "--solver")) {
      const char *s = argv[++i];
      if (!strcmp(s, "auto")) o->solve.solver = CV_SCATTER_AUTO;
      else if (!strcmp(s, "exact")) o->solve.solver = CV_SCATTER_EXACT;
      else if (!strcmp(s, "jacobi")) o->solve.solver = CV_SCATTER_JACOBI;
      else if (!strcmp(s, "bounded")) o->solve.solver = CV_SCATTER_BOUNDED;
      else return cli_fail("compensate", 2, "--solver: expected auto, exact, jacobi or bounded, got '%s'", s);
    } else if (!strcmp(a, "--levels")) {
      if (cli_parse_int(argv[++i], 1, 64, &o->solve.levels))
        return cli_fail("compensate", 2, "--levels: expected 1..64, got '%s'", v);
    } else if (!strcmp(a, "--time-ms")) {
      if (cli_parse_double(argv[++i], &o->solve.time_ms) || o->solve.time_ms <= 0)
        return cli_fail("compensate", 2, "--time-ms: expected a positive number, got '%s'", v);
    } else if (!strcmp(a, "--threshold")) {
      if (cli_parse_double(argv[++i], &o->solve.threshold) || o->solve.threshold <= 0)
        return cli_fail("compensate", 2, "--threshold: expected a positive number, got '%s'", v);
    } else if (!strcmp(a, "--drop")) {
      if (cli_parse_double(argv[++i], &o->drop) || o->drop < 0 || o->drop >= 1)
        return cli_fail("compensate", 2, "--drop: expected 0 <= F < 1, got '%s'", v);
    } else {
      cli_print_usage(help);
      return cli_fail("compensate", 2, "unknown option '%s'", a);
    }
  }
  if (!o->display_path || !o->out || o->n_img == 0) {
    cli_print_usage(help);
    return cli_fail("compensate", 2, "--display, at least one --image and -o are required");
  }
  if (o->n_right && o->n_right != o->n_img)
    return cli_fail("compensate", 2, "--right: %d images for %d --image", o->n_right, o->n_img);
  if (!cli_has_ext(o->out, ".exr"))
    return cli_fail("compensate", 2, "-o: expected an .exr path, got '%s'", o->out);
  if (cli_check_output("compensate", "-o", o->out)) return 1; /* before minutes of work */
  return -1;
}

/* The display from a display description or a CAVE config. */
static int load_display(const char *path, cv_display **d) {
  cv_err err;
  cv_err_clear(&err);
  int is_cave = 0;
  if (cv_display_load_any(path, 0, -1, d, &is_cave, &err)) {
    if (!is_cave) { /* every problem of a display description, when there are several */
      char buf[8192];
      int np = 0;
      cv_display_validate_all(path, buf, sizeof buf, &np);
      if (np > 1) fputs(buf, stderr);
    }
    return cli_fail("compensate", 1, "%s", err.msg);
  }
  return 0;
}

/* Output file of eye e and surface k (k unused for an atlas). */
static void output_name(const comp_opts *o, const comp_input *in, int e, size_t k, char *path, size_t n) {
  const char *eye = in->eyes == 2 ? (e ? "_right" : "_left") : "";
  char suffix[100];
  if (in->atlas) {
    snprintf(suffix, sizeof suffix, "%s", eye);
  } else {
    const cv_display_surface *S = cv_display_surface_at(in->d, k);
    snprintf(suffix, sizeof suffix, "%s%s%s", in->ns > 1 ? "_" : "", in->ns > 1 ? S->name : "", eye);
  }
  out_path(o->out, suffix, path, n);
}

/* Every output file before any work, so that none is written when another
 * cannot be: not a folder, not one of the inputs. */
static int check_outputs(const comp_opts *o, const comp_input *in) {
  const size_t per_eye = in->atlas ? 1 : in->ns;
  for (int e = 0; e < in->eyes; e++)
    for (size_t k = 0; k < per_eye; k++) {
      char path[1200];
      output_name(o, in, e, k, path, sizeof path);
      const int rc = cli_check_output("compensate", "-o", path); /* a folder in the way */
      if (rc) return rc;
      if (cli_same_file(path, o->display_path))
        return cli_fail("compensate", 2, "-o: %s: is the --display file", path);
      for (int i = 0; i < o->n_img; i++)
        if (cli_same_file(path, o->img_path[i]) || (i < o->n_right && cli_same_file(path, o->right_path[i])))
          return cli_fail("compensate", 2, "-o: %s: is an input image; expected a new name", path);
    }
  return 0;
}

/* The display and every image, checked against each other. */
static int load_inputs(const comp_opts *o, comp_input *in) {
  int rc = load_display(o->display_path, &in->d);
  if (rc) return rc;
  in->ns = cv_display_surface_count(in->d);
  in->n = cv_display_patch_count(in->d);
  in->atlas = o->n_img == 1 && in->ns > 1;
  if (!in->atlas && (size_t)o->n_img != in->ns)
    return cli_fail("compensate", 2,
                    "%s has %zu surfaces: give one --image per surface or one atlas, not %d",
                    o->display_path, in->ns, o->n_img);
  in->eyes = o->n_right ? 2 : 1;
  if ((rc = check_outputs(o, in))) return rc;
  cv_err err;
  cv_err_clear(&err);
  for (int e = 0; e < in->eyes; e++)
    for (int k = 0; k < o->n_img; k++)
      if (cv_exr_read(e ? o->right_path[k] : o->img_path[k], &in->imgs[e][k], &err))
        return cli_fail("compensate", 1, "%s", err.msg);
  /* each eye's image of a surface (or atlas) has the same size: the cuts
   * and the correction are made with the left one's */
  for (int k = 0; k < o->n_right; k++) {
    const cv_image *l = in->imgs[0][k], *r = in->imgs[1][k];
    if (l->w != r->w || l->h != r->h)
      return cli_fail("compensate", 2, "--right %s is %dx%d, its --image %s is %dx%d: the eyes' "
                      "images must match", o->right_path[k], r->w, r->h, o->img_path[k], l->w, l->h);
  }
  for (int e = 0; e < in->eyes; e++)
    for (int k = 0; k < o->n_img; k++) warn_range(e ? o->right_path[k] : o->img_path[k], in->imgs[e][k]);
  in->w0 = in->imgs[0][0]->w;
  in->h0 = in->imgs[0][0]->h;
  if (in->atlas && in->w0 % (int)in->ns)
    return cli_fail("compensate", 1, "%s: atlas width %d is not a multiple of %zu surfaces",
                    o->img_path[0], in->w0, in->ns);
  return 0;
}

static void input_free(comp_input *in) {
  for (int e = 0; e < 2; e++)
    for (int k = 0; k < MAX_IMAGES; k++) cv_image_destroy(in->imgs[e][k]);
  cv_display_destroy(in->d);
}

/* Surface k's image of eye e: the image itself, or a copy of its atlas
 * column (the image type has no stride); *copied says which. */
static int surface_image(const comp_input *in, int e, size_t k, cv_image **part, int *copied) {
  cv_image *src = in->imgs[e][in->atlas ? 0 : k];
  *copied = in->atlas;
  if (!in->atlas) {
    *part = src;
    return 0;
  }
  const int cw = in->w0 / (int)in->ns;
  if (cv_image_create(cw, in->h0, 3, part)) return -1;
  for (int y = 0; y < in->h0; y++)
    memcpy(cv_image_at(*part, 0, y), cv_image_at(src, (int)k * cw, y), 3 * cw * sizeof(float));
  return 0;
}

static void solution_free(comp_solution *s) {
  for (int e = 0; e < 2; e++) {
    free(s->R[e]);
    free(s->Tf[e]);
  }
  free(s->I);
  free(s->I0);
  free(s->T);
  free(s->B);
  free(s->delta);
  cv_scatter_workspace_destroy(s->ws);
  cv_ffmatrix_destroy(s->F);
  cv_hmatrix_destroy(s->H);
  memset(s, 0, sizeof *s);
}

/* Every eye's images down-sampled to the display's patches. */
static int downsample_inputs(const comp_input *in, comp_solution *s) {
  for (int e = 0; e < in->eyes; e++) {
    if (!(s->R[e] = calloc(3 * in->n, sizeof(double)))) return COMP_NOMEM();
    for (size_t k = 0; k < in->ns; k++) {
      const cv_display_surface *S = cv_display_surface_at(in->d, k);
      cv_image *part;
      int copied, bad;
      if (surface_image(in, e, k, &part, &copied)) return COMP_NOMEM();
      bad = cv_downsample_to_patches(part, S->nu, S->nv, S->edge_u, S->edge_v, s->R[e] + 3 * S->offset);
      if (copied) cv_image_destroy(part);
      if (bad) return COMP_NOMEM();
    }
  }
  return 0;
}

/* Form factors (dense and sparsified, or compressed from the display), the
 * scattering system and the workspace its products use. */
static int build_system(const comp_opts *o, const comp_input *in, comp_solution *s) {
  cv_err err;
  cv_err_clear(&err);
  cv_ff_params fp;
  cv_ff_params_default(&fp);
  fp.quiet = o->quiet;
  if (o->drop >= 0) fp.drop_budget = o->drop;
  s->direct = o->compress == 3 || (o->compress == 1 && !o->half && dense_too_big(in->n));
  if (s->direct) {
    cv_hmatrix_direct_params hp;
    cv_hmatrix_direct_params_default(&hp);
    hp.quiet = o->quiet;
    const double t_ff = cv_now_seconds();
    if (cv_hmatrix_build_direct(in->d, &fp, &hp, &s->H, NULL, &err))
      return cli_fail("compensate", 1, "%s", err.msg);
    s->frep.seconds = cv_now_seconds() - t_ff;
    cv_display_scatter_system(in->d, NULL, &s->sys);
    s->sys.H = s->H;
  } else {
    if (cv_formfactors_build(in->d, &fp, &s->F, &s->frep, &err))
      return cli_fail("compensate", 1, "%s", err.msg);
    cv_display_scatter_system(in->d, s->F, &s->sys);
  }
  const int flags = (o->half ? CV_SCATTER_WS_HALF : 0) | (o->compress ? CV_SCATTER_WS_COMPRESS : 0);
  if (cv_scatter_workspace_create_ex(&s->sys, flags, &s->ws, &err))
    return cli_fail("compensate", 1, "%s", err.msg);
  cv_scatter_workspace_get_model(s->ws, &s->model);
  if (o->compress == 2 && strcmp(s->model.storage, "block low-rank"))
    fprintf(stderr, "cave compensate: --storage low-rank: the compressed form (%.1f MB) does not pay "
            "against %.1f MB plain; using %s\n", s->model.compressed_bytes / 1e6,
            s->model.source_bytes / 1e6, s->model.storage);
  return 0;
}

/* Wanted radiosity per eye, the solve, and the (eye-averaged) input, target
 * and correction at patch resolution. */
static int solve_patches(const comp_opts *o, const comp_input *in, comp_solution *s) {
  const size_t n = in->n;
  const cv_scatter_system *sys = &s->sys;
  for (int e = 0; e < in->eyes; e++) { /* what the images show without scattering */
    if (!(s->Tf[e] = malloc(3 * n * sizeof(float)))) return COMP_NOMEM();
    for (size_t i = 0; i < n; i++)
      for (int c = 0; c < 3; c++)
        s->Tf[e][3 * i + c] = (float)(sys->proj[i] * sys->refl[3 * i + c] * s->R[e][3 * i + c] +
                                      sys->env[3 * i + c] * sys->refl[3 * i + c]);
  }
  s->I = malloc(3 * n * sizeof(float));
  s->I0 = malloc(3 * n * sizeof(float));
  s->T = malloc(3 * n * sizeof(double));
  s->B = malloc(3 * n * sizeof(double));
  s->delta = malloc(3 * n * sizeof(double));
  if (!s->I || !s->I0 || !s->T || !s->B || !s->delta) return COMP_NOMEM();
  cv_err err;
  cv_err_clear(&err);
  int bad = in->eyes == 2 ? cv_scatter_solve_stereo(s->ws, s->Tf[0], s->Tf[1], &o->solve, s->I, &s->st, &err)
                          : cv_scatter_solve(s->ws, s->Tf[0], &o->solve, s->I, &s->st, &err);
  if (bad) return cli_fail("compensate", 1, "%s", err.msg);
  for (size_t k = 0; k < 3 * n; k++) {
    double r = in->eyes == 2 ? 0.5 * (s->R[0][k] + s->R[1][k]) : s->R[0][k];
    s->I0[k] = (float)r;
    s->T[k] = in->eyes == 2 ? 0.5 * ((double)s->Tf[0][k] + s->Tf[1][k]) : s->Tf[0][k];
    s->delta[k] = r - s->I[k];
  }
  return 0;
}

static int solve_display(const comp_opts *o, const comp_input *in, comp_solution *s) {
  int rc = downsample_inputs(in, s);
  if (!rc) rc = build_system(o, in, s);
  if (!rc) rc = solve_patches(o, in, s);
  return rc;
}

/* Seam refinement: while the estimated error of the up-sampled correction
 * near the seams exceeds the budget (up to 3 rounds), the patches are graded
 * ever more strongly towards the seams.  Sets *again when it re-patched. */
static int refine_seams(const comp_opts *o, const comp_input *in, const comp_solution *s, int *round,
                        cv_seam_estimate *est, int *again) {
  static const double grading[] = {3, 8, 20};
  *again = 0;
  if (!(o->seam_budget > 0 && in->ns > 1)) return 0;
  if (cv_seam_estimate_error(in->d, s->delta, 0.5, est)) return COMP_NOMEM();
  if (!o->quiet)
    printf("seam error estimate of the up-sampled correction within 0.5 m of a seam: RMS %.4f, "
           "max %.4f (budget %.4f RMS)%s\n", est->seam_rms, est->seam_max, o->seam_budget,
           *round ? " after grading" : "");
  if (!(est->seam_rms > o->seam_budget && *round < 3)) return 0;
  int nr = 0;
  if (cv_display_refine_seams(in->d, grading[*round], 0.15, &nr)) return COMP_NOMEM();
  if (!nr) return 0;
  if (!o->quiet)
    printf("  over budget: patches graded towards the seams (strength %g, width 0.15), "
           "solving again\n", grading[*round]);
  (*round)++;
  *again = 1;
  return 0;
}

static int write_exr(const char *path, const cv_image *im, int quiet) {
  cv_err err;
  cv_err_clear(&err);
  if (cv_exr_write(path, im, 1, CV_EXR_ZIP, &err)) return cli_fail("compensate", 1, "%s", err.msg);
  if (!quiet) printf("wrote %s\n", path);
  return 0;
}

/* Full resolution: the paper's equation 7 per surface and eye, written as
 * one atlas per eye or one image per surface.  Counts the clamped channels. */
static int write_outputs(const comp_opts *o, const comp_input *in, const comp_solution *s,
                         uint64_t *clamped) {
  for (int e = 0; e < in->eyes; e++) {
    cv_image *res = NULL;
    if (in->atlas && cv_image_create(in->w0, in->h0, 3, &res)) return COMP_NOMEM();
    for (size_t k = 0; k < in->ns; k++) {
      const cv_display_surface *S = cv_display_surface_at(in->d, k);
      cv_image *part, *im;
      int copied, rc = 0;
      if (surface_image(in, e, k, &part, &copied)) {
        cv_image_destroy(res);
        return COMP_NOMEM();
      }
      if (cv_image_create(part->w, part->h, 3, &im)) {
        if (copied) cv_image_destroy(part);
        cv_image_destroy(res);
        return COMP_NOMEM();
      }
      *clamped += cv_apply_patch_delta(part, s->delta + 3 * S->offset, S->nu, S->nv, S->edge_u,
                                       S->edge_v, im);
      if (in->atlas) {
        for (int y = 0; y < in->h0; y++)
          memcpy(cv_image_at(res, (int)k * part->w, y), cv_image_at(im, 0, y), 3 * part->w * sizeof(float));
      } else {
        char path[1200];
        output_name(o, in, e, k, path, sizeof path);
        rc = write_exr(path, im, o->quiet);
      }
      cv_image_destroy(im);
      if (copied) cv_image_destroy(part);
      if (rc) {
        cv_image_destroy(res);
        return rc;
      }
    }
    if (in->atlas) {
      char path[1200];
      output_name(o, in, e, 0, path, sizeof path);
      int rc = write_exr(path, res, o->quiet);
      cv_image_destroy(res);
      if (rc) return rc;
    }
  }
  return 0;
}

static void print_summary(const comp_input *in, const comp_solution *s, uint64_t clamped) {
  if (s->direct)
    printf("compensate: %zu patches, form factors built compressed (%.1f MB, %.1f s), solver %s, "
           "%d iterations, %.2f ms; %llu pixel channels clamped by equation 7\n",
           in->n, s->model.bytes / 1e6, s->frep.seconds, cv_scatter_solver_name(s->st.solver),
           s->st.iterations, s->st.ms, (unsigned long long)clamped);
  else
    printf("compensate: %zu patches, %zu form factors (%.2f%% of the energy dropped), solver %s, "
           "%d iterations, %.2f ms; %llu pixel channels clamped by equation 7\n",
           in->n, s->frep.nnz, 100 * s->frep.dropped_total, cv_scatter_solver_name(s->st.solver),
           s->st.iterations, s->st.ms, (unsigned long long)clamped);
}

/* Luminance compensated = (uncompensated - compensated) / uncompensated,
 * area-weighted, over all patches and over those within 0.5 m of another
 * surface (the seams); *peak is the most compensated patch's share. */
typedef struct {
  double all_u, all_c, seam_u, seam_c, peak;
  size_t seam_n;
} lum_compensated;

static void luminance_compensated(const cv_display *d, size_t n, const double *Bu, const double *Bc,
                                  lum_compensated *r) {
  memset(r, 0, sizeof *r);
  for (size_t i = 0; i < n; i++) {
    const cv_patch *p = cv_display_patch(d, i);
    double a = p->area, yu = a * lum(Bu + 3 * i), yc = a * lum(Bc + 3 * i);
    r->all_u += yu;
    r->all_c += yc;
    if (yu > 0 && (yu - yc) / yu > r->peak) r->peak = (yu - yc) / yu;
    int near = 0;
    for (size_t j = 0; j < n && !near; j++) {
      const cv_patch *q = cv_display_patch(d, j);
      if (q->surface == p->surface) continue;
      double dx = p->c[0] - q->c[0], dy = p->c[1] - q->c[1], dz = p->c[2] - q->c[2];
      near = dx * dx + dy * dy + dz * dz < 0.25;
    }
    if (near) {
      r->seam_u += yu;
      r->seam_c += yc;
      r->seam_n++;
    }
  }
}

static double share(double u, double c) { return u > 0 ? 100 * (u - c) / u : 0.0; }

/* --report: displayed error without and with compensation, luminance
 * compensated, the solver, seam refinement, storage and form factors. */
static int print_report(const comp_opts *o, const comp_input *in, comp_solution *s, int refine_round,
                        const cv_seam_estimate *seam_est) {
  display_stats un, co;
  double *Bu = malloc(3 * in->n * sizeof(double));
  if (!Bu || judge(&s->sys, s->I0, s->T, Bu, &un) || judge(&s->sys, s->I, s->T, s->B, &co)) {
    free(Bu);
    return cli_fail("compensate", 1, "the display physics did not converge");
  }
  lum_compensated lc;
  luminance_compensated(in->d, in->n, Bu, s->B, &lc);
  free(Bu);
  const cv_scatter_stats *st = &s->st;
  printf("report (radiosity units; wanted = what the images show without scattering):\n");
  printf("  %-14s displayed RMS error %.5f, max %.5f\n", "uncompensated", un.rms, un.max);
  printf("  %-14s displayed RMS error %.5f, max %.5f\n", "compensated", co.rms, co.max);
  if (lc.seam_n)
    printf("  luminance compensated: %.2f%% overall, %.2f%% within 0.5 m of a seam (%zu patches), "
           "%.2f%% on the most compensated patch\n",
           share(lc.all_u, lc.all_c), share(lc.seam_u, lc.seam_c), lc.seam_n, 100 * lc.peak);
  else
    printf("  luminance compensated: %.2f%% overall (no seams: a single surface)\n",
           share(lc.all_u, lc.all_c));
  printf("  solver %s%s, %d iterations, %zu clipped patches (%zu channels), spectral radius %.4f, "
         "%.2f ms\n",
         cv_scatter_solver_name(st->solver), st->stereo ? " (stereo average)" : "", st->iterations,
         st->clipped_patches, st->clipped_channels, st->rho, st->ms);
  if (o->seam_budget > 0 && in->ns > 1)
    printf("  seam refinement: %s (estimated seam RMS %.4f, budget %.4f)\n",
           refine_round ? "graded towards the seams" : "not needed", seam_est->seam_rms, o->seam_budget);
  printf("  storage of K: %s, %.2f MB read per product (plain %.2f MB), product error <= %.2e x max|x|\n",
         s->model.storage, s->model.bytes / 1e6, s->model.source_bytes / 1e6, s->model.error_bound);
  if (s->direct)
    printf("  form factors: built compressed from the display (no dense matrix), %.2f s; "
           "row error estimated <= %.2e of the row\n",
           s->frep.seconds, s->model.compress_info.max_rel_row_error);
  else
    printf("  form factors: %zu of %zu kept, %.3f%% of the energy dropped (worst row %.3f%%), %.2f s\n",
           s->frep.nnz, s->frep.nnz_full, 100 * s->frep.dropped_total, 100 * s->frep.dropped_max,
           s->frep.seconds);
  return 0;
}

int cmd_compensate(int argc, char **argv) {
  comp_opts o;
  int rc = parse_options(argc, argv, &o);
  if (rc >= 0) return rc;
  comp_input in;
  comp_solution s;
  memset(&in, 0, sizeof in);
  memset(&s, 0, sizeof s);
  int refine_round = 0, again = 1;
  cv_seam_estimate seam_est;
  memset(&seam_est, 0, sizeof seam_est);
  uint64_t clamped = 0;
  rc = load_inputs(&o, &in);
  while (!rc && again) { /* solve; re-patch towards the seams while over budget */
    solution_free(&s);
    rc = solve_display(&o, &in, &s);
    if (!rc) rc = refine_seams(&o, &in, &s, &refine_round, &seam_est, &again);
  }
  if (!rc) rc = write_outputs(&o, &in, &s, &clamped);
  if (!rc && !o.quiet) print_summary(&in, &s, clamped);
  if (!rc && o.report) rc = print_report(&o, &in, &s, refine_round, &seam_est);
  solution_free(&s);
  input_free(&in);
  return rc;
}
