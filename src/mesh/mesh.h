/* Indexed triangle meshes with per-triangle materials: the scene
 * representation shared by the cabin generator, the importers, geometry
 * cleaning, the ray tracer and the PRT bake.
 *
 * Coordinates: metres, right-handed, +Y up, the car looks along -Z, +X is the
 * driver's right (see docs/conventions.md).  Triangles are wound
 * counter-clockwise seen from the side their normal points to; for the cabin
 * that is the inside. */
#ifndef CV_MESH_MESH_H
#define CV_MESH_MESH_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"

enum {
  CV_MAT_WINDOW = 1u << 0, /* opening: rays crossing it reach the environment */
  CV_MAT_LCD = 1u << 1,    /* the dashboard LCD panel */
};

typedef struct cv_material {
  char name[64];
  float albedo[3]; /* diffuse reflectance, linear RGB in [0, 1] */
  uint32_t flags;  /* CV_MAT_* */
} cv_material;

#define CV_TEX_PATH_MAX 256

typedef struct cv_mesh {
  size_t nv, nt, nm;       /* vertices, triangles, materials */
  size_t cap_v, cap_t, cap_m;
  float *pos;              /* 3*nv: x y z */
  uint32_t *tri;           /* 3*nt: vertex indices */
  uint32_t *tri_mat;       /* nt: material index per triangle */
  cv_material *mats;       /* nm */
  /* Texture coordinates per triangle corner (not per vertex, so that welding
   * and crack closing never merge two sides of a UV seam): 6*nt floats
   * (u, v) for corners 0, 1, 2, origin at the image's bottom-left (assimp's
   * convention; v grows upwards), or NULL when the model has none. */
  float *tri_uv;
  /* Diffuse texture file per material ("" none), nm entries, or NULL when no
   * material has one (cv_mesh_set_texture). */
  char (*mat_tex)[CV_TEX_PATH_MAX];
} cv_mesh;

/* Creates an empty mesh; *out owned by the caller (cv_mesh_destroy). */
int cv_mesh_create(cv_mesh **out);
/* Frees the mesh; accepts NULL. */
void cv_mesh_destroy(cv_mesh *m);
/* Appends a material; returns its index in *idx.  name is truncated to 63 chars. */
int cv_mesh_add_material(cv_mesh *m, const char *name, const float albedo[3],
                         uint32_t flags, uint32_t *idx);
/* Index of the material with this exact name, or -1. */
int cv_mesh_find_material(const cv_mesh *m, const char *name);
/* Appends a vertex; its index goes to *idx (may be NULL). */
int cv_mesh_add_vertex(cv_mesh *m, float x, float y, float z, uint32_t *idx);
/* Appends a triangle (a, b, c must be existing vertex indices, mat an existing
 * material); returns CV_ERR_RANGE otherwise. */
int cv_mesh_add_tri(cv_mesh *m, uint32_t a, uint32_t b, uint32_t c, uint32_t mat);
/* Gives the mesh corner UVs (all zero so far; later triangles get zeros
 * too until set).  No-op if it has them already. */
int cv_mesh_enable_uv(cv_mesh *m);
/* Sets material mat's texture path (truncated to CV_TEX_PATH_MAX - 1 bytes;
 * "" = none); CV_ERR_RANGE for a bad index. */
int cv_mesh_set_texture(cv_mesh *m, uint32_t mat, const char *path);
/* Reserves room for at least nv vertices and nt triangles. */
int cv_mesh_reserve(cv_mesh *m, size_t nv, size_t nt);
/* Deep copy; *out owned by the caller. */
int cv_mesh_clone(const cv_mesh *m, cv_mesh **out);
/* Axis-aligned bounds; both zero for an empty mesh. */
void cv_mesh_bounds(const cv_mesh *m, float lo[3], float hi[3]);
/* Length of the bounding-box diagonal (the "scene size" tolerances scale with). */
float cv_mesh_diagonal(const cv_mesh *m);
/* Unnormalised geometric normal of triangle t (cross(b-a, c-a), length = 2*area). */
void cv_mesh_tri_normal(const cv_mesh *m, size_t t, float n[3]);
/* Area-weighted vertex normals (3*nv floats, unit length; zero for isolated
 * vertices) into caller-provided out. */
void cv_mesh_vertex_normals(const cv_mesh *m, float *out);
/* Checks indices, materials and that every coordinate is finite; err names
 * the first offending vertex or triangle. */
int cv_mesh_validate(const cv_mesh *m, cv_err *err);

#endif
