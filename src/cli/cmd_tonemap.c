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

int cmd_tonemap(int argc, char **argv) {
  const char *in = NULL, *out = NULL;
  cv_drago d;
  cv_drago_default(&d);
  int have_lwa = 0, have_lmax = 0;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    } else if (a[0] != '-') {
      if (in) return cli_fail("tonemap", 2, "more than one input ('%s' and '%s')", in, a);
      in = a;
    } else if (!v) {
      static const char *const value_opts[] = {"-o", "--bias", "--ldmax", "--lwa", "--lmax", NULL};
      return cli_value_missing("tonemap", help, a, value_opts);
    } else if (!strcmp(a, "-o")) {
      out = argv[++i];
    } else if (!strcmp(a, "--bias")) {
      if (cli_parse_double(argv[++i], &d.bias) || !(d.bias > 0) || !(d.bias < 1))
        return cli_fail("tonemap", 2, "--bias: expected 0 < B < 1, got '%s'", v);
    } else if (!strcmp(a, "--ldmax")) {
      if (cli_parse_double(argv[++i], &d.ldmax) || !(d.ldmax > 0 && d.ldmax <= LDMAX_MAX))
        return cli_fail("tonemap", 2, "--ldmax: expected 0 < L <= %g cd/m2, got '%s'", LDMAX_MAX, v);
    } else if (!strcmp(a, "--lwa")) {
      if (cli_parse_double(argv[++i], &d.lwa) || !(d.lwa >= LUM_MIN && d.lwa <= LUM_MAX))
        return cli_fail("tonemap", 2, "--lwa: expected %g..%g cd/m2, got '%s'", LUM_MIN, LUM_MAX, v);
      have_lwa = 1;
    } else if (!strcmp(a, "--lmax")) {
      if (cli_parse_double(argv[++i], &d.lwmax) || !(d.lwmax >= LUM_MIN && d.lwmax <= LUM_MAX))
        return cli_fail("tonemap", 2, "--lmax: expected %g..%g cd/m2, got '%s'", LUM_MIN, LUM_MAX, v);
      have_lmax = 1;
    } else {
      cli_print_usage(help);
      return cli_fail("tonemap", 2, "unknown option '%s'", a);
    }
  }
  if (!in || !out) {
    cli_print_usage(help);
    return cli_fail("tonemap", 2, "an input image and -o are required");
  }
  int png = cli_has_ext(out, ".png");
  if (!png && !cli_has_ext(out, ".exr"))
    return cli_fail("tonemap", 2, "-o: expected an .exr or .png path, got '%s'", out);
  if (cli_same_file(in, out))
    return cli_fail("tonemap", 2, "-o: %s: is the input image; expected a new .exr or .png path", out);
  if (have_lwa && have_lmax && d.lwmax < d.lwa * LMAX_MIN_RATIO)
    return cli_fail("tonemap", 2, "--lmax: %g cd/m2 is below 1e-6 x --lwa %g", d.lwmax, d.lwa);
  if (cli_check_output("tonemap", "-o", out)) return 1; /* a folder, a missing folder */

  cv_err err;
  cv_err_clear(&err);
  cv_image *img = NULL, *res = NULL;
  uint8_t *px8 = NULL;
  int rc = 1;
  cv_exr_read_info info;
  memset(&info, 0, sizeof info);
  if (cv_exr_read_ex(in, &img, &info, &err)) {
    cli_fail("tonemap", 1, "%s", err.msg);
    goto done;
  }
  /* Global statistics, weight 1 per pixel; an image without a valid pixel
   * keeps lwa at the eps floor (cv_drago_prepare's sanitising). */
  cv_lumstats st;
  memset(&st, 0, sizeof st);
  cv_lumstats_image(img, &st);
  double lwa = CV_LUM_EPS;
  cv_lumstats_lwa(&st, &lwa);
  if (!have_lwa) d.lwa = lwa;
  if (!have_lmax) d.lwmax = st.max_l;
  if (have_lmax && !have_lwa && d.lwmax < d.lwa * LMAX_MIN_RATIO) {
    rc = cli_fail("tonemap", 2, "--lmax: %g cd/m2 is below 1e-6 x the image's log-average "
                  "luminance %g cd/m2 (give --lwa, or a larger --lmax)", d.lwmax, d.lwa);
    goto done;
  }
  if (cv_image_create(img->w, img->h, img->c, &res)) {
    cli_fail("tonemap", 1, "out of memory");
    goto done;
  }
  uint64_t n_invalid = 0, n_sat = 0;
  if (cv_drago_image_counts(img, &d, png, res, &n_invalid, &n_sat)) {
    cli_fail("tonemap", 1, "%s: cannot tone-map this image", in);
    goto done;
  }
  if (png) {
    size_t n = (size_t)res->w * (size_t)res->h * (size_t)res->c;
    px8 = malloc(n);
    if (!px8) {
      cli_fail("tonemap", 1, "out of memory");
      goto done;
    }
    for (size_t i = 0; i < n; i++) {
      double e = res->px[i];
      px8[i] = (uint8_t)lrint((e > 1.0 ? 1.0 : (e > 0.0 ? e : 0.0)) * 255.0);
    }
    if (cv_png_write(out, res->w, res->h, res->c, px8, &err)) {
      cli_fail("tonemap", 1, "%s", err.msg);
      goto done;
    }
  } else if (cv_exr_write(out, res, 0, CV_EXR_ZIP, &err)) {
    cli_fail("tonemap", 1, "%s", err.msg);
    goto done;
  }
  cv_drago_consts k;
  cv_drago_prepare(&d, &k);
  printf("tonemap: %s -> %s: lwa %.6g cd/m2%s, lmax %.6g cd/m2%s, invalid %" PRIu64
         " pixels (negative values clamped on read: %" PRIu64 "), saturated %" PRIu64
         " pixels, bias %g, ldmax %g\n",
         in, out, have_lwa ? d.lwa : (double)k.lwa, have_lwa ? " (given)" : "",
         have_lmax ? d.lwmax : (double)k.lwa * k.lwmax_a, have_lmax ? " (given)" : "", n_invalid, info.negative_clamped, n_sat, d.bias, d.ldmax);
  rc = 0;
done:
  free(px8);
  cv_image_destroy(res);
  cv_image_destroy(img);
  return rc;
}
