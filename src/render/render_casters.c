/* The sun's shadow casters (opts.shadow_casters): a simplified copy of the
 * opaque triangles that the shadow map draws instead of the mesh itself.
 *
 * On llvmpipe the map costs about 17 ms of vertex and triangle set-up for
 * the 285K culled triangles of the 571K cabin whatever its size
 * (docs/benchmarks.md), so a lighting change cannot reach 30 ms with the
 * mesh itself.  The shadow needs only the surface, not the PRT vertices:
 * meshoptimizer's edge-collapse simplifier (meshopt_simplify, quadric error
 * metric, Garland and Heckbert 1997) on the positions welded exactly, with
 * every border edge locked (the window openings: where the sun comes in
 * stays exact), keeps every point of the surface within
 * opts.shadow_casters metres of the original.  Flat panels, most of a
 * tessellated CAD interior, collapse to a few triangles; curved parts keep
 * what the bound needs.
 *
 * Culling (opts.shadow_cull) needs a closed, consistently wound surface:
 * from a point in the air, the first surface towards the sun then faces
 * away from it.  Edge collapses keep that almost everywhere, but meshopt
 * 0.18 leaves a few folds (on the 571K cabin at 1 mm: 9 directed edges
 * used twice and 1 window-border edge lost, of 3,268 triangles), so it is
 * counted, not assumed: the casters' edges are compared with the original
 * opaque triangles' (every directed edge once; those without a reverse,
 * the window borders, the same set).  A fold can only misplace the shadow
 * of its own few triangles (millimetres); culling stays on while the
 * defects are at most CASTER_DEFECTS_MAX (2%) of the caster triangles, else
 * every caster is drawn.  The shadow error against Embree
 * (bench_shadow) is the check that this costs nothing measurable; the
 * defects are reported (cv_renderer_shadow_casters).
 *
 * Built on the first shadow map (an importer of shared lighting never draws
 * one, so never pays the build: build_ms in cv_renderer_shadow_casters). */
#include "render/render_casters.h"

#include "render/render_edges.h"

#include <meshoptimizer.h>
#include <stdint.h>

/* Culling stays on while the casters' closure defects are at most this
 * fraction of their triangles (see the file's comment). */
#define CASTER_DEFECTS_MAX 0.02

/* How far the casters are from pairing their edges as the original does
 * (the closedness that culling relies on; welded indices): directed edges
 * that occur twice plus border edges of one that are not border edges of
 * the other.  SIZE_MAX out of memory. */
static size_t closure_defects(const uint32_t *orig, size_t nt0, const uint32_t *cast, size_t nt1) {
  cvr_edges a = {0}, b = {0};
  size_t defects = SIZE_MAX;
  if (cvr_edges_build(&a, orig, nt0) == CV_OK && cvr_edges_build(&b, cast, nt1) == CV_OK)
    defects = a.dup + b.dup + cvr_edges_border_unmatched(&a, &b) + cvr_edges_border_unmatched(&b, &a);
  cvr_edges_free(&a), cvr_edges_free(&b);
  return defects;
}

/* The opaque triangles on exactly welded positions (degenerate ones
 * dropped): *pos (nu points) and *ib (nt triangles). */
static int weld_opaque(const cvr_scene *r, float **pos, size_t *nu, uint32_t **ib, size_t *nt) {
  *pos = NULL, *ib = NULL;
  unsigned *remap = malloc(r->nv_used * sizeof *remap + 4);
  if (!remap) return CV_ERR_NOMEM;
  *nu = meshopt_generateVertexRemap(remap, NULL, r->nv_used, r->pos_cpu, r->nv_used,
                                    3 * sizeof(float));
  *pos = malloc(3 * *nu * sizeof **pos + 4);
  *ib = malloc(3 * r->nt * sizeof **ib + 4);
  if (!*pos || !*ib) {
    free(remap), free(*pos), free(*ib);
    *pos = NULL, *ib = NULL;
    return CV_ERR_NOMEM;
  }
  meshopt_remapVertexBuffer(*pos, r->pos_cpu, r->nv_used, 3 * sizeof(float), remap);
  size_t k = 0;
  for (size_t t = 0; t < r->nt; t++) {
    const uint32_t *v = r->idx_cpu + 3 * t;
    const uint32_t a = remap[v[0]], b = remap[v[1]], c = remap[v[2]];
    if (a == b || b == c || c == a) continue;
    (*ib)[3 * k] = a, (*ib)[3 * k + 1] = b, (*ib)[3 * k + 2] = c;
    k++;
  }
  free(remap);
  *nt = k;
  return CV_OK;
}

static int build_casters(const cvr_ctx *c, cvr_casters *k, const cvr_scene *sc, cv_err *err) {
  const double t0 = cvr_now_ms();
  float *pos;
  uint32_t *ib;
  size_t nu, nt;
  if (weld_opaque(sc, &pos, &nu, &ib, &nt))
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory simplifying the shadow casters");
  uint32_t *out = malloc(3 * nt * sizeof *out + 4);
  if (!out) {
    free(pos), free(ib);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory simplifying the shadow casters");
  }
  const float scale = meshopt_simplifyScale(pos, nu, 3 * sizeof(float));
  float rel = 0;
  const size_t ni = scale > 0 ? meshopt_simplify(out, ib, 3 * nt, pos, nu, 3 * sizeof(float), 0,
                                                 (float)(c->o->shadow_casters / scale),
                                                 meshopt_SimplifyLockBorder, &rel)
                              : 3 * nt;
  if (!(scale > 0)) memcpy(out, ib, 3 * nt * sizeof *out);
  k->defects = closure_defects(ib, nt, out, ni / 3);
  k->culled = cvr_scene_shadow_culled(c, sc) && k->defects <= CASTER_DEFECTS_MAX * (ni / 3) ? 1 : 0;
  free(ib);
  /* Compact: only the vertices the casters use, in order of first use. */
  float *cpos = malloc(3 * nu * sizeof *cpos + 4);
  if (!cpos) {
    free(pos), free(out);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory simplifying the shadow casters");
  }
  const size_t nv = meshopt_optimizeVertexFetch(cpos, out, ni, pos, nu, 3 * sizeof(float));
  free(pos);
  k->nt = ni / 3;
  k->idx = out;
  k->pos = pos = cpos;
  k->n = malloc(3 * k->nt * sizeof *k->n + 4);
  k->draw = malloc(3 * k->nt * sizeof *k->draw + 4);
  if (!k->n || !k->draw)
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory simplifying the shadow casters");
  cvr_unit_normals(k->pos, k->idx, k->nt, k->n);
  k->err = (double)rel * scale;
  glGenVertexArrays(1, &k->vao);
  glGenBuffers(1, &k->buf_pos);
  glGenBuffers(1, &k->buf_idx);
  glBindVertexArray(k->vao);
  glBindBuffer(GL_ARRAY_BUFFER, k->buf_pos);
  glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(3 * nv * sizeof *pos + 4), pos, GL_STATIC_DRAW);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 0, 0);
  glEnableVertexAttribArray(0);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, k->buf_idx);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(3 * k->nt * sizeof *out + 4), out,
               GL_STREAM_DRAW);
  glBindVertexArray(0);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  k->built = 1;
  k->ms = cvr_now_ms() - t0;
  return cvr_gl_check("shadow casters", err);
}

/* The casters the map of sun s draws: with culling those facing away from
 * it or within split_margin of grazing (as DRAW_SHADOW), else all. */
static size_t cull_casters(const cvr_ctx *c, cvr_casters *k, const double s[3]) {
  if (!k->culled) {
    memcpy(k->draw, k->idx, 3 * k->nt * sizeof *k->draw);
    return k->nt;
  }
  const double m = c->o->split_margin > 0 ? c->o->split_margin : 0.0;
  size_t kept = 0;
  for (size_t t = 0; t < k->nt; t++) {
    const float *n = k->n + 3 * t;
    if ((double)n[0] * s[0] + (double)n[1] * s[1] + (double)n[2] * s[2] > m) continue;
    memcpy(k->draw + 3 * kept++, k->idx + 3 * t, 3 * sizeof *k->draw);
  }
  return kept;
}

int cvr_casters_draw(const cvr_ctx *c, cvr_casters *k, const cvr_scene *sc, const double s[3],
                     cv_err *err) {
  if (!k->built) {
    int st = build_casters(c, k, sc, err);
    if (st) return st;
  }
  const size_t n = cull_casters(c, k, s);
  glBindVertexArray(k->vao);
  glBufferSubData(GL_ELEMENT_ARRAY_BUFFER, 0, (GLsizeiptr)(3 * n * sizeof *k->draw), k->draw);
  if (n) glDrawElements(GL_TRIANGLES, (GLsizei)(3 * n), GL_UNSIGNED_INT, 0);
  glBindVertexArray(0);
  k->drawn = n;
  return CV_OK;
}

void cvr_casters_free(cvr_casters *k) {
  if (k->vao) glDeleteVertexArrays(1, &k->vao);
  if (k->buf_pos) glDeleteBuffers(1, &k->buf_pos);
  if (k->buf_idx) glDeleteBuffers(1, &k->buf_idx);
  k->vao = k->buf_pos = k->buf_idx = 0;
}

void cvr_casters_free_cpu(cvr_casters *k) {
  free(k->pos), free(k->n), free(k->idx), free(k->draw);
  k->pos = k->n = NULL, k->idx = k->draw = NULL;
}

void cvr_casters_info(const cvr_ctx *c, const cvr_casters *k, const cvr_scene *sc,
                      cv_shadow_casters *out) {
  memset(out, 0, sizeof *out);
  out->tolerance_m = c->o->shadow_casters;
  out->mesh_triangles = sc->nt;
  if (!k->built) return;
  out->built = 1;
  out->triangles = k->nt;
  out->error_m = k->err;
  out->culled = k->culled;
  out->defects = k->defects;
  out->drawn = k->drawn;
  out->build_ms = k->ms;
}
