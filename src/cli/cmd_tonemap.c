/* `cave tonemap`: Drago et al. 2003 adaptive logarithmic tone mapping of an
 * HDR image, the CPU reference of the wall-eye renderer's display operator.
 * Without --lwa the adaptation luminance is the log-average of the whole
 * image (eps 1e-4 cd/m2), without --lmax its maximum luminance; pixel values
 * are taken as cd/m2 (Rec.709 Y = 0.2126 R + 0.7152 G + 0.0722 B). */
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli/cli.h"
#include "io/exr.h"
#include "io/png.h"
#include "tonemap/drago.h"
#include "tonemap/foveal.h"

/* --lwa and --lmax: from the eps floor of the image statistics (the lwa of
 * an all-black image) up to 1e12 cd/m2, far above the sun's disc (~1.6e9),
 * so that the float uniforms hold them and lmax / lwa (beyond 1e30
 * cv_drago_prepare clamps it; an lwa beyond the float range gave a black
 * image). */
#define LUM_MIN CV_LUM_EPS
#define LUM_MAX 1e12
/* cv_drago_prepare replaces an lmax below lwa x this by lwa. */
#define LMAX_MIN_RATIO 1e-6
/* --ldmax: far above any display (HDR panels reach a few 1000 cd/m2). */
#define LDMAX_MAX 1e6

static void help(FILE *f) {
  fprintf(f,
          "usage: cave tonemap in.exr -o out.exr|out.png [--bias B] [--ldmax L] [--lwa L]\n"
          "                    [--lmax L]\n\n"
          "Drago et al. 2003 adaptive logarithmic tone mapping; pixel values in cd/m2.\n\n"
          "  --bias B    Drago's bias, 0 < B < 1 (default 0.85)\n"
          "  --ldmax L   display maximum luminance, 0 < L <= %g cd/m2 (default 100)\n"
          "  --lwa L     adaptation luminance, %g..%g cd/m2 (default: log-average of the\n"
          "              image, exp(mean(ln(Y + 1e-4))))\n"
          "  --lmax L    maximum world luminance, %g..%g cd/m2, at least 1e-6 x lwa\n"
          "              (default: the image's maximum Y)\n"
          "  -o FILE     .exr: display-linear values in [0, 1] (before the transfer curve);\n"
          "              .png: 8-bit with Drago's Rec.709 transfer curve (gamma 2.2);\n"
          "              not the input image\n\n"
          "Prints one line: lwa, lmax, invalid (NaN/Inf/negative) pixels set to 0, and\n"
          "saturated pixels (a channel above 1 after the colour ratio, clamped).\n"
          "Input EXRs with NaN or Inf are refused by the reader; negative values are\n"
          "clamped to 0 by the reader and counted.\n"
          "\nexamples:\n"
          "  cave tonemap frame00003_front_L.exr -o front.png\n"
          "  cave tonemap in.exr --lwa 2000 --lmax 2e5 -o out.png\n",
          LDMAX_MAX, LUM_MIN, LUM_MAX, LUM_MIN, LUM_MAX);
}

/* The command line of cave tonemap. */
typedef struct tm_opts {
  const char *in, *out;
  cv_drago d;
  int have_lwa, have_lmax, png;
} tm_opts;

/* argv into o.  Returns -1 to go on, else the exit code. */
static int parse_args(int argc, char **argv, tm_opts *o) {
  memset(o, 0, sizeof *o);
  cv_drago_default(&o->d);
  cv_drago *d = &o->d;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    } else if (a[0] != '-') {
      if (o->in) return cli_fail("tonemap", 2, "more than one input ('%s' and '%s')", o->in, a);
      o->in = a;
    } else if (!v) {
      static const char *const value_opts[] = {"-o", "--bias", "--ldmax", "--lwa", "--lmax", NULL};
      return cli_value_missing("tonemap", help, a, value_opts);
    } else if (!strcmp(a, "-o")) {
      o->out = argv[++i];
    } else if (!strcmp(a, "--bias")) {
      if (cli_parse_double(argv[++i], &d->bias) || !(d->bias > 0) || !(d->bias < 1))
        return cli_fail("tonemap", 2, "--bias: expected 0 < B < 1, got '%s'", v);
    } else if (!strcmp(a, "--ldmax")) {
      if (cli_parse_double(argv[++i], &d->ldmax) || !(d->ldmax > 0 && d->ldmax <= LDMAX_MAX))
        return cli_fail("tonemap", 2, "--ldmax: expected 0 < L <= %g cd/m2, got '%s'", LDMAX_MAX, v);
    } else if (!strcmp(a, "--lwa")) {
      if (cli_parse_double(argv[++i], &d->lwa) || !(d->lwa >= LUM_MIN && d->lwa <= LUM_MAX))
        return cli_fail("tonemap", 2, "--lwa: expected %g..%g cd/m2, got '%s'", LUM_MIN, LUM_MAX, v);
      o->have_lwa = 1;
    } else if (!strcmp(a, "--lmax")) {
      if (cli_parse_double(argv[++i], &d->lwmax) || !(d->lwmax >= LUM_MIN && d->lwmax <= LUM_MAX))
        return cli_fail("tonemap", 2, "--lmax: expected %g..%g cd/m2, got '%s'", LUM_MIN, LUM_MAX, v);
      o->have_lmax = 1;
    } else {
      cli_print_usage(help);
      return cli_fail("tonemap", 2, "unknown option '%s'", a);
    }
  }
  return -1;
}

/* The input, the output's kind and folder, --lmax against --lwa.  Returns
 * 0 or the exit code. */
static int check_args(tm_opts *o) {
  if (!o->in || !o->out) {
    cli_print_usage(help);
    return cli_fail("tonemap", 2, "an input image and -o are required");
  }
  o->png = cli_has_ext(o->out, ".png");
  if (!o->png && !cli_has_ext(o->out, ".exr"))
    return cli_fail("tonemap", 2, "-o: expected an .exr or .png path, got '%s'", o->out);
  if (cli_same_file(o->in, o->out))
    return cli_fail("tonemap", 2, "-o: %s: is the input image; expected a new .exr or .png path", o->out);
  if (o->have_lwa && o->have_lmax && o->d.lwmax < o->d.lwa * LMAX_MIN_RATIO)
    return cli_fail("tonemap", 2, "--lmax: %g cd/m2 is below 1e-6 x --lwa %g", o->d.lwmax, o->d.lwa);
  if (cli_check_output("tonemap", "-o", o->out)) return 1; /* a folder, a missing folder */
  return 0;
}

/* The image's global statistics (weight 1 per pixel) as the Drago
 * parameters not given: an image without a valid pixel keeps lwa at the
 * eps floor (cv_drago_prepare's sanitising).  Returns 0 or the exit code. */
static int image_parameters(const cv_image *img, tm_opts *o) {
  cv_lumstats st;
  memset(&st, 0, sizeof st);
  cv_lumstats_image(img, &st);
  double lwa = CV_LUM_EPS;
  cv_lumstats_lwa(&st, &lwa);
  if (!o->have_lwa) o->d.lwa = lwa;
  if (!o->have_lmax) o->d.lwmax = st.max_l;
  if (o->have_lmax && !o->have_lwa && o->d.lwmax < o->d.lwa * LMAX_MIN_RATIO)
    return cli_fail("tonemap", 2, "--lmax: %g cd/m2 is below 1e-6 x the image's log-average "
                    "luminance %g cd/m2 (give --lwa, or a larger --lmax)", o->d.lwmax, o->d.lwa);
  return 0;
}

/* The tone-mapped image as 8-bit PNG or linear EXR.  Returns 0 or the exit
 * code. */
static int write_result(const tm_opts *o, const cv_image *res) {
  cv_err err;
  cv_err_clear(&err);
  if (!o->png) return cv_exr_write(o->out, res, 0, CV_EXR_ZIP, &err) ? cli_fail("tonemap", 1, "%s", err.msg) : 0;
  size_t n = (size_t)res->w * (size_t)res->h * (size_t)res->c;
  uint8_t *px8 = malloc(n);
  if (!px8) return cli_fail("tonemap", 1, "out of memory");
  for (size_t i = 0; i < n; i++) {
    double e = res->px[i];
    px8[i] = (uint8_t)lrint((e > 1.0 ? 1.0 : (e > 0.0 ? e : 0.0)) * 255.0);
  }
  int rc = cv_png_write(o->out, res->w, res->h, res->c, px8, &err) ? cli_fail("tonemap", 1, "%s", err.msg) : 0;
  free(px8);
  return rc;
}

/* Reads, tone-maps, writes and reports.  Returns 0 or the exit code. */
static int run_tonemap(tm_opts *o) {
  cv_err err;
  cv_err_clear(&err);
  cv_image *img = NULL, *res = NULL;
  cv_exr_read_info info;
  memset(&info, 0, sizeof info);
  uint64_t n_invalid = 0, n_sat = 0;
  int rc = 0;
  if (cv_exr_read_ex(o->in, &img, &info, &err))
    rc = cli_fail("tonemap", 1, "%s", err.msg);
  if (!rc) rc = image_parameters(img, o);
  if (!rc && cv_image_create(img->w, img->h, img->c, &res)) rc = cli_fail("tonemap", 1, "out of memory");
  if (!rc && cv_drago_image_counts(img, &o->d, o->png, res, &n_invalid, &n_sat))
    rc = cli_fail("tonemap", 1, "%s: cannot tone-map this image", o->in);
  if (!rc) rc = write_result(o, res);
  if (!rc) {
    const cv_drago *d = &o->d;
    cv_drago_consts k;
    cv_drago_prepare(d, &k);
    printf("tonemap: %s -> %s: lwa %.6g cd/m2%s, lmax %.6g cd/m2%s, invalid %" PRIu64
           " pixels (negative values clamped on read: %" PRIu64 "), saturated %" PRIu64
           " pixels, bias %g, ldmax %g\n",
           o->in, o->out, o->have_lwa ? d->lwa : (double)k.lwa, o->have_lwa ? " (given)" : "",
           o->have_lmax ? d->lwmax : (double)k.lwa * k.lwmax_a, o->have_lmax ? " (given)" : "",
           n_invalid, info.negative_clamped, n_sat, d->bias, d->ldmax);
  }
  cv_image_destroy(res);
  cv_image_destroy(img);
  return rc;
}

int cmd_tonemap(int argc, char **argv) {
  tm_opts o;
  int rc = parse_args(argc, argv, &o);
  if (rc >= 0) return rc;
  if ((rc = check_args(&o)) != 0) return rc;
  return run_tonemap(&o);
}
