/* Mesh import through assimp's C API: OBJ (+MTL), PLY, glTF 2 (.gltf/.glb)
 * and whatever else assimp 5.2 reads, into one cv_mesh in the file's units
 * (times opts->scale); stats->frame says which units and up axis the file
 * declares, and cv_mesh_place (mesh/place.h) converts to metres, Y up.
 *
 * Post-processing is fixed for predictability: Triangulate,
 * JoinIdenticalVertices, SortByPType, PreTransformVertices (node transforms,
 * e.g. glTF translations, are applied and the hierarchy flattened) and
 * ValidateDataStructure.  Points and lines are dropped and counted.
 *
 * Materials: albedo = the base colour (AI_MATKEY_BASE_COLOR, "$clr.base",
 * which assimp 5.2 fills from glTF's pbrMetallicRoughness.baseColorFactor)
 * when present, else the diffuse colour (AI_MATKEY_COLOR_DIFFUSE, MTL Kd),
 * else opts->default_albedo.  A material with a diffuse texture (glTF
 * baseColorTexture, MTL map_Kd; a PNG file found relative to the model) gets
 * the colour (1 if none) times the texture's mean linear RGB (sRGB decoded):
 * the average albedo that other surfaces' bounce light sees in the bake.
 * Each component is clamped to [0, 1] (NaN -> 0)
 * and clamps are counted.  A material whose name starts with "window" gets
 * CV_MAT_WINDOW, "lcd" gets CV_MAT_LCD (case-insensitive); opts->overrides
 * then replace albedo and/or flags by exact material name.  Only materials
 * used by some triangle are kept, in the file's material order.
 *
 * After import the result is checked independently of assimp (which is
 * permissive): every index in range, every coordinate finite.  OBJ files are
 * also pre-scanned line by line so that an out-of-range face index or an
 * unparsable number is reported with its line instead of being silently
 * dropped or read as 0. */
#ifndef CV_IO_MESH_IMPORT_H
#define CV_IO_MESH_IMPORT_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"
#include "mesh/mesh.h"
#include "mesh/place.h"

/* Per-material override, e.g. filled from a scene config entry
 * {"name": "glass", "albedo": [0,0,0], "flags": ["window"]}. */
typedef struct cv_material_override {
  char name[64];    /* exact (case-sensitive) material name as in the file */
  int has_albedo;   /* nonzero: replace the albedo with `albedo` */
  float albedo[3];  /* linear RGB; clamped to [0, 1] and counted like file values */
  int has_flags;    /* nonzero: replace the flags (CV_MAT_*) with `flags` */
  uint32_t flags;
} cv_material_override;

typedef struct cv_import_opts {
  const cv_material_override *overrides; /* borrowed; n_overrides entries */
  size_t n_overrides;
  float default_albedo[3]; /* for materials with no colour (default 0.5 grey) */
  double scale;            /* multiplies coordinates (file units -> metres), default 1 */
  /* Guards of cv_mesh_import(_ex), which runs assimp in a child process:
   * wall-clock seconds and MB of address space the import child may add to
   * the process's at the fork (0 = no limit; child_guard.h).  Defaults:
   * CAVE_IMPORT_TIMEOUT (seconds, else CV_IMPORT_DEFAULT_SECONDS) and
   * CAVE_IMPORT_MEMORY_MB (else CV_IMPORT_DEFAULT_MEMORY_MB or 3/4 of the
   * physical memory, whichever is less); raise them for
   * very big CAD models.  The memory limit is not applied in an
   * AddressSanitizer build (its shadow memory needs terabytes of addresses). */
  double limit_seconds;
  double limit_memory_mb;
} cv_import_opts;

#define CV_IMPORT_DEFAULT_SECONDS 600.0
/* 8 GB.  A higher default lets a lying header make assimp touch that much
 * memory before failing: assimp's invalid/OutOfMemory.off took 46 s under an
 * 18 GB limit, 0.2 s under 8 GB (docs/fuzzing.md). */
#define CV_IMPORT_DEFAULT_MEMORY_MB 8192.0

/* What the import did (everything that was dropped, clamped or defaulted). */
typedef struct cv_import_stats {
  size_t meshes;            /* assimp meshes read */
  size_t triangles;         /* triangles kept */
  size_t points_dropped;    /* point primitives */
  size_t lines_dropped;     /* line primitives */
  size_t albedo_clamped;    /* albedo components clamped into [0, 1] */
  size_t albedo_defaulted;  /* materials without a colour */
  size_t overrides_applied; /* overrides that matched a kept material */
  size_t overrides_unused;  /* overrides whose name matched no kept material */
  size_t textures_averaged; /* materials whose albedo is their diffuse texture's mean */
  size_t textures_unread;   /* materials whose texture could not be read: missing, not a
                               PNG or JPEG, corrupt (their colour is used alone) */
  size_t textures_embedded; /* textures embedded in the model, written to the texture
                               cache (io/texture_embed.h) */
  char texture_error[320];  /* why the first unread texture was not read ("" if none) */
  cv_file_frame frame;      /* units and up axis the file declares (glTF: metres, Y up by
                               its specification; FBX: UnitScaleFactor (cm) and UpAxis
                               metadata; COLLADA and IFC: converted by assimp, so
                               metres and Y up); zeros where the format says nothing.
                               Coordinates are NOT converted here: see cv_mesh_place. */
} cv_import_stats;

/* Defaults: no overrides, default albedo 0.5, scale 1, limits as above. */
void cv_import_opts_default(cv_import_opts *o);
/* Sets only o's two limits from the environment (see cv_import_opts). */
void cv_import_limits_default(cv_import_opts *o);

/* Imports the file at path into a new mesh *out (owned by the caller,
 * cv_mesh_destroy; NULL on error).  opts may be NULL (defaults).
 * Errors (err gets one line starting with the path):
 *   CV_ERR_INVALID  NULL path/out, or a bad option (scale not finite/positive)
 *   CV_ERR_IO       the file cannot be opened
 *   CV_ERR_FORMAT   assimp failed (its aiGetErrorString() is included), an
 *                   OBJ line is malformed (line number given), or an index is
 *                   out of range
 *   CV_ERR_NONFINITE a NaN/Inf coordinate
 *   CV_ERR_EMPTY    the scene has no triangles (points/lines only, or nothing)
 *   CV_ERR_NOMEM */
int cv_mesh_import(const char *path, const cv_import_opts *opts, cv_mesh **out, cv_err *err);

/* As cv_mesh_import, and fills *stats (may be NULL).  Both run the import in
 * a forked child under opts' limits (src/io/import_guard.c), the mesh coming
 * back through a pipe, assimp's own output dropped (shown after the error
 * if the child crashed, or always with CAVE_IMPORT_VERBOSE=1).  More errors:
 *   CV_ERR_RANGE    the time limit was hit ("time limit N s hit")
 *   CV_ERR_NOMEM    the memory limit was hit ("memory limit N MB hit")
 *   CV_ERR_BACKEND  the import crashed (signal named) */
int cv_mesh_import_ex(const char *path, const cv_import_opts *opts, cv_mesh **out,
                      cv_import_stats *stats, cv_err *err);
/* The import itself, in this process, without limits (what the child runs). */
int cv_mesh_import_direct(const char *path, const cv_import_opts *opts, cv_mesh **out,
                          cv_import_stats *stats, cv_err *err);

#endif
