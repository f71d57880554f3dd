/* OpenEXR reading and writing through OpenEXR's C APIs (<openexr.h>, <ImfCRgbaFile.h>).
 *
 * Reading: a single-part scanline or tiled (level 0) image with HALF, FLOAT
 * or UINT channels and any compression is returned as 3-channel linear RGB
 * float (R, G, B; a lone Y is replicated; A and other channels are ignored;
 * a layer prefix such as "rgb.R" is accepted when there are no plain R, G,
 * B).  The data window may have any origin: the image holds exactly the data
 * window, row 0 at its top.
 *
 * DWAA/DWAB and B44/B44A: OpenEXR 3.1's Core library cannot decompress DWA
 * ("not yet implemented in C"), yet blender-data's environment maps are
 * DWAB, and its B44 is not interoperable with the C++ codec.  Those files
 * are read through OpenEXR's other C API, the C interface to its C++
 * library (<ImfCRgbaFile.h>), at half precision (what those codecs store
 * for lossy channels); a float value beyond 65504 in such a file comes
 * back as Inf and is rejected.  That library is not hardened against
 * hostile files, so it runs in a guarded child process under a time and a
 * memory limit (cv_exr_guard; src/io/exr_imf.c): a crash or hang inside it
 * becomes one line of error.  All other compressions go through
 * OpenEXRCore at full precision, in this process.
 *
 * Before any pixel is decoded the header is walked once more: an attribute
 * whose declared size is more than the file holds after it is refused, and
 * so are a channel list whose entries do not fill exactly its declared size
 * and a data window needing more pixel bytes than the file can hold under
 * its compression.
 *
 * Pixels are validated: any NaN or Inf fails the read (CV_ERR_NONFINITE,
 * naming the pixel and channel); negative values are clamped to 0 and
 * counted (cv_exr_read_ex).
 *
 * Writing: scanline RGB (c = 3), RGBA (c = 4) or Y (c = 1), half or float,
 * through a temporary file renamed into place, so a partial file never
 * remains under the final name. */
#ifndef CV_IO_EXR_H
#define CV_IO_EXR_H

#include <stdint.h>

#include "core/image.h"
#include "core/status.h"

/* Compression for cv_exr_write; values equal OpenEXR's EXR_COMPRESSION_*. */
typedef enum cv_exr_compression {
  CV_EXR_NONE = 0,
  CV_EXR_RLE = 1,
  CV_EXR_ZIPS = 2,
  CV_EXR_ZIP = 3,
  CV_EXR_PIZ = 4,
  CV_EXR_PXR24 = 5,
  CV_EXR_B44 = 6,
  CV_EXR_B44A = 7,
  CV_EXR_DWAA = 8,
  CV_EXR_DWAB = 9
} cv_exr_compression;

/* Lower-case name of a compression ("none", "zip", "dwab", ...); "?" if
 * out of range. */
const char *cv_exr_compression_name(int compression);

/* What a read found. */
typedef struct cv_exr_read_info {
  int width, height;     /* data window size = image size */
  int origin_x, origin_y; /* data window minimum (may be non-zero) */
  int compression;       /* cv_exr_compression value */
  char compression_name[8];
  char pixel_type[8];    /* type of the channels read: "half", "float", "uint" or "mixed" */
  int tiled;             /* 1 for a tiled part (level 0 read) */
  int nchannels;         /* channels in the file */
  char channels[160];    /* their names, comma-separated (truncated) */
  char used[48];         /* the channels that were read, e.g. "R,G,B" or "Y" */
  uint64_t negative_clamped; /* channel values < 0 set to 0 */
  int guarded;           /* 1 when the pixels were decoded in a guarded child */
} cv_exr_read_info;

/* How the C++ fallback (DWAA/DWAB, B44/B44A) runs. */
typedef struct cv_exr_guard {
  int in_process;   /* 1: in this process, no limits (tests, measurements) */
  double seconds;   /* wall-clock limit (0 = none); CAVE_EXR_TIMEOUT, default 120 */
  double memory_mb; /* MB the child may add to the process's address space (0 = none;
                       < 0: 1024 + twice the file's raw pixel bytes, the default);
                       CAVE_EXR_MEMORY_MB; not applied under AddressSanitizer */
  int verbose;      /* CAVE_EXR_VERBOSE=1: the library's output copied to stderr */
} cv_exr_guard;

/* The defaults above, from the environment (an unparsable value or a
 * negative number is ignored). */
void cv_exr_guard_default(cv_exr_guard *g);

/* Reads path into a new w x h x 3 float image (*out, owned by the caller;
 * cv_image_destroy).  Errors (err gets one line naming the file):
 * CV_ERR_IO (cannot open/read), CV_ERR_FORMAT (not EXR, truncated or
 * corrupt, missing R/G/B or Y; the message quotes OpenEXR's own error),
 * CV_ERR_UNSUPPORTED (multi-part, deep, subsampled channels),
 * CV_ERR_NONFINITE ("<path>: pixel (x, y) channel R is NaN"), CV_ERR_NOMEM. */
int cv_exr_read(const char *path, cv_image **out, cv_err *err);

/* As cv_exr_read; info (may be NULL) is filled on success and, as far as
 * known, on failure. */
int cv_exr_read_ex(const char *path, cv_image **out, cv_exr_read_info *info, cv_err *err);

/* As cv_exr_read_ex with the fallback run as g says (NULL: defaults).  More
 * errors from the guard: CV_ERR_RANGE (time limit hit), CV_ERR_NOMEM (memory
 * limit hit), CV_ERR_BACKEND ("crashed: signal SIGSEGV (...) in OpenEXR"). */
int cv_exr_read_with(const char *path, const cv_exr_guard *g, cv_image **out,
                     cv_exr_read_info *info, cv_err *err);

/* What a write did. */
typedef struct cv_exr_write_info {
  uint64_t half_clamped; /* |values| > 65504 clamped to the largest half */
} cv_exr_write_info;

/* Writes img (c = 1: Y, 3: RGB, 4: RGBA) as a single-part scanline EXR with
 * HALF (half != 0) or FLOAT channels and the given cv_exr_compression.
 * NaN/Inf pixels are refused (CV_ERR_NONFINITE, naming the pixel) and
 * nothing is written.  The file appears under path only when complete.
 * Errors: CV_ERR_INVALID (bad image/compression), CV_ERR_IO, CV_ERR_BACKEND
 * (OpenEXR failure, message quoted), CV_ERR_UNSUPPORTED (a compression this
 * OpenEXR build cannot encode: DWAA/DWAB with OpenEXR 3.1; B44/B44A are
 * always refused because 3.1 Core's B44 output is misread by other
 * readers).  ZIP/ZIPS chunks that do not shrink are stored raw, as the format
 * says (works around OpenEXR issue #2306, present in Debian 12's 3.1.5). */
int cv_exr_write(const char *path, const cv_image *img, int half, int compression, cv_err *err);

/* As cv_exr_write; info (may be NULL) reports values clamped to half range. */
int cv_exr_write_ex(const char *path, const cv_image *img, int half, int compression,
                    cv_exr_write_info *info, cv_err *err);

/* IEEE 754 binary16 conversions (round to nearest even), exposed for tests
 * and for modules that store half data. */
uint16_t cv_float_to_half(float f);
float cv_half_to_float(uint16_t h);

#endif
