/* Geometry preprocessor: repairs the mesh defects that spoil a per-vertex PRT
 * bake (Dmitriev et al. 2004, section 4.1.1: "duplicated triangles, cracks
 * between patches resulting from the NURBS tessellation, ... sliver-like
 * triangles"; remove duplicates and cracks thinner than a user threshold).
 *
 * Steps, in order, all deterministic (results depend only on the input
 * arrays, never on hash-table iteration order):
 *  (a) weld: vertices closer than weld_tol are merged into the lowest-index
 *      representative found through a spatial hash grid (O(n)), but only
 *      when their area-weighted normals differ by at most crease_deg, so
 *      deliberately split creases stay split.  The survivor keeps its own
 *      position (no averaging, no drift).
 *  (b) degenerate triangles are removed: a repeated vertex index, or a
 *      smallest altitude at or below weld_tol (2 * area <= weld_tol *
 *      longest edge; for edges of the order of weld_tol this is an area
 *      below ~weld_tol^2).
 *  (c) duplicate triangles (the same three vertex indices, either winding)
 *      are removed, keeping the first; same- and opposite-winding copies are
 *      counted separately.
 *  (d) cracks: boundary vertices (on an edge used by exactly one triangle)
 *      within crack_width of another boundary vertex that shares no edge
 *      with them are merged into it (the higher index into the lower, the
 *      nearest first); then a boundary vertex within crack_width of the
 *      interior of a boundary edge whose triangle does not contain it splits
 *      that triangle there (several vertices on one edge give a fan), which
 *      removes T-junctions.  Both only happen when the normals agree within
 *      crease_deg: two objects that merely touch (opposite normals) or
 *      meet at a crease are left alone.  Then (b) and (c) run again; the
 *      whole step repeats until nothing changes (at most 4 passes).
 *  (e) slivers: triangles with longest edge / smallest altitude above
 *      sliver_aspect are counted (and the worst reported), not changed.
 *  (g) material boundaries: a vertex used by triangles of materials with
 *      different albedos is split, one copy per albedo (the first group in
 *      triangle order keeps the original index, the others get new vertices
 *      at the same position), so that a per-vertex quantity such as the
 *      PRT's fan albedo never blends two materials: the LCD panel keeps its
 *      own albedo at its edges.  Window triangles (CV_MAT_WINDOW, no albedo
 *      of their own) never cause a split.  Runs after (d), before (f).
 *  (f) unreferenced vertices are dropped, the order of the others kept.
 * Materials are left as they are. */
#ifndef CV_MESH_CLEAN_H
#define CV_MESH_CLEAN_H

#include <stdio.h>

#include "core/status.h"
#include "mesh/mesh.h"

typedef struct cv_clean_params {
  double weld_tol_rel;    /* weld tolerance / bounding-box diagonal (default 1e-6) */
  double crease_deg;      /* max normal angle for welding / crack closing (default 60) */
  double crack_width_rel; /* crack width / bounding-box diagonal (default 1e-4) */
  double sliver_aspect;   /* longest edge / smallest altitude threshold (default 1e3) */
} cv_clean_params;

typedef struct cv_clean_report {
  size_t nv_before, nt_before, nv_after, nt_after;
  double diagonal, weld_tol, crack_width; /* absolute values used (metres) */
  /* (a) */
  size_t welded;             /* vertices merged into another */
  size_t weld_crease_kept;   /* vertices within weld_tol of a representative but
                                kept apart by the crease test */
  /* (b), (c) */
  size_t degenerate_index;   /* repeated vertex index after welding */
  size_t degenerate_area;    /* smallest altitude <= weld_tol */
  size_t duplicate_same;     /* same winding as the kept copy */
  size_t duplicate_opposite; /* opposite winding */
  size_t nt_after_bc;        /* triangles after (b) and (c) */
  /* (d) */
  size_t boundary_edges_before, boundary_edges_after;
  size_t crack_vertex_merges; /* boundary vertex merged into another */
  size_t crack_edge_splits;   /* boundary vertices inserted into an edge */
  size_t crack_tris_added;    /* triangles added by the splits */
  size_t crack_removed;       /* degenerate + duplicate triangles removed after snapping */
  int crack_passes;
  size_t nt_after_d; /* triangles after (d) */
  /* (e) */
  size_t slivers;
  double worst_aspect; /* largest longest-edge / smallest-altitude ratio seen */
  size_t worst_tri;    /* its index in the OUTPUT mesh (0 if nt_after == 0) */
  /* (g) */
  size_t material_splits; /* vertices added by splitting at material boundaries */
  /* (f) */
  size_t unreferenced;
} cv_clean_report;

/* Defaults: weld 1e-6, crease 60 deg, crack 1e-4, sliver aspect 1e3. */
void cv_clean_default_params(cv_clean_params *p);

/* Cleans m in place (steps (a)-(f) above).  p NULL = defaults; rep may be
 * NULL.  Errors: CV_ERR_INVALID for a NULL mesh or a negative / non-finite
 * parameter; the errors of cv_mesh_validate (empty mesh, bad index,
 * non-finite coordinate); CV_ERR_NOMEM (m is then left valid but possibly
 * partly cleaned). */
int cv_mesh_clean(cv_mesh *m, const cv_clean_params *p, cv_clean_report *rep, cv_err *err);

/* Prints the report (what each step changed, counts before and after) to f. */
void cv_clean_report_print(FILE *f, const cv_clean_report *rep);

#endif
