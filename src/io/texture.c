/* Diffuse albedo textures (see texture.h): PNG through cv_png_read, JPEG
 * through libjpeg (libjpeg-turbo), told apart by their first bytes. */
#include "io/texture.h"

#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <jpeglib.h>

#include "io/png.h"

#define JPEG_MAX_SIDE 32768 /* texels; larger is refused before decoding */

static float srgb_to_linear(float v) {
  return v <= 0.04045f ? v / 12.92f : (float)pow((v + 0.055) / 1.055, 2.4);
}

/* libjpeg reports errors through error_exit, which must not return: back to
 * read_jpeg by longjmp with the library's message.  Warnings (corrupt data
 * that libjpeg decodes anyway, as grey) are counted and refused as well. */
typedef struct jerr {
  struct jpeg_error_mgr pub;
  jmp_buf jb;
  char msg[JMSG_LENGTH_MAX];
} jerr;

static void jerr_exit(j_common_ptr ci) {
  jerr *e = (jerr *)ci->err;
  (*ci->err->format_message)(ci, e->msg);
  longjmp(e->jb, 1);
}

static void jerr_emit(j_common_ptr ci, int level) {
  jerr *e = (jerr *)ci->err;
  if (level < 0 && !e->pub.num_warnings++) (*ci->err->format_message)(ci, e->msg);
}

/* Decodes the JPEG in f into *out (3 channels, sRGB values in [0, 1]). */
static int read_jpeg(FILE *f, const char *path, cv_image **out, cv_err *err) {
  struct jpeg_decompress_struct ci;
  jerr je;
  memset(&je, 0, sizeof je);
  ci.err = jpeg_std_error(&je.pub);
  je.pub.error_exit = jerr_exit;
  je.pub.emit_message = jerr_emit;
  cv_image *volatile img = NULL;
  JSAMPLE *volatile row = NULL;
  if (setjmp(je.jb)) {
    jpeg_destroy_decompress(&ci);
    cv_image_destroy(img);
    free(row);
    return cv_err_set(err, CV_ERR_FORMAT, "%s: not a readable JPEG: %s", path, je.msg);
  }
  jpeg_create_decompress(&ci);
  jpeg_stdio_src(&ci, f);
  jpeg_read_header(&ci, TRUE);
  if (ci.image_width > JPEG_MAX_SIDE || ci.image_height > JPEG_MAX_SIDE) {
    const unsigned w = ci.image_width, h = ci.image_height;
    jpeg_destroy_decompress(&ci);
    return cv_err_set(err, CV_ERR_FORMAT, "%s: JPEG of %u x %u texels, at most %d per side", path,
                      w, h, JPEG_MAX_SIDE);
  }
  ci.out_color_space = JCS_RGB; /* grey and YCbCr converted; CMYK is an error */
  jpeg_start_decompress(&ci);
  cv_image *tmp = NULL;
  const int cst = cv_image_create((int)ci.output_width, (int)ci.output_height, 3, &tmp);
  img = tmp;
  if (cst || !(row = malloc((size_t)ci.output_width * 3))) {
    jpeg_destroy_decompress(&ci);
    cv_image_destroy(img);
    free(row);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  }
  while (ci.output_scanline < ci.output_height) {
    const int y = (int)ci.output_scanline;
    JSAMPROW rp = row;
    jpeg_read_scanlines(&ci, &rp, 1);
    float *dst = cv_image_at(img, 0, y);
    for (size_t i = 0; i < (size_t)ci.output_width * 3; i++) dst[i] = row[i] / 255.0f;
  }
  jpeg_finish_decompress(&ci);
  const long warnings = je.pub.num_warnings;
  jpeg_destroy_decompress(&ci);
  free(row);
  if (warnings) {
    cv_image_destroy(img);
    return cv_err_set(err, CV_ERR_FORMAT, "%s: corrupt JPEG: %s", path, je.msg);
  }
  *out = img;
  return CV_OK;
}

/* The file's sRGB values in [0, 1]: PNG or JPEG by signature. */
static int read_image(const char *path, cv_image **out, cv_err *err) {
  FILE *f = fopen(path, "rb");
  if (!f) return cv_err_set(err, CV_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
  unsigned char sig[8] = {0};
  const size_t n = fread(sig, 1, sizeof sig, f);
  int st;
  if (n >= 3 && sig[0] == 0xff && sig[1] == 0xd8 && sig[2] == 0xff) {
    rewind(f);
    st = read_jpeg(f, path, out, err);
    fclose(f);
  } else if (n == 8 && !memcmp(sig, "\x89PNG\r\n\x1a\n", 8)) {
    fclose(f);
    st = cv_png_read(path, out, err);
  } else {
    fclose(f);
    st = cv_err_set(err, CV_ERR_FORMAT, "%s: neither a PNG nor a JPEG (first bytes %02x %02x %02x)",
                    path, sig[0], sig[1], sig[2]);
  }
  return st;
}

int cv_texture_load(const char *path, cv_image **out, cv_err *err) {
  *out = NULL;
  cv_image *in = NULL, *t = NULL;
  int st = read_image(path, &in, err);
  if (st) return st;
  if (cv_image_create(in->w, in->h, 3, &t)) {
    cv_image_destroy(in);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  }
  const size_t n = (size_t)in->w * (size_t)in->h;
  for (size_t i = 0; i < n; i++)
    for (int k = 0; k < 3; k++)
      t->px[3 * i + k] = srgb_to_linear(in->px[i * (size_t)in->c + (in->c >= 3 ? k : 0)]);
  cv_image_destroy(in);
  *out = t;
  return CV_OK;
}

void cv_texture_match_mean(cv_image *t, const float albedo[3]) {
  const size_t n = (size_t)t->w * (size_t)t->h;
  double acc[3] = {0, 0, 0};
  for (size_t i = 0; i < n; i++)
    for (int k = 0; k < 3; k++) acc[k] += t->px[3 * i + k];
  for (int k = 0; k < 3; k++) {
    const double mean = acc[k] / (double)n;
    if (!(mean > 0) || !isfinite(albedo[k])) continue;
    const float f = (float)(albedo[k] / mean);
    for (size_t i = 0; i < n; i++) t->px[3 * i + k] *= f;
  }
}

static int wrap(long i, int n) {
  long r = i % n;
  return (int)(r < 0 ? r + n : r);
}

void cv_texture_sample(const cv_image *t, double u, double v, float rgb[3]) {
  if (!isfinite(u) || !isfinite(v)) u = v = 0;
  u -= floor(u); /* wrap first: no overflow converting to long below */
  v -= floor(v);
  double x = u * t->w - 0.5, y = (1.0 - v) * t->h - 0.5;
  double fx = floor(x), fy = floor(y), ax = x - fx, ay = y - fy;
  int x0 = wrap((long)fx, t->w), x1 = wrap((long)fx + 1, t->w);
  int y0 = wrap((long)fy, t->h), y1 = wrap((long)fy + 1, t->h);
  const float *a = cv_image_at(t, x0, y0), *b = cv_image_at(t, x1, y0),
              *c = cv_image_at(t, x0, y1), *d = cv_image_at(t, x1, y1);
  for (int k = 0; k < 3; k++)
    rgb[k] = (float)((1 - ay) * ((1 - ax) * a[k] + ax * b[k]) + ay * ((1 - ax) * c[k] + ax * d[k]));
}
