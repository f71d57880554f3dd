/* Embree 3 wrapper (see rt.h).  The opaque and window triangles go into two
 * scenes so that "blocked" and "crosses a window" are two cheap occlusion
 * queries instead of an any-hit filter callback. */
#include "rt/rt.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#if defined(__x86_64__) || defined(__i386__)
#include <pmmintrin.h>
#include <xmmintrin.h>
#endif

struct cv_rt {
  RTCDevice dev;
  RTCScene opaque;
  RTCScene windows; /* NULL when the mesh has no window triangles */
  uint32_t *prim_to_tri; /* opaque primitive index -> mesh triangle */
  uint32_t *win_to_tri;  /* window primitive index -> mesh triangle */
  const uint32_t *opaque_vtx; /* Embree's index buffer of the opaque scene */
  /* The device's first error, from Embree's error callback (any thread). */
  int err_set;
  enum RTCError err_code;
  char err_msg[256];
};

static const char *rtc_error_name(enum RTCError e) {
  switch (e) {
  case RTC_ERROR_NONE: return "no error";
  case RTC_ERROR_UNKNOWN: return "unknown error";
  case RTC_ERROR_INVALID_ARGUMENT: return "invalid argument";
  case RTC_ERROR_INVALID_OPERATION: return "invalid operation";
  case RTC_ERROR_OUT_OF_MEMORY: return "out of memory";
  case RTC_ERROR_UNSUPPORTED_CPU: return "unsupported CPU";
  case RTC_ERROR_CANCELLED: return "cancelled";
  }
  return "unknown error";
}

/* Embree's error callback: keeps the first error of the device (later ones
 * are usually its consequences). */
static void on_device_error(void *user, enum RTCError code, const char *str) {
  cv_rt *rt = user;
  int expected = 0;
  if (!__atomic_compare_exchange_n(&rt->err_set, &expected, 1, 0, __ATOMIC_ACQ_REL, __ATOMIC_ACQUIRE))
    return;
  rt->err_code = code;
  snprintf(rt->err_msg, sizeof rt->err_msg, "%s%s%s", rtc_error_name(code), str && str[0] ? ": " : "",
           str ? str : "");
}

int cv_rt_status(const cv_rt *rt, cv_err *err) {
  if (!__atomic_load_n(&rt->err_set, __ATOMIC_ACQUIRE)) return CV_OK;
  return cv_err_set(err, rt->err_code == RTC_ERROR_OUT_OF_MEMORY ? CV_ERR_NOMEM : CV_ERR_BACKEND,
                    "Embree: %s", rt->err_msg);
}

void cv_rt_thread_init(void) {
#if defined(__x86_64__) || defined(__i386__)
  _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
  _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
#endif
}

/* Builds one committed scene from the triangles whose window flag equals
 * `want_window`; writes the primitive -> triangle map when map != NULL. */
static int build_scene(cv_rt *rt, const cv_mesh *m, int want_window, uint32_t *map,
                       RTCScene *out, size_t *count, const uint32_t **index) {
  RTCDevice dev = rt->dev;
  size_t n = 0;
  for (size_t t = 0; t < m->nt; t++)
    if (!!(m->mats[m->tri_mat[t]].flags & CV_MAT_WINDOW) == want_window) n++;
  *count = n;
  *out = NULL;
  if (n == 0) return CV_OK;
  RTCScene sc = rtcNewScene(dev);
  rtcSetSceneFlags(sc, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(sc, RTC_BUILD_QUALITY_HIGH);
  RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
  float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                      3 * sizeof(float), m->nv);
  uint32_t *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                         3 * sizeof(uint32_t), n);
  if (!vb || !ib) {
    rtcReleaseGeometry(g);
    rtcReleaseScene(sc);
    return CV_ERR_BACKEND;
  }
  memcpy(vb, m->pos, m->nv * 3 * sizeof(float));
  size_t k = 0;
  for (size_t t = 0; t < m->nt; t++) {
    if (!!(m->mats[m->tri_mat[t]].flags & CV_MAT_WINDOW) != want_window) continue;
    memcpy(ib + 3 * k, m->tri + 3 * t, 3 * sizeof(uint32_t));
    if (map) map[k] = (uint32_t)t;
    k++;
  }
  rtcCommitGeometry(g);
  if (index) *index = ib; /* kept alive by the scene that holds g */
  rtcAttachGeometry(sc, g);
  rtcReleaseGeometry(g);
  rtcCommitScene(sc);
  *out = sc;
  return rt->err_set ? CV_ERR_BACKEND : CV_OK;
}

int cv_rt_create(const cv_mesh *m, cv_rt **out, cv_err *err) {
  *out = NULL;
  int st = cv_mesh_validate(m, err);
  if (st) return st;
  cv_rt *rt = calloc(1, sizeof *rt);
  if (!rt) return cv_err_set(err, CV_ERR_NOMEM, "out of memory building the ray tracer");
  rt->dev = rtcNewDevice(NULL);
  if (!rt->dev) {
    free(rt);
    /* no device to report through the callback: the thread's last error */
    return cv_err_set(err, CV_ERR_BACKEND, "Embree: cannot create a device: %s",
                      rtc_error_name(rtcGetDeviceError(NULL)));
  }
  rtcSetDeviceErrorFunction(rt->dev, on_device_error, rt);
  rt->prim_to_tri = malloc(m->nt * sizeof(uint32_t));
  rt->win_to_tri = malloc(m->nt * sizeof(uint32_t));
  if (!rt->prim_to_tri || !rt->win_to_tri) {
    cv_rt_destroy(rt);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory building the ray tracer");
  }
  size_t nop = 0, nwin = 0;
  st = build_scene(rt, m, 0, rt->prim_to_tri, &rt->opaque, &nop, &rt->opaque_vtx);
  if (!st) st = build_scene(rt, m, 1, rt->win_to_tri, &rt->windows, &nwin, NULL);
  if (st) {
    cv_err e;
    cv_err_clear(&e);
    if (!cv_rt_status(rt, &e)) cv_err_set(&e, CV_ERR_BACKEND, "Embree: no buffer for the scene");
    cv_rt_destroy(rt);
    return cv_err_set(err, e.status, "%s (scene build)", e.msg);
  }
  if (nop == 0) {
    cv_rt_destroy(rt);
    return cv_err_set(err, CV_ERR_EMPTY, "the mesh has no opaque triangles to trace");
  }
  *out = rt;
  return CV_OK;
}

void cv_rt_destroy(cv_rt *rt) {
  if (!rt) return;
  if (rt->opaque) rtcReleaseScene(rt->opaque);
  if (rt->windows) rtcReleaseScene(rt->windows);
  if (rt->dev) rtcReleaseDevice(rt->dev);
  free(rt->prim_to_tri);
  free(rt->win_to_tri);
  free(rt);
}

int cv_rt_has_windows(const cv_rt *rt) { return rt->windows != NULL; }

static inline void make_ray(struct RTCRay *r, const float o[3], const float d[3], float tnear,
                            float tfar) {
  r->org_x = o[0];
  r->org_y = o[1];
  r->org_z = o[2];
  r->dir_x = d[0];
  r->dir_y = d[1];
  r->dir_z = d[2];
  r->tnear = tnear;
  r->tfar = tfar;
  r->time = 0.0f;
  r->mask = 0xFFFFFFFFu;
  r->id = 0;
  r->flags = 0;
}

static int closest(RTCScene sc, const uint32_t *map, const float org[3], const float dir[3],
                   float tnear, float tfar, cv_hit *hit) {
  struct RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  struct RTCRayHit rh;
  make_ray(&rh.ray, org, dir, tnear, tfar);
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(sc, &ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return 0;
  hit->tri = map[rh.hit.primID];
  hit->u = rh.hit.u;
  hit->v = rh.hit.v;
  hit->t = rh.ray.tfar;
  hit->ng[0] = rh.hit.Ng_x;
  hit->ng[1] = rh.hit.Ng_y;
  hit->ng[2] = rh.hit.Ng_z;
  return 1;
}

int cv_rt_intersect(const cv_rt *rt, const float org[3], const float dir[3], float tnear,
                    float tfar, cv_hit *hit) {
  return closest(rt->opaque, rt->prim_to_tri, org, dir, tnear, tfar, hit);
}

int cv_rt_window_hit(const cv_rt *rt, const float org[3], const float dir[3], float tnear,
                     cv_hit *hit) {
  if (!rt->windows) return 0;
  return closest(rt->windows, rt->win_to_tri, org, dir, tnear, INFINITY, hit);
}

/* --- packets ---------------------------------------------------------------- */

static inline void init_context(struct RTCIntersectContext *ctx, int coherent) {
  rtcInitIntersectContext(ctx);
  ctx->flags = coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
}

/* One packet function per native width W: SoA fill of the n <= W rays
 * (inactive and unused lanes masked off with valid = 0), the traversal,
 * and the hits written back.  Unused lanes still get finite dummy rays. */
#define CV_RT_PACKET_FN(W)                                                                       \
  static int closest##W(RTCScene sc, const uint32_t *map, int n, const float *org,              \
                        const float *dir, const uint8_t *active, float tnear, float tfar,        \
                        int coherent, cv_hit *hit, uint8_t *found) {                             \
    struct RTCIntersectContext ctx;                                                              \
    init_context(&ctx, coherent);                                                                \
    RTC_ALIGN(4 * W) int valid[W];                                                               \
    struct RTCRayHit##W rh;                                                                      \
    for (int i = 0; i < W; i++) {                                                                \
      const int on = i < n && (!active || active[i]);                                           \
      const int j = i < n ? i : 0;                                                               \
      valid[i] = on ? -1 : 0;                                                                    \
      rh.ray.org_x[i] = org[3 * j];                                                              \
      rh.ray.org_y[i] = org[3 * j + 1];                                                          \
      rh.ray.org_z[i] = org[3 * j + 2];                                                          \
      rh.ray.dir_x[i] = dir[3 * j];                                                              \
      rh.ray.dir_y[i] = dir[3 * j + 1];                                                          \
      rh.ray.dir_z[i] = dir[3 * j + 2];                                                          \
      rh.ray.tnear[i] = tnear;                                                                   \
      rh.ray.tfar[i] = tfar;                                                                     \
      rh.ray.time[i] = 0.0f;                                                                     \
      rh.ray.mask[i] = 0xFFFFFFFFu;                                                              \
      rh.ray.id[i] = (unsigned)i;                                                                \
      rh.ray.flags[i] = 0;                                                                       \
      rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;                                                \
      rh.hit.primID[i] = RTC_INVALID_GEOMETRY_ID;                                                \
    }                                                                                            \
    rtcIntersect##W(valid, sc, &ctx, &rh);                                                       \
    int count = 0;                                                                               \
    for (int i = 0; i < n; i++) {                                                                \
      found[i] = valid[i] && rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;                        \
      if (!found[i]) continue;                                                                   \
      hit[i].tri = map[rh.hit.primID[i]];                                                        \
      hit[i].u = rh.hit.u[i];                                                                    \
      hit[i].v = rh.hit.v[i];                                                                    \
      hit[i].t = rh.ray.tfar[i];                                                                 \
      hit[i].ng[0] = rh.hit.Ng_x[i];                                                             \
      hit[i].ng[1] = rh.hit.Ng_y[i];                                                             \
      hit[i].ng[2] = rh.hit.Ng_z[i];                                                             \
      count++;                                                                                   \
    }                                                                                            \
    return count;                                                                                \
  }
CV_RT_PACKET_FN(4)
CV_RT_PACKET_FN(8)
CV_RT_PACKET_FN(16)

static int closest_packet(RTCScene sc, const uint32_t *map, int n, const float *org,
                          const float *dir, const uint8_t *active, float tnear, float tfar,
                          int coherent, cv_hit *hit, uint8_t *found) {
  if (n < 1 || n > CV_RT_PACKET_MAX) return -1;
  if (!sc) {
    memset(found, 0, (size_t)n);
    return 0;
  }
  if (n <= 4) return closest4(sc, map, n, org, dir, active, tnear, tfar, coherent, hit, found);
  if (n <= 8) return closest8(sc, map, n, org, dir, active, tnear, tfar, coherent, hit, found);
  return closest16(sc, map, n, org, dir, active, tnear, tfar, coherent, hit, found);
}

int cv_rt_intersect_packet(const cv_rt *rt, int n, const float *org, const float *dir,
                           const uint8_t *active, float tnear, float tfar, int coherent,
                           cv_hit *hit, uint8_t *found) {
  return closest_packet(rt->opaque, rt->prim_to_tri, n, org, dir, active, tnear, tfar, coherent,
                        hit, found);
}

int cv_rt_window_hit_packet(const cv_rt *rt, int n, const float *org, const float *dir,
                            const uint8_t *active, float tnear, int coherent, cv_hit *hit,
                            uint8_t *found) {
  return closest_packet(rt->windows, rt->win_to_tri, n, org, dir, active, tnear, INFINITY,
                        coherent, hit, found);
}

/* SoA packets returning primitives: the lanes copied as they are, unused
 * lanes given lane 0's finite ray and masked off. */
#define CV_RT_SOA_FN(W)                                                                          \
  static int soa##W(RTCScene sc, int n, const cv_ray_soa *r, float tnear, float tfar,           \
                    uint32_t *prim, float *u, float *v) {                                        \
    struct RTCIntersectContext ctx;                                                              \
    init_context(&ctx, 0);                                                                       \
    RTC_ALIGN(4 * W) int valid[W];                                                               \
    struct RTCRayHit##W rh;                                                                      \
    for (int i = 0; i < W; i++) {                                                                \
      const int j = i < n ? i : 0;                                                               \
      valid[i] = i < n ? -1 : 0;                                                                 \
      rh.ray.org_x[i] = r->org[0][j];                                                            \
      rh.ray.org_y[i] = r->org[1][j];                                                            \
      rh.ray.org_z[i] = r->org[2][j];                                                            \
      rh.ray.dir_x[i] = r->dir[0][j];                                                            \
      rh.ray.dir_y[i] = r->dir[1][j];                                                            \
      rh.ray.dir_z[i] = r->dir[2][j];                                                            \
      rh.ray.tnear[i] = tnear;                                                                   \
      rh.ray.tfar[i] = tfar;                                                                     \
      rh.ray.time[i] = 0.0f;                                                                     \
      rh.ray.mask[i] = 0xFFFFFFFFu;                                                              \
      rh.ray.id[i] = (unsigned)i;                                                                \
      rh.ray.flags[i] = 0;                                                                       \
      rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;                                                \
      rh.hit.primID[i] = RTC_INVALID_GEOMETRY_ID;                                                \
    }                                                                                            \
    rtcIntersect##W(valid, sc, &ctx, &rh);                                                       \
    int count = 0;                                                                               \
    for (int i = 0; i < n; i++) {                                                                \
      const int hit = rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;                               \
      prim[i] = hit ? rh.hit.primID[i] : CV_RT_NO_HIT;                                           \
      u[i] = hit ? rh.hit.u[i] : 0.0f;                                                           \
      v[i] = hit ? rh.hit.v[i] : 0.0f;                                                           \
      count += hit;                                                                              \
    }                                                                                            \
    return count;                                                                                \
  }
CV_RT_SOA_FN(4)
CV_RT_SOA_FN(8)
CV_RT_SOA_FN(16)

int cv_rt_intersect_packet_soa(const cv_rt *rt, int n, const cv_ray_soa *r, float tnear,
                               float tfar, uint32_t *prim, float *u, float *v) {
  if (n < 1 || n > CV_RT_PACKET_MAX) return -1;
  if (n <= 4) return soa4(rt->opaque, n, r, tnear, tfar, prim, u, v);
  if (n <= 8) return soa8(rt->opaque, n, r, tnear, tfar, prim, u, v);
  return soa16(rt->opaque, n, r, tnear, tfar, prim, u, v);
}

const uint32_t *cv_rt_opaque_vertices(const cv_rt *rt) { return rt->opaque_vtx; }

uint32_t cv_rt_opaque_triangle(const cv_rt *rt, uint32_t prim) { return rt->prim_to_tri[prim]; }

/* Occlusion packets (any hit in (tnear, tfar)): the SoA fill of
 * CV_RT_PACKET_FN without the hit record. */
#define CV_RT_OCCLUDED_FN(W)                                                                     \
  static int any##W(RTCScene sc, int n, const float *org, const float *dir, float tnear,          \
                    float tfar, int coherent, uint8_t *found) {                                  \
    struct RTCIntersectContext ctx;                                                              \
    init_context(&ctx, coherent);                                                                \
    RTC_ALIGN(4 * W) int valid[W];                                                               \
    struct RTCRay##W r;                                                                          \
    for (int i = 0; i < W; i++) {                                                                \
      const int j = i < n ? i : 0;                                                               \
      valid[i] = i < n ? -1 : 0;                                                                 \
      r.org_x[i] = org[3 * j];                                                                   \
      r.org_y[i] = org[3 * j + 1];                                                               \
      r.org_z[i] = org[3 * j + 2];                                                               \
      r.dir_x[i] = dir[3 * j];                                                                   \
      r.dir_y[i] = dir[3 * j + 1];                                                               \
      r.dir_z[i] = dir[3 * j + 2];                                                               \
      r.tnear[i] = tnear;                                                                        \
      r.tfar[i] = tfar;                                                                          \
      r.time[i] = 0.0f;                                                                          \
      r.mask[i] = 0xFFFFFFFFu;                                                                   \
      r.id[i] = (unsigned)i;                                                                     \
      r.flags[i] = 0;                                                                            \
    }                                                                                            \
    rtcOccluded##W(valid, sc, &ctx, &r);                                                         \
    int count = 0;                                                                               \
    for (int i = 0; i < n; i++) {                                                                \
      found[i] = r.tfar[i] < 0.0f; /* Embree sets tfar = -inf on a hit */                        \
      count += found[i];                                                                         \
    }                                                                                            \
    return count;                                                                                \
  }
CV_RT_OCCLUDED_FN(4)
CV_RT_OCCLUDED_FN(8)
CV_RT_OCCLUDED_FN(16)

int cv_rt_window_any_packet(const cv_rt *rt, int n, const float *org, const float *dir,
                            float tnear, int coherent, uint8_t *found) {
  if (n < 1 || n > CV_RT_PACKET_MAX) return -1;
  if (!rt->windows) {
    memset(found, 0, (size_t)n);
    return 0;
  }
  if (n <= 4) return any4(rt->windows, n, org, dir, tnear, INFINITY, coherent, found);
  if (n <= 8) return any8(rt->windows, n, org, dir, tnear, INFINITY, coherent, found);
  return any16(rt->windows, n, org, dir, tnear, INFINITY, coherent, found);
}

#define STREAM_CHUNK 256

size_t cv_rt_intersect_stream(const cv_rt *rt, size_t n, const float *org, const float *dir,
                              const uint8_t *active, float tnear, float tfar, int coherent,
                              cv_hit *hit, uint8_t *found) {
  struct RTCIntersectContext ctx;
  init_context(&ctx, coherent);
  struct RTCRayHit rh[STREAM_CHUNK];
  uint32_t idx[STREAM_CHUNK];
  size_t count = 0;
  for (size_t i0 = 0; i0 < n; i0 += STREAM_CHUNK) {
    const size_t m = n - i0 < STREAM_CHUNK ? n - i0 : STREAM_CHUNK;
    unsigned k = 0;
    for (size_t i = i0; i < i0 + m; i++) {
      found[i] = 0;
      if (active && !active[i]) continue;
      make_ray(&rh[k].ray, org + 3 * i, dir + 3 * i, tnear, tfar);
      rh[k].hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh[k].hit.primID = RTC_INVALID_GEOMETRY_ID;
      idx[k++] = (uint32_t)(i - i0);
    }
    if (!k) continue;
    rtcIntersect1M(rt->opaque, &ctx, rh, k, sizeof rh[0]);
    for (unsigned j = 0; j < k; j++) {
      if (rh[j].hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
      const size_t i = i0 + idx[j];
      found[i] = 1;
      hit[i].tri = rt->prim_to_tri[rh[j].hit.primID];
      hit[i].u = rh[j].hit.u;
      hit[i].v = rh[j].hit.v;
      hit[i].t = rh[j].ray.tfar;
      hit[i].ng[0] = rh[j].hit.Ng_x;
      hit[i].ng[1] = rh[j].hit.Ng_y;
      hit[i].ng[2] = rh[j].hit.Ng_z;
      count++;
    }
  }
  return count;
}

static int occluded(RTCScene sc, const float org[3], const float dir[3], float tnear,
                    float tfar) {
  struct RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  struct RTCRay r;
  make_ray(&r, org, dir, tnear, tfar);
  rtcOccluded1(sc, &ctx, &r);
  return r.tfar < 0.0f; /* Embree sets tfar = -inf on a hit */
}

int cv_rt_occluded(const cv_rt *rt, const float org[3], const float dir[3], float tnear,
                   float tfar) {
  return occluded(rt->opaque, org, dir, tnear, tfar);
}

int cv_rt_reaches_env(const cv_rt *rt, const float org[3], const float dir[3], float tnear) {
  if (occluded(rt->opaque, org, dir, tnear, INFINITY)) return 0;
  if (!rt->windows) return 1;
  return occluded(rt->windows, org, dir, tnear, INFINITY);
}

/* Waechter & Binder 2019, "A Fast and Robust Method for Avoiding
 * Self-Intersection", Ray Tracing Gems ch. 6: move the origin by a fixed number
 * of float ULPs along the normal (robust at any scale), and by a small
 * absolute amount near the origin where ULPs are tiny. */
void cv_rt_offset_origin(const float p[3], const float ng[3], float out[3]) {
  const float origin = 1.0f / 32.0f, float_scale = 1.0f / 65536.0f, int_scale = 256.0f;
  float l = sqrtf(ng[0] * ng[0] + ng[1] * ng[1] + ng[2] * ng[2]);
  float n[3] = {0, 0, 0};
  if (l > 0) {
    n[0] = ng[0] / l;
    n[1] = ng[1] / l;
    n[2] = ng[2] / l;
  }
  for (int k = 0; k < 3; k++) {
    int32_t of = (int32_t)(int_scale * n[k]);
    /* unsigned: -0.0f has the bits of INT32_MIN, and a signed add would
     * overflow there (that value is not used: |p| < origin) */
    uint32_t bits;
    memcpy(&bits, &p[k], sizeof bits);
    bits += (uint32_t)((p[k] < 0) ? -of : of);
    float pi;
    memcpy(&pi, &bits, sizeof pi);
    out[k] = fabsf(p[k]) < origin ? p[k] + float_scale * n[k] : pi;
  }
}
