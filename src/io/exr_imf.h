/* The EXR reader's fallback decoder (used by exr.c): OpenEXR's C++ library
 * through its C interface (<ImfCRgbaFile.h>), for the compressions Debian
 * 12's OpenEXR 3.1 Core cannot decode (DWAA/DWAB, B44/B44A).
 *
 * That library is not hardened against hostile files: libFuzzer found a
 * 471-byte file that damages its heap (tests/fuzz/exr/crash-c6cbe3...).
 * So by default the decode runs in a guarded child process
 * (child_guard.h) under a time and a memory limit; the child writes the
 * pixels into memory shared with the parent (cv_exr_rgba_alloc) and a short
 * reply through the pipe, and a crash, a hang or runaway allocation in the
 * library becomes one line of error.  Limits from the environment
 * (cv_exr_guard_default, docs/fuzzing.md):
 *   CAVE_EXR_TIMEOUT    wall-clock seconds (default 120; 0 = none)
 *   CAVE_EXR_MEMORY_MB  MB the child may add to the process's address space
 *                       (default 1024 + twice the file's raw pixel bytes;
 *                       0 = none; not applied under AddressSanitizer)
 *   CAVE_EXR_VERBOSE    1: copy what the library printed to stderr */
#ifndef CV_IO_EXR_IMF_H
#define CV_IO_EXR_IMF_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"
#include "io/exr.h"

#define CV_EXR_DEFAULT_SECONDS 120.0
#define CV_EXR_BASE_MEMORY_MB 1024.0

/* The data window to decode: origin and size in pixels. */
typedef struct cv_exr_window {
  int min_x, min_y, w, h;
} cv_exr_window;

/* w x h pixels of 4 halves (R, G, B, A: ImfRgba's layout), row 0 at the
 * window's top, in memory a child can write (MAP_SHARED); NULL when out of
 * memory.  Free with cv_exr_rgba_free and the same size. */
uint16_t *cv_exr_rgba_alloc(size_t w, size_t h);
void cv_exr_rgba_free(uint16_t *px, size_t w, size_t h);

/* Decodes path's window into px (from cv_exr_rgba_alloc) with OpenEXR's
 * C++ library: in a guarded child unless g->in_process (g NULL: defaults
 * from the environment).  raw_bytes, the file's raw pixel bytes (all
 * channels), sets the default memory limit.  Errors, one line naming path:
 * CV_ERR_FORMAT (the library refused the file; its message quoted, or no
 * R, G, B or Y channel), CV_ERR_RANGE (time limit), CV_ERR_NOMEM (memory
 * limit), CV_ERR_BACKEND (the library crashed: signal named), CV_ERR_IO (no
 * child could be started). */
int cv_exr_imf_decode(const char *path, const cv_exr_window *win, double raw_bytes, uint16_t *px,
                      const cv_exr_guard *g, cv_err *err);

#endif
