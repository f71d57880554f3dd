/* Independent mesh checks shared by the mesh tests: exact-position vertex
 * identification, edge-manifold / orientation checks, signed volume and
 * per-material area, all written without the library code under test. */
#ifndef CV_TESTS_MESH_CHECK_H
#define CV_TESTS_MESH_CHECK_H

#include <stddef.h>
#include <stdint.h>

#include "mesh/mesh.h"

/* ids[v] = smallest vertex index with bit-identical position (caller frees). */
uint32_t *mc_position_ids(const cv_mesh *m);

/* For triangles [t0, t1) with vertices identified by position: number of
 * undirected edges not used exactly twice (*bad_undirected) and number of
 * directed edges used other than once with the reverse used once
 * (*bad_directed; 0 means consistently oriented and closed). */
void mc_edge_check(const cv_mesh *m, size_t t0, size_t t1, size_t *bad_undirected,
                   size_t *bad_directed);

/* Number of boundary edges (undirected, by index, used by one triangle). */
size_t mc_boundary_edges(const cv_mesh *m);

/* Signed volume sum dot(a, b x c) / 6 over triangles [t0, t1) (double). */
double mc_signed_volume(const cv_mesh *m, size_t t0, size_t t1);

/* Area of triangle t, and its smallest altitude. */
double mc_tri_area(const cv_mesh *m, size_t t);
double mc_tri_min_altitude(const cv_mesh *m, size_t t);

/* Total area of the triangles whose material has any of `flags` (or, if
 * name != NULL, whose material is called name). */
double mc_area_flags(const cv_mesh *m, uint32_t flags);
double mc_area_named(const cv_mesh *m, const char *name);

#endif
