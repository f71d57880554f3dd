/* Reference path tracer (see ref.h). */
#include "ref/ref.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <omp.h>

#include "core/progress.h"
#include "rt/rt.h"

struct cv_ref_scene {
  cv_rt *rt;
  size_t nv, nt;
  float *pos;      /* 3*nv */
  uint32_t *tri;   /* 3*nt */
  float *albedo;   /* 3*nt: the triangle's material albedo */
  uint32_t *mat;   /* nt: material index */
  int has_windows;
  /* Window openings for area sampling: nw triangles, 9 floats each, and the
   * cumulative area table (win_cdf[k] = area of triangles 0..k). */
  size_t nw;
  float *win;
  double *win_cdf, win_area;
};

void cv_ref_scene_destroy(cv_ref_scene *s) {
  if (!s) return;
  cv_rt_destroy(s->rt);
  free(s->pos);
  free(s->tri);
  free(s->albedo);
  free(s->mat);
  free(s->win);
  free(s->win_cdf);
  free(s);
}

/* Window triangles and their area table (for window-area sampling). */
static int build_windows(cv_ref_scene *s, const cv_mesh *m) {
  size_t nw = 0;
  for (size_t t = 0; t < m->nt; t++) nw += (m->mats[m->tri_mat[t]].flags & CV_MAT_WINDOW) != 0;
  s->win = malloc(9 * nw * sizeof *s->win + 1);
  s->win_cdf = malloc(nw * sizeof *s->win_cdf + 1);
  if (!s->win || !s->win_cdf) return CV_ERR_NOMEM;
  double acc = 0;
  size_t k = 0;
  for (size_t t = 0; t < m->nt; t++) {
    if (!(m->mats[m->tri_mat[t]].flags & CV_MAT_WINDOW)) continue;
    float n[3];
    cv_mesh_tri_normal(m, t, n);
    double a = 0.5 * sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
    for (int v = 0; v < 3; v++)
      memcpy(s->win + 9 * k + 3 * v, m->pos + 3 * m->tri[3 * t + v], 3 * sizeof(float));
    acc += a;
    s->win_cdf[k++] = acc;
  }
  s->nw = nw;
  s->win_area = acc;
  return CV_OK;
}

int cv_ref_scene_create(const cv_mesh *m, cv_ref_scene **out, cv_err *err) {
  *out = NULL;
  for (size_t i = 0; i < m->nm; i++)
    for (int c = 0; c < 3; c++) {
      float a = m->mats[i].albedo[c];
      if (!(a >= 0.0f && a <= 1.0f))
        return cv_err_set(err, CV_ERR_RANGE,
                          "material '%s': albedo channel %d is %g, expected 0..1",
                          m->mats[i].name, c, (double)a);
    }
  cv_ref_scene *s = calloc(1, sizeof *s);
  if (!s) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  int st = cv_rt_create(m, &s->rt, err);
  if (st) {
    free(s);
    return st;
  }
  s->nv = m->nv;
  s->nt = m->nt;
  s->pos = malloc(3 * m->nv * sizeof *s->pos + 1);
  s->tri = malloc(3 * m->nt * sizeof *s->tri + 1);
  s->albedo = malloc(3 * m->nt * sizeof *s->albedo + 1);
  s->mat = malloc(m->nt * sizeof *s->mat + 1);
  if (!s->pos || !s->tri || !s->albedo || !s->mat) {
    cv_ref_scene_destroy(s);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  }
  memcpy(s->pos, m->pos, 3 * m->nv * sizeof *s->pos);
  memcpy(s->tri, m->tri, 3 * m->nt * sizeof *s->tri);
  memcpy(s->mat, m->tri_mat, m->nt * sizeof *s->mat);
  for (size_t t = 0; t < m->nt; t++)
    memcpy(s->albedo + 3 * t, m->mats[m->tri_mat[t]].albedo, 3 * sizeof(float));
  s->has_windows = cv_rt_has_windows(s->rt);
  if (s->has_windows && build_windows(s, m)) {
    cv_ref_scene_destroy(s);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  }
  *out = s;
  return CV_OK;
}

void cv_ref_params_default(cv_ref_params *p) {
  memset(p, 0, sizeof *p);
  p->spp = 64;
  p->pass_spp = 16;
  p->bounces = -1;
  p->seed = 1;
}

/* --- random numbers: splitmix64 streams keyed by (seed, pixel, sample) ---- */
typedef struct {
  uint64_t s;
} rng;

static uint64_t mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

static rng rng_init(uint32_t seed, uint64_t pixel, uint64_t sample) {
  rng r = {mix64(mix64(((uint64_t)seed << 32) ^ 0x5EEDULL) ^ pixel) ^ mix64(sample + 0x9E37ULL)};
  return r;
}

/* Uniform double in [0, 1). */
static double rnd(rng *r) {
  r->s += 0x9E3779B97F4A7C15ULL;
  return (double)(mix64(r->s) >> 11) * 0x1p-53;
}

/* --- geometry helpers ------------------------------------------------------ */
static double dot3(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Cosine-weighted direction about unit n (Malley's method). */
static void cosine_dir(const double n[3], double u1, double u2, double d[3]) {
  double t[3], b[3];
  if (fabs(n[0]) > 0.5) {
    t[0] = n[1]; t[1] = -n[0]; t[2] = 0;
  } else {
    t[0] = 0; t[1] = n[2]; t[2] = -n[1];
  }
  double l = sqrt(dot3(t, t));
  for (int k = 0; k < 3; k++) t[k] /= l;
  b[0] = n[1] * t[2] - n[2] * t[1];
  b[1] = n[2] * t[0] - n[0] * t[2];
  b[2] = n[0] * t[1] - n[1] * t[0];
  double ph = 2 * M_PI * u1, st = sqrt(u2), ct = sqrt(1 - u2);
  for (int k = 0; k < 3; k++) d[k] = st * cos(ph) * t[k] + st * sin(ph) * b[k] + ct * n[k];
}

typedef struct {
  uint64_t rays, vertices, nonfinite, blocked_view;
} counters;

/* For a ray (o, d) that hits no opaque triangle: returns 1 if it reaches the
 * environment (it crosses a window, or the scene has none) and, when pw is
 * not NULL, the solid-angle density with which window-area sampling from o
 * would have drawn d: sum over the window triangles crossed of
 * t^2 / (A_windows |cos|) (all crossings, so double-layered glass counts). */
static int escapes(const cv_ref_scene *s, const float o[3], const float d[3], double *pw,
                   counters *c) {
  if (pw) *pw = 0;
  if (!s->has_windows) return 1;
  cv_hit h;
  float tnear = 0;
  int n = 0;
  for (int k = 0; k < 16; k++) {
    c->rays++;
    if (!cv_rt_window_hit(s->rt, o, d, tnear, &h)) break;
    n++;
    if (!pw) break;
    double nl = sqrt((double)h.ng[0] * h.ng[0] + (double)h.ng[1] * h.ng[1] + (double)h.ng[2] * h.ng[2]);
    double cs = nl > 0 ? fabs(h.ng[0] * d[0] + h.ng[1] * d[1] + h.ng[2] * d[2]) / nl : 0;
    if (cs > 1e-9 && s->win_area > 0) *pw += (double)h.t * h.t / (s->win_area * cs);
    tnear = h.t * (1 + 1e-5f) + 1e-6f;
  }
  return n > 0;
}

/* 1 if direction d from o reaches the environment (no opaque triangle up to
 * infinity, a window crossed); pw as for escapes(). */
static int visible_env(const cv_ref_scene *s, const float o[3], const double d[3], double *pw,
                       counters *c) {
  const float df[3] = {(float)d[0], (float)d[1], (float)d[2]};
  c->rays++;
  if (cv_rt_occluded(s->rt, o, df, 0, INFINITY)) return 0;
  return escapes(s, o, df, pw, c);
}

/* Window-area sampling: a point uniform over the openings' area, seen from
 * x.  Fills the unit direction; returns 0 when there are no windows or the
 * point is (numerically) at x. */
static int sample_window(const cv_ref_scene *s, const double x[3], double u1, double u2,
                         double u3, double d[3]) {
  if (!s->nw || !(s->win_area > 0)) return 0;
  double target = u1 * s->win_area;
  size_t lo = 0, hi = s->nw - 1;
  while (lo < hi) {
    size_t mid = (lo + hi) / 2;
    if (s->win_cdf[mid] <= target) lo = mid + 1;
    else hi = mid;
  }
  const float *v = s->win + 9 * lo;
  double su = sqrt(u2), b0 = 1 - su, b1 = u3 * su, b2 = 1 - b0 - b1, l2 = 0;
  for (int k = 0; k < 3; k++) {
    d[k] = b0 * v[k] + b1 * v[3 + k] + b2 * v[6 + k] - x[k];
    l2 += d[k] * d[k];
  }
  if (!(l2 > 1e-20)) return 0;
  double l = sqrt(l2);
  for (int k = 0; k < 3; k++) d[k] /= l;
  return 1;
}

/* Radiance along the camera ray (o, d) into L. */
static void trace(const cv_ref_scene *s, const cv_ref_light *l, const cv_ref_params *p,
                  const float o0[3], const float d0[3], rng *r, double L[3], counters *c) {
  L[0] = L[1] = L[2] = 0;
  cv_hit h;
  c->rays++;
  if (!cv_rt_intersect(s->rt, o0, d0, 0, INFINITY, &h)) {
    if (escapes(s, o0, d0, NULL, c)) {
      const double dd[3] = {d0[0], d0[1], d0[2]};
      float bg[3];
      cv_ref_light_background(l, dd, bg);
      for (int k = 0; k < 3; k++) L[k] = bg[k];
    } else {
      c->blocked_view++;
    }
    return;
  }
  double beta[3] = {1, 1, 1}, d[3] = {d0[0], d0[1], d0[2]};
  double sun_d[3], sun_E[3];
  const int has_sun = cv_ref_light_sun(l, sun_d, sun_E);
  for (int k = 0;; k++) {
    c->vertices++;
    const uint32_t *t = s->tri + 3 * h.tri;
    double x[3], n[3];
    const double w0 = 1.0 - h.u - h.v;
    for (int i = 0; i < 3; i++)
      x[i] = w0 * s->pos[3 * t[0] + i] + h.u * s->pos[3 * t[1] + i] + h.v * s->pos[3 * t[2] + i];
    double nl = sqrt((double)h.ng[0] * h.ng[0] + (double)h.ng[1] * h.ng[1] +
                     (double)h.ng[2] * h.ng[2]);
    if (!(nl > 0)) break;
    for (int i = 0; i < 3; i++) n[i] = h.ng[i] / nl;
    if (dot3(n, d) > 0)
      for (int i = 0; i < 3; i++) n[i] = -n[i]; /* two-sided: face the arriving ray */
    const float *alb = s->albedo + 3 * h.tri;
    for (int i = 0; i < 3; i++) L[i] += beta[i] * p->emission[i];
    float xf[3] = {(float)x[0], (float)x[1], (float)x[2]}, nf[3] = {(float)n[0], (float)n[1], (float)n[2]};
    float o[3];
    cv_rt_offset_origin(xf, nf, o);
    /* Next-event estimation: the sun (delta light) ... */
    if (has_sun) {
      double cs = dot3(n, sun_d);
      if (cs > 0 && visible_env(s, o, sun_d, NULL, c))
        for (int i = 0; i < 3; i++) L[i] += beta[i] * alb[i] / M_PI * sun_E[i] * cs;
    }
    /* ... and the map, by two strategies (luminance table, window area)
     * combined with the cosine continuation below by the balance heuristic:
     * each strategy's sample counts f L cos / (p_map + p_window + p_cosine). */
    {
      double u1 = rnd(r), u2 = rnd(r), u3 = rnd(r), dl[3], Le[3], pl, pw;
      if (cv_ref_light_sample(l, u1, u2, u3, dl, Le, &pl)) {
        double cs = dot3(n, dl);
        if (cs > 0 && pl > 0 && visible_env(s, o, dl, &pw, c)) {
          double den = pl + pw + cs / M_PI;
          for (int i = 0; i < 3; i++) L[i] += beta[i] * alb[i] / M_PI * Le[i] * cs / den;
        }
      }
      u1 = rnd(r), u2 = rnd(r), u3 = rnd(r);
      if (sample_window(s, x, u1, u2, u3, dl)) {
        double cs = dot3(n, dl);
        if (cs > 0 && visible_env(s, o, dl, &pw, c) && pw > 0) {
          cv_ref_light_env(l, dl, Le);
          double den = cv_ref_light_pdf(l, dl) + pw + cs / M_PI;
          for (int i = 0; i < 3; i++) L[i] += beta[i] * alb[i] / M_PI * Le[i] * cs / den;
        }
      }
    }
    /* Continuation: cosine-weighted, throughput *= albedo. */
    double dn[3];
    cosine_dir(n, rnd(r), rnd(r), dn);
    double pc = dot3(n, dn) / M_PI;
    if (!(pc > 0)) break;
    for (int i = 0; i < 3; i++) beta[i] *= alb[i];
    if (beta[0] <= 0 && beta[1] <= 0 && beta[2] <= 0) break;
    const float df[3] = {(float)dn[0], (float)dn[1], (float)dn[2]};
    c->rays++;
    if (!cv_rt_intersect(s->rt, o, df, 0, INFINITY, &h)) {
      double pw;
      if (escapes(s, o, df, &pw, c)) {
        double Le[3], pl = cv_ref_light_pdf(l, dn), wmis = pc / (pc + pl + pw);
        cv_ref_light_env(l, dn, Le);
        for (int i = 0; i < 3; i++) L[i] += beta[i] * Le[i] * wmis;
      }
      break;
    }
    if (p->bounces >= 0 && k + 1 > p->bounces) break;
    if (k + 1 >= 2) { /* Russian roulette from the third vertex on */
      double q = fmax(beta[0], fmax(beta[1], beta[2]));
      if (q > 0.95) q = 0.95;
      if (rnd(r) >= q) break;
      for (int i = 0; i < 3; i++) beta[i] /= q;
    }
    memcpy(d, dn, sizeof d);
  }
  if (!isfinite(L[0]) || !isfinite(L[1]) || !isfinite(L[2])) {
    c->nonfinite++;
    L[0] = L[1] = L[2] = 0;
  }
}

/* Camera frame, exactly as `cave shade --view` builds it. */
typedef struct {
  double f[3], r[3], u[3], th, aspect;
} frame;

static int camera_frame(const cv_ref_camera *v, frame *fr) {
  double *f = fr->f, *r = fr->r, *u = fr->u;
  for (int k = 0; k < 3; k++) f[k] = v->look[k] - v->eye[k];
  double fl = sqrt(dot3(f, f));
  if (!(fl > 0)) return -1;
  for (int k = 0; k < 3; k++) f[k] /= fl;
  r[0] = f[1] * v->up[2] - f[2] * v->up[1];
  r[1] = f[2] * v->up[0] - f[0] * v->up[2];
  r[2] = f[0] * v->up[1] - f[1] * v->up[0];
  double rl = sqrt(dot3(r, r));
  if (!(rl > 0)) return -1;
  for (int k = 0; k < 3; k++) r[k] /= rl;
  u[0] = r[1] * f[2] - r[2] * f[1];
  u[1] = r[2] * f[0] - r[0] * f[2];
  u[2] = r[0] * f[1] - r[1] * f[0];
  fr->th = tan(v->fov_deg * M_PI / 360);
  fr->aspect = (double)v->w / v->h;
  return 0;
}

static void pixel_ray(const cv_ref_camera *v, const frame *fr, int x, int y, float o[3],
                      float d[3]) {
  double sx = (2 * (x + 0.5) / v->w - 1) * fr->th * fr->aspect,
         sy = (1 - 2 * (y + 0.5) / v->h) * fr->th;
  double dl = 0;
  for (int k = 0; k < 3; k++) {
    double dk = fr->f[k] + sx * fr->r[k] + sy * fr->u[k];
    d[k] = (float)dk;
    dl += dk * dk;
  }
  for (int k = 0; k < 3; k++) {
    d[k] /= (float)sqrt(dl);
    o[k] = (float)v->eye[k];
  }
}

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* Median and 90th percentile of se(Y)/Y over pixels with Y > 0. */
static void rel_se_quantiles(size_t np, const double *sumY, const double *sumY2, int n,
                             double *med, double *p90) {
  *med = *p90 = 0;
  double *v = malloc(np * sizeof *v + 1);
  if (!v) return;
  size_t m = 0;
  for (size_t i = 0; i < np; i++) {
    double mu = sumY[i] / n;
    if (!(mu > 0) || n < 2) continue;
    double var = fmax(0.0, sumY2[i] / n - mu * mu) * n / (n - 1.0);
    v[m++] = sqrt(var / n) / mu;
  }
  if (m) {
    qsort(v, m, sizeof *v, cmp_double);
    *med = v[m / 2];
    *p90 = v[(size_t)(0.9 * (double)(m - 1))];
  }
  free(v);
}

static int check_params(const cv_ref_params *p, cv_err *err) {
  if (p->spp < 1) return cv_err_set(err, CV_ERR_INVALID, "reference: spp %d, expected >= 1", p->spp);
  if (p->pass_spp < 1)
    return cv_err_set(err, CV_ERR_INVALID, "reference: pass_spp %d, expected >= 1", p->pass_spp);
  if (p->bounces < -1 || p->bounces > 1000)
    return cv_err_set(err, CV_ERR_INVALID, "reference: bounces %d, expected -1..1000", p->bounces);
  for (int c = 0; c < 3; c++)
    if (!(p->emission[c] >= 0) || !isfinite(p->emission[c]))
      return cv_err_set(err, CV_ERR_INVALID, "reference: emission %g, expected finite >= 0",
                        p->emission[c]);
  return CV_OK;
}

int cv_ref_render(const cv_ref_scene *s, const cv_ref_light *l, const cv_ref_camera *cam,
                  const cv_ref_params *p, cv_image *mean, cv_image *se, cv_ref_stats *stats,
                  cv_err *err) {
  int st = check_params(p, err);
  if (st) return st;
  frame fr;
  if (cam->w < 1 || cam->h < 1 || !(cam->fov_deg > 1 && cam->fov_deg < 179) ||
      camera_frame(cam, &fr))
    return cv_err_set(err, CV_ERR_INVALID,
                      "reference: camera %dx%d fov %g: expected a size >= 1, fov in (1, 179), "
                      "look != eye and up not along the view",
                      cam->w, cam->h, cam->fov_deg);
  if (!mean || mean->w != cam->w || mean->h != cam->h || mean->c != 3 ||
      (se && (se->w != cam->w || se->h != cam->h || se->c != 3)))
    return cv_err_set(err, CV_ERR_INVALID, "reference: output images must be %dx%d RGB", cam->w,
                      cam->h);
  const int w = cam->w, h = cam->h;
  const size_t np = (size_t)w * h;
  double *sum = calloc(3 * np, sizeof *sum), *sum2 = calloc(3 * np, sizeof *sum2);
  double *sumY = calloc(np, sizeof *sumY), *sumY2 = calloc(np, sizeof *sumY2);
  if (!sum || !sum2 || !sumY || !sumY2) {
    free(sum);
    free(sum2);
    free(sumY);
    free(sumY2);
    return cv_err_set(err, CV_ERR_NOMEM, "reference: out of memory for %dx%d", w, h);
  }
  counters tot = {0};
  double t0 = cv_now_seconds();
  int done = 0;
  while (done < p->spp) {
    int s1 = done + p->pass_spp < p->spp ? done + p->pass_spp : p->spp;
    uint64_t rays = 0, verts = 0, nonf = 0, blocked = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : rays, verts, nonf, blocked)
    for (int y = 0; y < h; y++) {
      cv_rt_thread_init();
      counters c = {0};
      for (int x = 0; x < w; x++) {
        float o[3], d[3];
        pixel_ray(cam, &fr, x, y, o, d);
        size_t i = (size_t)y * w + x;
        for (int smp = done; smp < s1; smp++) {
          rng r = rng_init(p->seed, i, (uint64_t)smp);
          double L[3];
          trace(s, l, p, o, d, &r, L, &c);
          for (int k = 0; k < 3; k++) {
            sum[3 * i + k] += L[k];
            sum2[3 * i + k] += L[k] * L[k];
          }
          double Y = 0.2126 * L[0] + 0.7152 * L[1] + 0.0722 * L[2];
          sumY[i] += Y;
          sumY2[i] += Y * Y;
        }
      }
      rays += c.rays;
      verts += c.vertices;
      nonf += c.nonfinite;
      blocked += c.blocked_view;
    }
    tot.rays += rays;
    tot.vertices += verts;
    tot.nonfinite += nonf;
    tot.blocked_view += blocked;
    done = s1;
    if (!p->quiet) {
      double med, p90;
      rel_se_quantiles(np, sumY, sumY2, done, &med, &p90);
      fprintf(stderr, "reference: %d/%d spp, %.1f s, relative standard error median %.2f%% p90 %.2f%%\n",
              done, p->spp, cv_now_seconds() - t0, 100 * med, 100 * p90);
    }
  }
  const int n = p->spp;
  for (size_t i = 0; i < np; i++)
    for (int k = 0; k < 3; k++) {
      double mu = sum[3 * i + k] / n;
      mean->px[3 * i + k] = (float)mu;
      if (se) {
        double var = n > 1 ? fmax(0.0, sum2[3 * i + k] / n - mu * mu) * n / (n - 1.0) : 0;
        se->px[3 * i + k] = (float)sqrt(var / n);
      }
    }
  if (stats) {
    memset(stats, 0, sizeof *stats);
    stats->paths = (uint64_t)np * n;
    stats->rays = tot.rays;
    stats->vertices = tot.vertices;
    stats->nonfinite = tot.nonfinite;
    stats->blocked_view = tot.blocked_view / (uint64_t)n;
    stats->seconds = cv_now_seconds() - t0;
    rel_se_quantiles(np, sumY, sumY2, n, &stats->median_rel_se, &stats->p90_rel_se);
  }
  free(sum);
  free(sum2);
  free(sumY);
  free(sumY2);
  return CV_OK;
}

int cv_ref_material_ids(const cv_ref_scene *s, const cv_ref_camera *cam, cv_image *ids,
                        cv_err *err) {
  frame fr;
  if (cam->w < 1 || cam->h < 1 || !(cam->fov_deg > 1 && cam->fov_deg < 179) ||
      camera_frame(cam, &fr))
    return cv_err_set(err, CV_ERR_INVALID, "reference: bad camera %dx%d fov %g", cam->w, cam->h,
                      cam->fov_deg);
  if (!ids || ids->w != cam->w || ids->h != cam->h || ids->c != 1)
    return cv_err_set(err, CV_ERR_INVALID, "reference: the id image must be %dx%d x 1", cam->w,
                      cam->h);
#pragma omp parallel for schedule(dynamic, 4)
  for (int y = 0; y < cam->h; y++) {
    cv_rt_thread_init();
    for (int x = 0; x < cam->w; x++) {
      float o[3], d[3];
      cv_hit h;
      pixel_ray(cam, &fr, x, y, o, d);
      ids->px[(size_t)y * cam->w + x] =
          cv_rt_intersect(s->rt, o, d, 0, INFINITY, &h) ? (float)s->mat[h.tri] + 1.0f : 0.0f;
    }
  }
  return CV_OK;
}

int cv_ref_radiance(const cv_ref_scene *s, const cv_ref_light *l, const cv_ref_params *p,
                    const double org[3], const double dir[3], int n, double mean[3],
                    double se[3], cv_ref_stats *stats) {
  if (check_params(p, NULL) || n < 1) return CV_ERR_INVALID;
  double dl = sqrt(dot3(dir, dir));
  if (!(dl > 0)) return CV_ERR_INVALID;
  const float o[3] = {(float)org[0], (float)org[1], (float)org[2]};
  const float d[3] = {(float)(dir[0] / dl), (float)(dir[1] / dl), (float)(dir[2] / dl)};
  double sum[3] = {0}, sum2[3] = {0};
  counters tot = {0};
  double t0 = cv_now_seconds();
  cv_rt_thread_init();
  for (int smp = 0; smp < n; smp++) {
    rng r = rng_init(p->seed, 0, (uint64_t)smp);
    double L[3];
    trace(s, l, p, o, d, &r, L, &tot);
    for (int k = 0; k < 3; k++) {
      sum[k] += L[k];
      sum2[k] += L[k] * L[k];
    }
  }
  for (int k = 0; k < 3; k++) {
    mean[k] = sum[k] / n;
    if (se) se[k] = n > 1 ? sqrt(fmax(0.0, sum2[k] / n - mean[k] * mean[k]) / (n - 1.0)) : 0;
  }
  if (stats) {
    memset(stats, 0, sizeof *stats);
    stats->paths = (uint64_t)n;
    stats->rays = tot.rays;
    stats->vertices = tot.vertices;
    stats->nonfinite = tot.nonfinite;
    stats->blocked_view = tot.blocked_view;
    stats->seconds = cv_now_seconds() - t0;
  }
  return CV_OK;
}
