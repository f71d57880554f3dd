/* Parametric car-cabin generator (see cabin.h).
 *
 * Everything is built from structured quad grids.  A grid is given by a left
 * and a right end point per row and a list of parameters across the row; its
 * vertices are lerp(L[j], R[j], u[i]).  Neighbouring grids that meet along an
 * edge evaluate that edge with the SAME end points, the SAME parameter list
 * and the SAME lerp, so their vertices along the edge are bit-identical: the
 * surface is watertight by position although vertices are duplicated across
 * creases (each face owns its vertices, so the PRT bake, which averages
 * samples into vertices, never mixes a floor with a wall).
 *
 * Layout: all object coordinates are designed for the default 2.6 x 1.45 x
 * 1.2 m cabin and mapped through S() (a per-axis scale) to the requested
 * dimensions; the steering-wheel sizes and the LCD size stay absolute. */
#include "mesh/cabin.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Design dimensions (metres) that the layout below is drawn for. */
#define D_LEN 2.6
#define D_WID 1.45
#define D_HGT 1.2
/* Edge length of grid cells at tess = 1; tuned so tess 1 gives ~10K triangles. */
#define CELL_H 0.09
#define LCD_W 0.20
#define LCD_H 0.12
#define TESS_MAX 64
#define CV_PI 3.14159265358979323846

typedef struct bld {
  cv_mesh *m; /* NULL: count only */
  size_t nv, nt;
  int status;
  double scale[3]; /* design -> actual, per axis */
  double h;        /* cell edge length = CELL_H / tess */
  int tess;
} bld;

typedef struct axis {
  int n;     /* segments */
  double *t; /* n + 1 parameters in [0, 1], increasing, t[0] = 0, t[n] = 1 */
} axis;

typedef struct region {
  double u0, u1, v0, v1; /* cells whose centre lies inside get `mat` */
  uint32_t mat;
} region;

enum { M_CARPET, M_ROOF, M_TRIM, M_DASH, M_LCD, M_SEAT, M_WHEEL, M_CONSOLE,
       M_WIN_WS, M_WIN_FL, M_WIN_RL, M_WIN_FR, M_WIN_RR, M_WIN_REAR, M_COUNT };

static const struct {
  const char *name;
  float albedo[3];
  uint32_t flags;
} k_mats[M_COUNT] = {
    {"floor_carpet", {0.10f, 0.10f, 0.10f}, 0},
    {"roof_liner", {0.72f, 0.70f, 0.66f}, 0},
    {"body_trim", {0.30f, 0.29f, 0.28f}, 0},
    {"dashboard", {0.10f, 0.10f, 0.10f}, 0},
    {"lcd_panel", {0.03f, 0.03f, 0.03f}, CV_MAT_LCD},
    {"seat_fabric", {0.45f, 0.42f, 0.38f}, 0},
    {"steering_wheel", {0.06f, 0.06f, 0.06f}, 0},
    {"console", {0.12f, 0.12f, 0.12f}, 0},
    {"window_windshield", {0, 0, 0}, CV_MAT_WINDOW},
    {"window_front_left", {0, 0, 0}, CV_MAT_WINDOW},
    {"window_rear_left", {0, 0, 0}, CV_MAT_WINDOW},
    {"window_front_right", {0, 0, 0}, CV_MAT_WINDOW},
    {"window_rear_right", {0, 0, 0}, CV_MAT_WINDOW},
    {"window_rear", {0, 0, 0}, CV_MAT_WINDOW},
};

/* ---- small vector helpers (double) ---- */
static void v_set(double o[3], double x, double y, double z) { o[0] = x, o[1] = y, o[2] = z; }
static void v_sub(const double a[3], const double b[3], double o[3]) {
  for (int k = 0; k < 3; k++) o[k] = a[k] - b[k];
}
static double v_dot(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static void v_cross(const double a[3], const double b[3], double o[3]) {
  double r[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  memcpy(o, r, sizeof r);
}
static void v_norm(double a[3]) {
  double l = sqrt(v_dot(a, a));
  if (l > 0)
    for (int k = 0; k < 3; k++) a[k] /= l;
}
/* a + t (b - a), returning the end points exactly at t = 0 and t = 1 so that
 * grids sharing an edge agree bit for bit at the corners. */
static void lerp3(const double a[3], const double b[3], double t, double o[3]) {
  if (t <= 0.0) {
    memcpy(o, a, 3 * sizeof(double));
  } else if (t >= 1.0) {
    memcpy(o, b, 3 * sizeof(double));
  } else {
    for (int k = 0; k < 3; k++) o[k] = a[k] + t * (b[k] - a[k]);
  }
}

/* Design coordinates -> actual coordinates. */
static void S(const bld *b, double x, double y, double z, double o[3]) {
  o[0] = x * b->scale[0];
  o[1] = y * b->scale[1];
  o[2] = z * b->scale[2];
}

/* ---- output ---- */
static uint32_t add_v(bld *b, const double p[3]) {
  uint32_t idx = (uint32_t)b->nv++;
  if (b->m && !b->status) b->status = cv_mesh_add_vertex(b->m, (float)p[0], (float)p[1], (float)p[2], NULL);
  return idx;
}
static void add_t(bld *b, uint32_t a, uint32_t c, uint32_t d, uint32_t mat) {
  b->nt++;
  if (b->m && !b->status) b->status = cv_mesh_add_tri(b->m, a, c, d, mat);
}

/* ---- axes ---- */
/* Piecewise-uniform parameters: knots k[0] = 0 < ... < k[nk-1] = 1, each
 * interval split into ceil(len * dk * tess / CELL_H) >= 1 segments, where len
 * is the longest physical edge the axis is used on. */
static int axis_make(bld *b, axis *a, const double *k, int nk, double len) {
  int n = 0;
  int seg[16];
  for (int i = 0; i + 1 < nk; i++) {
    double cells = (k[i + 1] - k[i]) * len / b->h;
    int s = (int)ceil(cells - 1e-9);
    seg[i] = s < 1 ? 1 : s;
    n += seg[i];
  }
  a->n = n;
  a->t = malloc((size_t)(n + 1) * sizeof(double));
  if (!a->t) return CV_ERR_NOMEM;
  int j = 0;
  for (int i = 0; i + 1 < nk; i++)
    for (int s = 0; s < seg[i]; s++) a->t[j++] = k[i] + (k[i + 1] - k[i]) * s / seg[i];
  a->t[n] = 1.0;
  return CV_OK;
}
static int axis_uniform(bld *b, axis *a, double len) {
  static const double k01[2] = {0.0, 1.0};
  return axis_make(b, a, k01, 2, len);
}
static void axis_free(axis *a) {
  free(a->t);
  a->t = NULL;
}

/* ---- structured grid ---- */
/* Grid of (nu+1) x (nv+1) vertices, vertex (i, j) = lerp(L[j], R[j], u[i]).
 * The winding is chosen so that the normal points towards `ref` (toward =
 * 1, the cabin shell) or away from it (toward = 0, closed objects).  Cell
 * (i, j) gets the material of the first region containing its parameter
 * centre ((u[i]+u[i+1])/2, (v[j]+v[j+1])/2), else `mat`. */
static void grid(bld *b, const axis *au, const double *v, int nv, const double (*L)[3],
                 const double (*R)[3], const double ref[3], int toward, uint32_t mat,
                 const region *rg, int nrg) {
  int nu = au->n;
  /* Newell normal of the outline L0 R0 Rn Ln decides the orientation. */
  const double *q[4] = {L[0], R[0], R[nv], L[nv]};
  double n[3] = {0, 0, 0}, c[3] = {0, 0, 0};
  for (int e = 0; e < 4; e++) {
    const double *p0 = q[e], *p1 = q[(e + 1) % 4];
    n[0] += (p0[1] - p1[1]) * (p0[2] + p1[2]);
    n[1] += (p0[2] - p1[2]) * (p0[0] + p1[0]);
    n[2] += (p0[0] - p1[0]) * (p0[1] + p1[1]);
    for (int k = 0; k < 3; k++) c[k] += 0.25 * p0[k];
  }
  double d[3];
  v_sub(ref, c, d); /* points from the patch to ref */
  int flip = toward ? (v_dot(n, d) < 0) : (v_dot(n, d) > 0);

  uint32_t base = (uint32_t)b->nv;
  for (int j = 0; j <= nv; j++)
    for (int i = 0; i <= nu; i++) {
      double p[3];
      lerp3(L[j], R[j], au->t[i], p);
      add_v(b, p);
    }
  for (int j = 0; j < nv; j++) {
    double vc = 0.5 * (v[j] + v[j + 1]);
    for (int i = 0; i < nu; i++) {
      double uc = 0.5 * (au->t[i] + au->t[i + 1]);
      uint32_t mt = mat;
      for (int r = 0; r < nrg; r++)
        if (uc > rg[r].u0 && uc < rg[r].u1 && vc > rg[r].v0 && vc < rg[r].v1) {
          mt = rg[r].mat;
          break;
        }
      uint32_t a = base + (uint32_t)(j * (nu + 1) + i), bb = a + 1;
      uint32_t dd = a + (uint32_t)(nu + 1), cc = dd + 1;
      if (!flip) {
        add_t(b, a, bb, cc, mt);
        add_t(b, a, cc, dd, mt);
      } else {
        add_t(b, a, cc, bb, mt);
        add_t(b, a, dd, cc, mt);
      }
    }
  }
}

/* Bilinear quad patch with corners c00 (u=0,v=0), c10, c01, c11. */
static int patch(bld *b, const double c00[3], const double c10[3], const double c01[3],
                 const double c11[3], const axis *au, const axis *av, const double ref[3],
                 int toward, uint32_t mat, const region *rg, int nrg) {
  double(*L)[3] = malloc((size_t)(av->n + 1) * sizeof *L);
  double(*R)[3] = malloc((size_t)(av->n + 1) * sizeof *R);
  if (!L || !R) {
    free(L);
    free(R);
    return CV_ERR_NOMEM;
  }
  for (int j = 0; j <= av->n; j++) {
    lerp3(c00, c01, av->t[j], L[j]);
    lerp3(c10, c11, av->t[j], R[j]);
  }
  grid(b, au, av->t, av->n, (const double(*)[3])L, (const double(*)[3])R, ref, toward, mat, rg,
       nrg);
  free(L);
  free(R);
  return CV_OK;
}

static double dist3(const double a[3], const double b[3]) {
  double d[3];
  v_sub(a, b, d);
  return sqrt(v_dot(d, d));
}

/* Hexahedron with corners c[i + 2j + 4k] (i along the first axis, j the
 * second, k the third), faces wound outward, every face its own vertices.
 * Axes are given as knot lists (NULL = uniform); `rg` tags cells of the
 * face k = 1 (parameters u along i, v along j). */
static int hexa(bld *b, const double c[8][3], const double *ku, int nku, const double *kv,
                int nkv, uint32_t mat, const region *rg, int nrg) {
  static const double k01[2] = {0.0, 1.0};
  double len[3] = {0, 0, 0}; /* longest edge along each direction */
  for (int a = 0; a < 3; a++)
    for (int q = 0; q < 8; q++)
      if (!(q & (1 << a))) {
        double l = dist3(c[q], c[q | (1 << a)]);
        if (l > len[a]) len[a] = l;
      }
  axis ax[3] = {{0, NULL}, {0, NULL}, {0, NULL}};
  int st = axis_make(b, &ax[0], ku ? ku : k01, ku ? nku : 2, len[0]);
  if (!st) st = axis_make(b, &ax[1], kv ? kv : k01, kv ? nkv : 2, len[1]);
  if (!st) st = axis_uniform(b, &ax[2], len[2]);
  double ctr[3] = {0, 0, 0};
  for (int q = 0; q < 8; q++)
    for (int k = 0; k < 3; k++) ctr[k] += 0.125 * c[q][k];
#define C(i, j, k) c[(i) + 2 * (j) + 4 * (k)]
  for (int s = 0; s < 2 && !st; s++) {
    st = patch(b, C(s, 0, 0), C(s, 1, 0), C(s, 0, 1), C(s, 1, 1), &ax[1], &ax[2], ctr, 0, mat,
               NULL, 0);
    if (!st)
      st = patch(b, C(0, s, 0), C(1, s, 0), C(0, s, 1), C(1, s, 1), &ax[0], &ax[2], ctr, 0, mat,
                 NULL, 0);
    if (!st)
      st = patch(b, C(0, 0, s), C(1, 0, s), C(0, 1, s), C(1, 1, s), &ax[0], &ax[1], ctr, 0, mat,
                 s ? rg : NULL, s ? nrg : 0);
  }
#undef C
  for (int a = 0; a < 3; a++) axis_free(&ax[a]);
  return st;
}

/* Axis-aligned design box [x0,x1] x [y0,y1] x [z0,z1] mapped through S(). */
static int box(bld *b, double x0, double x1, double y0, double y1, double z0, double z1,
               uint32_t mat) {
  double c[8][3];
  for (int q = 0; q < 8; q++) S(b, q & 1 ? x1 : x0, q & 2 ? y1 : y0, q & 4 ? z1 : z0, c[q]);
  return hexa(b, c, NULL, 0, NULL, 0, mat, NULL, 0);
}

/* Design-frame slanted slab: bottom face y = y0 spanning z in [zb0, zb1],
 * top face y = y1 spanning z in [zt0, zt1], x in [x0, x1]. */
static int slab(bld *b, double x0, double x1, double y0, double zb0, double zb1, double y1,
                double zt0, double zt1, uint32_t mat) {
  double c[8][3];
  for (int q = 0; q < 8; q++) {
    int top = (q & 2) != 0, back = (q & 4) != 0;
    double z = top ? (back ? zt1 : zt0) : (back ? zb1 : zb0);
    S(b, q & 1 ? x1 : x0, top ? y1 : y0, z, c[q]);
  }
  return hexa(b, c, NULL, 0, NULL, 0, mat, NULL, 0);
}

/* Oriented box: centre o, unit axes e[3], half extents h[3] (absolute). */
static int obox(bld *b, const double o[3], const double e[3][3], const double h[3],
                uint32_t mat) {
  double c[8][3];
  for (int q = 0; q < 8; q++)
    for (int k = 0; k < 3; k++)
      c[q][k] = o[k] + (q & 1 ? 1 : -1) * h[0] * e[0][k] + (q & 2 ? 1 : -1) * h[1] * e[1][k] +
                (q & 4 ? 1 : -1) * h[2] * e[2][k];
  return hexa(b, c, NULL, 0, NULL, 0, mat, NULL, 0);
}

/* Torus around centre o in the plane spanned by e1, e2 (normal a = e1 x e2):
 * major radius R, tube radius r, nu x nv cells, wound outward. */
static void torus(bld *b, const double o[3], const double e1[3], const double e2[3],
                  const double a[3], double R, double r, int nu, int nv, uint32_t mat) {
  uint32_t base = (uint32_t)b->nv;
  double p[3];
  for (int i = 0; i < nu; i++) {
    double th = 2.0 * CV_PI * i / nu;
    for (int j = 0; j < nv; j++) {
      double ph = 2.0 * CV_PI * j / nv, rr = R + r * cos(ph);
      for (int k = 0; k < 3; k++)
        p[k] = o[k] + rr * (cos(th) * e1[k] + sin(th) * e2[k]) + r * sin(ph) * a[k];
      add_v(b, p);
    }
  }
  /* With e1 x e2 = a, d/dth x d/dph = (R + r cos ph) r (cos ph dir + sin ph a)
   * is the outward tube normal, so wind (i,j) -> (i+1,j) -> (i+1,j+1). */
  for (int i = 0; i < nu; i++)
    for (int j = 0; j < nv; j++) {
      uint32_t v00 = base + (uint32_t)(i * nv + j);
      uint32_t v10 = base + (uint32_t)(((i + 1) % nu) * nv + j);
      uint32_t v01 = base + (uint32_t)(i * nv + (j + 1) % nv);
      uint32_t v11 = base + (uint32_t)(((i + 1) % nu) * nv + (j + 1) % nv);
      add_t(b, v00, v10, v11, mat);
      add_t(b, v00, v11, v01, mat);
    }
}

/* ---- the cabin ---- */
static int build_shell(bld *b) {
  const double L2 = 1.3, W2 = 0.725, H = 1.2, YB = 0.8; /* design frame */
  const double ZWT = -0.55, ZRT = 0.85;                 /* roof front / rear */
  int st = CV_OK;
  double cen[3];
  S(b, 0, 0.5 * H, 0, cen);
  /* profile points (z, y), left (x = -W2) and right (x = +W2) copies */
  double F0[2][3], F1[2][3], F2[2][3], R0[2][3], R1[2][3], R2[2][3];
  for (int s = 0; s < 2; s++) {
    double x = s ? W2 : -W2;
    S(b, x, 0, -L2, F0[s]);
    S(b, x, YB, -L2, F1[s]);
    S(b, x, H, ZWT, F2[s]);
    S(b, x, 0, L2, R0[s]);
    S(b, x, YB, L2, R1[s]);
    S(b, x, H, ZRT, R2[s]);
  }
  /* Shared axes: x across the width (pillar knots for windshield and rear
   * window), t front-to-rear (pillar knots for side windows), lower band
   * (floor to belt line) and s (belt line to roof along windshield, side
   * windows and rear window). */
  const double pil = 0.07 / D_WID;
  const double kx[4] = {0, pil, 1 - pil, 1};
  const double tA = 0.04, tB0 = 0.50, tB1 = 0.55, tC = 0.93;
  const double kt[6] = {0, tA, tB0, tB1, tC, 1};
  const double sB = 0.08, sT = 0.90;
  const double ks[4] = {0, sB, sT, 1};
  axis ax = {0, NULL}, at = {0, NULL}, al = {0, NULL}, as = {0, NULL};
  double lws = dist3(F1[0], F2[0]), lrw = dist3(R1[0], R2[0]);
  st = axis_make(b, &ax, kx, 4, dist3(F0[0], F0[1]));
  if (!st) st = axis_make(b, &at, kt, 6, dist3(F0[0], R0[0]));
  if (!st) st = axis_uniform(b, &al, dist3(F0[0], F1[0]));
  if (!st) st = axis_make(b, &as, ks, 4, lws > lrw ? lws : lrw);
  if (st) goto done;

  const region ws = {pil, 1 - pil, sB, sT, M_WIN_WS};
  const region rw = {pil, 1 - pil, sB, sT, M_WIN_REAR};
  st = patch(b, F0[0], F0[1], R0[0], R0[1], &ax, &at, cen, 1, M_CARPET, NULL, 0);
  if (!st) st = patch(b, F0[0], F0[1], F1[0], F1[1], &ax, &al, cen, 1, M_TRIM, NULL, 0);
  if (!st) st = patch(b, F1[0], F1[1], F2[0], F2[1], &ax, &as, cen, 1, M_TRIM, &ws, 1);
  if (!st) st = patch(b, F2[0], F2[1], R2[0], R2[1], &ax, &at, cen, 1, M_ROOF, NULL, 0);
  if (!st) st = patch(b, R1[0], R1[1], R2[0], R2[1], &ax, &as, cen, 1, M_TRIM, &rw, 1);
  if (!st) st = patch(b, R0[0], R0[1], R1[0], R1[1], &ax, &al, cen, 1, M_TRIM, NULL, 0);
  if (st) goto done;

  /* Side walls: rows run from the front profile (firewall, then windshield
   * edge) to the rear profile (rear wall, then rear-window edge).  Row
   * parameter v is al - 1 in the lower band and s in the upper band, so the
   * window regions (v in (sB, sT)) only hit the upper band. */
  {
    int nv = al.n + as.n;
    double(*Lc)[3] = malloc((size_t)(nv + 1) * sizeof *Lc);
    double(*Rc)[3] = malloc((size_t)(nv + 1) * sizeof *Rc);
    double *v = malloc((size_t)(nv + 1) * sizeof *v);
    if (!Lc || !Rc || !v) st = CV_ERR_NOMEM;
    for (int s = 0; s < 2 && !st; s++) {
      for (int j = 0; j <= nv; j++) {
        if (j <= al.n) {
          lerp3(F0[s], F1[s], al.t[j], Lc[j]);
          lerp3(R0[s], R1[s], al.t[j], Rc[j]);
          v[j] = al.t[j] - 1.0;
        } else {
          lerp3(F1[s], F2[s], as.t[j - al.n], Lc[j]);
          lerp3(R1[s], R2[s], as.t[j - al.n], Rc[j]);
          v[j] = as.t[j - al.n];
        }
      }
      region sw[2] = {{tA, tB0, sB, sT, s ? M_WIN_FR : M_WIN_FL},
                      {tB1, tC, sB, sT, s ? M_WIN_RR : M_WIN_RL}};
      grid(b, &at, v, nv, (const double(*)[3])Lc, (const double(*)[3])Rc, cen, 1, M_TRIM, sw, 2);
    }
    free(Lc);
    free(Rc);
    free(v);
  }
done:
  axis_free(&ax);
  axis_free(&at);
  axis_free(&al);
  axis_free(&as);
  return st;
}

static int build_objects(bld *b, cv_cabin_info *info) {
  int st = CV_OK;
  const double W2 = 0.725, L2 = 1.3;

  /* Dashboard: full width, resting on the firewall and both side walls; its
   * rear face leans forward so it faces up towards the occupants.  The LCD
   * sits in that face, centred at x = 0 and 60 % up the face; knots put its
   * edges on grid lines so it is an exact rectangle. */
  {
    const double yb = 0.40, yt = 0.78, zrb = -0.92, zrt = -1.00, vc = 0.6;
    double c[8][3];
    for (int q = 0; q < 8; q++) {
      int top = (q & 2) != 0, rear = (q & 4) != 0;
      S(b, q & 1 ? W2 : -W2, top ? yt : yb, rear ? (top ? zrt : zrb) : -L2, c[q]);
    }
    /* c[4] = rear bottom left, c[5] rear bottom right, c[6] rear top left */
    double wid = dist3(c[4], c[5]), flen = dist3(c[4], c[6]);
    double hu = 0.5 * LCD_W / wid, hv = 0.5 * LCD_H / flen;
    double ku[4] = {0, 0.5 - hu, 0.5 + hu, 1}, kv[4] = {0, vc - hv, vc + hv, 1};
    region lcd = {ku[1], ku[2], kv[1], kv[2], M_LCD};
    st = hexa(b, c, ku, 4, kv, 4, M_DASH, &lcd, 1);
    if (info) {
      double bot[3], topp[3], p[3], u[3], v[3], n[3];
      lerp3(c[4], c[6], vc, bot); /* left edge point at vc */
      lerp3(c[5], c[7], vc, topp);
      lerp3(bot, topp, 0.5, p);
      v_sub(c[5], c[4], u);
      v_norm(u);
      v_sub(c[6], c[4], v);
      v_norm(v);
      v_cross(u, v, n);
      v_norm(n);
      for (int k = 0; k < 3; k++) {
        info->lcd.center[k] = (float)p[k];
        info->lcd.u[k] = (float)u[k];
        info->lcd.v[k] = (float)v[k];
        info->lcd.normal[k] = (float)n[k];
      }
      info->lcd.size[0] = (float)LCD_W;
      info->lcd.size[1] = (float)LCD_H;
    }
  }
  /* Front seats (driver at x = -0.37) and the rear bench.  Backrests are
   * inset from the cushion's rear and side faces so that no edge of one
   * lies along a nearly coplanar face of the other (no T-junctions). */
  for (int s = 0; s < 2 && !st; s++) {
    double xc = s ? 0.37 : -0.37;
    st = box(b, xc - 0.25, xc + 0.25, 0.0, 0.30, -0.35, 0.15, M_SEAT);
    if (!st) st = slab(b, xc - 0.23, xc + 0.23, 0.30, 0.02, 0.14, 0.95, 0.194, 0.314, M_SEAT);
    if (!st) st = box(b, xc - 0.13, xc + 0.13, 0.95, 1.12, 0.21, 0.31, M_SEAT);
  }
  if (!st) st = box(b, -0.70, 0.70, 0.0, 0.32, 0.58, 1.12, M_SEAT);
  if (!st) st = slab(b, -0.68, 0.68, 0.32, 0.97, 1.11, 0.85, 1.05, 1.19, M_SEAT);
  /* Centre console between the front seats. */
  if (!st) st = box(b, -0.10, 0.10, 0.0, 0.35, -0.90, -0.20, M_CONSOLE);

  /* Steering wheel: rim (torus), hub, three spokes and a column into the
   * dashboard; the wheel plane is tilted 25 degrees from vertical. */
  if (!st) {
    const double R = 0.19, r = 0.015, tilt = 25.0 * CV_PI / 180.0;
    double o[3], e[3][3];
    S(b, -0.37, 0.78, -0.62, o);
    v_set(e[0], 1, 0, 0);
    v_set(e[1], 0, cos(tilt), -sin(tilt));
    v_set(e[2], 0, sin(tilt), cos(tilt)); /* = e0 x e1, towards the driver */
    torus(b, o, e[0], e[1], e[2], R, r, 24 * b->tess, 8 * b->tess, M_WHEEL);
    double hh[3] = {0.05, 0.05, 0.025};
    st = obox(b, o, (const double(*)[3])e, hh, M_WHEEL);
    /* spokes along +e0, -e0, -e1, from inside the hub to the rim's centre line */
    const double d0 = 0.04, d1 = R;
    for (int sp = 0; sp < 3 && !st; sp++) {
      double ax[3][3], c[3], h[3] = {0.5 * (d1 - d0), 0.0125, 0.008};
      const double *dir = sp < 2 ? e[0] : e[1];
      double sg = sp == 0 ? 1.0 : -1.0;
      for (int k = 0; k < 3; k++) {
        ax[0][k] = sg * dir[k];
        ax[1][k] = sp < 2 ? e[1][k] : e[0][k];
        c[k] = o[k] + sg * dir[k] * 0.5 * (d0 + d1);
      }
      v_cross(ax[0], ax[1], ax[2]);
      st = obox(b, c, (const double(*)[3])ax, h, M_WHEEL);
    }
    if (!st) {
      double c[3], h[3] = {0.03, 0.03, 0.20};
      for (int k = 0; k < 3; k++) c[k] = o[k] - e[2][k] * 0.22;
      st = obox(b, c, (const double(*)[3])e, h, M_WHEEL);
    }
  }
  if (info && !st) {
    double eye[3];
    S(b, -0.37, 1.02, 0.0, eye);
    double dir[3] = {0, -0.2, -1};
    v_norm(dir);
    for (int k = 0; k < 3; k++) {
      info->eye[k] = (float)eye[k];
      info->cam_pos[k] = (float)eye[k];
      info->cam_target[k] = (float)(eye[k] + dir[k]);
      info->cam_up[k] = k == 1 ? 1.0f : 0.0f;
    }
    info->cam_fov_y_deg = 70.0f;
  }
  return st;
}

static int check_params(const cv_cabin_params *p, cv_err *err) {
  if (!p) return cv_err_set(err, CV_ERR_INVALID, "cabin: params is NULL");
  if (!(p->length >= 1.5 && p->length <= 5.0))
    return cv_err_set(err, CV_ERR_RANGE, "cabin: length = %g m, expected [1.5, 5]", p->length);
  if (!(p->width >= 1.0 && p->width <= 2.5))
    return cv_err_set(err, CV_ERR_RANGE, "cabin: width = %g m, expected [1, 2.5]", p->width);
  if (!(p->height >= 0.9 && p->height <= 2.0))
    return cv_err_set(err, CV_ERR_RANGE, "cabin: height = %g m, expected [0.9, 2]", p->height);
  if (p->tess < 1 || p->tess > TESS_MAX)
    return cv_err_set(err, CV_ERR_RANGE, "cabin: tess = %d, expected [1, %d]", p->tess,
                      TESS_MAX);
  return CV_OK;
}

static int run(bld *b, const cv_cabin_params *p, cv_cabin_info *info) {
  b->scale[0] = p->width / D_WID;
  b->scale[1] = p->height / D_HGT;
  b->scale[2] = p->length / D_LEN;
  b->tess = p->tess;
  b->h = CELL_H / p->tess;
  int st = build_shell(b);
  if (info) {
    info->shell_tri_begin = 0;
    info->shell_tri_end = b->nt;
  }
  if (!st) st = build_objects(b, info);
  return st ? st : b->status;
}

void cv_cabin_default_params(cv_cabin_params *p) {
  p->length = D_LEN;
  p->width = D_WID;
  p->height = D_HGT;
  p->tess = 1;
}

int cv_cabin_count(const cv_cabin_params *p, size_t *nv, size_t *nt, cv_err *err) {
  int st = check_params(p, err);
  if (st) return st;
  bld b;
  memset(&b, 0, sizeof b);
  st = run(&b, p, NULL);
  if (st) return cv_err_set(err, st, "cabin: %s", cv_status_str(st));
  if (nv) *nv = b.nv;
  if (nt) *nt = b.nt;
  return CV_OK;
}

int cv_cabin_generate_ex(const cv_cabin_params *p, cv_mesh **out, cv_cabin_info *info,
                         cv_err *err) {
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "cabin: out is NULL");
  *out = NULL;
  size_t nv, nt;
  int st = cv_cabin_count(p, &nv, &nt, err);
  if (st) return st;
  bld b;
  memset(&b, 0, sizeof b);
  if (cv_mesh_create(&b.m)) return cv_err_set(err, CV_ERR_NOMEM, "cabin: out of memory");
  st = cv_mesh_reserve(b.m, nv, nt);
  for (int i = 0; i < M_COUNT && !st; i++)
    st = cv_mesh_add_material(b.m, k_mats[i].name, k_mats[i].albedo, k_mats[i].flags, NULL);
  if (info) memset(info, 0, sizeof *info);
  if (!st) st = run(&b, p, info);
  if (st) {
    cv_mesh_destroy(b.m);
    return cv_err_set(err, st, "cabin: %s", cv_status_str(st));
  }
  *out = b.m;
  return CV_OK;
}

int cv_cabin_generate(const cv_cabin_params *p, cv_mesh **out, cv_err *err) {
  return cv_cabin_generate_ex(p, out, NULL, err);
}

int cv_cabin_tess_for_triangles(size_t target) {
  cv_cabin_params p;
  cv_cabin_default_params(&p);
  for (p.tess = 1; p.tess < TESS_MAX; p.tess++) {
    size_t nt = 0;
    if (cv_cabin_count(&p, NULL, &nt, NULL) == CV_OK && nt >= target) return p.tess;
  }
  return TESS_MAX;
}
