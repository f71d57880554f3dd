/* Patch-to-patch form factors and the sparse gather matrix (see formfactor.h
 * for the method, the normalisations and the sparsification rule). */
#include "compensate/formfactor.h"

#include "core/vec3d.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/progress.h"
#include "mesh/mesh.h"
#include "rt/rt.h"

#define PI 3.14159265358979323846
#define MAXV 16

/* Quadrature order by rho = gap / size of the (sub-)sender, where gap is
 * its distance to the receiver polygon minus its circumradius and size its
 * diameter.  Tuned so that far entries are within ~1e-4 relative and the
 * shared-edge unit squares within 1e-4 (tests/compensate/test_formfactor.c). */
#ifndef RHO_1PT
#define RHO_1PT 24.0   /* 1 point (the centre) */
#endif
#ifndef RHO_2PT
#define RHO_2PT 4.0    /* 2x2 Gauss */
#endif
#ifndef RHO_3PT
#define RHO_3PT 1.5    /* 3x3 Gauss; below: subdivide 2x2 */
#endif
#ifndef MAX_DEPTH
#define MAX_DEPTH 6
#endif
/* Product rule over both patches for non-Lambertian senders: rho = gap
 * between the two sub-quads / the larger diameter. */
#ifndef RHO_P2
#define RHO_P2 6.0     /* 2x2 x 2x2 */
#endif
#ifndef RHO_P3
#define RHO_P3 2.5     /* 3x3 x 3x3 */
#endif
#ifndef RHO_P4
#define RHO_P4 1.0     /* 4x4 x 4x4; below: split the larger sub-quad */
#endif
#ifndef MAX_DEPTH_P
#define MAX_DEPTH_P 8 /* splits of either side along one branch */
#endif

/* Gauss-Legendre nodes and weights on [0, 1], orders 1..4. */
static const double GL_X[5][4] = {
    {0},
    {0.5},
    {0.21132486540518713, 0.78867513459481287},
    {0.11270166537925831, 0.5, 0.88729833462074169},
    {0.069431844202973713, 0.33000947820757187, 0.66999052179242813, 0.93056815579702629}};
static const double GL_W[5][4] = {
    {0},
    {1.0},
    {0.5, 0.5},
    {5.0 / 18, 8.0 / 18, 5.0 / 18},
    {0.17392742256872693, 0.32607257743127307, 0.32607257743127307, 0.17392742256872693}};

/* --- point to polygon ------------------------------------------------------ */

/* Sutherland-Hodgman: keeps the part of polygon in[0..k-1] with
 * n . (q - x) > 0.  Returns the new vertex count (0: nothing in front). */
static int clip_front(const double (*in)[3], int k, const double x[3], const double n[3],
                      double (*out)[3]) {
  double d[MAXV + 4];
  int pos = 0;
  for (int i = 0; i < k; i++) {
    double w[3];
    sub3(in[i], x, w);
    d[i] = dot3(n, w);
    pos += d[i] > 0;
  }
  if (pos == 0) return 0;
  if (pos == k) {
    memcpy(out, in, (size_t)k * sizeof *out);
    return k;
  }
  int m = 0;
  for (int i = 0; i < k; i++) {
    int i1 = (i + 1) % k;
    if (d[i] > 0) memcpy(out[m++], in[i], sizeof *out);
    if ((d[i] > 0) != (d[i1] > 0)) {
      double t = d[i] / (d[i] - d[i1]);
      for (int a = 0; a < 3; a++) out[m][a] = in[i][a] + t * (in[i1][a] - in[i][a]);
      m++;
    }
  }
  return m;
}

/* Lambert's contour integral (formfactor.h), no clipping. */
static double contour(const double x[3], const double n[3], const double (*q)[3], int k) {
  double sum = 0;
  for (int i = 0; i < k; i++) {
    double a[3], b[3], c[3];
    sub3(q[i], x, a);
    sub3(q[(i + 1) % k], x, b);
    cross3(a, b, c);
    double lc = len3(c);
    if (!(lc > 1e-300)) continue; /* degenerate edge, or x on its line */
    sum += atan2(lc, dot3(a, b)) * dot3(n, c) / lc;
  }
  return -sum / (2.0 * PI);
}

double cv_ff_point_polygon(const double x[3], const double n[3], const double (*q)[3], int k) {
  if (k < 3 || k > MAXV) return 0;
  double poly[MAXV + 4][3];
  int m = clip_front(q, k, x, n, poly);
  return m >= 3 ? contour(x, n, (const double(*)[3])poly, m) : 0.0;
}

double cv_ff_point_to_point(const cv_patch *s, const cv_patch *r) {
  double w[3];
  sub3(r->c, s->c, w);
  double d2 = dot3(w, w);
  if (!(d2 > 0)) return 0;
  double d = sqrt(d2);
  double cs = dot3(s->n, w) / d, cr = -dot3(r->n, w) / d;
  if (cs <= 0 || cr <= 0) return 0;
  return r->area * cs * cr / (PI * d2);
}

/* --- pair integration ------------------------------------------------------ */

typedef struct vis_ctx {
  cv_rt *rt;
  double eps; /* offset of segment ends off their surfaces, m */
} vis_ctx;

typedef struct pair_ctx {
  const cv_patch *s, *r;  /* sender (integrated numerically), receiver */
  double emit[3];         /* sender's emission axis */
  int clip_geo;           /* also clip to the sender's geometric half-space */
  double scale;           /* contour path: pi * lobe_norm (1 for Lambert) */
  double cexp, lobe;      /* sender's cosine exponent and lobe_norm */
  double rr;              /* receiver circumradius about r->c */
  const vis_ctx *vis;     /* NULL: no rays */
  uint64_t evals, rays;
  int refined;
} pair_ctx;

static inline void bilinear(const double (*q)[3], double s, double t, double p[3]) {
  const double w0 = (1 - s) * (1 - t), w1 = s * (1 - t), w2 = s * t, w3 = (1 - s) * t;
  for (int a = 0; a < 3; a++) p[a] = w0 * q[0][a] + w1 * q[1][a] + w2 * q[2][a] + w3 * q[3][a];
}

/* |dP/ds x dP/dt| of the bilinear map at (s, t). */
static inline double bilinear_jac(const double (*q)[3], double s, double t) {
  double ps[3], pt[3], c[3];
  for (int a = 0; a < 3; a++) {
    ps[a] = (1 - t) * (q[1][a] - q[0][a]) + t * (q[2][a] - q[3][a]);
    pt[a] = (1 - s) * (q[3][a] - q[0][a]) + s * (q[2][a] - q[1][a]);
  }
  cross3(ps, pt, c);
  return len3(c);
}

/* Distance from p to the receiver quad (planar, convex). */
static double dist_point_quad(const double p[3], const cv_patch *r) {
  double w[3];
  sub3(p, r->q[0], w);
  double dp = dot3(r->n, w);
  double pr[3] = {p[0] - dp * r->n[0], p[1] - dp * r->n[1], p[2] - dp * r->n[2]};
  int inside = 1;
  double best = INFINITY;
  for (int k = 0; k < 4; k++) {
    const double *a = r->q[k], *b = r->q[(k + 1) & 3];
    double e[3], v[3], c[3];
    sub3(b, a, e);
    double ee = dot3(e, e);
    if (!(ee > 0)) continue;
    sub3(pr, a, v);
    cross3(e, v, c);
    if (dot3(c, r->n) < 0) inside = 0;
    double u[3];
    sub3(p, a, u);
    double t = fmin(1.0, fmax(0.0, dot3(u, e) / ee));
    double cp[3] = {a[0] + t * e[0], a[1] + t * e[1], a[2] + t * e[2]};
    best = fmin(best, dist3(p, cp));
  }
  return inside ? fabs(dp) : best;
}

/* 1 if the segment from x (on the sender) to the receiver's centre is free. */
static double visible(pair_ctx *c, const double x[3]) {
  const vis_ctx *v = c->vis;
  double a[3], b[3], w[3];
  for (int k = 0; k < 3; k++) {
    a[k] = x[k] + v->eps * c->s->n[k];
    b[k] = c->r->c[k] + v->eps * c->r->n[k];
  }
  sub3(b, a, w);
  double L = len3(w);
  if (!(L > 0)) return 1.0;
  float o[3] = {(float)a[0], (float)a[1], (float)a[2]};
  float dir[3] = {(float)(w[0] / L), (float)(w[1] / L), (float)(w[2] / L)};
  c->rays++;
  return cv_rt_occluded(v->rt, o, dir, (float)(1e-6 * L), (float)(L * (1 - 1e-5))) ? 0.0 : 1.0;
}

/* Form factor from the point x of the sender to the whole receiver. */
static double point_value(pair_ctx *c, const double x[3]) {
  const cv_patch *r = c->r;
  double w[3];
  sub3(x, r->c, w);
  if (!(dot3(r->n, w) > 0)) return 0; /* the receiver is seen from behind */
  double p1[MAXV + 4][3], p2[MAXV + 4][3];
  int m = clip_front(r->q, 4, x, c->emit, p1);
  if (m >= 3 && c->clip_geo) {
    m = clip_front((const double(*)[3])p1, m, x, c->s->n, p2);
    memcpy(p1, p2, (size_t)m * sizeof p1[0]);
  }
  c->evals++;
  double v = m >= 3 ? c->scale * contour(x, c->emit, (const double(*)[3])p1, m) : 0.0;
  if (v > 0 && c->vis) v *= visible(c, x);
  return v > 0 ? v : 0.0;
}

/* Integral over the sender sub-quad [s0,s1]x[t0,t1] of point_value dA. */
static double sender_rec(pair_ctx *c, double s0, double s1, double t0, double t1, int depth) {
  const cv_patch *s = c->s;
  double cen[3];
  bilinear(s->q, 0.5 * (s0 + s1), 0.5 * (t0 + t1), cen);
  double rs = 0;
  if (depth == 0) {
    for (int k = 0; k < 4; k++) rs = fmax(rs, dist3(s->q[k], cen));
  } else {
    double cr[3];
    const double ss[4] = {s0, s1, s1, s0}, tt[4] = {t0, t0, t1, t1};
    for (int k = 0; k < 4; k++) {
      bilinear(s->q, ss[k], tt[k], cr);
      rs = fmax(rs, dist3(cr, cen));
    }
  }
  const double size = 2 * rs + 1e-300;
  int order;
  if (dist3(cen, c->r->c) - c->rr - rs >= RHO_1PT * size) {
    order = 1; /* cheap ball test first */
  } else {
    double rho = (dist_point_quad(cen, c->r) - rs) / size;
    if (rho >= RHO_1PT)
      order = 1;
    else if (rho >= RHO_2PT)
      order = 2;
    else if (rho >= RHO_3PT)
      order = 3;
    else if (depth >= MAX_DEPTH)
      order = 4;
    else {
      c->refined = 1;
      double sm = 0.5 * (s0 + s1), tm = 0.5 * (t0 + t1);
      return sender_rec(c, s0, sm, t0, tm, depth + 1) + sender_rec(c, sm, s1, t0, tm, depth + 1) +
             sender_rec(c, s0, sm, tm, t1, depth + 1) + sender_rec(c, sm, s1, tm, t1, depth + 1);
    }
  }
  double sum = 0;
  for (int a = 0; a < order; a++)
    for (int b = 0; b < order; b++) {
      double ps = s0 + (s1 - s0) * GL_X[order][a], pt = t0 + (t1 - t0) * GL_X[order][b];
      double x[3];
      bilinear(s->q, ps, pt, x);
      double f = point_value(c, x);
      if (f != 0) sum += GL_W[order][a] * GL_W[order][b] * bilinear_jac(s->q, ps, pt) * f;
    }
  return sum * (s1 - s0) * (t1 - t0);
}

/* Sub-quad [s0,s1]x[t0,t1] of a patch: centre and circumradius. */
static double subquad(const cv_patch *p, const double r[4], double cen[3]) {
  bilinear(p->q, 0.5 * (r[0] + r[1]), 0.5 * (r[2] + r[3]), cen);
  double rad = 0, q[3];
  const double ss[4] = {r[0], r[1], r[1], r[0]}, tt[4] = {r[2], r[2], r[3], r[3]};
  for (int k = 0; k < 4; k++) {
    bilinear(p->q, ss[k], tt[k], q);
    rad = fmax(rad, dist3(q, cen));
  }
  return rad;
}

static inline double powc(double x, double c) {
  if (c == 2.0) return x * x;
  if (c == 3.0) return x * x * x;
  if (c == 4.0) {
    double y = x * x;
    return y * y;
  }
  return pow(x, c);
}

/* Non-Lambertian senders: integral over the sender sub-quad rs and the
 * receiver sub-quad rr of  cos_e^c cos_r / r^2  (cos_e about the emission
 * axis, zero behind either patch), by product Gauss rules, splitting the
 * larger sub-quad where they are close.  Splitting pairs rather than nesting
 * one adaptive integral in another keeps the cost near a shared edge at
 * O(D 2^D) leaf pairs instead of O(4^D).  Visibility: one segment per sender
 * node to the receiver's centre. */
static double pair_product(pair_ctx *c, const double rs[4], const double rr[4], int depth) {
  const cv_patch *s = c->s, *r = c->r;
  double cs[3], cr[3];
  double ras = subquad(s, rs, cs), rar = subquad(r, rr, cr);
  double rho = (dist3(cs, cr) - ras - rar) / (2 * fmax(ras, rar) + 1e-300);
  int n;
  if (rho >= RHO_P2)
    n = 2;
  else if (rho >= RHO_P3)
    n = 3;
  else if (rho >= RHO_P4 || depth >= MAX_DEPTH_P)
    n = 4;
  else {
    c->refined = 1;
    double sum = 0;
    const int split_s = ras >= rar;
    const double *q = split_s ? rs : rr;
    const double sm = 0.5 * (q[0] + q[1]), tm = 0.5 * (q[2] + q[3]);
    const double kids[4][4] = {
        {q[0], sm, q[2], tm}, {sm, q[1], q[2], tm}, {q[0], sm, tm, q[3]}, {sm, q[1], tm, q[3]}};
    for (int k = 0; k < 4; k++)
      sum += split_s ? pair_product(c, kids[k], rr, depth + 1)
                     : pair_product(c, rs, kids[k], depth + 1);
    return sum;
  }
  double ys[4][4][3], wr[4][4];
  for (int a = 0; a < n; a++)
    for (int b = 0; b < n; b++) {
      double u = rr[0] + (rr[1] - rr[0]) * GL_X[n][a], v = rr[2] + (rr[3] - rr[2]) * GL_X[n][b];
      bilinear(r->q, u, v, ys[a][b]);
      wr[a][b] = GL_W[n][a] * GL_W[n][b] * bilinear_jac(r->q, u, v);
    }
  double sum = 0;
  for (int a = 0; a < n; a++)
    for (int b = 0; b < n; b++) {
      double u = rs[0] + (rs[1] - rs[0]) * GL_X[n][a], v = rs[2] + (rs[3] - rs[2]) * GL_X[n][b];
      double x[3];
      bilinear(s->q, u, v, x);
      double w0[3];
      sub3(x, r->c, w0);
      if (!(dot3(r->n, w0) > 0)) continue;
      double inner = 0;
      for (int e = 0; e < n; e++)
        for (int f = 0; f < n; f++) {
          double w[3];
          sub3(ys[e][f], x, w);
          double d2 = dot3(w, w);
          if (!(d2 > 0)) continue;
          double id = 1.0 / sqrt(d2);
          double ce = dot3(c->emit, w) * id, cg = dot3(s->n, w) * id, crv = -dot3(r->n, w) * id;
          if (cg <= 0 || crv <= 0) continue;
          /* the difference to the Lambertian kernel (added back exactly) */
          double k = (ce > 0 ? c->lobe * powc(ce, c->cexp) : 0.0) - cg * (1.0 / PI);
          inner += wr[e][f] * k * crv / d2;
        }
      c->evals += (uint64_t)(n * n);
      if (inner != 0 && c->vis) inner *= visible(c, x);
      sum += GL_W[n][a] * GL_W[n][b] * bilinear_jac(s->q, u, v) * inner;
    }
  return sum * (rs[1] - rs[0]) * (rs[3] - rs[2]) * (rr[1] - rr[0]) * (rr[3] - rr[2]);
}

static double circumradius(const cv_patch *p) {
  double r = 0;
  for (int k = 0; k < 4; k++) r = fmax(r, dist3(p->q[k], p->c));
  return r;
}

/* 1 when every corner of a is on or behind the plane of b (within tol). */
static int behind_plane(const cv_patch *a, const cv_patch *b, double tol) {
  for (int k = 0; k < 4; k++) {
    double w[3];
    sub3(a->q[k], b->c, w);
    if (dot3(b->n, w) > tol) return 0;
  }
  return 1;
}

static int is_lambert(const cv_display_surface *s) {
  return s->cosine_exponent == 1.0 && s->normal_tilt_deg == 0.0;
}

typedef struct pair_stats {
  uint64_t evals, rays;
  size_t refined, clamped;
} pair_stats;

/* F_ji (sender j, receiver i) with optional visibility. */
static double pair_value(const cv_display *d, size_t j, size_t i, const vis_ctx *vis,
                         pair_stats *st) {
  if (i == j) return 0;
  const cv_patch *pj = &d->patches[j], *pi = &d->patches[i];
  const double tol = 1e-9 * (sqrt(pj->area) + sqrt(pi->area));
  if (behind_plane(pj, pi, tol) || behind_plane(pi, pj, tol)) return 0;
  const cv_display_surface *sj = &d->surfaces[pj->surface], *si = &d->surfaces[pi->surface];
  pair_ctx c;
  memset(&c, 0, sizeof c);
  c.vis = vis;
  double value;
  if (is_lambert(sj) && is_lambert(si)) {
    /* G = A_s F_{s->r} is symmetric: integrate over the smaller patch. */
    int j_sends = pj->area < pi->area || (pj->area == pi->area && j < i);
    c.s = j_sends ? pj : pi;
    c.r = j_sends ? pi : pj;
    memcpy(c.emit, c.s->n, sizeof c.emit);
    c.scale = 1.0;
    c.cexp = 1.0;
    c.rr = circumradius(c.r);
    double G = sender_rec(&c, 0, 1, 0, 1, 0);
    value = G / pj->area;
  } else {
    c.s = pj;
    c.r = pi;
    memcpy(c.emit, pj->nt, sizeof c.emit);
    c.clip_geo = sj->normal_tilt_deg != 0.0;
    c.cexp = sj->cosine_exponent;
    c.lobe = sj->lobe_norm;
    c.scale = PI * sj->lobe_norm;
    c.rr = circumradius(pi);
    if (c.cexp == 1.0) {
      value = sender_rec(&c, 0, 1, 0, 1, 0) / pj->area;
    } else {
      /* F_c = F_Lambert (contour, exact at shared edges) + the difference
       * of the kernels by the product rule: the difference of two lobes
       * that both integrate to 1 is small where the product rule is weak. */
      const double unit[4] = {0, 1, 0, 1};
      pair_ctx l = c;
      memcpy(l.emit, pj->n, sizeof l.emit);
      l.clip_geo = 0;
      l.scale = 1.0;
      l.cexp = 1.0;
      double f1 = sender_rec(&l, 0, 1, 0, 1, 0);
      double dk = pair_product(&c, unit, unit, 0);
      c.evals += l.evals;
      c.rays += l.rays;
      c.refined |= l.refined;
      value = (f1 + dk) / pj->area;
    }
  }
  /* Rounding can leave a grazing pair (or F_1 + D) a hair below zero; a
   * non-finite value would mean a degenerate patch.  Both become 0 and are
   * counted when they are not negligible (below -1e-9 relative to 1). */
  int bad = !isfinite(value) || value < -1e-9;
  if (st) {
    st->evals += c.evals;
    st->rays += c.rays;
    st->refined += (size_t)c.refined;
    st->clamped += (size_t)bad;
  }
  return isfinite(value) && value > 0 ? value : 0.0;
}

double cv_ff_patch_pair(const cv_display *d, size_t j, size_t i) {
  if (i >= d->n_patches || j >= d->n_patches) return 0;
  return pair_value(d, j, i, NULL, NULL);
}

/* --- visibility: can any segment between two patches cross a third? ------ */

/* 1 when p is in the closed inner region of surface s (within eps). */
static int in_region(const cv_display_surface *s, const double p[3], double eps) {
  double w[3];
  switch (s->kind) {
  case CV_SURFACE_PLANE: {
    double e1[3], e2[3], n[3];
    sub3(s->pb, s->pa, e1);
    sub3(s->pc, s->pa, e2);
    cross3(e1, e2, n);
    double ln = len3(n);
    sub3(p, s->pa, w);
    return dot3(n, w) / ln >= -eps;
  }
  case CV_SURFACE_CYLINDER:
    return hypot(p[0] - s->center[0], p[2] - s->center[2]) <= s->radius + eps;
  case CV_SURFACE_DOME:
    sub3(p, s->center, w);
    return len3(w) <= s->radius + eps;
  }
  return 0;
}

/* 0 when the surfaces provably cannot occlude each other: every surface
 * lies in the inner region of every other one, so all of them lie on the
 * boundary of the intersection of those convex regions, and a segment
 * between two boundary points of a convex set does not cross the boundary
 * (up to the faceting of curved surfaces into chord quads). */
static int may_occlude(const cv_display *d) {
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < d->n_patches; i++)
    for (int k = 0; k < 4; k++)
      for (int a = 0; a < 3; a++) {
        lo[a] = fmin(lo[a], d->patches[i].q[k][a]);
        hi[a] = fmax(hi[a], d->patches[i].q[k][a]);
      }
  double diag[3];
  sub3(hi, lo, diag);
  const double eps = 1e-6 * len3(diag) + 1e-12;
  for (size_t k = 0; k < d->n_surfaces; k++)
    for (size_t i = 0; i < d->n_patches; i++) {
      if (d->patches[i].surface == k) continue;
      for (int c = 0; c < 4; c++)
        if (!in_region(&d->surfaces[k], d->patches[i].q[c], eps)) return 1;
    }
  return 0;
}

static int build_rt(const cv_display *d, cv_rt **rt, double *diag_out, cv_err *err) {
  cv_mesh *m = NULL;
  int st = cv_mesh_create(&m);
  if (st) return cv_err_set(err, st, "form factors: out of memory");
  const float alb[3] = {0.5f, 0.5f, 0.5f};
  uint32_t mat;
  st = cv_mesh_add_material(m, "screen", alb, 0, &mat);
  if (!st) st = cv_mesh_reserve(m, 4 * d->n_patches, 2 * d->n_patches);
  for (size_t i = 0; i < d->n_patches && !st; i++) {
    const cv_patch *p = &d->patches[i];
    uint32_t v0 = 0;
    for (int k = 0; k < 4 && !st; k++) {
      uint32_t idx;
      st = cv_mesh_add_vertex(m, (float)p->q[k][0], (float)p->q[k][1], (float)p->q[k][2], &idx);
      if (k == 0) v0 = idx;
    }
    if (!st) st = cv_mesh_add_tri(m, v0, v0 + 1, v0 + 2, mat);
    if (!st) st = cv_mesh_add_tri(m, v0, v0 + 2, v0 + 3, mat);
  }
  if (st) {
    cv_mesh_destroy(m);
    return cv_err_set(err, st, "form factors: building the visibility mesh: %s",
                      cv_status_str(st));
  }
  *diag_out = cv_mesh_diagonal(m);
  st = cv_rt_create(m, rt, err);
  cv_mesh_destroy(m);
  if (st) return cv_err_prefix(err, "form factors: visibility");
  return CV_OK;
}

/* --- matrix build ------------------------------------------------------------ */

void cv_ff_params_default(cv_ff_params *p) {
  memset(p, 0, sizeof *p);
  p->visibility = CV_FF_VIS_AUTO;
  p->rel_threshold = 0.0;
  p->drop_budget = 1e-3;
  p->quiet = 0;
}

/* Upper-triangle pass output for row i: senders j > i with both directions,
 * a = F_ji (row i, column j) and b = F_ij (row j, column i). */
typedef struct upper_row {
  uint32_t *col;
  float *a, *b;
  size_t cnt;
  pair_stats st;
} upper_row;

static int cmp_float(const void *x, const void *y) {
  float u = *(const float *)x, v = *(const float *)y;
  return (u > v) - (u < v);
}

/* Corner points of a planar surface (for the whole-surface rejection). */
static void surface_corners(const cv_display_surface *s, double q[4][3]) {
  for (int a = 0; a < 3; a++) {
    q[0][a] = s->pa[a];
    q[1][a] = s->pb[a];
    q[2][a] = s->pc[a];
    q[3][a] = s->pb[a] + s->pc[a] - s->pa[a];
  }
}

/* The parameters' checks shared by the dense build and the kernel. */
static int check_params(const cv_ff_params *params, cv_ff_params *p, cv_err *err) {
  if (params)
    *p = *params;
  else
    cv_ff_params_default(p);
  if (!(p->rel_threshold >= 0 && p->rel_threshold < 1))
    return cv_err_set(err, CV_ERR_INVALID, "form factors: rel_threshold %g is outside [0, 1)",
                      p->rel_threshold);
  if (!(p->drop_budget >= 0 && p->drop_budget < 1))
    return cv_err_set(err, CV_ERR_INVALID, "form factors: drop_budget %g is outside [0, 1)",
                      p->drop_budget);
  if (p->visibility != CV_FF_VIS_AUTO && p->visibility != CV_FF_VIS_NONE &&
      p->visibility != CV_FF_VIS_RAYS)
    return cv_err_set(err, CV_ERR_INVALID, "form factors: unknown visibility mode %d",
                      (int)p->visibility);
  return CV_OK;
}

struct cv_ff_kernel {
  const cv_display *d;
  int trace;
  vis_ctx vis;
  unsigned char *skip; /* ns x ns: 1 = the two surfaces exchange no light */
};

void cv_ff_kernel_destroy(cv_ff_kernel *k) {
  if (!k) return;
  cv_rt_destroy(k->vis.rt);
  free(k->skip);
  free(k);
}

int cv_ff_kernel_create(const cv_display *d, const cv_ff_params *params, cv_ff_kernel **out,
                        cv_err *err) {
  *out = NULL;
  cv_ff_params p;
  int st = check_params(params, &p, err);
  if (st) return st;
  const size_t n = d->n_patches;
  if (n == 0 || n >= UINT32_MAX)
    return cv_err_set(err, CV_ERR_INVALID, "form factors: %zu patches", n);
  cv_ff_kernel *k = calloc(1, sizeof *k);
  const size_t ns = d->n_surfaces;
  if (k) k->skip = calloc(ns * ns, 1);
  if (!k || !k->skip) {
    cv_ff_kernel_destroy(k);
    return cv_err_set(err, CV_ERR_NOMEM, "form factors: out of memory");
  }
  k->d = d;
  k->trace =
      p.visibility == CV_FF_VIS_RAYS || (p.visibility == CV_FF_VIS_AUTO && may_occlude(d));
  if (k->trace) {
    double diag = 0;
    st = build_rt(d, &k->vis.rt, &diag, err);
    if (st) {
      cv_ff_kernel_destroy(k);
      return st;
    }
    k->vis.eps = 1e-5 * diag;
  }
  /* Planar surfaces entirely behind (or in) the plane of another planar
   * surface never exchange light: skip whole blocks of senders. */
  for (size_t a = 0; a < ns; a++)
    for (size_t b = 0; b < ns; b++) {
      const cv_display_surface *sa = &d->surfaces[a], *sb = &d->surfaces[b];
      if (sa->kind != CV_SURFACE_PLANE || sb->kind != CV_SURFACE_PLANE) continue;
      cv_patch qa, qb; /* only q, c and n are used by behind_plane */
      memset(&qa, 0, sizeof qa);
      memset(&qb, 0, sizeof qb);
      surface_corners(sa, qa.q);
      surface_corners(sb, qb.q);
      const cv_patch *pa = &d->patches[sa->offset], *pb = &d->patches[sb->offset];
      memcpy(qa.c, pa->c, sizeof qa.c);
      memcpy(qa.n, pa->n, sizeof qa.n);
      memcpy(qb.c, pb->c, sizeof qb.c);
      memcpy(qb.n, pb->n, sizeof qb.n);
      double tol = 1e-9 * (dist3(sa->pa, sa->pb) + dist3(sb->pa, sb->pb));
      k->skip[a * ns + b] =
          (unsigned char)(behind_plane(&qb, &qa, tol) || behind_plane(&qa, &qb, tol));
    }
  *out = k;
  return CV_OK;
}

int cv_ff_kernel_traces(const cv_ff_kernel *k) { return k->trace; }
const cv_display *cv_ff_kernel_display(const cv_ff_kernel *k) { return k->d; }

void cv_ff_kernel_thread_init(const cv_ff_kernel *k) {
  if (k->trace) cv_rt_thread_init();
}

int cv_ff_kernel_surfaces_exchange(const cv_ff_kernel *k, size_t a, size_t b) {
  return !k->skip[a * k->d->n_surfaces + b];
}

double cv_ff_kernel_gather(const cv_ff_kernel *k, size_t i, size_t j) {
  const cv_display *d = k->d;
  if (i == j || i >= d->n_patches || j >= d->n_patches) return 0;
  const cv_patch *pi = &d->patches[i], *pj = &d->patches[j];
  if (k->skip[pi->surface * d->n_surfaces + pj->surface]) return 0;
  const double f = pair_value(d, j, i, k->trace ? &k->vis : NULL, NULL);
  return f > 0 ? f * (pj->area / pi->area) : 0.0;
}

/* Pass 1, one row: the senders j > i of patch i (both directions of each
 * pair) into ur, using the scratch tc/ta/tb (n entries each).  Returns 1
 * when out of memory. */
static int upper_row_fill(const cv_display *d, const cv_ff_kernel *kern, size_t i, uint32_t *tc,
                          float *ta, float *tb, upper_row *ur) {
  const int trace = kern->trace;
  const vis_ctx *vis = trace ? &kern->vis : NULL;
  const unsigned char *skip = kern->skip;
  const size_t ns = d->n_surfaces;
  const cv_patch *pi = &d->patches[i];
  const int li = is_lambert(&d->surfaces[pi->surface]);
  size_t m = 0;
  for (size_t k = 0; k < ns; k++) {
    if (skip[pi->surface * ns + k]) continue;
    const cv_display_surface *sk = &d->surfaces[k];
    size_t j0 = sk->offset, j1 = sk->offset + (size_t)sk->nu * sk->nv;
    if (j1 <= i + 1) continue;
    if (j0 < i + 1) j0 = i + 1;
    const int lk = is_lambert(sk);
    for (size_t j = j0; j < j1; j++) {
      double fji, fij;
      if (li && lk) {
        fji = pair_value(d, j, i, vis, &ur->st);
        fij = fji * d->patches[j].area / pi->area; /* reciprocity */
      } else {
        fji = pair_value(d, j, i, vis, &ur->st);
        fij = pair_value(d, i, j, vis, &ur->st);
      }
      if (fji > 0 || fij > 0) {
        tc[m] = (uint32_t)j;
        ta[m] = (float)fji;
        tb[m++] = (float)fij;
      }
    }
  }
  ur->col = malloc((m ? m : 1) * sizeof *ur->col);
  ur->a = malloc((m ? m : 1) * sizeof *ur->a);
  ur->b = malloc((m ? m : 1) * sizeof *ur->b);
  if (!ur->col || !ur->a || !ur->b) return 1;
  memcpy(ur->col, tc, m * sizeof *tc);
  memcpy(ur->a, ta, m * sizeof *ta);
  memcpy(ur->b, tb, m * sizeof *tb);
  ur->cnt = m;
  return 0;
}

/* Pass 1: every unordered pair once (row i, senders j > i), both
 * directions.  Rows are independent: the result does not depend on the
 * schedule.  Returns 1 when out of memory. */
static int pass_upper(const cv_display *d, const cv_ff_kernel *kern, int quiet, upper_row *up) {
  const size_t n = d->n_patches;
  cv_progress *prog = NULL;
  if (n >= 2048)
    cv_progress_create_ex("form factors", (uint64_t)n * (n - 1) / 2,
                          quiet ? CV_PROGRESS_QUIET : 0, NULL, &prog);
  int nomem = 0;
#pragma omp parallel
  {
    uint32_t *tc = malloc(n * sizeof *tc);
    float *ta = malloc(n * sizeof *ta), *tb = malloc(n * sizeof *tb);
    if (!tc || !ta || !tb) {
#pragma omp atomic write
      nomem = 1;
    }
    if (kern->trace) cv_rt_thread_init();
#pragma omp for schedule(dynamic, 4)
    for (size_t i = 0; i < n; i++) {
      if (!tc || !ta || !tb) continue;
      if (upper_row_fill(d, kern, i, tc, ta, tb, &up[i])) {
#pragma omp atomic write
        nomem = 1;
        continue;
      }
      cv_progress_add(prog, n - 1 - i);
    }
    free(tc);
    free(ta);
    free(tb);
  }
  cv_progress_finish(prog);
  cv_progress_destroy(prog);
  return nomem;
}

/* Pass 2: the full gather rows (lower part = transposed upper lists),
 * columns ascending; zero entries are not stored.  off (n + 1) gets the row
 * offsets, *fcol / *fval the entries (*nnz_full of them).  Returns 1 when
 * out of memory. */
static int pass_gather_rows(const cv_display *d, const upper_row *up, size_t *off, uint32_t **fcol_out,
                            float **fval_out, size_t *nnz_full) {
  const size_t n = d->n_patches;
  for (size_t i = 0; i < n; i++)
    for (size_t k = 0; k < up[i].cnt; k++) {
      off[i] += up[i].a[k] > 0;
      off[up[i].col[k]] += up[i].b[k] > 0;
    }
  *nnz_full = 0;
  for (size_t i = 0; i < n; i++) {
    size_t c = off[i];
    off[i] = *nnz_full;
    *nnz_full += c;
  }
  off[n] = *nnz_full;
  uint32_t *fcol = *fcol_out = malloc((*nnz_full + 1) * sizeof *fcol);
  float *fval = *fval_out = malloc((*nnz_full + 1) * sizeof *fval);
  size_t *fill = malloc((n + 1) * sizeof *fill);
  if (!fcol || !fval || !fill) {
    free(fill);
    return 1;
  }
  memcpy(fill, off, (n + 1) * sizeof *fill);
  /* lower entries first (k < i, in ascending k), then the upper list */
  for (size_t k = 0; k < n; k++) {
    const upper_row *ur = &up[k];
    for (size_t e = 0; e < ur->cnt; e++) {
      size_t i = ur->col[e];
      /* Row r gathers the light sender c puts on r per unit of r's area:
       * G_rc = (A_c / A_r) F_{c->r} (sender c's own lobe), which is
       * F_{r->c} for Lambertian patches by reciprocity. */
      if (ur->b[e] > 0) {
        fcol[fill[i]] = (uint32_t)k;
        fval[fill[i]++] = (float)(ur->b[e] * (d->patches[k].area / d->patches[i].area));
      }
    }
    for (size_t e = 0; e < ur->cnt; e++)
      if (ur->a[e] > 0) {
        fcol[fill[k]] = ur->col[e];
        fval[fill[k]++] = (float)(ur->a[e] * (d->patches[ur->col[e]].area / d->patches[k].area));
      }
  }
  /* the upper entries of row k were appended after all its lower
   * entries only if every lower entry came first: true, because the
   * lower entries of row k come from rows < k, processed earlier. */
  free(fill);
  return 0;
}

/* Pass 1's statistics into r, and its rows freed. */
static void upper_rows_free(upper_row *up, size_t n, cv_ff_report *r) {
  for (size_t i = 0; i < n; i++) {
    r->point_evals += up[i].st.evals;
    r->rays += up[i].st.rays;
    r->refined_pairs += up[i].st.refined;
    r->clamped_pairs += up[i].st.clamped;
    free(up[i].col);
    free(up[i].a);
    free(up[i].b);
  }
  free(up);
}

/* Pass 3, one row: keeps the entries of row [b, e) at or above the cut
 * (rel_threshold of the row's energy, raised while the dropped energy fits
 * drop_budget), compacting the row in place; sum, dropped energy and kept
 * count out.  sorted: scratch of e - b entries. */
static void sparsify_row(const cv_ff_params *p, size_t b, size_t e, uint32_t *fcol, float *fval,
                         float *sorted, double *rsum, double *rdrop, size_t *kept) {
  double sum = 0;
  for (size_t k = b; k < e; k++) sum += fval[k];
  double cut = p->rel_threshold * sum;
  if (p->drop_budget > 0 && e > b) {
    size_t q = 0;
    double below = 0;
    for (size_t k = b; k < e; k++) {
      if (fval[k] < cut)
        below += fval[k];
      else
        sorted[q++] = fval[k];
    }
    qsort(sorted, q, sizeof *sorted, cmp_float);
    double budget = p->drop_budget * sum - below, acc = 0;
    size_t k = 0;
    while (k < q && acc + sorted[k] <= budget) acc += sorted[k++];
    if (k > 0 && k < q) cut = fmax(cut, sorted[k]);
  }
  size_t w = b;
  double dropped = 0;
  for (size_t k = b; k < e; k++) {
    if (fval[k] >= cut) {
      fcol[w] = fcol[k];
      fval[w++] = fval[k];
    } else {
      dropped += fval[k];
    }
  }
  *rsum = sum;
  *rdrop = dropped;
  *kept = w - b;
}

/* Pass 3: sparsify each row relative to its energy.  Returns 1 when out of
 * memory. */
static int pass_sparsify(const cv_ff_params *p, size_t n, const size_t *off, uint32_t *fcol,
                         float *fval, double *rsum, double *rdrop, size_t *kept) {
  int nomem = 0;
#pragma omp parallel
  {
    float *sorted = malloc((n + 1) * sizeof *sorted);
    if (!sorted) {
#pragma omp atomic write
      nomem = 1;
    }
#pragma omp for schedule(dynamic, 16)
    for (size_t i = 0; i < n; i++) {
      if (!sorted) continue;
      sparsify_row(p, off[i], off[i + 1], fcol, fval, sorted, &rsum[i], &rdrop[i], &kept[i]);
    }
    free(sorted);
  }
  return nomem;
}

/* The kept entries of every row into F (allocated here), and the row and
 * column sums and dropped shares into r. */
static int assemble(size_t n, const size_t *off, const uint32_t *fcol, const float *fval,
                    const size_t *kept, const double *rsum, const double *rdrop, cv_ffmatrix **out,
                    cv_ff_report *r) {
  size_t nnz = 0;
  for (size_t i = 0; i < n; i++) nnz += kept[i];
  cv_ffmatrix *F = NULL;
  int st = cv_ffmatrix_alloc(n, nnz, &F);
  double *colsum = st ? NULL : calloc(n, sizeof *colsum);
  if (!st && !colsum) st = CV_ERR_NOMEM;
  if (st) {
    cv_ffmatrix_destroy(F);
    return st;
  }
  size_t o = 0, with_energy = 0;
  double tot = 0, tot_drop = 0, drop_sum = 0;
  r->row_sum_min = INFINITY;
  for (size_t i = 0; i < n; i++) {
    F->row_off[i] = o;
    memcpy(F->col + o, fcol + off[i], kept[i] * sizeof *fcol);
    memcpy(F->val + o, fval + off[i], kept[i] * sizeof *fval);
    for (size_t k = o; k < o + kept[i]; k++) colsum[F->col[k]] += F->val[k];
    o += kept[i];
    r->row_sum_min = fmin(r->row_sum_min, rsum[i]);
    r->row_sum_max = fmax(r->row_sum_max, rsum[i]);
    r->row_sum_mean += rsum[i] / (double)n;
    tot += rsum[i];
    tot_drop += rdrop[i];
    if (rsum[i] > 0) {
      double frac = rdrop[i] / rsum[i];
      r->dropped_max = fmax(r->dropped_max, frac);
      drop_sum += frac;
      with_energy++;
    }
  }
  F->row_off[n] = o;
  for (size_t j = 0; j < n; j++) r->col_sum_max = fmax(r->col_sum_max, colsum[j]);
  r->dropped_mean = with_energy ? drop_sum / (double)with_energy : 0;
  r->dropped_total = tot > 0 ? tot_drop / tot : 0;
  r->nnz = nnz;
  free(colsum);
  *out = F;
  return CV_OK;
}

int cv_formfactors_build(const cv_display *d, const cv_ff_params *params, cv_ffmatrix **F_gather,
                         cv_ff_report *rep, cv_err *err) {
  *F_gather = NULL;
  cv_ff_params p;
  int kst = check_params(params, &p, err);
  if (kst) return kst;
  const double t_start = cv_now_seconds();
  const size_t n = d->n_patches;
  cv_ff_kernel *kern = NULL;
  kst = cv_ff_kernel_create(d, &p, &kern, err);
  if (kst) return kst;
  const int trace = kern->trace;
  upper_row *up = calloc(n, sizeof *up);
  size_t *off = calloc(n + 1, sizeof *off);
  if (!up || !off) {
    free(up);
    free(off);
    cv_ff_kernel_destroy(kern);
    return cv_err_set(err, CV_ERR_NOMEM, "form factors: out of memory");
  }
  int nomem = pass_upper(d, kern, p.quiet, up);
  cv_ff_kernel_destroy(kern);

  cv_ff_report r;
  memset(&r, 0, sizeof r);
  uint32_t *fcol = NULL;
  float *fval = NULL;
  size_t nnz_full = 0;
  if (!nomem) nomem = pass_gather_rows(d, up, off, &fcol, &fval, &nnz_full);
  upper_rows_free(up, n, &r);

  double *rsum = NULL, *rdrop = NULL;
  size_t *kept = NULL;
  if (!nomem) {
    rsum = calloc(n, sizeof *rsum);
    rdrop = calloc(n, sizeof *rdrop);
    kept = calloc(n + 1, sizeof *kept);
    if (!rsum || !rdrop || !kept) nomem = 1;
  }
  if (!nomem) nomem = pass_sparsify(&p, n, off, fcol, fval, rsum, rdrop, kept);

  cv_ffmatrix *F = NULL;
  int st = nomem ? CV_ERR_NOMEM : assemble(n, off, fcol, fval, kept, rsum, rdrop, &F, &r);
  free(fcol);
  free(fval);
  free(off);
  free(rsum);
  free(rdrop);
  free(kept);
  if (st)
    return cv_err_set(err, st, "form factors: out of memory (%zu patches, %zu entries)", n,
                      nnz_full);
  r.n = n;
  r.nnz_full = nnz_full;
  r.visibility_traced = trace;
  r.seconds = cv_now_seconds() - t_start;
  if (rep) *rep = r;
  *F_gather = F;
  return CV_OK;
}
