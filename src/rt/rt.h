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
/* The first error Embree's device reported (its error callback, set at
 * creation): CV_OK when none, else CV_ERR_NOMEM or CV_ERR_BACKEND with
 * "Embree: <kind>: <Embree's message>" in err.  Scene builds check it
 * themselves; a caller may check it after tracing. */
int cv_rt_status(const cv_rt *rt, cv_err *err);
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

/* --- packets and streams ----------------------------------------------------
 * Many rays per call, for coherent work such as the LCD final gather (most
 * rays of one texel leave near its mirror direction).  Rays are AoS: ray i
 * has origin org[3*i .. 3*i+2] and direction dir[3*i .. 3*i+2] (unit, as
 * for cv_rt_intersect).  active may be NULL (every ray) or n flags: an
 * inactive ray is not traced and gets found[i] = 0.  coherent != 0 passes
 * RTC_INTERSECT_CONTEXT_FLAG_COHERENT (Embree then sorts and packs the rays
 * for packet traversal).  found[i] = 1 and hit[i] filled for each hit; the
 * return value is the number of hits.
 *
 * Each ray gets the closest hit that cv_rt_intersect gives it (the same
 * triangle; t, u, v may differ from the single-ray path in the last bits,
 * Embree's packet kernels round differently), and its result depends only on
 * its own ray and on the set of rays in the call, never on the thread: a
 * caller that needs bit-identical results whatever its work split must keep
 * the composition of each call fixed. */

/* Largest n of a packet call (Embree's widest native packet). */
#define CV_RT_PACKET_MAX 16

/* Closest opaque hits of 1 <= n <= CV_RT_PACKET_MAX rays traced together
 * as one Embree packet (rtcIntersect4, 8 or 16: the smallest that holds n;
 * unused lanes are masked off).  Returns -1 (nothing traced) for n outside
 * [1, CV_RT_PACKET_MAX]. */
int cv_rt_intersect_packet(const cv_rt *rt, int n, const float *org, const float *dir,
                           const uint8_t *active, float tnear, float tfar, int coherent,
                           cv_hit *hit, uint8_t *found);
/* Whether each of 1 <= n <= CV_RT_PACKET_MAX rays crosses a window
 * triangle in (tnear, inf) (any one: an occlusion query, cheaper than the
 * closest crossing); found[i] = 0 for every ray when the mesh has no
 * windows.  Returns the number of rays that cross, -1 for a bad n. */
int cv_rt_window_any_packet(const cv_rt *rt, int n, const float *org, const float *dir,
                            float tnear, int coherent, uint8_t *found);
/* Closest window triangle crossed in (tnear, inf) for 1 <= n <=
 * CV_RT_PACKET_MAX rays, as cv_rt_window_hit (hit->tri is the window
 * triangle's index in the mesh); found[i] = 0 for every ray when the mesh
 * has no windows.  Returns the number of crossings, -1 for a bad n. */
int cv_rt_window_hit_packet(const cv_rt *rt, int n, const float *org, const float *dir,
                            const uint8_t *active, float tnear, int coherent, cv_hit *hit,
                            uint8_t *found);
/* A packet in SoA layout (lane i: origin org[0..2][i], unit direction
 * dir[0..2][i]), which Embree's packet kernels take as is. */
typedef struct cv_ray_soa {
  float org[3][CV_RT_PACKET_MAX];
  float dir[3][CV_RT_PACKET_MAX];
} cv_ray_soa;

/* prim[i] of a lane that hits nothing. */
#define CV_RT_NO_HIT UINT32_MAX

/* Closest opaque hits of lanes 0..n-1 of r (1 <= n <= CV_RT_PACKET_MAX),
 * traced as cv_rt_intersect_packet traces them (same packet width, hence the
 * same hits to the bit), returning only what a caller interpolating vertex
 * data needs: prim[i] = the hit's opaque primitive (an index into
 * cv_rt_opaque_vertices) or CV_RT_NO_HIT, u[i], v[i] its barycentrics.
 * Returns the number of hits, -1 (nothing traced) for a bad n. */
int cv_rt_intersect_packet_soa(const cv_rt *rt, int n, const cv_ray_soa *r, float tnear,
                               float tfar, uint32_t *prim, float *u, float *v);
/* The three mesh vertex indices of each opaque primitive (3 per primitive,
 * in the primitive order of cv_rt_intersect_packet_soa): a hit's vertices in
 * one read, without the primitive -> triangle map.  Valid while rt lives. */
const uint32_t *cv_rt_opaque_vertices(const cv_rt *rt);
/* The mesh triangle of opaque primitive prim. */
uint32_t cv_rt_opaque_triangle(const cv_rt *rt, uint32_t prim);

/* Closest opaque hits of any number of rays through Embree's stream
 * interface (rtcIntersect1M, in chunks of 256 rays). */
size_t cv_rt_intersect_stream(const cv_rt *rt, size_t n, const float *org, const float *dir,
                              const uint8_t *active, float tnear, float tfar, int coherent,
                              cv_hit *hit, uint8_t *found);

/* Offsets a ray origin p off its surface along the geometric normal ng (any
 * length; the side is sign(dot(ng, dir)) chosen by the caller by passing ng
 * already flipped towards the ray), with a scale-aware epsilon in integer ULPs
 * (Waechter & Binder, Ray Tracing Gems, ch. 6). */
void cv_rt_offset_origin(const float p[3], const float ng[3], float out[3]);

#endif
