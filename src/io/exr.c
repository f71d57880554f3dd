/* OpenEXR reading/writing via the OpenEXR C APIs (see exr.h).
 *
 * OpenEXRCore (<openexr.h>) reads and writes NONE, RLE, ZIPS, ZIP, PIZ and
 * PXR24.  OpenEXR 3.1's core does not implement DWAA/DWAB ("not yet
 * implemented in C"), and its B44/B44A disagrees with the reference C++
 * codec, so files with those compressions - blender-data's maps are DWAB -
 * are read through the same package's C interface to its C++ library
 * (<ImfCRgbaFile.h>): RGBA at half precision, which is what those codecs
 * store for lossy channels.  A float value beyond the half range (65504) in
 * such a file becomes Inf and is rejected like any non-finite pixel.  That
 * library is not hardened against hostile files, so it runs in a guarded
 * child process (exr_imf.c, child_guard.c).
 *
 * Layout of this file:
 *   1. half <-> float
 *   2. file streams and error capture (the library must never print)
 *   4. reader (3. the guarded ImfCRgbaFile path for DWA and B44)
 *   5. writer */
#include "io/exr.h"

#include "core/outfile.h"
#include "io/exr_imf.h"
#include "io/json_keys.h"

#include <endian.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <openexr.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

/* ------------------------------------------------------------------------ */
/* 1. half <-> float                                                        */
/* ------------------------------------------------------------------------ */

uint16_t cv_float_to_half(float f) {
  uint32_t x;
  memcpy(&x, &f, sizeof x);
  uint32_t sign = (x >> 16) & 0x8000u;
  uint32_t ax = x & 0x7fffffffu;
  if (ax >= 0x7f800000u) /* Inf stays Inf, NaN stays a quiet NaN */
    return (uint16_t)(sign | 0x7c00u | (ax > 0x7f800000u ? 0x200u : 0u));
  if (ax >= 0x477ff000u) return (uint16_t)(sign | 0x7c00u); /* >= 65520 rounds to Inf */
  if (ax < 0x38800000u) {                                   /* below 2^-14: subnormal */
    if (ax <= 0x33000000u) return (uint16_t)sign;           /* <= 2^-25 rounds to 0 */
    uint32_t m = (ax & 0x7fffffu) | 0x800000u;
    int shift = 126 - (int)(ax >> 23);
    uint32_t hm = m >> shift;
    uint32_t rem = m & ((1u << shift) - 1u), halfway = 1u << (shift - 1);
    if (rem > halfway || (rem == halfway && (hm & 1u))) hm++;
    return (uint16_t)(sign | hm);
  }
  uint32_t h = (ax - 0x38000000u) >> 13; /* rebias exponent 127 -> 15 */
  uint32_t rem = ax & 0x1fffu;
  if (rem > 0x1000u || (rem == 0x1000u && (h & 1u))) h++;
  return (uint16_t)(sign | h);
}

float cv_half_to_float(uint16_t h) {
  uint32_t s = (uint32_t)(h & 0x8000u) << 16;
  uint32_t e = (h >> 10) & 0x1fu, m = h & 0x3ffu, bits;
  if (e == 0) {
    if (m == 0) {
      bits = s;
    } else { /* subnormal: normalise */
      e = 113;
      while (!(m & 0x400u)) {
        m <<= 1;
        e--;
      }
      bits = s | (e << 23) | ((m & 0x3ffu) << 13);
    }
  } else if (e == 31) {
    bits = s | 0x7f800000u | (m << 13);
  } else {
    bits = s | ((e + 112u) << 23) | (m << 13);
  }
  float f;
  memcpy(&f, &bits, sizeof f);
  return f;
}


/* ------------------------------------------------------------------------ */
/* 2. streams and error capture                                             */
/* ------------------------------------------------------------------------ */

/* Our own file stream so that user_data is ours: the error handler finds
 * the message buffer through it instead of letting the library print. */
typedef struct exr_stream {
  int fd;
  int64_t size;
  int have_msg;
  char msg[300];
} exr_stream;

/* The stream of the write in progress on this thread.  A write context
 * holds its (non-recursive) lock while it calls the write function, and
 * exr_get_user_data takes that lock again: a write error reported from
 * inside exr_write_header (a full disk) hung every writer for ever.  So the
 * handler of a write finds its stream here, never through the context. */
static _Thread_local exr_stream *tl_write_stream;

static void on_exr_error(exr_const_context_t ctxt, exr_result_t code, const char *msg) {
  void *ud = tl_write_stream;
  if (!ud && (exr_get_user_data(ctxt, &ud) != EXR_ERR_SUCCESS || !ud)) return; /* read: no lock */
  exr_stream *s = ud;
  if (s->have_msg) return; /* keep the first, most specific, message */
  s->have_msg = 1;
  snprintf(s->msg, sizeof s->msg, "%s (%s)", msg ? msg : exr_get_default_error_message(code),
           exr_get_error_code_as_string(code));
}

static int64_t stream_read(exr_const_context_t ctxt, void *ud, void *buf, uint64_t sz,
                           uint64_t off, exr_stream_error_func_ptr_t error_cb) {
  exr_stream *s = ud;
  uint8_t *p = buf;
  uint64_t got = 0;
  while (got < sz) {
    ssize_t r = pread(s->fd, p + got, (size_t)(sz - got), (off_t)(off + got));
    if (r < 0) {
      if (errno == EINTR) continue;
      if (error_cb) error_cb(ctxt, EXR_ERR_READ_IO, "read failed: %s", strerror(errno));
      return -1;
    }
    if (r == 0) break; /* end of file: short read, the library reports it */
    got += (uint64_t)r;
  }
  return (int64_t)got;
}

static int64_t stream_size(exr_const_context_t ctxt, void *ud) {
  (void)ctxt;
  return ((exr_stream *)ud)->size;
}

static int64_t stream_write(exr_const_context_t ctxt, void *ud, const void *buf, uint64_t sz,
                            uint64_t off, exr_stream_error_func_ptr_t error_cb) {
  exr_stream *s = ud;
  const uint8_t *p = buf;
  uint64_t put = 0;
  while (put < sz) {
    ssize_t r = pwrite(s->fd, p + put, (size_t)(sz - put), (off_t)(off + put));
    if (r < 0) {
      if (errno == EINTR) continue;
      if (error_cb) error_cb(ctxt, EXR_ERR_WRITE_IO, "write failed: %s", strerror(errno));
      return -1;
    }
    put += (uint64_t)r;
  }
  return (int64_t)put;
}

/* Message for a failed library call: the captured text or the code's. */
static const char *exr_msg(const exr_stream *s, exr_result_t rv) {
  return s->have_msg ? s->msg : exr_get_default_error_message(rv);
}

const char *cv_exr_compression_name(int c) {
  static const char *names[] = {"none", "rle",  "zips", "zip",  "piz",
                                "pxr24", "b44", "b44a", "dwaa", "dwab"};
  return (c >= 0 && c <= 9) ? names[c] : "?";
}

/* The most raw bytes one byte of a chunk's payload can stand for under a
 * compression: deflate's 1032:1 (ZIP, ZIPS, PXR24's zip of 24-bit values),
 * RLE's 128 bytes from 2, B44's 32 bytes from 14 and B44A's from 3; PIZ's
 * Huffman run codes and DWA's DCT + deflate are bounded generously.  A
 * data window needing more than the file can hold is refused before any
 * allocation (fuzzing found a 669-byte file asking for 2.4 GB). */
static double max_expansion(int comp) {
  switch (comp) {
  case EXR_COMPRESSION_NONE: return 1.0;
  case EXR_COMPRESSION_RLE: return 64.0;
  case EXR_COMPRESSION_ZIPS:
  case EXR_COMPRESSION_ZIP: return 1040.0;
  case EXR_COMPRESSION_PXR24: return 1400.0;
  case EXR_COMPRESSION_B44: return 32.0 / 14.0 + 1.0;
  case EXR_COMPRESSION_B44A: return 32.0 / 3.0 + 1.0;
  case EXR_COMPRESSION_PIZ: return 8192.0;
  default: return 65536.0; /* DWAA, DWAB and anything newer */
  }
}

/* Bytes of the raw pixels of a w x h window: all channels, half 2 bytes,
 * float and uint 4. */
static double raw_pixel_bytes(const exr_attr_chlist_t *cl, int64_t w, int64_t h) {
  double bpp = 0;
  for (int c = 0; c < cl->num_channels; ++c)
    bpp += cl->entries[c].pixel_type == EXR_PIXEL_HALF ? 2.0 : 4.0;
  return (double)w * (double)h * bpp;
}

static int check_size_against_file(const char *path, int64_t file_size, int comp, double raw,
                                   int64_t w, int64_t h, cv_err *err) {
  const double room = (double)file_size * max_expansion(comp);
  if (raw > room)
    return cv_err_set(err, CV_ERR_FORMAT,
                      "%s: data window %lld x %lld (%.0f bytes of pixels) cannot be held by a file "
                      "of %lld bytes under %s compression (at most %.0f bytes)",
                      path, (long long)w, (long long)h, raw, (long long)file_size,
                      cv_exr_compression_name(comp), room);
  return CV_OK;
}

/* Reads a NUL-terminated string of at most n - 1 bytes at *off; 0 and
 * *off past it, or -1 when the file ends first or it is longer. */
static int read_cstring(int fd, int64_t size, int64_t *off, char *s, size_t n) {
  ssize_t got = *off < size ? pread(fd, s, n, (off_t)*off) : 0;
  if (got <= 0) return -1;
  void *nul = memchr(s, '\0', (size_t)got);
  if (!nul) return -1;
  *off += (char *)nul - s + 1;
  return 0;
}

/* Bytes a channel list at off takes when read the way OpenEXR's C++
 * library reads it - entries (name, NUL, 16 bytes) up to an empty name,
 * whatever the declared size - or -1 when the file ends first. */
static int64_t chlist_extent(int fd, int64_t size, int64_t off) {
  const int64_t start = off;
  char name[257];
  for (;;) {
    if (read_cstring(fd, size, &off, name, sizeof name)) return -1;
    if (!name[0]) return off - start;
    off += 16; /* pixel type, pLinear and reserved, x and y sampling */
    if (off > size) return -1;
  }
}

/* Walks the (first) header's attributes - name, type, 4-byte size, value -
 * and refuses one whose declared size is more than the file holds after it,
 * before OpenEXR's C++ library would try to read it (libFuzzer found a
 * 471-byte file declaring a 1.9 GB attribute that damages that library's
 * heap).  OpenEXR's Core has parsed the header already, so running off
 * the file here is refused too. */
static int check_attribute_sizes(const char *path, int fd, int64_t size, cv_err *err) {
  int64_t off = 8; /* magic and version */
  char name[257], type[257];
  for (int k = 0; k < 100000; ++k) {
    if (read_cstring(fd, size, &off, name, sizeof name))
      return cv_err_set(err, CV_ERR_FORMAT, "%s: header ends inside attribute %d", path, k + 1);
    if (!name[0]) return CV_OK; /* end of the header */
    int32_t decl = 0;
    char shown[64];
    if (read_cstring(fd, size, &off, type, sizeof type) || off + 4 > size ||
        pread(fd, &decl, 4, (off_t)off) != 4)
      return cv_err_set(err, CV_ERR_FORMAT, "%s: header ends inside attribute '%s'", path,
                        cv_json_key_show(name, shown, sizeof shown));
    decl = (int32_t)le32toh((uint32_t)decl);
    off += 4;
    if (decl < 0 || decl > size - off) {
      char tshown[64];
      return cv_err_set(err, CV_ERR_FORMAT,
                        "%s: header attribute '%s' (type '%s') declares %ld bytes, the file has %lld "
                        "after it",
                        path, cv_json_key_show(name, shown, sizeof shown),
                        cv_json_key_show(type, tshown, sizeof tshown), (long)decl,
                        (long long)(size - off));
    }
    if (strcmp(type, "chlist") == 0) {
      /* the Core skips the declared size, the C++ library reads to the
       * list's end: where they differ, the two see different headers */
      int64_t ext = chlist_extent(fd, size, off);
      if (ext != decl)
        return cv_err_set(err, CV_ERR_FORMAT,
                          "%s: header attribute '%s' (chlist) declares %ld bytes, its channel list "
                          "takes %lld",
                          path, cv_json_key_show(name, shown, sizeof shown), (long)decl,
                          (long long)ext);
    }
    off += decl;
  }
  return cv_err_set(err, CV_ERR_FORMAT, "%s: header has more than 100000 attributes", path);
}

static const char *pixel_type_name(int t) {
  return t == EXR_PIXEL_HALF ? "half" : t == EXR_PIXEL_FLOAT ? "float" : t == EXR_PIXEL_UINT ? "uint" : "?";
}

/* ------------------------------------------------------------------------ */
/* 4. reader                                                                */
/* ------------------------------------------------------------------------ */

/* Part of a channel name after the last '.' (the layer prefix removed). */
static const char *chan_suffix(const char *name) {
  const char *s = strrchr(name, '.');
  return s ? s + 1 : name;
}

/* Picks the channels to read: plain R,G,B; else plain Y; else the first
 * "<layer>.R/.G/.B" triple; else "<layer>.Y".  idx[] gets chlist indices
 * (idx[1..2] = -1 for Y).  Returns the number found (3 or 1) or 0. */
static int pick_channels(const exr_attr_chlist_t *cl, int idx[3]) {
  const char *want[3] = {"R", "G", "B"};
  int n = cl->num_channels;
  int found = 1;
  for (int k = 0; k < 3; ++k) {
    idx[k] = -1;
    for (int c = 0; c < n; ++c)
      if (strcmp(cl->entries[c].name.str, want[k]) == 0) idx[k] = c;
    if (idx[k] < 0) found = 0;
  }
  if (found) return 3;
  for (int c = 0; c < n; ++c)
    if (strcmp(cl->entries[c].name.str, "Y") == 0) {
      idx[0] = c;
      idx[1] = idx[2] = -1;
      return 1;
    }
  for (int c = 0; c < n; ++c) { /* layered R,G,B */
    const char *nm = cl->entries[c].name.str, *suf = chan_suffix(nm);
    if (suf == nm || strcmp(suf, "R") != 0) continue;
    size_t plen = (size_t)(suf - nm);
    int gi = -1, bi = -1;
    for (int c2 = 0; c2 < n; ++c2) {
      const char *n2 = cl->entries[c2].name.str;
      if (strncmp(n2, nm, plen) != 0) continue;
      if (strcmp(n2 + plen, "G") == 0) gi = c2;
      if (strcmp(n2 + plen, "B") == 0) bi = c2;
    }
    if (gi >= 0 && bi >= 0) {
      idx[0] = c;
      idx[1] = gi;
      idx[2] = bi;
      return 3;
    }
  }
  for (int c = 0; c < n; ++c) {
    const char *nm = cl->entries[c].name.str, *suf = chan_suffix(nm);
    if (suf != nm && strcmp(suf, "Y") == 0) {
      idx[0] = c;
      idx[1] = idx[2] = -1;
      return 1;
    }
  }
  return 0;
}

/* State of one read. */
typedef struct exr_reader {
  const char *path;
  exr_context_t ctxt;
  exr_stream stream;
  const exr_attr_chlist_t *cl;
  exr_attr_box2i_t dw;
  int width, height, compression, nsel;
  int sel[3];            /* chlist index of output channel k */
  uint8_t *plane[3];     /* per output channel: chunk values, native type, planar */
  size_t plane_cap[3];
  cv_image *img;
  cv_exr_read_info *info;
} exr_reader;

static int reader_grow(uint8_t **buf, size_t *cap, size_t need) {
  if (need <= *cap) return 0;
  uint8_t *p = realloc(*buf, need);
  if (!p) return -1;
  *buf = p;
  *cap = need;
  return 0;
}

/* Decodes one chunk into r->plane[k] (values of output channel k for the
 * chunk's cw x ch pixels, in the file's pixel type, native byte order). */
static int read_chunk_planes(exr_reader *r, const exr_chunk_info_t *ci, cv_err *err) {
  int cw = ci->width, chh = ci->height;
  size_t npx = (size_t)cw * (size_t)chh;
  {
    for (int k = 0; k < r->nsel; ++k)
      if (reader_grow(&r->plane[k], &r->plane_cap[k], npx * 4)) return CV_ERR_NOMEM;
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    exr_result_t rv = exr_decoding_initialize(r->ctxt, 0, ci, &dec);
    if (rv == EXR_ERR_SUCCESS) {
      for (int c = 0; c < dec.channel_count; ++c) {
        exr_coding_channel_info_t *cc = &dec.channels[c];
        cc->decode_to_ptr = NULL;
        for (int k = 0; k < r->nsel; ++k) {
          if (strcmp(cc->channel_name, r->cl->entries[r->sel[k]].name.str) != 0) continue;
          /* same type as the file: the library only decompresses and
           * de-interleaves; conversion is ours */
          cc->decode_to_ptr = r->plane[k];
          cc->user_data_type = cc->data_type;
          cc->user_bytes_per_element = cc->bytes_per_element;
          cc->user_pixel_stride = cc->bytes_per_element;
          cc->user_line_stride = cw * cc->bytes_per_element;
        }
      }
      rv = exr_decoding_choose_default_routines(r->ctxt, 0, &dec);
    }
    if (rv == EXR_ERR_SUCCESS) rv = exr_decoding_run(r->ctxt, 0, &dec);
    exr_decoding_destroy(r->ctxt, &dec);
    if (rv != EXR_ERR_SUCCESS)
      return cv_err_set(err, CV_ERR_FORMAT, "%s: cannot decode pixel block at y=%d: %s", r->path,
                        ci->start_y, exr_msg(&r->stream, rv));
    return CV_OK;
  }
}

/* Converts the planes of a chunk at pixel (x0, y0) of the data window
 * (relative to its origin) into the image; checks finiteness, clamps and
 * counts negatives. */
static int store_chunk(exr_reader *r, int x0, int y0, int cw, int chh, cv_err *err) {
  static const char *cname3[3] = {"R", "G", "B"};
  for (int k = 0; k < r->nsel; ++k) {
    int type = r->cl->entries[r->sel[k]].pixel_type;
    const uint8_t *pl = r->plane[k];
    for (int y = 0; y < chh; ++y) {
      for (int x = 0; x < cw; ++x) {
        size_t i = (size_t)y * (size_t)cw + (size_t)x;
        float v;
        if (type == EXR_PIXEL_HALF) {
          uint16_t h;
          memcpy(&h, pl + 2 * i, 2);
          v = cv_half_to_float(h);
        } else if (type == EXR_PIXEL_FLOAT) {
          memcpy(&v, pl + 4 * i, 4);
        } else {
          uint32_t u;
          memcpy(&u, pl + 4 * i, 4);
          v = (float)u;
        }
        int px = x0 + x, py = y0 + y;
        if (!isfinite(v)) {
          const char *nm = r->nsel == 3 ? cname3[k] : "Y";
          return cv_err_set(err, CV_ERR_NONFINITE, "%s: pixel (%d, %d) channel %s is %s", r->path,
                            px, py, nm, isnan(v) ? "NaN" : (v > 0 ? "+Inf" : "-Inf"));
        }
        if (v < 0.0f) {
          v = 0.0f;
          r->info->negative_clamped++;
        }
        float *dst = cv_image_at(r->img, px, py);
        if (r->nsel == 3)
          dst[k] = v;
        else
          dst[0] = dst[1] = dst[2] = v;
      }
    }
  }
  return CV_OK;
}

/* 3. DWAA/DWAB/B44/B44A through the C interface of OpenEXR's C++ library,
 * in a guarded child (exr_imf.c) unless g says otherwise.  Same checks as
 * store_chunk: non-finite pixels rejected with their position, negatives
 * clamped and counted.  Grey (Y-only) files come back with R = G = B. */
static int read_via_imf(exr_reader *r, const cv_exr_guard *g, double raw_bytes, cv_err *err) {
  const size_t w = (size_t)r->width, h = (size_t)r->height;
  uint16_t *buf = cv_exr_rgba_alloc(w, h);
  if (!buf) return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory for %zu x %zu pixels", r->path, w, h);
  const cv_exr_window win = {r->dw.min.x, r->dw.min.y, r->width, r->height};
  int rc = cv_exr_imf_decode(r->path, &win, raw_bytes, buf, g, err);
  r->info->guarded = !g->in_process;
  if (rc != CV_OK) {
    cv_exr_rgba_free(buf, w, h);
    return rc;
  }
  static const char *cname[3] = {"R", "G", "B"};
  for (size_t y = 0; y < h; y++)
    for (size_t x = 0; x < w; x++) {
      const uint16_t *p = &buf[4 * (y * w + x)];
      float v[3] = {cv_half_to_float(p[0]), cv_half_to_float(p[1]), cv_half_to_float(p[2])};
      float *dst = cv_image_at(r->img, (int)x, (int)y);
      for (int k = 0; k < 3; k++) {
        if (!isfinite(v[k])) {
          rc = cv_err_set(err, CV_ERR_NONFINITE, "%s: pixel (%zu, %zu) channel %s is %s", r->path, x, y,
                          cname[k], isnan(v[k]) ? "NaN" : (v[k] > 0 ? "+Inf" : "-Inf"));
          cv_exr_rgba_free(buf, w, h);
          return rc;
        }
        if (v[k] < 0.0f) {
          v[k] = 0.0f;
          r->info->negative_clamped++;
        }
        dst[k] = v[k];
      }
    }
  cv_exr_rgba_free(buf, w, h);
  return CV_OK;
}

static int read_pixels(exr_reader *r, exr_storage_t storage, cv_err *err) {
  int rc;
  if (storage == EXR_STORAGE_SCANLINE) {
    int32_t lines = 0;
    exr_result_t rv = exr_get_scanlines_per_chunk(r->ctxt, 0, &lines);
    if (rv != EXR_ERR_SUCCESS || lines <= 0)
      return cv_err_set(err, CV_ERR_FORMAT, "%s: %s", r->path, exr_msg(&r->stream, rv));
    for (int64_t y = r->dw.min.y; y <= r->dw.max.y; y += lines) {
      exr_chunk_info_t ci;
      rv = exr_read_scanline_chunk_info(r->ctxt, 0, (int)y, &ci);
      if (rv != EXR_ERR_SUCCESS)
        return cv_err_set(err, CV_ERR_FORMAT, "%s: pixel block at y=%d: %s", r->path, (int)y,
                          exr_msg(&r->stream, rv));
      if (ci.width != r->width || ci.height <= 0 || ci.start_y < r->dw.min.y ||
          (int64_t)ci.start_y + ci.height - 1 > r->dw.max.y)
        return cv_err_set(err, CV_ERR_FORMAT, "%s: pixel block at y=%d has a bad extent", r->path,
                          (int)y);
      if ((rc = read_chunk_planes(r, &ci, err)) != CV_OK) return rc;
      if ((rc = store_chunk(r, 0, ci.start_y - r->dw.min.y, ci.width, ci.height, err)) != CV_OK)
        return rc;
    }
    return CV_OK;
  }
  /* tiled: level (0, 0) only */
  uint32_t tw = 0, th = 0;
  exr_tile_level_mode_t lm;
  exr_tile_round_mode_t rm;
  exr_result_t rv = exr_get_tile_descriptor(r->ctxt, 0, &tw, &th, &lm, &rm);
  if (rv != EXR_ERR_SUCCESS || tw == 0 || th == 0)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: tile description: %s", r->path, exr_msg(&r->stream, rv));
  int ntx = (int)(((uint32_t)r->width + tw - 1) / tw), nty = (int)(((uint32_t)r->height + th - 1) / th);
  for (int ty = 0; ty < nty; ++ty) {
    for (int tx = 0; tx < ntx; ++tx) {
      exr_chunk_info_t ci;
      rv = exr_read_tile_chunk_info(r->ctxt, 0, tx, ty, 0, 0, &ci);
      if (rv != EXR_ERR_SUCCESS)
        return cv_err_set(err, CV_ERR_FORMAT, "%s: tile (%d, %d): %s", r->path, tx, ty,
                          exr_msg(&r->stream, rv));
      int x0 = tx * (int)tw, y0 = ty * (int)th;
      if (ci.width <= 0 || ci.height <= 0 || x0 + ci.width > r->width || y0 + ci.height > r->height)
        return cv_err_set(err, CV_ERR_FORMAT, "%s: tile (%d, %d) has a bad extent", r->path, tx, ty);
      if ((rc = read_chunk_planes(r, &ci, err)) != CV_OK) return rc;
      if ((rc = store_chunk(r, x0, y0, ci.width, ci.height, err)) != CV_OK) return rc;
    }
  }
  return CV_OK;
}

int cv_exr_read_ex(const char *path, cv_image **out, cv_exr_read_info *info, cv_err *err) {
  return cv_exr_read_with(path, NULL, out, info, err);
}

int cv_exr_read_with(const char *path, const cv_exr_guard *g, cv_image **out,
                     cv_exr_read_info *info, cv_err *err) {
  cv_exr_read_info dummy;
  cv_exr_guard gdef;
  if (!g) {
    cv_exr_guard_default(&gdef);
    g = &gdef;
  }
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "cv_exr_read: out is NULL");
  *out = NULL;
  if (!info) info = &dummy;
  memset(info, 0, sizeof *info);
  if (!path) return cv_err_set(err, CV_ERR_INVALID, "cv_exr_read: path is NULL");

  exr_reader r;
  memset(&r, 0, sizeof r);
  r.path = path;
  r.info = info;
  r.stream.fd = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK); /* a FIFO must not block the open */
  if (r.stream.fd < 0)
    return cv_err_set(err, CV_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
  struct stat sb;
  if (fstat(r.stream.fd, &sb) != 0 || !S_ISREG(sb.st_mode)) {
    close(r.stream.fd);
    return cv_err_set(err, CV_ERR_IO, "%s: not a regular file", path);
  }
  r.stream.size = (int64_t)sb.st_size;

  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  init.error_handler_fn = on_exr_error;
  init.user_data = &r.stream;
  init.read_fn = stream_read;
  init.size_fn = stream_size;
  init.flags = 0; /* not SILENT_HEADER_PARSE: on_exr_error keeps the detail (which attribute) */
  int rc = CV_OK;
  exr_result_t rv = exr_start_read(&r.ctxt, path, &init);
  if (rv != EXR_ERR_SUCCESS) {
    rc = cv_err_set(err, rv == EXR_ERR_OUT_OF_MEMORY ? CV_ERR_NOMEM : CV_ERR_FORMAT,
                    "%s: not a readable OpenEXR file: %s", path, exr_msg(&r.stream, rv));
    goto done;
  }
  int nparts = 0;
  exr_storage_t storage = EXR_STORAGE_LAST_TYPE;
  exr_compression_t comp = EXR_COMPRESSION_NONE;
  if ((rv = exr_get_count(r.ctxt, &nparts)) != EXR_ERR_SUCCESS ||
      (rv = exr_get_storage(r.ctxt, 0, &storage)) != EXR_ERR_SUCCESS ||
      (rv = exr_get_data_window(r.ctxt, 0, &r.dw)) != EXR_ERR_SUCCESS ||
      (rv = exr_get_compression(r.ctxt, 0, &comp)) != EXR_ERR_SUCCESS ||
      (rv = exr_get_channels(r.ctxt, 0, &r.cl)) != EXR_ERR_SUCCESS) {
    rc = cv_err_set(err, CV_ERR_FORMAT, "%s: bad header: %s", path, exr_msg(&r.stream, rv));
    goto done;
  }
  int64_t w = (int64_t)r.dw.max.x - r.dw.min.x + 1, h = (int64_t)r.dw.max.y - r.dw.min.y + 1;
  info->origin_x = r.dw.min.x;
  info->origin_y = r.dw.min.y;
  info->compression = (int)comp;
  snprintf(info->compression_name, sizeof info->compression_name, "%s",
           cv_exr_compression_name((int)comp));
  info->tiled = storage == EXR_STORAGE_TILED;
  info->nchannels = r.cl->num_channels;
  for (int c = 0; c < r.cl->num_channels; ++c) {
    size_t l = strlen(info->channels);
    snprintf(info->channels + l, sizeof info->channels - l, "%s%s", c ? "," : "",
             r.cl->entries[c].name.str);
  }
  if (nparts != 1) {
    rc = cv_err_set(err, CV_ERR_UNSUPPORTED, "%s: %d parts; only single-part files are read", path, nparts);
    goto done;
  }
  if (storage != EXR_STORAGE_SCANLINE && storage != EXR_STORAGE_TILED) {
    rc = cv_err_set(err, CV_ERR_UNSUPPORTED, "%s: deep images are not supported", path);
    goto done;
  }
  if (w <= 0 || h <= 0 || w * h > ((int64_t)1 << 28)) {
    rc = cv_err_set(err, CV_ERR_FORMAT, "%s: unreasonable data window %lld x %lld", path,
                    (long long)w, (long long)h);
    goto done;
  }
  const double raw = raw_pixel_bytes(r.cl, w, h);
  if ((rc = check_size_against_file(path, r.stream.size, (int)comp, raw, w, h, err)) != CV_OK) goto done;
  if ((rc = check_attribute_sizes(path, r.stream.fd, r.stream.size, err)) != CV_OK) goto done;
  r.width = (int)w;
  r.height = (int)h;
  info->width = r.width;
  info->height = r.height;
  r.compression = (int)comp;
  r.nsel = pick_channels(r.cl, r.sel);
  if (r.nsel == 0) {
    rc = cv_err_set(err, CV_ERR_FORMAT, "%s: no R,G,B or Y channels (found: %s)", path,
                    info->channels[0] ? info->channels : "none");
    goto done;
  }
  {
    int t0 = r.cl->entries[r.sel[0]].pixel_type, mixed = 0;
    for (int k = 0; k < r.nsel; ++k) {
      const exr_attr_chlist_entry_t *e = &r.cl->entries[r.sel[k]];
      if ((int)e->pixel_type != t0) mixed = 1;
      if (e->x_sampling != 1 || e->y_sampling != 1) {
        rc = cv_err_set(err, CV_ERR_UNSUPPORTED, "%s: channel %s is subsampled (%d x %d)", path,
                        e->name.str, e->x_sampling, e->y_sampling);
        goto done;
      }
      size_t l = strlen(info->used);
      snprintf(info->used + l, sizeof info->used - l, "%s%s", k ? "," : "", e->name.str);
    }
    snprintf(info->pixel_type, sizeof info->pixel_type, "%s", mixed ? "mixed" : pixel_type_name(t0));
  }
  if ((rc = cv_image_create(r.width, r.height, 3, &r.img)) != CV_OK) {
    cv_err_set(err, rc, "%s: cannot allocate %d x %d image", path, r.width, r.height);
    goto done;
  }
  if (comp == EXR_COMPRESSION_DWAA || comp == EXR_COMPRESSION_DWAB || comp == EXR_COMPRESSION_B44 ||
      comp == EXR_COMPRESSION_B44A)
    rc = read_via_imf(&r, g, raw, err); /* sets err itself, the guard's limits included */
  else if ((rc = read_pixels(&r, storage, err)) == CV_ERR_NOMEM)
    cv_err_set(err, rc, "%s: out of memory", path);

done:
  if (r.ctxt) exr_finish(&r.ctxt);
  close(r.stream.fd);
  for (int k = 0; k < 3; ++k) free(r.plane[k]);
  if (rc != CV_OK) {
    cv_image_destroy(r.img);
    return rc;
  }
  *out = r.img;
  return CV_OK;
}

int cv_exr_read(const char *path, cv_image **out, cv_err *err) {
  return cv_exr_read_with(path, NULL, out, NULL, err);
}

/* ------------------------------------------------------------------------ */
/* 5. writer                                                                */
/* ------------------------------------------------------------------------ */

static const char *write_channel_name(int nc, int k) {
  static const char *rgba[4] = {"R", "G", "B", "A"};
  return nc == 1 ? "Y" : rgba[k];
}

/* OpenEXR issue #2306 (fixed upstream by PR #2307; Debian 12 ships 3.1.5
 * without it): when zlib's output is exactly as long as the packed chunk, the
 * Core ZIP/ZIPS encoder stores the zlib bytes, and every reader, seeing equal
 * sizes, takes them as raw pixels.  The file format says a chunk that does
 * not shrink is stored raw, so after the library's compressor ran, such a
 * chunk gets the packed bytes.  The library's own routine is kept in the
 * pipeline's user data. */
typedef struct zip_guard {
  exr_result_t (*compress)(exr_encode_pipeline_t *enc);
} zip_guard;

static exr_result_t zip_guard_compress(exr_encode_pipeline_t *enc) {
  const zip_guard *g = enc->encoding_user_data;
  exr_result_t rv = g->compress(enc);
  if (rv == EXR_ERR_SUCCESS && enc->compressed_buffer && enc->packed_buffer &&
      enc->compressed_buffer != enc->packed_buffer && enc->compressed_bytes >= enc->packed_bytes) {
    memcpy(enc->compressed_buffer, enc->packed_buffer, enc->packed_bytes);
    enc->compressed_bytes = enc->packed_bytes;
  }
  return rv;
}

int cv_exr_write(const char *path, const cv_image *img, int half, int compression, cv_err *err) {
  return cv_exr_write_ex(path, img, half, compression, NULL, err);
}

int cv_exr_write_ex(const char *path, const cv_image *img, int half, int compression,
                    cv_exr_write_info *info, cv_err *err) {
  cv_exr_write_info dummy;
  if (!info) info = &dummy;
  memset(info, 0, sizeof *info);
  if (!path || !img || !img->px || img->w <= 0 || img->h <= 0)
    return cv_err_set(err, CV_ERR_INVALID, "cv_exr_write: %s: empty image or path", path ? path : "(null)");
  if (img->c != 1 && img->c != 3 && img->c != 4)
    return cv_err_set(err, CV_ERR_INVALID, "%s: %d channels; expected 1 (Y), 3 (RGB) or 4 (RGBA)", path,
                      img->c);
  if (compression < CV_EXR_NONE || compression > CV_EXR_DWAB)
    return cv_err_set(err, CV_ERR_INVALID, "%s: unknown compression %d", path, compression);
  if (compression == CV_EXR_B44 || compression == CV_EXR_B44A)
    return cv_err_set(err, CV_ERR_UNSUPPORTED,
                      "%s: B44/B44A writing disabled: OpenEXR 3.1 Core's B44 encoder is not readable by the "
                      "reference library", path);
  const int w = img->w, h = img->h, nc = img->c;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int k = 0; k < nc; ++k) {
        float v = cv_image_at(img, x, y)[k];
        if (!isfinite(v))
          return cv_err_set(err, CV_ERR_NONFINITE, "%s: pixel (%d, %d) channel %s is %s; nothing written",
                            path, x, y, write_channel_name(nc, k), isnan(v) ? "NaN" : "Inf");
      }

  cv_outfile of;
  int orc = cv_outfile_open(&of, path, 0, err);
  if (orc != CV_OK) return orc;
  const char *tmp = of.tmp;
  exr_stream s;
  memset(&s, 0, sizeof s);
  s.fd = of.fd;

  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  init.error_handler_fn = on_exr_error;
  init.user_data = &s;
  init.write_fn = stream_write;
  exr_context_t ctxt = NULL;
  int rc = CV_OK, part = 0;
  uint8_t *plane[4] = {NULL, NULL, NULL, NULL};
  const int bpe = half ? 2 : 4;
  tl_write_stream = &s; /* cleared on both ways out below */
  exr_result_t rv = exr_start_write(&ctxt, tmp, EXR_WRITE_FILE_DIRECTLY, &init);
  if (rv == EXR_ERR_SUCCESS) rv = exr_add_part(ctxt, "main", EXR_STORAGE_SCANLINE, &part);
  if (rv == EXR_ERR_SUCCESS)
    rv = exr_initialize_required_attr_simple(ctxt, part, w, h, (exr_compression_t)compression);
  for (int k = 0; k < nc && rv == EXR_ERR_SUCCESS; ++k)
    rv = exr_add_channel(ctxt, part, write_channel_name(nc, k), half ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT,
                         (nc == 4 && k == 3) ? EXR_PERCEPTUALLY_LINEAR : EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
  if (rv == EXR_ERR_SUCCESS) rv = exr_write_header(ctxt);
  int32_t lines = 0;
  if (rv == EXR_ERR_SUCCESS) rv = exr_get_scanlines_per_chunk(ctxt, part, &lines);
  if (rv != EXR_ERR_SUCCESS || lines <= 0) {
    rc = cv_err_set(err, CV_ERR_BACKEND, "%s: cannot set up EXR header: %s", path, exr_msg(&s, rv));
    goto fail;
  }
  for (int k = 0; k < nc; ++k) {
    plane[k] = malloc((size_t)lines * (size_t)w * (size_t)bpe);
    if (!plane[k]) {
      rc = cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
      goto fail;
    }
  }
  for (int y0 = 0; y0 < h; y0 += lines) {
    exr_chunk_info_t ci;
    rv = exr_write_scanline_chunk_info(ctxt, part, y0, &ci);
    if (rv != EXR_ERR_SUCCESS) {
      rc = cv_err_set(err, CV_ERR_BACKEND, "%s: pixel block at y=%d: %s", path, y0, exr_msg(&s, rv));
      goto fail;
    }
    for (int y = 0; y < ci.height; ++y)
      for (int x = 0; x < w; ++x) {
        const float *src = cv_image_at(img, x, y0 + y);
        for (int k = 0; k < nc; ++k) {
          size_t i = (size_t)y * (size_t)w + (size_t)x;
          float v = src[k];
          if (half) {
            if (fabsf(v) > 65504.0f) {
              v = v > 0 ? 65504.0f : -65504.0f;
              info->half_clamped++;
            }
            uint16_t hv = cv_float_to_half(v);
            memcpy(plane[k] + 2 * i, &hv, 2);
          } else {
            memcpy(plane[k] + 4 * i, &v, 4);
          }
        }
      }
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    rv = exr_encoding_initialize(ctxt, part, &ci, &enc);
    if (rv == EXR_ERR_SUCCESS) {
      for (int c = 0; c < enc.channel_count; ++c) {
        exr_coding_channel_info_t *cc = &enc.channels[c];
        for (int k = 0; k < nc; ++k) {
          if (strcmp(cc->channel_name, write_channel_name(nc, k)) != 0) continue;
          cc->encode_from_ptr = plane[k];
          cc->user_data_type = cc->data_type;
          cc->user_bytes_per_element = (int16_t)bpe;
          cc->user_pixel_stride = bpe;
          cc->user_line_stride = w * bpe;
        }
      }
      rv = exr_encoding_choose_default_routines(ctxt, part, &enc);
    }
    zip_guard guard = {enc.compress_fn};
    if (rv == EXR_ERR_SUCCESS && enc.compress_fn &&
        (compression == CV_EXR_ZIP || compression == CV_EXR_ZIPS)) {
      enc.encoding_user_data = &guard;
      enc.compress_fn = zip_guard_compress;
    }
    if (rv == EXR_ERR_SUCCESS) rv = exr_encoding_run(ctxt, part, &enc);
    exr_encoding_destroy(ctxt, &enc);
    if (rv != EXR_ERR_SUCCESS) {
      int st = rv == EXR_ERR_FEATURE_NOT_IMPLEMENTED ? CV_ERR_UNSUPPORTED : CV_ERR_BACKEND;
      rc = cv_err_set(err, st, "%s: cannot encode %s pixel block at y=%d: %s", path,
                      cv_exr_compression_name(compression), y0, exr_msg(&s, rv));
      goto fail;
    }
  }
  rv = exr_finish(&ctxt);
  ctxt = NULL;
  tl_write_stream = NULL;
  if (rv != EXR_ERR_SUCCESS) {
    rc = cv_err_set(err, CV_ERR_BACKEND, "%s: cannot finish EXR: %s", path, exr_msg(&s, rv));
    goto fail;
  }
  for (int k = 0; k < nc; ++k) free(plane[k]);
  return cv_outfile_commit(&of, err);

fail:
  if (ctxt) exr_finish(&ctxt);
  tl_write_stream = NULL;
  cv_outfile_abort(&of);
  for (int k = 0; k < 4; ++k) free(plane[k]);
  return rc;
}
