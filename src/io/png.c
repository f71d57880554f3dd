/* PNG reading and writing with libpng (see png.h).  libpng reports errors
 * by longjmp: the handlers below copy its message into a context so the
 * caller gets one line naming the file; nothing is printed. */
#include "io/png.h"

#include "core/outfile.h"

#include <errno.h>
#include <png.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef struct png_ctx {
  jmp_buf jb;
  char msg[200];
  FILE *f;     /* writing: the file, written by on_png_write */
  int write_errno; /* the errno of a failed write (a full disk), 0 if none */
} png_ctx;

static void on_png_error(png_structp png, png_const_charp msg) {
  png_ctx *c = png_get_error_ptr(png);
  snprintf(c->msg, sizeof c->msg, "%s", msg ? msg : "libpng error");
  longjmp(c->jb, 1);
}

static void on_png_warning(png_structp png, png_const_charp msg) {
  (void)png;
  (void)msg; /* library code never prints */
}

/* libpng's own writer says only "Write Error": ours keeps errno, so that a
 * full disk is named as such. */
static void on_png_write(png_structp png, png_bytep data, size_t n) {
  png_ctx *c = png_get_io_ptr(png);
  errno = 0;
  if (fwrite(data, 1, n, c->f) != n) {
    c->write_errno = errno ? errno : EIO;
    png_error(png, "write failed");
  }
}

static void on_png_flush(png_structp png) {
  png_ctx *c = png_get_io_ptr(png);
  if (fflush(c->f) != 0) {
    c->write_errno = errno ? errno : EIO;
    png_error(png, "write failed");
  }
}

/* Writes the image to an open FILE; returns CV_OK or an error in err. */
static int png_write_file(FILE *f, const char *path, int w, int h, int channels,
                          const uint8_t *px, cv_err *err) {
  png_ctx ctx;
  ctx.msg[0] = '\0';
  ctx.f = f;
  ctx.write_errno = 0;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &ctx, on_png_error, on_png_warning);
  if (!png) return cv_err_set(err, CV_ERR_NOMEM, "%s: cannot create PNG writer", path);
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, NULL);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: cannot create PNG writer", path);
  }
  if (setjmp(ctx.jb)) {
    png_destroy_write_struct(&png, &info);
    if (ctx.write_errno)
      return cv_err_set(err, CV_ERR_IO, "%s: write failed: %s", path, strerror(ctx.write_errno));
    return cv_err_set(err, CV_ERR_BACKEND, "%s: libpng: %s", path, ctx.msg);
  }
  png_set_write_fn(png, &ctx, on_png_write, on_png_flush);
  int ct = channels == 1 ? PNG_COLOR_TYPE_GRAY : channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_RGBA;
  png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, 8, ct, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  size_t stride = (size_t)w * (size_t)channels;
  for (int y = 0; y < h; ++y) png_write_row(png, (png_const_bytep)(px + (size_t)y * stride));
  png_write_end(png, NULL);
  png_destroy_write_struct(&png, &info);
  return CV_OK;
}

int cv_png_write(const char *path, int w, int h, int channels, const uint8_t *px, cv_err *err) {
  if (!path || !px || w <= 0 || h <= 0)
    return cv_err_set(err, CV_ERR_INVALID, "cv_png_write: %s: empty image", path ? path : "(null)");
  if (channels != 1 && channels != 3 && channels != 4)
    return cv_err_set(err, CV_ERR_INVALID, "%s: %d channels; expected 1, 3 or 4", path, channels);
  cv_outfile of;
  int rc = cv_outfile_open(&of, path, 1, err);
  if (rc != CV_OK) return rc;
  rc = png_write_file(of.f, path, w, h, channels, px, err);
  if (rc != CV_OK) {
    cv_outfile_abort(&of);
    return rc;
  }
  return cv_outfile_commit(&of, err);
}

/* The encoder's output buffer for cv_png_encode (grown by doubling). */
typedef struct png_mem {
  uint8_t *buf;
  size_t n, cap;
  int oom;
} png_mem;

static void png_mem_write(png_structp png, png_bytep data, png_size_t len) {
  png_mem *m = png_get_io_ptr(png);
  if (m->oom) return;
  if (m->n + len > m->cap) {
    size_t cap = m->cap ? m->cap : 65536;
    while (cap < m->n + len) cap *= 2;
    uint8_t *nb = realloc(m->buf, cap);
    if (!nb) {
      m->oom = 1;
      return;
    }
    m->buf = nb;
    m->cap = cap;
  }
  memcpy(m->buf + m->n, data, len);
  m->n += len;
}

static void png_mem_flush(png_structp png) { (void)png; }

int cv_png_encode(int w, int h, int channels, const uint8_t *px, int level, uint8_t **out, size_t *n,
                  cv_err *err) {
  if (!out || !n || !px || w <= 0 || h <= 0 || (channels != 1 && channels != 3 && channels != 4))
    return cv_err_set(err, CV_ERR_INVALID, "cv_png_encode: empty image or %d channels", channels);
  *out = NULL;
  *n = 0;
  png_ctx ctx;
  ctx.msg[0] = '\0';
  png_mem mem = {0};
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &ctx, on_png_error, on_png_warning);
  png_infop info = png ? png_create_info_struct(png) : NULL;
  if (!png || !info) {
    png_destroy_write_struct(&png, &info);
    return cv_err_set(err, CV_ERR_NOMEM, "cv_png_encode: cannot create PNG writer");
  }
  if (setjmp(ctx.jb)) {
    png_destroy_write_struct(&png, &info);
    free(mem.buf);
    return cv_err_set(err, CV_ERR_BACKEND, "cv_png_encode: libpng: %s", ctx.msg);
  }
  png_set_write_fn(png, &mem, png_mem_write, png_mem_flush);
  png_set_compression_level(png, level < 0 ? 0 : level > 9 ? 9 : level);
  int ct = channels == 1 ? PNG_COLOR_TYPE_GRAY : channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_RGBA;
  png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, 8, ct, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  const size_t stride = (size_t)w * (size_t)channels;
  for (int y = 0; y < h; ++y) png_write_row(png, (png_const_bytep)(px + (size_t)y * stride));
  png_write_end(png, NULL);
  png_destroy_write_struct(&png, &info);
  if (mem.oom) {
    free(mem.buf);
    return cv_err_set(err, CV_ERR_NOMEM, "cv_png_encode: out of memory (%d x %d)", w, h);
  }
  *out = mem.buf;
  *n = mem.n;
  return CV_OK;
}

int cv_png_read(const char *path, cv_image **out, cv_err *err) {
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "cv_png_read: out is NULL");
  *out = NULL;
  if (!path) return cv_err_set(err, CV_ERR_INVALID, "cv_png_read: path is NULL");
  FILE *f = fopen(path, "rb");
  if (!f) return cv_err_set(err, CV_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
  unsigned char sig[8];
  if (fread(sig, 1, 8, f) != 8 || png_sig_cmp(sig, 0, 8) != 0) {
    fclose(f);
    return cv_err_set(err, CV_ERR_FORMAT, "%s: not a PNG file", path);
  }
  png_ctx ctx;
  ctx.msg[0] = '\0';
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &ctx, on_png_error, on_png_warning);
  png_infop info = png ? png_create_info_struct(png) : NULL;
  if (!png || !info) {
    png_destroy_read_struct(&png, &info, NULL);
    fclose(f);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: cannot create PNG reader", path);
  }
  /* modified between setjmp and longjmp, hence volatile */
  cv_image *volatile img = NULL;
  uint8_t *volatile row = NULL;
  png_bytep *volatile rows = NULL;
  if (setjmp(ctx.jb)) {
    png_destroy_read_struct(&png, &info, NULL);
    fclose(f);
    cv_image_destroy(img);
    free(row);
    free(rows);
    return cv_err_set(err, CV_ERR_FORMAT, "%s: corrupt PNG: %s", path, ctx.msg);
  }
  png_init_io(png, f);
  png_set_sig_bytes(png, 8);
  png_read_info(png, info);
  png_set_expand(png); /* palette -> RGB, gray < 8 bits -> 8, tRNS -> alpha */
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  png_uint_32 w = png_get_image_width(png, info), h = png_get_image_height(png, info);
  int depth = png_get_bit_depth(png, info), nc = png_get_channels(png, info);
  if (w == 0 || h == 0 || w > 65536 || h > 65536 || nc < 1 || nc > 4 || (depth != 8 && depth != 16)) {
    png_destroy_read_struct(&png, &info, NULL);
    fclose(f);
    return cv_err_set(err, CV_ERR_FORMAT, "%s: unsupported PNG (%u x %u, %d channels, %d bits)", path,
                      (unsigned)w, (unsigned)h, nc, depth);
  }
  cv_image *im = NULL;
  if (cv_image_create((int)w, (int)h, nc, &im) != CV_OK) {
    png_destroy_read_struct(&png, &info, NULL);
    fclose(f);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  }
  img = im;
  size_t rowbytes = png_get_rowbytes(png, info);
  row = malloc(rowbytes * h);
  if (!row) {
    png_destroy_read_struct(&png, &info, NULL);
    fclose(f);
    cv_image_destroy(im);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  }
  rows = malloc(h * sizeof *rows);
  if (!rows) {
    png_destroy_read_struct(&png, &info, NULL);
    fclose(f);
    cv_image_destroy(im);
    free(row);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  }
  for (png_uint_32 y = 0; y < h; ++y) rows[y] = row + (size_t)y * rowbytes;
  png_read_image(png, rows); /* on error: longjmp to the handler above */
  png_read_end(png, NULL);
  free(rows);
  rows = NULL;
  png_destroy_read_struct(&png, &info, NULL);
  fclose(f);
  size_t n = (size_t)w * h * (size_t)nc;
  for (size_t i = 0; i < n; ++i) {
    if (depth == 8)
      im->px[i] = row[i] / 255.0f;
    else
      im->px[i] = (float)((row[2 * i] << 8) | row[2 * i + 1]) / 65535.0f; /* PNG is big-endian */
  }
  free(row);
  *out = im;
  return CV_OK;
}
