/* Display description for scattering compensation (Bimber et al. 2006,
 * section 3.5; issue 4): the projection screens of a CAVE, a two-sided wall,
 * a cylinder section or a dome, split into patches, with their reflectance,
 * the uncontrolled environment light and the projectors.  Loaded from JSON
 * (configs/displays/, format below); the form-factor code
 * (formfactor.h) turns it into the scattering system (system.h).
 *
 * JSON format (every field is checked; unknown fields are errors):
 *   {
 *     "description": "free text" (optional),
 *     "surfaces": [ SURFACE, ... ]           (at least one; names unique),
 *     "environment": [r, g, b]               (optional, >= 0, default 0),
 *     "viewer": [x, y, z]                    (optional; when given, every patch
 *                                             must face it: catches swapped corners),
 *     "projectors": "ideal"                  (default: F_i = 1 for every patch)
 *                 | [ {"position": [x, y, z],
 *                      "surfaces": ["name", ...]   (optional, default all),
 *                      "intensity_scale": f        (optional, > 0, default 1)}, ... ]
 *   }
 *   SURFACE, planar ("type": "plane" is optional):
 *     {"name", "corners": [pa, pb, pc], "patches": [nu, nv], "reflectance": [r, g, b],
 *      "cosine_exponent": c (optional, > 0, default 1),
 *      "normal_tilt_deg": t (optional, |t| < 90, default 0),
 *      "refine": {"seams": "auto" | ["left", "right", "bottom", "top"],
 *                 "strength": A (0..100, default 3), "width": w (0.01..1, default 0.15)}
 *                 (optional: patches graded towards those edges with density
 *                  1 + A exp(-d / w), d the distance to the edge as a fraction
 *                  of the surface; "auto" picks the edges that touch another
 *                  surface; the patch counts stay nu x nv)}
 *     pa, pb, pc: lower-left, lower-right and upper-left corner in metres AS
 *     SEEN BY THE VIEWER; pa->pb and pa->pc must be perpendicular (within
 *     0.01 degree).  The front (viewer) side is the side of
 *     n = cross(pb - pa, pc - pa) / |..|, which with that corner order points
 *     towards the viewer.
 *   SURFACE, cylinder section (axis vertical, +Y; the inner side is the front):
 *     {"name", "type": "cylinder", "center": [x, y, z], "radius": r,
 *      "angle_deg": [a0, a1], "height": [y0, y1], "patches", "reflectance", ...}
 *     angle a is measured from -Z (straight ahead) towards +X (the right), so
 *     the point at angle a, height h is center + (r sin a, h, -r cos a);
 *     heights are relative to center.y; a1 > a0, a1 - a0 <= 360.
 *   SURFACE, dome (part of a sphere; the inner side is the front):
 *     {"name", "type": "dome", "center", "radius", "elevation_deg": [e0, e1],
 *      "azimuth_deg": [a0, a1], "patches", "reflectance", ...}
 *     the point at azimuth a, elevation e is
 *     center + r (cos e sin a, sin e, -cos e cos a); -90 <= e0 < e1 <= 90.
 *
 * Patches: surface k is split into nu x nv patches, u along pa->pb (angle,
 * azimuth), v along pa->pc (height, elevation), v = 0 at the bottom.  Patch
 * index = surfaces[k].offset + v * nu + u.  Every patch is the planar quad of
 * its four corner points on the surface (for cylinders and domes these four
 * points are coplanar: a chord rectangle or an isosceles trapezoid), and the
 * form factors treat it as that quad.
 *
 * Light-directing screens (paper section 3.6): a patch reflects with the
 * angular distribution cos^c about its emission axis (the geometric normal
 * tilted by normal_tilt_deg about the surface's u axis, positive towards +v),
 * restricted to the front hemisphere and normalised so that everything it
 * reflects into the front hemisphere sums to 1: the exponent and the tilt
 * change where the light goes, not how much (see formfactor.h).
 *
 * Errors name the file and the field path, e.g.
 *   cave.json: surfaces[2].corners: pa->pb and pa->pc are not perpendicular (angle 87.3 deg)
 * and the loader collects every problem (cv_display_validate_all lists them). */
#ifndef CV_COMPENSATE_DISPLAY_H
#define CV_COMPENSATE_DISPLAY_H

#include <stddef.h>
#include <stdint.h>

#include "compensate/system.h"
#include "core/status.h"

typedef enum cv_surface_kind {
  CV_SURFACE_PLANE = 0,
  CV_SURFACE_CYLINDER = 1,
  CV_SURFACE_DOME = 2,
} cv_surface_kind;

typedef struct cv_display_surface {
  char name[64];
  cv_surface_kind kind;
  double pa[3], pb[3], pc[3]; /* plane: lower-left, lower-right, upper-left */
  double center[3], radius;   /* cylinder and dome */
  double range_u[2];          /* cylinder: angle, dome: azimuth (radians) */
  double range_v[2];          /* cylinder: height (m, relative to center.y);
                                 dome: elevation (radians) */
  int nu, nv;                 /* patches along u and v */
  size_t offset;              /* index of the surface's first patch */
  double reflectance[3];      /* M, RGB in [0, 1] */
  double cosine_exponent;     /* c > 0 (1 = Lambertian) */
  double normal_tilt_deg;     /* emission axis tilt about u, towards +v */
  /* 1 / integral over the front hemisphere of max(0, cos about the
   * emission axis)^c d(omega): the lobe normalisation (= (c+1) / (2 pi)
   * without tilt; computed numerically with tilt). */
  double lobe_norm;
  /* Patch boundaries in the surface parameters (nu + 1 and nv + 1 values
   * from 0 to 1; owned by the display).  Uniform unless "refine" asks for
   * patches graded towards seams (edges that touch another surface), where a
   * correction solved on coarse patches and up-sampled errs most (Bimber et
   * al. 2006, future work: adaptive subdivision). */
  double *edge_u, *edge_v;
  int refine;                 /* 1 when "refine" was given */
  int refine_auto;            /* seams found automatically */
  unsigned refine_edges;      /* CV_EDGE_* bits: graded towards these edges */
  double refine_strength;     /* A: patches up to 1 + A times denser at a seam */
  double refine_width;        /* w: decay length as a fraction of the surface */
} cv_display_surface;

/* Surface edges (u = 0 is "left", u = 1 "right", v = 0 "bottom", v = 1 "top"). */
enum { CV_EDGE_LEFT = 1u, CV_EDGE_RIGHT = 2u, CV_EDGE_BOTTOM = 4u, CV_EDGE_TOP = 8u };

typedef struct cv_patch {
  double q[4][3];  /* corners (u,v), (u+1,v), (u+1,v+1), (u,v+1): counter-
                      clockwise seen from the front side */
  double c[3];     /* centre: mean of the corners (lies in the quad) */
  double n[3];     /* unit geometric normal, towards the front (viewer) side */
  double nt[3];    /* unit emission axis: n tilted by normal_tilt_deg */
  double area;     /* area of the quad, m^2 */
  uint32_t surface;
  uint32_t u, v;
} cv_patch;

typedef struct cv_display_projector {
  double position[3];
  double intensity_scale;
  unsigned char *lights; /* n_surfaces flags: 1 = lights that surface */
} cv_display_projector;

/* Everything is owned by the display (cv_display_destroy) and read-only for
 * users; the per-patch arrays refl / proj / env are the inputs of
 * cv_scatter_system and are borrowed by cv_display_scatter_system. */
typedef struct cv_display {
  char source[512];           /* file name (or the name given to cv_display_parse) */
  size_t n_surfaces;
  cv_display_surface *surfaces;
  size_t n_patches;
  cv_patch *patches;
  double environment[3];      /* E (RGB), arriving at every patch */
  int has_viewer;
  double viewer[3];
  int ideal_projectors;       /* 1: "projectors": "ideal" (F_i = 1) */
  size_t n_projectors;
  cv_display_projector *projectors;
  float *refl;                /* 3 n: M_i */
  float *proj;                /* n: F_i projector-to-patch factor (> 0) */
  float *env;                 /* 3 n: E_i */
  /* n: tile of each patch (CV_DISPLAY_TILE x CV_DISPLAY_TILE patches of one
   * surface's grid), the clusters of K's block compression (hmatrix.h). */
  uint32_t *cluster;
  size_t n_clusters;
} cv_display;

/* Edge of the square patch tiles that group patches for compression. */
#define CV_DISPLAY_TILE 8

/* Loads and validates a display description.  *out owned by the caller
 * (cv_display_destroy).  On failure returns CV_ERR_IO (unreadable),
 * CV_ERR_CONFIG (syntax error with its line, or the first validation problem
 * as "file: field.path: what", followed by " [+N more problems]" when there
 * are others), CV_ERR_NOMEM; *out is NULL then. */
int cv_display_load(const char *path, cv_display **out, cv_err *err);
/* The JSON tree of a display description or CAVE config file (*root owned by
 * the caller, cJSON_Delete), with the display loader's errors (unreadable,
 * "path: line L, column C: what"). */
struct cJSON;
int cv_display_read_json(const char *path, struct cJSON **root, cv_err *err);
/* The display of a parsed display description (errors as cv_display_load). */
int cv_display_from_json(const struct cJSON *root, const char *name, cv_display **out, cv_err *err);
/* Loads a display description or a CAVE config (a top-level "walls" and no
 * "surfaces": its walls and "screens", as cv_display_from_cave with patches
 * and reflectance), reading and parsing the file once; *is_cave (may be
 * NULL) says which it was, also on failure once the file parsed.  Errors
 * as cv_display_load, or the CAVE loader's ("path: ..." for the screens).
 * `cave compensate --display` and `cave run --display` take either. */
int cv_display_load_any(const char *path, int patches, double reflectance, cv_display **out,
                        int *is_cave, cv_err *err);

/* As cv_display_load on JSON text already in memory; name is used in the
 * messages in place of the file name. */
int cv_display_parse(const char *json, const char *name, cv_display **out, cv_err *err);

/* Lists every problem of the file, one "file: field: what" line each, into
 * buf (NUL-terminated, truncated to n bytes; buf may be NULL when n is 0),
 * and their count into *n_problems (may be NULL).  Returns CV_OK when the
 * file is valid, else the status of the first problem. */
int cv_display_validate_all(const char *path, char *buf, size_t n, int *n_problems);
/* Same on JSON text. */
int cv_display_validate_text(const char *json, const char *name, char *buf, size_t n,
                             int *n_problems);

void cv_display_destroy(cv_display *d);

/* Accessors (d must be non-NULL, indices in range). */
size_t cv_display_patch_count(const cv_display *d);
size_t cv_display_surface_count(const cv_display *d);
const cv_patch *cv_display_patch(const cv_display *d, size_t i);
const cv_display_surface *cv_display_surface_at(const cv_display *d, size_t k);
/* Index of the surface with this name, or -1. */
int cv_display_find_surface(const cv_display *d, const char *name);

/* Edges of surface k (CV_EDGE_* bits) that touch another surface (seams). */
unsigned cv_display_seam_edges(const cv_display *d, size_t k);

/* Grades the patches of every surface without explicit "refine" edges
 * towards its seams (found automatically), density 1 + strength
 * exp(-d / width) as for "refine": the patch counts stay, so per-patch
 * arrays keep their size, but patches, projector factors and clusters are
 * rebuilt: form factors and workspaces built before must be rebuilt.
 * *n_regraded (may be NULL): surfaces regraded.  CV_ERR_INVALID (strength
 * outside (0, 100], width outside [0.01, 1]), CV_ERR_NOMEM. */
int cv_display_refine_seams(cv_display *d, double strength, double width, int *n_regraded);
/* Patch index of (surface k, u, v). */
size_t cv_display_patch_index(const cv_display *d, size_t k, int u, int v);

/* Fills *out with the scattering system of the display and the gather matrix
 * F (both borrowed: they must outlive *out). */
void cv_display_scatter_system(const cv_display *d, const cv_ffmatrix *F, cv_scatter_system *out);

/* The display of a CAVE config (display_cave.c): its walls with the
 * config's screen reflectance and patches per side (patches > 0 and
 * reflectance >= 0 override them), graded towards the seams, ideal
 * projectors, viewer at the CAVE's head.  *out owned by the caller.
 * Errors: those of cv_display_parse, CV_ERR_NOMEM. */
struct cv_cave;
int cv_display_from_cave(const struct cv_cave *c, int patches, double reflectance, cv_display **out,
                         cv_err *err);

#endif
