/* Texture files (io/texture.c) and embedded textures (io/texture_embed.c):
 *  - a JPEG written by libjpeg at quality 100 reads back as its sRGB values
 *    decoded to linear (within JPEG's error), grey JPEGs replicated;
 *  - PNG and JPEG are told by their bytes, not the file name;
 *  - a texture scaled to its material's albedo (the colour factor);
 *  - missing, garbage and truncated files: an error naming the file, no crash;
 *  - embedded textures of an aiScene: compressed PNG bytes ("*0") written
 *    to the cache as they are, raw BGRA texels as a PNG, the same texture
 *    always to the same path; an index past the textures is an error, a
 *    name no embedded texture has is not embedded. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>
#include "cv_test_near.h"
#include <jpeglib.h>

#include "io/png.h"
#include "io/texture.h"
#include "io/texture_embed.h"

static char tmp[512];

static const char *path_of(const char *name) {
  snprintf(tmp, sizeof tmp, "%s/%s", CV_TEST_TMP_DIR, name);
  return tmp;
}

static double lin(double s) { return s <= 0.04045 ? s / 12.92 : pow((s + 0.055) / 1.055, 2.4); }

/* w x h JPEG of one colour (comps 1 or 3) at quality 100. */
static void write_jpeg(const char *path, int w, int h, int comps, const uint8_t *colour) {
  FILE *f = fopen(path, "wb");
  assert_non_null(f);
  struct jpeg_compress_struct ci;
  struct jpeg_error_mgr je;
  ci.err = jpeg_std_error(&je);
  jpeg_create_compress(&ci);
  jpeg_stdio_dest(&ci, f);
  ci.image_width = (JDIMENSION)w, ci.image_height = (JDIMENSION)h;
  ci.input_components = comps;
  ci.in_color_space = comps == 1 ? JCS_GRAYSCALE : JCS_RGB;
  jpeg_set_defaults(&ci);
  jpeg_set_quality(&ci, 100, TRUE);
  jpeg_start_compress(&ci, TRUE);
  uint8_t *row = malloc((size_t)w * comps);
  for (int x = 0; x < w; x++) memcpy(row + (size_t)x * comps, colour, (size_t)comps);
  while (ci.next_scanline < ci.image_height) {
    JSAMPROW rp = row;
    jpeg_write_scanlines(&ci, &rp, 1);
  }
  jpeg_finish_compress(&ci);
  jpeg_destroy_compress(&ci);
  free(row);
  fclose(f);
}

static void test_jpeg_read(void **state) {
  (void)state;
  const uint8_t rgb[3] = {200, 100, 30}, grey[1] = {77};
  char p1[512], p2[512];
  snprintf(p1, sizeof p1, "%s", path_of("flat.jpg"));
  snprintf(p2, sizeof p2, "%s", path_of("grey.texture")); /* any name: the bytes decide */
  write_jpeg(p1, 24, 16, 3, rgb);
  write_jpeg(p2, 8, 8, 1, grey);
  cv_image *t = NULL;
  cv_err err;
  assert_int_equal(cv_texture_load(p1, &t, &err), CV_OK);
  assert_int_equal(t->w, 24);
  assert_int_equal(t->h, 16);
  assert_int_equal(t->c, 3);
  double worst = 0;
  for (int i = 0; i < 24 * 16; i++)
    for (int c = 0; c < 3; c++) {
      /* JPEG's colour conversion and quantisation: within 2 codes */
      double lo = lin((rgb[c] - 2) / 255.0), hi = lin((rgb[c] + 2) / 255.0), v = t->px[3 * i + c];
      assert_true(v >= lo && v <= hi);
      worst = fmax(worst, fabs(v - lin(rgb[c] / 255.0)));
    }
  printf("flat JPEG: largest difference from the sRGB-decoded colour %.2e\n", worst);
  cv_image_destroy(t);
  assert_int_equal(cv_texture_load(p2, &t, &err), CV_OK);
  for (int i = 0; i < 64; i++)
    for (int c = 0; c < 3; c++) assert_near(t->px[3 * i + c], lin(77 / 255.0), 2e-3);
  cv_image_destroy(t);
}

static uint8_t *slurp(const char *path, size_t *n) {
  FILE *f = fopen(path, "rb");
  assert_non_null(f);
  fseek(f, 0, SEEK_END);
  *n = (size_t)ftell(f);
  rewind(f);
  uint8_t *b = malloc(*n);
  assert_int_equal(fread(b, 1, *n, f), *n);
  fclose(f);
  return b;
}

static void test_bad_files(void **state) {
  (void)state;
  cv_image *t = NULL;
  cv_err err;
  assert_int_equal(cv_texture_load(path_of("no_such.jpg"), &t, &err), CV_ERR_IO);
  assert_non_null(strstr(err.msg, "no_such.jpg"));
  FILE *f = fopen(path_of("garbage.png"), "wb");
  fputs("this is not an image at all", f);
  fclose(f);
  assert_int_equal(cv_texture_load(path_of("garbage.png"), &t, &err), CV_ERR_FORMAT);
  assert_non_null(strstr(err.msg, "neither a PNG nor a JPEG"));
  /* a JPEG cut after its first 300 bytes: libjpeg would fill grey; refused */
  char full[512];
  snprintf(full, sizeof full, "%s", path_of("full.jpg"));
  uint8_t c[3] = {10, 120, 240};
  write_jpeg(full, 64, 64, 3, c);
  FILE *in = fopen(full, "rb");
  uint8_t buf[300];
  assert_int_equal(fread(buf, 1, sizeof buf, in), sizeof buf);
  fclose(in);
  f = fopen(path_of("cut.jpg"), "wb");
  fwrite(buf, 1, sizeof buf, f);
  fclose(f);
  assert_int_equal(cv_texture_load(path_of("cut.jpg"), &t, &err), CV_ERR_FORMAT);
  printf("truncated JPEG: %s\n", err.msg);
  assert_non_null(strstr(err.msg, "cut.jpg"));
  assert_null(t);
  /* the end of the scan cut off: libjpeg warns (premature end) and fills in
   * grey; refused as well */
  size_t nfull;
  uint8_t *whole = slurp(full, &nfull);
  f = fopen(path_of("end.jpg"), "wb");
  fwrite(whole, 1, nfull - 40, f);
  fclose(f);
  free(whole);
  assert_int_equal(cv_texture_load(path_of("end.jpg"), &t, &err), CV_ERR_FORMAT);
  printf("JPEG without its end: %s\n", err.msg);
  assert_non_null(strstr(err.msg, "corrupt JPEG"));
  assert_null(t);
  /* only the header: an error from libjpeg itself (longjmp path) */
  f = fopen(path_of("head.jpg"), "wb");
  fwrite(buf, 1, 20, f);
  fclose(f);
  assert_int_equal(cv_texture_load(path_of("head.jpg"), &t, &err), CV_ERR_FORMAT);
  printf("JPEG header only: %s\n", err.msg);
  assert_null(t);
}

/* cv_texture_match_mean: each channel scaled to the given mean (the
 * material's albedo: colour factor x texture mean). */
static void test_match_mean(void **state) {
  (void)state;
  cv_image *t;
  assert_int_equal(cv_image_create(2, 2, 3, &t), CV_OK);
  const float v[12] = {0.1f, 0.2f, 0.0f, 0.3f, 0.4f, 0.0f, 0.5f, 0.6f, 0.0f, 0.7f, 0.8f, 0.0f};
  memcpy(t->px, v, sizeof v);
  const float albedo[3] = {0.2f, 0.25f, 0.3f}; /* means were 0.4, 0.5, 0 */
  cv_texture_match_mean(t, albedo);
  for (int i = 0; i < 4; i++) {
    assert_near(t->px[3 * i], v[3 * i] * 0.5, 1e-7);
    assert_near(t->px[3 * i + 1], v[3 * i + 1] * 0.5, 1e-7);
    assert_true(t->px[3 * i + 2] == 0.0f); /* a zero mean is left */
  }
  cv_image_destroy(t);
}

static void test_embedded(void **state) {
  (void)state;
  char cache[512];
  snprintf(cache, sizeof cache, "%s/texcache", CV_TEST_TMP_DIR);
  setenv("CAVE_TEXTURE_DIR", cache, 1);
  /* a 2 x 2 PNG as compressed bytes, and raw texels */
  const uint8_t px[12] = {255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255};
  char png[512];
  snprintf(png, sizeof png, "%s", path_of("emb_src.png"));
  cv_err err;
  assert_int_equal(cv_png_write(png, 2, 2, 3, px, &err), CV_OK);
  size_t n;
  uint8_t *bytes = slurp(png, &n);
  struct aiTexture comp, raw;
  memset(&comp, 0, sizeof comp);
  memset(&raw, 0, sizeof raw);
  comp.mWidth = (unsigned)n, comp.mHeight = 0;
  memcpy(comp.achFormatHint, "png", 4);
  comp.pcData = (struct aiTexel *)bytes;
  struct aiTexel texels[2] = {{.b = 10, .g = 20, .r = 30, .a = 255}, {.b = 40, .g = 50, .r = 60, .a = 128}};
  raw.mWidth = 2, raw.mHeight = 1;
  raw.pcData = texels;
  const char *name = "textures/skin.png";
  raw.mFilename.length = (unsigned)strlen(name);
  memcpy(raw.mFilename.data, name, strlen(name) + 1);
  struct aiTexture *list[2] = {&comp, &raw};
  struct aiScene sc;
  memset(&sc, 0, sizeof sc);
  sc.mNumTextures = 2;
  sc.mTextures = list;

  char out[256], out2[256];
  assert_int_equal(cv_texture_embedded_file(&sc, "*0", out, sizeof out, &err), 1);
  printf("*0 -> %s\n", out);
  assert_non_null(strstr(out, "/texcache/embedded-"));
  size_t n2;
  uint8_t *copy = slurp(out, &n2);
  assert_int_equal(n2, n);
  assert_memory_equal(copy, bytes, n); /* written as it is */
  free(copy);
  cv_image *t;
  assert_int_equal(cv_texture_load(out, &t, &err), CV_OK);
  assert_true(t->w == 2);
  assert_true(t->h == 2);
  assert_near(t->px[0], 1, 1e-6);
  assert_true(t->px[1] == 0);
  cv_image_destroy(t);
  assert_int_equal(cv_texture_embedded_file(&sc, "*0", out2, sizeof out2, &err), 1);
  assert_string_equal(out, out2); /* the same texture, the same file */
  /* by name (the model's path, or just the file name) */
  assert_int_equal(cv_texture_embedded_file(&sc, "skin.png", out, sizeof out, &err), 1);
  assert_int_equal(cv_texture_embedded_file(&sc, "*1", out2, sizeof out2, &err), 1);
  assert_string_equal(out, out2);
  assert_int_equal(cv_texture_load(out, &t, &err), CV_OK);
  assert_true(t->w == 2 && t->h == 1);
  assert_near(t->px[0], lin(30 / 255.0), 1e-6);
  assert_near(t->px[5], lin(40 / 255.0), 1e-6);
  cv_image_destroy(t);
  /* not embedded; a bad index */
  assert_int_equal(cv_texture_embedded_file(&sc, "other.png", out, sizeof out, &err), 0);
  assert_int_equal(cv_texture_embedded_file(&sc, "*7", out, sizeof out, &err), -1);
  printf("*7: %s\n", err.msg);
  assert_non_null(strstr(err.msg, "2 embedded textures"));
  /* bytes that are neither PNG nor JPEG */
  uint8_t junk[16] = "DDS junk bytes.";
  comp.mWidth = sizeof junk;
  comp.pcData = (struct aiTexel *)junk;
  memcpy(comp.achFormatHint, "dds", 4);
  assert_int_equal(cv_texture_embedded_file(&sc, "*0", out, sizeof out, &err), -1);
  printf("*0 (dds): %s\n", err.msg);
  assert_non_null(strstr(err.msg, "neither PNG nor JPEG"));
  free(bytes);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_jpeg_read),
      cmocka_unit_test(test_bad_files),
      cmocka_unit_test(test_match_mean),
      cmocka_unit_test(test_embedded),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
