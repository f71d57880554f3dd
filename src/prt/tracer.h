/* The bake's per-scene sampling context (cv_tracer): the ray tracer of a
 * mesh plus each vertex's fan of opaque triangles and the window openings,
 * and the bake's sample rays (prt/bake.h describes the sampling scheme).
 * Used by the bake, the relight's window split, the view auto mode and the
 * LCD gather. */
#ifndef CV_PRT_TRACER_H
#define CV_PRT_TRACER_H

#include <stddef.h>
#include <stdint.h>

#include "mesh/mesh.h"
#include "rt/rt.h"

/* Default fraction of a vertex's fan over which ray origins are spread.
 * 1 is the paper's whole hat; smaller values trade leak protection (still
 * ample against overlaps much thinner than the fan) for lower variance:
 * measured in docs/benchmarks.md. */
#define CV_BAKE_DEFAULT_SPREAD 0.5f

/* Per-scene sampling context: the ray tracer plus each vertex's fan. */
typedef struct cv_tracer cv_tracer;

/* Builds the tracer from a mesh (copied).  *out owned by the caller. */
int cv_tracer_create(const cv_mesh *m, cv_tracer **out, cv_err *err);
void cv_tracer_destroy(cv_tracer *tr);
const cv_rt *cv_tracer_rt(const cv_tracer *tr);
/* Sets / reads the spread of ray origins (default CV_BAKE_DEFAULT_SPREAD);
 * CV_ERR_RANGE outside [0, 1].  Not thread-safe against concurrent bakes. */
int cv_tracer_set_spread(cv_tracer *tr, float spread);
float cv_tracer_spread(const cv_tracer *tr);
/* Window importance sampling in the direct pass (default on; it applies
 * only when the mesh has window triangles). */
void cv_tracer_set_window_sampling(cv_tracer *tr, int on);
int cv_tracer_window_sampling(const cv_tracer *tr);
/* on != 0 (the default): the bounce pass sums hits with AVX2 + F16C when the
 * CPU has both; 0: the portable sums (the same bits, for tests and
 * benchmarks).  Returns 1 when the AVX2 sums are in use. */
int cv_tracer_set_simd(cv_tracer *tr, int on);
/* The tracer's mesh (its own copy). */
const cv_mesh *cv_tracer_mesh(const cv_tracer *tr);
/* Number of vertices of the tracer's mesh. */
size_t cv_tracer_vertex_count(const cv_tracer *tr);
/* The i-th vertex the bake's passes visit (0 <= i < vertex count). */
uint32_t cv_tracer_bake_vertex(const cv_tracer *tr, size_t i);
/* Number of opaque triangles in vertex v's fan. */
int cv_tracer_fan_size(const cv_tracer *tr, uint32_t v);

/* Sample j of vertex v under `seed`: ray origin (already offset), unit
 * direction, the fan triangle it starts on.  Returns 0 when v has an empty fan. */
int cv_tracer_sample(const cv_tracer *tr, uint32_t v, uint32_t j, uint32_t seed,
                     float org[3], float dir[3], uint32_t *tri);

#endif
