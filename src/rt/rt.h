/* Ray queries against a cv_mesh: the only module that includes Embree.
 *
 * A cv_rt holds two Embree 3 scenes built from one mesh: the opaque
 * triangles, and the window openings (material flag CV_MAT_WINDOW).  Window
 * triangles never block light; they only mark where a ray may leave the car.
 * Following Dmitriev et al. 2004, section 4.1.1, a ray reaches the
 * environment only if it escapes the opaque geometry AND crosses a window;
 * every other escaping ray (through a crack in a non-closed CAD shell) is
 * blocked.
 *
 * Queries are thread-safe; call cv_rt_thread_init() once in each thread that
 * traces (it sets flush-to-zero / denormals-are-zero as Embree recommends). */
#ifndef CV_RT_RT_H
#define CV_RT_RT_H

#include <stdint.h>

#include "mesh/mesh.h"

typedef struct cv_rt cv_rt;

typedef struct cv_hit {
  uint32_t tri; /* index of the hit triangle in the source mesh */
  float u, v;   /* barycentrics of the triangle's 2nd and 3rd vertex */
  float t;      /* distance along the (unit) ray direction */
  float ng[3];  /* unnormalised geometric normal of the hit triangle */
} cv_hit;

/* Builds the acceleration structures.  The mesh is copied; the caller keeps
 * ownership of m.  *out owned by the caller (cv_rt_destroy).
 * Errors: CV_ERR_EMPTY (no opaque triangle), CV_ERR_BACKEND (Embree). */
int cv_rt_create(const cv_mesh *m, cv_rt **out, cv_err *err);
void cv_rt_destroy(cv_rt *rt);

/* Sets FTZ/DAZ for the calling thread (no-op off x86). */
void cv_rt_thread_init(void);

/* Closest opaque hit in (tnear, tfar); returns 1 and fills hit, or 0. */
int cv_rt_intersect(const cv_rt *rt, const float org[3], const float dir[3], float tnear,
                    float tfar, cv_hit *hit);
/* 1 if any opaque triangle lies in (tnear, tfar). */
int cv_rt_occluded(const cv_rt *rt, const float org[3], const float dir[3], float tnear,
                   float tfar);
/* 1 if the ray reaches the environment: no opaque hit and at least one window
 * crossed (or, when the mesh has no windows at all, simply no opaque hit, so
 * that open test scenes without tagged openings work). */
int cv_rt_reaches_env(const cv_rt *rt, const float org[3], const float dir[3], float tnear);
/* Closest window triangle crossed in (tnear, inf): returns 1 and fills hit
 * (hit->tri is the window triangle's index in the mesh), or 0. */
int cv_rt_window_hit(const cv_rt *rt, const float org[3], const float dir[3], float tnear,
                     cv_hit *hit);
/* 1 when the mesh has window triangles. */
int cv_rt_has_windows(const cv_rt *rt);

/* Offsets a ray origin p off its surface along the geometric normal ng (any
 * length; the side is sign(dot(ng, dir)) chosen by the caller by passing ng
 * already flipped towards the ray), with a scale-aware epsilon in integer ULPs
 * (Waechter & Binder, Ray Tracing Gems, ch. 6). */
void cv_rt_offset_origin(const float p[3], const float ng[3], float out[3]);

#endif
