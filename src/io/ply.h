/* PLY point clouds and triangle soups for debugging and comparing renders
 * (e.g. bake sample positions coloured by radiance).
 *
 * Written and read subset (PLY 1.0, ascii or binary_little_endian):
 *   element vertex N
 *     property float x / y / z
 *     property float red / green / blue   (optional together; linear
 *                                          radiance as float, not uchar)
 *   element face M                          (optional)
 *     property list uchar int vertex_indices   (triangles only)
 * Anything else is rejected by the reader with the file, line or element. */
#ifndef CV_IO_PLY_H
#define CV_IO_PLY_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"

/* Writes n points (xyz: 3n floats; rgb: 3n floats or NULL for no colour)
 * and ntris triangles (tris: 3*ntris indices < n, or NULL with ntris = 0),
 * ascii (binary == 0) or binary little-endian.  The file appears under path
 * only when complete.  Errors: CV_ERR_INVALID, CV_ERR_NONFINITE (names the
 * vertex), CV_ERR_RANGE (index >= n, names the face), CV_ERR_IO. */
int cv_ply_write_points(const char *path, size_t n, const float *xyz, const float *rgb,
                        const uint32_t *tris, size_t ntris, int binary, cv_err *err);

/* What cv_ply_read_points returns; free with cv_ply_points_destroy. */
typedef struct cv_ply_points {
  size_t n;       /* vertices */
  float *xyz;     /* 3n */
  float *rgb;     /* 3n, or NULL when the file has no colour */
  size_t ntris;   /* triangles */
  uint32_t *tris; /* 3*ntris, or NULL */
  int binary;     /* format of the file read */
} cv_ply_points;

/* Reads a PLY of exactly the subset above.  *out owned by the caller.
 * Errors: CV_ERR_IO, CV_ERR_FORMAT ("<path>:<line>: ..." in the header,
 * "<path>: vertex 12: ..." in the body), CV_ERR_RANGE (face index out of
 * range), CV_ERR_NOMEM. */
int cv_ply_read_points(const char *path, cv_ply_points **out, cv_err *err);

/* Frees the points; accepts NULL. */
void cv_ply_points_destroy(cv_ply_points *p);

#endif
