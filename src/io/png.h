/* PNG files via libpng: 8-bit previews out (written through a temporary
 * file renamed into place) and, for tests and comparisons, any PNG in as
 * floats in [0, 1] (values as stored: not linearised). */
#ifndef CV_IO_PNG_H
#define CV_IO_PNG_H

#include <stdint.h>

#include "core/image.h"
#include "core/status.h"

/* Writes w x h pixels of `channels` interleaved 8-bit samples (1 = gray,
 * 3 = RGB, 4 = RGBA), row 0 at the top.  The file appears under path only
 * when complete.  Errors: CV_ERR_INVALID (sizes, channels, NULL), CV_ERR_IO
 * (cannot create/rename), CV_ERR_BACKEND (libpng error, message quoted). */
int cv_png_write(const char *path, int w, int h, int channels, const uint8_t *px, cv_err *err);

/* The same PNG encoded into memory: *out (malloc'd, the caller frees it)
 * holds *n bytes.  level: zlib level 0..9 (1: fast, for live views).
 * Errors: CV_ERR_INVALID, CV_ERR_NOMEM, CV_ERR_BACKEND. */
int cv_png_encode(int w, int h, int channels, const uint8_t *px, int level, uint8_t **out, size_t *n,
                  cv_err *err);

/* Reads any PNG (palette, gray, gray+alpha, RGB, RGBA; 1..16 bits) into a
 * new image with 1..4 channels of floats in [0, 1] (sample / max), *out
 * owned by the caller.  Errors: CV_ERR_IO, CV_ERR_FORMAT (not a PNG or
 * corrupt; message names the file), CV_ERR_NOMEM. */
int cv_png_read(const char *path, cv_image **out, cv_err *err);

#endif
