/* Geometry preprocessor (see clean.h for the steps and their rules).
 *
 * Spatial look-ups use a hash grid with chaining (cell -> entries); every
 * choice among candidates is made by an explicit key (nearest, then lowest
 * index), so results never depend on bucket or chain order. */
#include "mesh/clean.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define CV_PI 3.14159265358979323846
#define CRACK_MAX_PASSES 4

void cv_clean_default_params(cv_clean_params *p) {
  p->weld_tol_rel = 1e-6;
  p->crease_deg = 60.0;
  p->crack_width_rel = 1e-4;
  p->sliver_aspect = 1e3;
}

static uint64_t mix64(uint64_t x) { /* splitmix64 finaliser */
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ull;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebull;
  x ^= x >> 31;
  return x;
}

static size_t pow2_at_least(size_t n) {
  size_t s = 16;
  while (s < n) s <<= 1;
  return s;
}

/* ---------------- spatial hash grid ---------------- */
typedef struct sgrid {
  double inv; /* 1 / cell size */
  double org[3];
  size_t mask;
  uint32_t *head; /* bucket -> entry + 1 */
  uint32_t *next; /* entry -> entry + 1 */
  int64_t (*cell)[3];
  uint32_t *item;
  size_t n, cap;
} sgrid;

static int sgrid_init(sgrid *g, size_t cap, double cs, const double org[3]) {
  memset(g, 0, sizeof *g);
  g->inv = 1.0 / cs;
  memcpy(g->org, org, sizeof g->org);
  size_t nb = pow2_at_least(2 * cap + 1);
  g->mask = nb - 1;
  g->head = calloc(nb, sizeof *g->head);
  g->next = malloc((cap + 1) * sizeof *g->next);
  g->cell = malloc((cap + 1) * sizeof *g->cell);
  g->item = malloc((cap + 1) * sizeof *g->item);
  g->cap = cap;
  return (g->head && g->next && g->cell && g->item) ? CV_OK : CV_ERR_NOMEM;
}
static void sgrid_free(sgrid *g) {
  free(g->head);
  free(g->next);
  free(g->cell);
  free(g->item);
}
static void sgrid_cell(const sgrid *g, const double p[3], int64_t c[3]) {
  for (int k = 0; k < 3; k++) c[k] = (int64_t)floor((p[k] - g->org[k]) * g->inv);
}
static size_t sgrid_bucket(const sgrid *g, const int64_t c[3]) {
  uint64_t h = mix64((uint64_t)c[0] * 0x9e3779b97f4a7c15ull ^ mix64((uint64_t)c[1]) ^
                     mix64((uint64_t)c[2] + 0x632be59bd9b4e019ull));
  return (size_t)(h & g->mask);
}
static int sgrid_insert(sgrid *g, const int64_t c[3], uint32_t item) {
  if (g->n >= g->cap) return CV_ERR_NOMEM; /* capacity is sized by the caller */
  size_t e = g->n++, b = sgrid_bucket(g, c);
  memcpy(g->cell[e], c, sizeof g->cell[e]);
  g->item[e] = item;
  g->next[e] = g->head[b];
  g->head[b] = (uint32_t)(e + 1);
  return CV_OK;
}
/* Calls visit(ctx, item) for every entry in the cells within +-r of c. */
typedef void (*sgrid_visit)(void *ctx, uint32_t item);
static void sgrid_query(const sgrid *g, const int64_t c[3], int r, sgrid_visit visit, void *ctx) {
  for (int dz = -r; dz <= r; dz++)
    for (int dy = -r; dy <= r; dy++)
      for (int dx = -r; dx <= r; dx++) {
        int64_t q[3] = {c[0] + dx, c[1] + dy, c[2] + dz};
        for (uint32_t e = g->head[sgrid_bucket(g, q)]; e; e = g->next[e - 1]) {
          const int64_t *ce = g->cell[e - 1];
          if (ce[0] == q[0] && ce[1] == q[1] && ce[2] == q[2]) visit(ctx, g->item[e - 1]);
        }
      }
}

/* ---------------- helpers ---------------- */
static void vpos(const cv_mesh *m, uint32_t v, double p[3]) {
  for (int k = 0; k < 3; k++) p[k] = m->pos[3 * (size_t)v + k];
}
static double dist2(const double a[3], const double b[3]) {
  double d0 = a[0] - b[0], d1 = a[1] - b[1], d2 = a[2] - b[2];
  return d0 * d0 + d1 * d1 + d2 * d2;
}
/* Normals agree within the crease angle; a zero normal (isolated vertex)
 * agrees with anything. */
static int compat(const float *na, const float *nb, double cosc) {
  double d = (double)na[0] * nb[0] + (double)na[1] * nb[1] + (double)na[2] * nb[2];
  int za = na[0] == 0 && na[1] == 0 && na[2] == 0, zb = nb[0] == 0 && nb[1] == 0 && nb[2] == 0;
  return za || zb || d >= cosc;
}
/* Twice the area and the longest edge of triangle t, in double. */
static void tri_shape(const cv_mesh *m, size_t t, double *area2, double *lmax, double *lmin) {
  double a[3], b[3], c[3];
  vpos(m, m->tri[3 * t], a);
  vpos(m, m->tri[3 * t + 1], b);
  vpos(m, m->tri[3 * t + 2], c);
  double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  double e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                 e1[0] * e2[1] - e1[1] * e2[0]};
  *area2 = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  double l0 = dist2(a, b), l1 = dist2(b, c), l2 = dist2(c, a);
  double mx = l0 > l1 ? l0 : l1, mn = l0 < l1 ? l0 : l1;
  mx = mx > l2 ? mx : l2;
  mn = mn < l2 ? mn : l2;
  *lmax = sqrt(mx);
  if (lmin) *lmin = sqrt(mn);
}

/* ---------------- (a) weld ---------------- */
typedef struct weld_ctx {
  const cv_mesh *m;
  const float *nrm;
  double p[3], tol2, cosc;
  uint32_t v, best;
  int blocked;
} weld_ctx;

static void weld_visit(void *vc, uint32_t r) {
  weld_ctx *c = vc;
  double q[3];
  vpos(c->m, r, q);
  if (dist2(c->p, q) > c->tol2) return;
  if (!compat(c->nrm + 3 * (size_t)c->v, c->nrm + 3 * (size_t)r, c->cosc)) {
    c->blocked = 1;
    return;
  }
  if (r < c->best) c->best = r;
}

/* cell >= tol is the grid cell size. */
static int weld(cv_mesh *m, double cell_size, double tol, double cosc, const double org[3],
                cv_clean_report *rep) {
  int st = CV_OK;
  float *nrm = malloc(3 * m->nv * sizeof *nrm);
  uint32_t *map = malloc(m->nv * sizeof *map);
  sgrid g = {0};
  if (!nrm || !map || sgrid_init(&g, m->nv, cell_size, org)) {
    st = CV_ERR_NOMEM;
    goto done;
  }
  cv_mesh_vertex_normals(m, nrm);
  weld_ctx c = {m, nrm, {0, 0, 0}, tol * tol, cosc, 0, 0, 0};
  for (size_t v = 0; v < m->nv; v++) {
    int64_t cell[3];
    vpos(m, (uint32_t)v, c.p);
    sgrid_cell(&g, c.p, cell);
    c.v = (uint32_t)v;
    c.best = UINT32_MAX;
    c.blocked = 0;
    sgrid_query(&g, cell, 1, weld_visit, &c);
    if (c.best != UINT32_MAX) {
      map[v] = c.best;
      rep->welded++;
    } else {
      map[v] = (uint32_t)v;
      if (c.blocked) rep->weld_crease_kept++;
      sgrid_insert(&g, cell, (uint32_t)v);
    }
  }
  for (size_t i = 0; i < 3 * m->nt; i++) m->tri[i] = map[m->tri[i]];
done:
  sgrid_free(&g);
  free(nrm);
  free(map);
  return st;
}

/* ---------------- (b) + (c) degenerate and duplicate triangles ---------------- */
static void sort3(const uint32_t *t, uint32_t s[3]) {
  uint32_t a = t[0], b = t[1], c = t[2], x;
  if (a > b) x = a, a = b, b = x;
  if (b > c) x = b, b = c, c = x;
  if (a > b) x = a, a = b, b = x;
  s[0] = a, s[1] = b, s[2] = c;
}
/* Same cyclic order (winding) of the same three indices? */
static int same_winding(const uint32_t *t, const uint32_t *u) {
  for (int r = 0; r < 3; r++)
    if (t[0] == u[r] && t[1] == u[(r + 1) % 3] && t[2] == u[(r + 2) % 3]) return 1;
  return 0;
}

typedef struct tricount {
  size_t idx, area, same, opp;
} tricount;

/* Compacts m's triangles in place, dropping degenerate ones (repeated index,
 * or 2*area <= tol * longest edge) and duplicates of an earlier triangle. */
static int remove_bad_tris(cv_mesh *m, double tol, tricount *tc) {
  size_t nb = pow2_at_least(2 * m->nt + 1), mask = nb - 1, k = 0;
  uint32_t *tab = calloc(nb, sizeof *tab); /* kept triangle + 1 */
  if (!tab) return CV_ERR_NOMEM;
  for (size_t t = 0; t < m->nt; t++) {
    uint32_t tr[3] = {m->tri[3 * t], m->tri[3 * t + 1], m->tri[3 * t + 2]};
    uint32_t mat = m->tri_mat[t];
    if (tr[0] == tr[1] || tr[1] == tr[2] || tr[0] == tr[2]) {
      tc->idx++;
      continue;
    }
    double a2, lmax;
    tri_shape(m, t, &a2, &lmax, NULL);
    if (a2 <= tol * lmax) {
      tc->area++;
      continue;
    }
    uint32_t s[3];
    sort3(tr, s);
    size_t h = (size_t)(mix64(((uint64_t)s[0] << 32 | s[1]) ^ mix64(s[2])) & mask);
    int dup = 0;
    for (; tab[h]; h = (h + 1) & mask) {
      const uint32_t *u = m->tri + 3 * (size_t)(tab[h] - 1);
      uint32_t su[3];
      sort3(u, su);
      if (su[0] == s[0] && su[1] == s[1] && su[2] == s[2]) {
        dup = 1;
        if (same_winding(tr, u))
          tc->same++;
        else
          tc->opp++;
        break;
      }
    }
    if (dup) continue;
    tab[h] = (uint32_t)(k + 1);
    memcpy(m->tri + 3 * k, tr, sizeof tr);
    m->tri_mat[k] = mat;
    if (m->tri_uv) memmove(m->tri_uv + 6 * k, m->tri_uv + 6 * t, 6 * sizeof(float));
    k++;
  }
  m->nt = k;
  free(tab);
  return CV_OK;
}

/* ---------------- edge map ---------------- */
typedef struct edgemap {
  size_t mask;
  uint64_t *key; /* (min << 32 | max) + 1; 0 = empty */
  uint32_t *count;
  uint32_t *tri; /* first triangle using it */
  uint8_t *loc;  /* local edge index in that triangle: vertex loc -> loc+1 */
} edgemap;

static uint64_t ekey(uint32_t a, uint32_t b) {
  return a < b ? ((uint64_t)a << 32 | b) : ((uint64_t)b << 32 | a);
}
static size_t edge_slot(const edgemap *e, uint64_t k) {
  size_t h = (size_t)(mix64(k) & e->mask);
  while (e->key[h] && e->key[h] != k + 1) h = (h + 1) & e->mask;
  return h;
}
static void edgemap_free(edgemap *e) {
  free(e->key);
  free(e->count);
  free(e->tri);
  free(e->loc);
  memset(e, 0, sizeof *e);
}
static int edgemap_build(edgemap *e, const cv_mesh *m) {
  size_t nb = pow2_at_least(6 * m->nt + 1);
  e->mask = nb - 1;
  e->key = calloc(nb, sizeof *e->key);
  e->count = calloc(nb, sizeof *e->count);
  e->tri = malloc(nb * sizeof *e->tri);
  e->loc = malloc(nb);
  if (!e->key || !e->count || !e->tri || !e->loc) return CV_ERR_NOMEM;
  for (size_t t = 0; t < m->nt; t++)
    for (int j = 0; j < 3; j++) {
      uint64_t k = ekey(m->tri[3 * t + j], m->tri[3 * t + (j + 1) % 3]);
      size_t h = edge_slot(e, k);
      if (!e->key[h]) {
        e->key[h] = k + 1;
        e->tri[h] = (uint32_t)t;
        e->loc[h] = (uint8_t)j;
      }
      e->count[h]++;
    }
  return CV_OK;
}
static uint32_t edge_count(const edgemap *e, uint32_t a, uint32_t b) {
  size_t h = edge_slot(e, ekey(a, b));
  return e->key[h] ? e->count[h] : 0;
}
static size_t count_boundary(const edgemap *e) {
  size_t n = 0;
  for (size_t h = 0; h <= e->mask; h++) n += e->key[h] && e->count[h] == 1;
  return n;
}

/* ---------------- (d) cracks ---------------- */
typedef struct vv_ctx {
  const cv_mesh *m;
  const float *nrm;
  const edgemap *em;
  double p[3], cw2, cosc, bestd;
  uint32_t v, best;
} vv_ctx;

static void vv_visit(void *vc, uint32_t w) {
  vv_ctx *c = vc;
  double q[3];
  vpos(c->m, w, q);
  double d = dist2(c->p, q);
  if (d > c->cw2 || d > c->bestd || (d == c->bestd && w > c->best)) return;
  if (!compat(c->nrm + 3 * (size_t)c->v, c->nrm + 3 * (size_t)w, c->cosc)) return;
  if (edge_count(c->em, c->v, w)) return; /* a short mesh edge, not a crack */
  c->bestd = d;
  c->best = w;
}

/* Vertex-to-vertex pass: returns the number of merges in *nmerge. */
static int crack_vv(cv_mesh *m, double cell_size, double cw, double cosc, const double org[3],
                    size_t *nmerge) {
  int st = CV_OK;
  edgemap em = {0};
  float *nrm = malloc(3 * m->nv * sizeof *nrm);
  uint8_t *bnd = calloc(m->nv, 1);
  uint32_t *map = malloc(m->nv * sizeof *map);
  sgrid g = {0};
  if (!nrm || !bnd || !map || edgemap_build(&em, m) ||
      sgrid_init(&g, m->nv, cell_size, org)) {
    st = CV_ERR_NOMEM;
    goto done;
  }
  cv_mesh_vertex_normals(m, nrm);
  for (size_t h = 0; h <= em.mask; h++)
    if (em.key[h] && em.count[h] == 1) {
      uint64_t k = em.key[h] - 1;
      bnd[k >> 32] = bnd[k & 0xffffffffu] = 1;
    }
  vv_ctx c = {m, nrm, &em, {0, 0, 0}, cw * cw, cosc, 0, 0, 0};
  for (size_t v = 0; v < m->nv; v++) {
    map[v] = (uint32_t)v;
    if (!bnd[v]) continue;
    int64_t cell[3];
    vpos(m, (uint32_t)v, c.p);
    sgrid_cell(&g, c.p, cell);
    c.v = (uint32_t)v;
    c.best = UINT32_MAX;
    c.bestd = INFINITY;
    sgrid_query(&g, cell, 1, vv_visit, &c);
    if (c.best != UINT32_MAX) {
      map[v] = c.best;
      (*nmerge)++;
    } else {
      sgrid_insert(&g, cell, (uint32_t)v);
    }
  }
  for (size_t i = 0; i < 3 * m->nt; i++) m->tri[i] = map[m->tri[i]];
done:
  sgrid_free(&g);
  edgemap_free(&em);
  free(nrm);
  free(bnd);
  free(map);
  return st;
}

typedef struct bedge {
  uint32_t a, b, c; /* triangle (a, b, c) owns boundary edge a -> b */
  uint32_t tri;
} bedge;

typedef struct ve_rec {
  uint32_t edge, v;
  double t;
} ve_rec;

typedef struct ve_ctx {
  const cv_mesh *m;
  const float *nrm;
  const bedge *be;
  const double (*tn)[3]; /* unit normal of each boundary edge's triangle */
  double p[3], cw2, tol2, cosc, bestd, bestt;
  uint32_t v, best;
} ve_ctx;

static void ve_visit(void *vc, uint32_t ei) {
  ve_ctx *c = vc;
  const bedge *e = &c->be[ei];
  if (c->v == e->a || c->v == e->b || c->v == e->c) return;
  double a[3], b[3];
  vpos(c->m, e->a, a);
  vpos(c->m, e->b, b);
  double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  double ap[3] = {c->p[0] - a[0], c->p[1] - a[1], c->p[2] - a[2]};
  double l2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
  if (l2 <= 0) return;
  double t = (ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]) / l2;
  if (!(t > 0.0 && t < 1.0)) return;
  if (dist2(c->p, a) <= c->tol2 || dist2(c->p, b) <= c->tol2) return; /* vertex case */
  double q[3] = {a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]};
  double d = dist2(c->p, q);
  if (d > c->cw2 || d > c->bestd || (d == c->bestd && ei > c->best)) return;
  const float *nv = c->nrm + 3 * (size_t)c->v;
  float tn[3] = {(float)c->tn[ei][0], (float)c->tn[ei][1], (float)c->tn[ei][2]};
  if (!compat(nv, tn, c->cosc)) return;
  c->bestd = d;
  c->best = ei;
  c->bestt = t;
}

static int cmp_rec(const void *x, const void *y) {
  const ve_rec *a = x, *b = y;
  if (a->edge != b->edge) return a->edge < b->edge ? -1 : 1;
  if (a->t != b->t) return a->t < b->t ? -1 : 1;
  return a->v < b->v ? -1 : a->v > b->v;
}

/* The boundary edges in triangle order (deterministic) into be[] with
 * their triangle's unit normal tn[]; their vertices marked in bnd[].
 * Returns their number; *lsum their total length. */
static size_t boundary_edges(const cv_mesh *m, const edgemap *em, bedge *be, double (*tn)[3],
                             uint8_t *bnd, double *lsum) {
  size_t nbe = 0;
  *lsum = 0;
  for (size_t t = 0; t < m->nt; t++)
    for (int j = 0; j < 3; j++) {
      uint32_t a = m->tri[3 * t + j], b = m->tri[3 * t + (j + 1) % 3];
      if (edge_count(em, a, b) != 1) continue;
      bedge *e = &be[nbe];
      e->a = a, e->b = b, e->c = m->tri[3 * t + (j + 2) % 3], e->tri = (uint32_t)t;
      float n[3];
      cv_mesh_tri_normal(m, t, n);
      double l = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
      for (int k = 0; k < 3; k++) tn[nbe][k] = l > 0 ? n[k] / l : 0.0;
      double pa[3], pb[3];
      vpos(m, a, pa);
      vpos(m, b, pb);
      *lsum += sqrt(dist2(pa, pb));
      bnd[a] = bnd[b] = 1;
      nbe++;
    }
  return nbe;
}

/* The boundary edges into the grid g of cell size cs: each edge entered at
 * samples every half cell (once per cell it crosses).  Returns the status. */
static int index_edges(const cv_mesh *m, const bedge *be, size_t nbe, double cs, const double org[3],
                       sgrid *g) {
  size_t nsamp = 0;
  for (size_t i = 0; i < nbe; i++) {
    double pa[3], pb[3];
    vpos(m, be[i].a, pa);
    vpos(m, be[i].b, pb);
    nsamp += (size_t)ceil(sqrt(dist2(pa, pb)) / (0.5 * cs)) + 1;
  }
  if (sgrid_init(g, nsamp, cs, org)) return CV_ERR_NOMEM;
  for (size_t i = 0; i < nbe; i++) {
    double pa[3], pb[3];
    vpos(m, be[i].a, pa);
    vpos(m, be[i].b, pb);
    size_t ns = (size_t)ceil(sqrt(dist2(pa, pb)) / (0.5 * cs)) + 1;
    int64_t prev[3] = {INT64_MIN, 0, 0};
    for (size_t s = 0; s < ns; s++) {
      double t = ns > 1 ? (double)s / (double)(ns - 1) : 0.0, q[3];
      for (int k = 0; k < 3; k++) q[k] = pa[k] + t * (pb[k] - pa[k]);
      int64_t c[3];
      sgrid_cell(g, q, c);
      if (c[0] == prev[0] && c[1] == prev[1] && c[2] == prev[2]) continue;
      memcpy(prev, c, sizeof prev);
      sgrid_insert(g, c, (uint32_t)i);
    }
  }
  return CV_OK;
}

/* Fan-splits the triangle of edge rec[i].edge at the vertices rec[i..j)
 * (sorted along the edge): (a, v1, c), (v1, v2, c), ..., (vk, b, c), the
 * corner UVs on the edge at each split point's t.  Returns the status. */
static int fan_split(cv_mesh *m, const bedge *e, const ve_rec *rec, size_t i, size_t j,
                     size_t *nadded) {
  int st = CV_OK;
  uint32_t mat = m->tri_mat[e->tri], prev = e->a;
  float uva[2] = {0, 0}, uvb[2] = {0, 0}, uvc[2] = {0, 0};
  if (m->tri_uv) {
    const float *q = m->tri_uv + 6 * (size_t)e->tri;
    int ja = m->tri[3 * (size_t)e->tri] == e->a ? 0 : m->tri[3 * (size_t)e->tri + 1] == e->a ? 1 : 2;
    memcpy(uva, q + 2 * ja, sizeof uva);
    memcpy(uvb, q + 2 * ((ja + 1) % 3), sizeof uvb);
    memcpy(uvc, q + 2 * ((ja + 2) % 3), sizeof uvc);
  }
  double tprev = 0;
  for (size_t r = i; r <= j && !st; r++) {
    uint32_t cur = r < j ? rec[r].v : e->b;
    double tcur = r < j ? rec[r].t : 1.0;
    size_t tt;
    if (r == i) {
      tt = e->tri;
      m->tri[3 * tt] = prev;
      m->tri[3 * tt + 1] = cur;
      m->tri[3 * tt + 2] = e->c;
    } else {
      tt = m->nt;
      st = cv_mesh_add_tri(m, prev, cur, e->c, mat);
      (*nadded)++;
    }
    if (!st && m->tri_uv) {
      float *q = m->tri_uv + 6 * tt;
      for (int k = 0; k < 2; k++) {
        q[k] = (float)(uva[k] + tprev * (uvb[k] - uva[k]));
        q[2 + k] = (float)(uva[k] + tcur * (uvb[k] - uva[k]));
        q[4 + k] = uvc[k];
      }
    }
    prev = cur;
    tprev = tcur;
  }
  return st;
}

/* Vertex-to-edge pass: splits boundary edges at nearby boundary vertices. */
static int crack_ve(cv_mesh *m, double cell_min, double cw, double tol, double cosc,
                    const double org[3], size_t *nsplit, size_t *nadded, int *deferred) {
  int st = CV_OK;
  edgemap em = {0};
  float *nrm = malloc(3 * m->nv * sizeof *nrm);
  uint8_t *bnd = calloc(m->nv, 1);
  uint8_t *tsplit = calloc(m->nt ? m->nt : 1, 1);
  bedge *be = NULL;
  double(*tn)[3] = NULL;
  ve_rec *rec = NULL;
  size_t nrec = 0;
  sgrid g = {0};
  if (!nrm || !bnd || !tsplit || edgemap_build(&em, m)) {
    st = CV_ERR_NOMEM;
    goto done;
  }
  cv_mesh_vertex_normals(m, nrm);
  size_t cap = count_boundary(&em);
  if (!cap) goto done;
  be = malloc(cap * sizeof *be);
  tn = malloc(cap * sizeof *tn);
  rec = malloc(m->nv * sizeof *rec);
  if (!be || !tn || !rec) {
    st = CV_ERR_NOMEM;
    goto done;
  }
  double lsum;
  const size_t nbe = boundary_edges(m, &em, be, tn, bnd, &lsum);
  /* Cell size >= crack width; edges are entered at samples every half cell,
   * so an edge within cw of a vertex has a sample within 1.25 cells: query
   * +-2 cells. */
  double cs = lsum / (double)nbe;
  if (cs < cell_min) cs = cell_min;
  st = index_edges(m, be, nbe, cs, org, &g);
  if (st) goto done;
  ve_ctx c = {m, nrm, be, (const double(*)[3])tn, {0, 0, 0}, cw * cw, tol * tol, cosc, 0, 0,
              0, 0};
  for (size_t v = 0; v < m->nv; v++) {
    if (!bnd[v]) continue;
    int64_t cell[3];
    vpos(m, (uint32_t)v, c.p);
    sgrid_cell(&g, c.p, cell);
    c.v = (uint32_t)v;
    c.best = UINT32_MAX;
    c.bestd = INFINITY;
    sgrid_query(&g, cell, 2, ve_visit, &c);
    if (c.best != UINT32_MAX) rec[nrec++] = (ve_rec){c.best, (uint32_t)v, c.bestt};
  }
  qsort(rec, nrec, sizeof *rec, cmp_rec);
  /* A triangle is split along one edge per pass; the rest waits. */
  for (size_t i = 0; i < nrec && !st;) {
    size_t j = i;
    while (j < nrec && rec[j].edge == rec[i].edge) j++;
    const bedge *e = &be[rec[i].edge];
    if (tsplit[e->tri]) {
      *deferred = 1;
    } else {
      tsplit[e->tri] = 1;
      st = fan_split(m, e, rec, i, j, nadded);
      *nsplit += j - i;
    }
    i = j;
  }
done:
  sgrid_free(&g);
  edgemap_free(&em);
  free(nrm);
  free(bnd);
  free(tsplit);
  free(be);
  free(tn);
  free(rec);
  return st;
}

/* ---------------- driver ---------------- */
/* (g): one vertex per (vertex, albedo) pair.  Incidence lists in CSR form;
 * groups are found by exact albedo equality in triangle order, so the
 * result is deterministic. */
static int split_materials(cv_mesh *m, size_t *added) {
  size_t nv = m->nv, nt = m->nt;
  uint32_t *off = calloc(nv + 1, sizeof *off), *inc = malloc((3 * nt + 1) * sizeof *inc);
  uint32_t *fill = calloc(nv + 1, sizeof *fill);
  int st = CV_OK;
  if (!off || !inc || !fill) {
    st = CV_ERR_NOMEM;
    goto done;
  }
  for (size_t i = 0; i < 3 * nt; i++) off[m->tri[i] + 1]++;
  for (size_t v = 0; v < nv; v++) off[v + 1] += off[v];
  for (size_t i = 0; i < 3 * nt; i++) {
    uint32_t v = m->tri[i];
    inc[off[v] + fill[v]++] = (uint32_t)i; /* corner index: triangle i / 3 */
  }
  for (size_t v = 0; v < nv; v++) {
    const float *first = NULL;
    for (uint32_t k = off[v]; k < off[v + 1]; k++) {
      const cv_material *mt = &m->mats[m->tri_mat[inc[k] / 3]];
      if ((mt->flags & CV_MAT_WINDOW) || m->tri[inc[k]] != v) continue; /* moved already */
      if (!first) first = mt->albedo;
      if (!memcmp(first, mt->albedo, sizeof mt->albedo)) continue;
      /* A new albedo at v: one new vertex for every corner with it. */
      uint32_t nvtx;
      const float *a = mt->albedo;
      float px = m->pos[3 * v], py = m->pos[3 * v + 1], pz = m->pos[3 * v + 2];
      if ((st = cv_mesh_add_vertex(m, px, py, pz, &nvtx))) goto done;
      (*added)++;
      for (uint32_t j = k; j < off[v + 1]; j++) {
        const cv_material *mj = &m->mats[m->tri_mat[inc[j] / 3]];
        if (!(mj->flags & CV_MAT_WINDOW) && m->tri[inc[j]] == v &&
            !memcmp(a, mj->albedo, sizeof mj->albedo))
          m->tri[inc[j]] = nvtx;
      }
    }
  }
done:
  free(off);
  free(inc);
  free(fill);
  return st;
}

static int bad_param(double x) { return !isfinite(x) || x < 0; }

int cv_mesh_clean(cv_mesh *m, const cv_clean_params *p, cv_clean_report *rep, cv_err *err) {
  cv_clean_params def;
  cv_clean_report local;
  if (!p) {
    cv_clean_default_params(&def);
    p = &def;
  }
  if (!rep) rep = &local;
  memset(rep, 0, sizeof *rep);
  if (!m) return cv_err_set(err, CV_ERR_INVALID, "clean: mesh is NULL");
  if (bad_param(p->weld_tol_rel) || bad_param(p->crack_width_rel) ||
      bad_param(p->sliver_aspect) || bad_param(p->crease_deg) || p->crease_deg > 180)
    return cv_err_set(err, CV_ERR_INVALID,
                      "clean: parameters must be finite and >= 0 (crease_deg <= 180)");
  int st = cv_mesh_validate(m, err);
  if (st) return cv_err_prefix(err, "clean");
  if (m->nv >= UINT32_MAX || 6 * m->nt >= UINT32_MAX)
    return cv_err_set(err, CV_ERR_RANGE, "clean: mesh too large (%zu vertices, %zu triangles)",
                      m->nv, m->nt);

  rep->nv_before = m->nv;
  rep->nt_before = m->nt;
  double diag = cv_mesh_diagonal(m);
  rep->diagonal = diag;
  rep->weld_tol = p->weld_tol_rel * diag;
  rep->crack_width = p->crack_width_rel * diag;
  double cosc = cos(p->crease_deg * CV_PI / 180.0);
  float lo[3], hi[3];
  cv_mesh_bounds(m, lo, hi);
  double org[3] = {lo[0], lo[1], lo[2]};
  /* Grid cells must not be vanishingly small against the coordinates. */
  double cmin = diag > 0 ? diag * 1e-9 : 1.0;
  double wcell = rep->weld_tol > cmin ? rep->weld_tol : cmin;

  /* (a) */
  st = weld(m, wcell, rep->weld_tol, cosc, org, rep);
  /* (b), (c) */
  tricount tc = {0, 0, 0, 0};
  if (!st) st = remove_bad_tris(m, rep->weld_tol, &tc);
  rep->degenerate_index = tc.idx;
  rep->degenerate_area = tc.area;
  rep->duplicate_same = tc.same;
  rep->duplicate_opposite = tc.opp;
  rep->nt_after_bc = m->nt;

  /* (d) */
  edgemap em = {0};
  if (!st && (st = edgemap_build(&em, m)) == CV_OK) rep->boundary_edges_before = count_boundary(&em);
  edgemap_free(&em);
  if (rep->crack_width > 0) {
    double cw = rep->crack_width > cmin ? rep->crack_width : cmin;
    for (int pass = 0; pass < CRACK_MAX_PASSES && !st; pass++) {
      size_t merges = 0, splits = 0;
      int deferred = 0;
      tricount t2 = {0, 0, 0, 0};
      st = crack_vv(m, cw, rep->crack_width, cosc, org, &merges);
      if (!st && merges) st = remove_bad_tris(m, rep->weld_tol, &t2);
      if (!st)
        st = crack_ve(m, cw, rep->crack_width, rep->weld_tol, cosc, org, &splits,
                      &rep->crack_tris_added, &deferred);
      if (!st && splits) st = remove_bad_tris(m, rep->weld_tol, &t2);
      rep->crack_vertex_merges += merges;
      rep->crack_edge_splits += splits;
      rep->crack_removed += t2.idx + t2.area + t2.same + t2.opp;
      rep->crack_passes = pass + 1;
      if (!merges && !splits && !deferred) break;
    }
  }
  rep->nt_after_d = m->nt;
  if (!st && (st = edgemap_build(&em, m)) == CV_OK) rep->boundary_edges_after = count_boundary(&em);
  edgemap_free(&em);

  /* (g) */
  if (!st) st = split_materials(m, &rep->material_splits);

  /* (f) before (e) so that worst_tri indexes the output mesh; (e) changes
   * nothing, so the order does not matter otherwise. */
  if (!st) {
    uint32_t *map = malloc((m->nv ? m->nv : 1) * sizeof *map);
    if (!map) {
      st = CV_ERR_NOMEM;
    } else {
      for (size_t v = 0; v < m->nv; v++) map[v] = UINT32_MAX;
      for (size_t i = 0; i < 3 * m->nt; i++) map[m->tri[i]] = 0;
      size_t k = 0;
      for (size_t v = 0; v < m->nv; v++) {
        if (map[v] == UINT32_MAX) continue;
        map[v] = (uint32_t)k;
        if (k != v) memmove(m->pos + 3 * k, m->pos + 3 * v, 3 * sizeof(float));
        k++;
      }
      for (size_t i = 0; i < 3 * m->nt; i++) m->tri[i] = map[m->tri[i]];
      rep->unreferenced = m->nv - k;
      m->nv = k;
      free(map);
    }
  }
  /* (e) */
  if (!st)
    for (size_t t = 0; t < m->nt; t++) {
      double a2, lmax;
      tri_shape(m, t, &a2, &lmax, NULL);
      double asp = a2 > 0 ? lmax * lmax / a2 : INFINITY; /* lmax / (a2 / lmax) */
      if (asp > p->sliver_aspect) rep->slivers++;
      if (asp > rep->worst_aspect) {
        rep->worst_aspect = asp;
        rep->worst_tri = t;
      }
    }
  rep->nv_after = m->nv;
  rep->nt_after = m->nt;
  if (st) return cv_err_set(err, st, "clean: %s", cv_status_str(st));
  return CV_OK;
}

void cv_clean_report_print(FILE *f, const cv_clean_report *r) {
  fprintf(f, "geometry cleaning (diagonal %.6g m, weld tolerance %.3g m, crack width %.3g m)\n",
          r->diagonal, r->weld_tol, r->crack_width);
  fprintf(f, "  vertices   %zu -> %zu, triangles %zu -> %zu\n", r->nv_before, r->nv_after,
          r->nt_before, r->nt_after);
  fprintf(f, "  (a) weld: %zu vertices merged (%zu -> %zu in use), %zu kept apart by the crease "
          "angle\n", r->welded, r->nv_before, r->nv_before - r->welded, r->weld_crease_kept);
  fprintf(f, "  (b) degenerate triangles removed: %zu repeated index, %zu zero altitude\n",
          r->degenerate_index, r->degenerate_area);
  fprintf(f, "  (c) duplicate triangles removed: %zu same winding, %zu opposite winding "
          "(triangles %zu -> %zu after b, c)\n", r->duplicate_same, r->duplicate_opposite,
          r->nt_before, r->nt_after_bc);
  fprintf(f,
          "  (d) cracks: boundary edges %zu -> %zu; %zu vertex merges, %zu edge splits "
          "(+%zu triangles), %zu triangles removed after snapping, %d pass(es) "
          "(triangles %zu -> %zu)\n",
          r->boundary_edges_before, r->boundary_edges_after, r->crack_vertex_merges,
          r->crack_edge_splits, r->crack_tris_added, r->crack_removed, r->crack_passes,
          r->nt_after_bc, r->nt_after_d);
  fprintf(f, "  (e) slivers: %zu (worst aspect %.4g at triangle %zu), not changed\n", r->slivers,
          r->worst_aspect, r->worst_tri);
  fprintf(f, "  (g) material boundaries: %zu vertices split off (one per albedo)\n",
          r->material_splits);
  fprintf(f, "  (f) unreferenced vertices removed: %zu (vertices %zu -> %zu)\n", r->unreferenced,
          r->nv_before, r->nv_after);
}
