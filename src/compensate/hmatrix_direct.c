/* Direct build of the compressed gather matrix from the display, without
 * the dense matrix: see hmatrix.h cv_hmatrix_build_direct. */
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "compensate/display.h"
#include "compensate/formfactor.h"
#include "compensate/hmatrix.h"
#include "compensate/hmatrix_impl.h"
#include "core/progress.h"

#define KCAP 128 /* largest rank tried before a block is split */

/* A cluster: the patches [u0, u1) x [v0, v1) of one surface's grid, at
 * positions [p0, p0 + np) of the cluster order. */
typedef struct cnode {
  uint32_t surface, u0, u1, v0, v1;
  size_t p0, np;
  double lo[3], hi[3], diam;
  int child[4], nchild;
} cnode;

typedef struct ctree {
  cnode *node;
  size_t nn, cap;
} ctree;

static int tree_push(ctree *t) {
  if (t->nn == t->cap) {
    size_t c = t->cap ? 2 * t->cap : 256;
    cnode *m = realloc(t->node, c * sizeof *m);
    if (!m) return -1;
    t->node = m;
    t->cap = c;
  }
  memset(&t->node[t->nn], 0, sizeof t->node[0]);
  return (int)t->nn++;
}

/* Builds the quadtree below a new node for [u0, u1) x [v0, v1) of surface
 * k; leaves take the next positions (perm, cstart).  Returns the node
 * index, -1 when out of memory. */
static int build_cluster(ctree *t, const cv_display *d, uint32_t k, uint32_t u0, uint32_t u1,
                         uint32_t v0, uint32_t v1, int leaf, cv_hmatrix *h, size_t *pos,
                         size_t *nleaf) {
  const int id = tree_push(t);
  if (id < 0) return -1;
  cnode c;
  memset(&c, 0, sizeof c);
  c.surface = k;
  c.u0 = u0;
  c.u1 = u1;
  c.v0 = v0;
  c.v1 = v1;
  c.p0 = *pos;
  const uint32_t nu = u1 - u0, nv = v1 - v0;
  if (nu <= (uint32_t)leaf && nv <= (uint32_t)leaf) {
    h->cstart[*nleaf] = *pos;
    (*nleaf)++;
    for (uint32_t v = v0; v < v1; v++)
      for (uint32_t u = u0; u < u1; u++)
        h->perm[(*pos)++] = (uint32_t)cv_display_patch_index(d, k, (int)u, (int)v);
  } else {
    const uint32_t um = nu > (uint32_t)leaf ? u0 + nu / 2 : u1;
    const uint32_t vm = nv > (uint32_t)leaf ? v0 + nv / 2 : v1;
    const uint32_t us[3] = {u0, um, u1}, vs[3] = {v0, vm, v1};
    for (int b = 0; b < 2; b++)
      for (int a = 0; a < 2; a++) {
        if (us[a] == us[a + 1] || vs[b] == vs[b + 1]) continue;
        const int ch =
            build_cluster(t, d, k, us[a], us[a + 1], vs[b], vs[b + 1], leaf, h, pos, nleaf);
        if (ch < 0) return -1;
        c.child[c.nchild++] = ch;
      }
  }
  c.np = *pos - c.p0;
  for (int a = 0; a < 3; a++) {
    c.lo[a] = INFINITY;
    c.hi[a] = -INFINITY;
  }
  for (size_t p = c.p0; p < *pos; p++) {
    const cv_patch *pa = &d->patches[h->perm[p]];
    for (int q = 0; q < 4; q++)
      for (int a = 0; a < 3; a++) {
        c.lo[a] = fmin(c.lo[a], pa->q[q][a]);
        c.hi[a] = fmax(c.hi[a], pa->q[q][a]);
      }
  }
  c.diam = sqrt((c.hi[0] - c.lo[0]) * (c.hi[0] - c.lo[0]) +
                (c.hi[1] - c.lo[1]) * (c.hi[1] - c.lo[1]) +
                (c.hi[2] - c.lo[2]) * (c.hi[2] - c.lo[2]));
  t->node[id] = c;
  return id;
}

static double box_dist(const cnode *a, const cnode *b) {
  double s = 0;
  for (int k = 0; k < 3; k++) {
    const double g = fmax(0.0, fmax(a->lo[k] - b->hi[k], b->lo[k] - a->hi[k]));
    s += g * g;
  }
  return sqrt(s);
}

/* A block to compute: rows of cluster s, columns of cluster t. */
typedef struct job {
  int s, t;
  int dense;     /* 1: evaluate every entry */
  int status;    /* 0 pending, 1 stored, 2 zero, 3 split */
  hblock b;
  double *err;   /* m: estimated error per row of the block */
} job;

typedef struct jobs {
  job *j;
  size_t n, cap;
} jobs;

static int jobs_push(jobs *q, int s, int t, int dense) {
  if (q->n == q->cap) {
    size_t c = q->cap ? 2 * q->cap : 1024;
    job *m = realloc(q->j, c * sizeof *m);
    if (!m) return -1;
    q->j = m;
    q->cap = c;
  }
  job *j = &q->j[q->n++];
  memset(j, 0, sizeof *j);
  j->s = s;
  j->t = t;
  j->dense = dense;
  return 0;
}

/* Block tree: far pairs are low-rank jobs, near leaf pairs dense jobs, other
 * pairs are split on the larger (or the only splittable) side. */
static int partition(const ctree *t, double eta, int s, int u, jobs *q) {
  const cnode *a = &t->node[s], *b = &t->node[u];
  if (fmax(a->diam, b->diam) <= eta * box_dist(a, b)) return jobs_push(q, s, u, 0);
  if (!a->nchild && !b->nchild) return jobs_push(q, s, u, 1);
  const int split_a = a->nchild && (!b->nchild || a->diam >= b->diam);
  const cnode *p = split_a ? a : b;
  for (int c = 0; c < p->nchild; c++)
    if (partition(t, eta, split_a ? p->child[c] : s, split_a ? u : p->child[c], q)) return -1;
  return 0;
}

typedef struct aca_scratch {
  double *U, *V; /* m x KCAP (column q at U + q m), KCAP x w */
  double *r, *sum;
  uint8_t *used;
} aca_scratch;

/* Partially pivoted ACA of the block rows[0..m) x cols[0..w) of G with the
 * stopping rule of hmatrix.h.  When the rule holds, the residual of a few
 * check rows (check[0..nchk), e.g. the rows nearest the other cluster and
 * the corners) is evaluated in full; a check row outside the rule becomes
 * the next pivot.  Returns the rank (0: the block is zero as far as the
 * sampled rows show), -1 when kmax terms were not enough.  err[i]: the
 * newest term's size in row i (the estimate), or for a check row its
 * residual exactly. */
static int aca_partial(const cv_ff_kernel *K, const uint32_t *rows, size_t m,
                       const uint32_t *cols, size_t w, double tol, int kmax, aca_scratch *s,
                       const size_t *check, int nchk, double *err) {
  double *U = s->U, *V = s->V, *r = s->r, *sum = s->sum;
  memset(s->used, 0, m);
  for (size_t i = 0; i < m; i++) sum[i] = err[i] = 0;
  size_t pi = nchk > 0 ? check[0] : m / 2;
  int k = 0, misses = 0, checking = -1; /* >= 0: index of the check row being verified */
  double scale = 0, smax = 0; /* largest pivot, largest |row sum| so far */
  for (;;) {
    s->used[pi] = 1;
    size_t pj = 0;
    double best = -1, rabs = 0, rsum = 0;
    for (size_t j = 0; j < w; j++) {
      const double g = cv_ff_kernel_gather(K, rows[pi], cols[j]);
      double a = g;
      for (int q = 0; q < k; q++) a -= U[(size_t)q * m + pi] * V[(size_t)q * w + j];
      r[j] = a;
      rabs += fabs(a);
      rsum += g;
      if (fabs(a) > best) {
        best = fabs(a);
        pj = j;
      }
    }
    if (checking >= 0) {
      /* a check row: its residual is known exactly */
      if (rabs <= 0.5 * tol * fmax(rsum, 1e-6 * smax) || best <= 1e-14 * scale) {
        err[pi] = rabs;
        int next = checking + 1;
        while (next < nchk && s->used[check[next]]) next++;
        if (next >= nchk) return k;
        checking = next;
        pi = check[next];
        continue;
      }
      checking = -1; /* failed: it becomes the next pivot */
    } else if (best == 0 || best <= 1e-14 * scale) {
      /* this row is reproduced already: sample another one, spread over
       * the block; after 4 such rows the block is taken as done (k = 0:
       * zero) */
      if (++misses > 3) return k;
      size_t nx = (pi + m / 4 + 1) % m, tries = 0;
      while (s->used[nx] && tries++ < m) nx = (nx + 1) % m;
      if (s->used[nx]) return k;
      pi = nx;
      continue;
    }
    if (k == kmax) return -1;
    const double piv = r[pj];
    scale = fmax(scale, fabs(piv));
    double *v = V + (size_t)k * w, *u = U + (size_t)k * m;
    double vabs = 0, vsum = 0;
    for (size_t j = 0; j < w; j++) {
      v[j] = r[j] / piv;
      vabs += fabs(v[j]);
      vsum += v[j];
    }
    for (size_t i = 0; i < m; i++) {
      double a = cv_ff_kernel_gather(K, rows[i], cols[pj]);
      for (int q = 0; q < k; q++) a -= U[(size_t)q * m + i] * V[(size_t)q * w + pj];
      u[i] = a;
    }
    k++;
    int ok = 1;
    size_t nx = m;
    double umax = -1;
    for (size_t i = 0; i < m; i++) {
      sum[i] += u[i] * vsum;
      smax = fmax(smax, fabs(sum[i]));
    }
    for (size_t i = 0; i < m; i++) {
      err[i] = s->used[i] ? 0 : fabs(u[i]) * vabs; /* pivot rows are exact */
      /* rows that get under 1e-6 of the block's largest row are held to
       * that floor (they matter only against their whole row) */
      if (err[i] > 0.5 * tol * fmax(fabs(sum[i]), 1e-6 * smax)) ok = 0;
      if (!s->used[i] && fabs(u[i]) > umax) {
        umax = fabs(u[i]);
        nx = i;
      }
    }
    if (nx == m) return k; /* every row was a pivot: the block is exact */
    if (ok) {
      int c = 0;
      while (c < nchk && s->used[check[c]]) c++;
      if (c >= nchk) return k;
      checking = c;
      pi = check[c];
      continue;
    }
    pi = nx;
  }
}

/* Check rows of a block: the row nearest the column cluster's box centre,
 * the farthest, and the first and last rows (corners of the cluster). */
static int check_rows(const cv_display *d, const uint32_t *rows, size_t m, const double *lo,
                      const double *hi, size_t *chk) {
  const double c[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
  size_t near = 0, far = 0;
  double dn = INFINITY, df = -1;
  for (size_t i = 0; i < m; i++) {
    const double *p = d->patches[rows[i]].c;
    const double dd = (p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]) +
                      (p[2] - c[2]) * (p[2] - c[2]);
    if (dd < dn) {
      dn = dd;
      near = i;
    }
    if (dd > df) {
      df = dd;
      far = i;
    }
  }
  const size_t cand[4] = {near, far, 0, m - 1};
  int n = 0;
  for (int a = 0; a < 4; a++) {
    int dup = 0;
    for (int b = 0; b < n; b++) dup |= chk[b] == cand[a];
    if (!dup) chk[n++] = cand[a];
  }
  return n;
}

/* Computes one job; returns 0, or -1 when out of memory. */
static int run_job(const cv_ff_kernel *K, const cv_hmatrix *h, const ctree *t, double tol,
                   job *jb, aca_scratch *s) {
  const cnode *a = &t->node[jb->s], *b = &t->node[jb->t];
  const size_t m = a->np, w = b->np;
  const uint32_t *rows = h->perm + a->p0, *cols = h->perm + b->p0;
  jb->err = calloc(m, sizeof *jb->err);
  if (!jb->err) return -1;
  hblock *bl = &jb->b;
  bl->r0 = (uint32_t)a->p0;
  bl->m = (uint32_t)m;
  bl->c0 = (uint32_t)b->p0;
  bl->w = (uint32_t)w;
  if (!jb->dense) {
    int kmax = (int)(m * w / (2 * (m + w)));
    if (kmax > KCAP) kmax = KCAP;
    size_t chk[4];
    const int nchk = check_rows(cv_ff_kernel_display(K), rows, m, b->lo, b->hi, chk);
    const int k =
        kmax > 0 ? aca_partial(K, rows, m, cols, w, tol, kmax, s, chk, nchk, jb->err) : -1;
    if (k == 0) {
      jb->status = 2;
      return 0;
    }
    if (k > 0) {
      bl->rank = (uint32_t)k;
      bl->vals = malloc((size_t)k * (m + w) * sizeof *bl->vals);
      if (!bl->vals) return -1;
      float *U = bl->vals, *V = U + m * (size_t)k;
      for (size_t i = 0; i < m; i++)
        for (int q = 0; q < k; q++) U[i * (size_t)k + q] = (float)s->U[(size_t)q * m + i];
      double vmax = 0;
      for (int q = 0; q < k; q++)
        for (size_t j = 0; j < w; j++) {
          V[(size_t)q * w + j] = (float)s->V[(size_t)q * w + j];
          vmax = fmax(vmax, fabs(s->V[(size_t)q * w + j]));
        }
      /* float rounding of the factors: each product term errs by at most
       * 2^-23 (|u| |v| both rounded), summed over the row and the rank. */
      for (size_t i = 0; i < m; i++) {
        double mag = 0;
        for (int q = 0; q < k; q++) mag += fabs(s->U[(size_t)q * m + i]);
        jb->err[i] += ldexp(1.0, -23) * mag * vmax * (double)w;
      }
      jb->status = 1;
      return 0;
    }
    if (a->nchild || b->nchild) {
      jb->status = 3;
      return 0;
    }
    memset(jb->err, 0, m * sizeof *jb->err);
  }
  /* dense: every entry, exact up to float rounding (not counted: the dense
   * path does not count it either) */
  bl->rank = 0;
  bl->vals = malloc(m * w * sizeof *bl->vals);
  if (!bl->vals) return -1;
  for (size_t i = 0; i < m; i++)
    for (size_t j = 0; j < w; j++)
      bl->vals[i * w + j] = (float)cv_ff_kernel_gather(K, rows[i], cols[j]);
  jb->status = 1;
  return 0;
}

void cv_hmatrix_direct_params_default(cv_hmatrix_direct_params *p) {
  memset(p, 0, sizeof *p);
  p->tol = CV_HMATRIX_DIRECT_TOL;
  p->eta = 1.0;
  p->leaf = CV_DISPLAY_TILE;
  p->quiet = 0;
}

static double job_cost(const ctree *t, const job *j) {
  const double m = (double)t->node[j->s].np, w = (double)t->node[j->t].np;
  return j->dense ? m * w : 8 * (m + w);
}

static const ctree *sort_tree;
static int cmp_job_cost(const void *x, const void *y) {
  const double a = job_cost(sort_tree, x), b = job_cost(sort_tree, y);
  return (a < b) - (a > b);
}

/* Checks the parameters (defaults for NULL) into *p.  Returns the status. */
static int direct_params(const cv_display *d, const cv_hmatrix_direct_params *params,
                         cv_hmatrix_direct_params *p, cv_err *err) {
  if (params)
    *p = *params;
  else
    cv_hmatrix_direct_params_default(p);
  if (!d || d->n_patches == 0)
    return cv_err_set(err, CV_ERR_INVALID, "hmatrix: display without patches");
  if (!(p->tol > 0 && p->tol < 0.5))
    return cv_err_set(err, CV_ERR_INVALID, "hmatrix: tolerance %g, expected in (0, 0.5)", p->tol);
  if (!(p->eta > 0 && p->eta < 100))
    return cv_err_set(err, CV_ERR_INVALID, "hmatrix: eta %g, expected in (0, 100)", p->eta);
  if (p->leaf < 2 || p->leaf > 64)
    return cv_err_set(err, CV_ERR_INVALID, "hmatrix: leaf %d, expected 2..64", p->leaf);
  return CV_OK;
}

/* A safe upper bound of the leaves: halving keeps every leaf >= leaf/2 on
 * a side. */
static size_t max_leaves(const cv_display *d, int leaf) {
  size_t maxleaf = 0;
  for (size_t k = 0; k < d->n_surfaces; k++) {
    const size_t lu = (d->surfaces[k].nu + leaf - 1) / (size_t)leaf;
    const size_t lv = (d->surfaces[k].nv + leaf - 1) / (size_t)leaf;
    maxleaf += 4 * lu * lv;
  }
  return maxleaf;
}

/* The cluster tree of every surface (roots into root[]) and the first jobs:
 * the admissible partition of every pair of surfaces that exchange light;
 * *pairs the patch pairs they cover.  Returns the status. */
static int plan_jobs(const cv_display *d, const cv_ff_kernel *K, const cv_hmatrix_direct_params *p,
                     cv_hmatrix *h, ctree *tree, int *root, jobs *q, size_t *pairs, cv_err *err) {
  const size_t ns = d->n_surfaces;
  size_t pos = 0, nleaf = 0;
  for (size_t k = 0; k < ns; k++) {
    const cv_display_surface *S = &d->surfaces[k];
    root[k] = build_cluster(tree, d, (uint32_t)k, 0, (uint32_t)S->nu, 0, (uint32_t)S->nv, p->leaf,
                            h, &pos, &nleaf);
    if (root[k] < 0) return cv_err_set(err, CV_ERR_NOMEM, "hmatrix: out of memory");
  }
  h->nc = nleaf;
  h->cstart[nleaf] = pos;
  *pairs = 0;
  for (size_t a = 0; a < ns; a++)
    for (size_t b = 0; b < ns; b++) {
      if (!cv_ff_kernel_surfaces_exchange(K, a, b)) continue;
      *pairs += tree->node[root[a]].np * tree->node[root[b]].np;
      if (partition(tree, p->eta, root[a], root[b], q))
        return cv_err_set(err, CV_ERR_NOMEM, "hmatrix: out of memory");
    }
  return CV_OK;
}

/* Jobs [first, end) in parallel, the costliest first (mm: the largest
 * cluster of a job).  Returns 1 when out of memory. */
static int run_round(cv_ff_kernel *K, cv_hmatrix *h, const ctree *tree, double tol, jobs *q,
                     size_t first, size_t end, size_t mm, cv_progress *prog) {
  int fail = 0;
  sort_tree = tree;
  qsort(q->j + first, end - first, sizeof *q->j, cmp_job_cost);
#pragma omp parallel
  {
    aca_scratch s;
    s.U = malloc(mm * KCAP * sizeof *s.U);
    s.V = malloc(mm * KCAP * sizeof *s.V);
    s.r = malloc(mm * sizeof *s.r);
    s.sum = malloc(mm * sizeof *s.sum);
    s.used = malloc(mm);
    int ok = s.U && s.V && s.r && s.sum && s.used;
    cv_ff_kernel_thread_init(K);
#pragma omp for schedule(dynamic, 1)
    for (size_t j = first; j < end; j++) {
      if (!ok || run_job(K, h, tree, tol, &q->j[j], &s)) {
        ok = 0;
        continue;
      }
      if (q->j[j].status != 3)
        cv_progress_add(prog, (uint64_t)tree->node[q->j[j].s].np * tree->node[q->j[j].t].np);
    }
    if (!ok) {
#pragma omp atomic write
      fail = 1;
    }
    free(s.U);
    free(s.V);
    free(s.r);
    free(s.sum);
    free(s.used);
  }
  return fail;
}

/* Jobs [first, end) that did not compress enough (status 3): partitioned
 * one level down (the larger cluster split) as new jobs.  Returns 1 when
 * out of memory. */
static int split_failed_jobs(const ctree *tree, jobs *q, size_t first, size_t end) {
  for (size_t j = first; j < end; j++) {
    if (q->j[j].status != 3) continue;
    const cnode *a = &tree->node[q->j[j].s], *b = &tree->node[q->j[j].t];
    const int split_a = a->nchild && (!b->nchild || a->diam >= b->diam);
    const cnode *pn = split_a ? a : b;
    const int js = q->j[j].s, jt = q->j[j].t;
    for (int c = 0; c < pn->nchild; c++) {
      const int cs = split_a ? pn->child[c] : js, ct = split_a ? jt : pn->child[c];
      if (jobs_push(q, cs, ct, 0)) return 1; /* leaf pairs go dense if ACA fails */
    }
  }
  return 0;
}

/* Rounds of jobs until none is left (each round's failures split into the
 * next), with progress over `pairs` patch pairs.  Returns 1 when out of
 * memory. */
static int run_jobs(cv_ff_kernel *K, cv_hmatrix *h, const ctree *tree, double tol, jobs *q,
                    size_t pairs, int quiet) {
  cv_progress *prog = NULL;
  if (h->n >= 8192)
    cv_progress_create_ex("compressed form factors", (uint64_t)pairs,
                          quiet ? CV_PROGRESS_QUIET : 0, NULL, &prog);
  size_t mm = 1; /* largest cluster in a job (children are smaller) */
  for (size_t j = 0; j < q->n; j++) {
    if (tree->node[q->j[j].s].np > mm) mm = tree->node[q->j[j].s].np;
    if (tree->node[q->j[j].t].np > mm) mm = tree->node[q->j[j].t].np;
  }
  size_t first = 0;
  int fail = 0;
  while (first < q->n && !fail) {
    const size_t end = q->n;
    fail = run_round(K, h, tree, tol, q, first, end, mm, prog) || split_failed_jobs(tree, q, first, end);
    first = end;
  }
  cv_progress_finish(prog);
  cv_progress_destroy(prog);
  return fail;
}

/* The finished jobs' blocks into h (status 1: kept; 1 and 2: their error
 * counted).  Returns 1 when out of memory. */
static int collect_blocks(cv_hmatrix *h, jobs *q) {
  size_t cap_blocks = 0;
  for (size_t j = 0; j < q->n; j++) cap_blocks += q->j[j].status == 1;
  h->blocks = malloc((cap_blocks + 1) * sizeof *h->blocks);
  if (!h->blocks) return 1;
  for (size_t j = 0; j < q->n; j++) {
    job *jb = &q->j[j];
    if (jb->status == 1 || jb->status == 2)
      for (size_t i = 0; i < jb->b.m; i++) h->row_err[h->perm[jb->b.r0 + i]] += jb->err[i];
    if (jb->status == 1) {
      h->blocks[h->nb++] = jb->b;
      jb->b.vals = NULL;
    }
  }
  return 0;
}

int cv_hmatrix_build_direct(const cv_display *d, const cv_ff_params *fp,
                            const cv_hmatrix_direct_params *params, cv_hmatrix **out,
                            cv_hmatrix_info *info, cv_err *err) {
  const double t0 = omp_get_wtime();
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "hmatrix: out is NULL");
  *out = NULL;
  cv_hmatrix_direct_params p;
  int st = direct_params(d, params, &p, err);
  if (st) return st;
  cv_ff_kernel *K = NULL;
  st = cv_ff_kernel_create(d, fp, &K, err);
  if (st) return st;
  const size_t n = d->n_patches;
  cv_hmatrix *h = cv_hm_alloc(n, max_leaves(d, p.leaf));
  ctree tree = {0};
  jobs q = {0};
  int *root = calloc(d->n_surfaces, sizeof *root);
  size_t pairs = 0;
  if (!h || !root)
    st = cv_err_set(err, CV_ERR_NOMEM, "hmatrix: out of memory (%zu patches)", n);
  if (!st) st = plan_jobs(d, K, &p, h, &tree, root, &q, &pairs, err);
  if (!st && run_jobs(K, h, &tree, p.tol, &q, pairs, p.quiet))
    st = cv_err_set(err, CV_ERR_NOMEM, "hmatrix: out of memory while compressing");
  if (!st && (collect_blocks(h, &q) || cv_hm_finish(h)))
    st = cv_err_set(err, CV_ERR_NOMEM, "hmatrix: out of memory");
  if (!st) {
    cv_hm_info(h, pairs, (omp_get_wtime() - t0) * 1e3, &h->info);
    if (info) *info = h->info;
  }
  for (size_t j = 0; j < q.n; j++) {
    free(q.j[j].err);
    free(q.j[j].b.vals);
  }
  free(q.j);
  free(tree.node);
  free(root);
  cv_ff_kernel_destroy(K);
  if (st) {
    cv_hmatrix_destroy(h);
    return st;
  }
  *out = h;
  return CV_OK;
}
