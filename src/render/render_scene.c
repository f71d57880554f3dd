/* The scene feature (render_scene.h): the opaque mesh in Morton-ordered
 * chunks, its GL buffers, the per-view draw with frustum culling, the
 * chunks' partition of the sun split, and the closedness check. */
#include "render/render_scene.h"

#include "render/render_edges.h"

/* Per vertex the first vertex at exactly the same position (vertices split
 * at material boundaries are one point of the surface); NULL when out of
 * memory. */
static uint32_t *weld_positions(const cv_prt *p) {
  size_t cap = 1;
  while (cap < 2 * p->nv + 2) cap <<= 1;
  uint32_t *slot = malloc(cap * sizeof *slot), *id = malloc(p->nv * sizeof *id + 4);
  if (!slot || !id) {
    free(slot), free(id);
    return NULL;
  }
  memset(slot, 0xff, cap * sizeof *slot);
  for (size_t v = 0; v < p->nv; v++) {
    uint32_t b[3];
    memcpy(b, p->pos + 3 * v, sizeof b);
    size_t h = cvr_hash64(cvr_hash64((uint64_t)b[0] << 32 | b[1]) ^ b[2]) & (cap - 1);
    while (slot[h] != UINT32_MAX && memcmp(p->pos + 3 * (size_t)slot[h], p->pos + 3 * v, sizeof b))
      h = (h + 1) & (cap - 1);
    if (slot[h] == UINT32_MAX) slot[h] = (uint32_t)v;
    id[v] = slot[h];
  }
  free(slot);
  return id;
}

/* 1 when every directed edge of p's non-degenerate triangles, vertices
 * welded by position, occurs once and its reverse once (closed, consistently
 * wound); 0 otherwise or out of memory. */
static int mesh_closed(const cv_prt *p) {
  uint32_t *id = weld_positions(p), *tri = malloc(3 * p->nt * sizeof *tri + 4);
  cvr_edges e = {0};
  int closed = 0;
  if (id && tri) {
    for (size_t i = 0; i < 3 * p->nt; i++) tri[i] = id[p->tri[i]];
    if (cvr_edges_build(&e, tri, p->nt) == CV_OK)
      closed = e.dup == 0 && cvr_edges_border_unmatched(&e, NULL) == 0;
  }
  cvr_edges_free(&e);
  free(id), free(tri);
  return closed;
}

/* 1 when the box (lo, hi) lies entirely outside one clip plane of mvp. */
int cvr_box_outside(const float mvp[16], const float *lo, const float *hi) {
  int out[6] = {1, 1, 1, 1, 1, 1};
  for (int c = 0; c < 8; c++) {
    const float p[3] = {c & 1 ? hi[0] : lo[0], c & 2 ? hi[1] : lo[1], c & 4 ? hi[2] : lo[2]};
    float q[4];
    for (int i = 0; i < 4; i++)
      q[i] = mvp[i] * p[0] + mvp[4 + i] * p[1] + mvp[8 + i] * p[2] + mvp[12 + i];
    for (int a = 0; a < 3; a++) {
      out[2 * a] &= q[a] < -q[3];
      out[2 * a + 1] &= q[a] > q[3];
    }
  }
  return out[0] | out[1] | out[2] | out[3] | out[4] | out[5];
}

/* Draws the opaque triangles whose chunk intersects the frustum of mvp
 * (all of them when mvp is NULL or culling is off): part DRAW_ALL as runs
 * of consecutive chunks of buf_idx; DRAW_SUNLIT / DRAW_UNSUNLIT the
 * sun-facing / other triangles of those chunks from buf_idx_sun (the sun
 * split; DRAW_SHADOW those facing away or near grazing: the culled shadow
 * map), in one glMultiDrawElements.  Every pass of a view submits the same
 * triangles, which the depth-EQUAL pass relies on.  Returns the triangles
 * submitted. */
size_t cvr_scene_draw(const cvr_ctx *ctx, cvr_scene *r, const float *mvp, int part) {
  size_t nrun = 0, ntri = 0;
  for (size_t c = 0; c < r->nchunks; c++) {
    if (mvp && ctx->o->cull_frustum && cvr_box_outside(mvp, r->chunk_box + 6 * c, r->chunk_box + 6 * c + 3))
      continue;
    uint32_t first = (uint32_t)(c * CHUNK), n = (uint32_t)((c + 1) * CHUNK > r->nt ? r->nt - c * CHUNK : CHUNK);
    if (part == DRAW_SUNLIT) {
      n = r->chunk_nf[c];
    } else if (part == DRAW_UNSUNLIT) {
      first += r->chunk_nf[c];
      n -= r->chunk_nf[c];
    } else if (part == DRAW_SHADOW) {
      first += r->chunk_na[c];
      n -= r->chunk_na[c];
    }
    if (!n) continue;
    if (nrun && r->run[2 * (nrun - 1)] + r->run[2 * (nrun - 1) + 1] == first) {
      r->run[2 * (nrun - 1) + 1] += n;
    } else {
      r->run[2 * nrun] = first, r->run[2 * nrun + 1] = n;
      nrun++;
    }
    ntri += n;
  }
  glBindVertexArray(r->vao_geom);
  if (part == DRAW_ALL) {
    for (size_t i = 0; i < nrun; i++) {
      glDrawElements(GL_TRIANGLES, (GLsizei)(3 * r->run[2 * i + 1]), GL_UNSIGNED_INT,
                     (const void *)(uintptr_t)(3 * sizeof(uint32_t) * r->run[2 * i]));
    }
  } else if (nrun) {
    for (size_t i = 0; i < nrun; i++) {
      r->md_count[i] = (GLsizei)(3 * r->run[2 * i + 1]);
      r->md_off[i] = (const void *)(uintptr_t)(3 * sizeof(uint32_t) * r->run[2 * i]);
    }
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->buf_idx_sun); /* VAO state: restored below */
    glMultiDrawElements(GL_TRIANGLES, r->md_count, GL_UNSIGNED_INT, r->md_off, (GLsizei)nrun);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->buf_idx);
  }
  glBindVertexArray(0);
  return ntri;
}

/* Face culling of the view passes (opts.cull_back; -1: on a closed mesh);
 * the shadow map draws both sides (or, culled, the part facing away from
 * the sun). */
void cvr_scene_cull(const cvr_ctx *c, const cvr_scene *r, int on) {
  if (on && (c->o->cull_back < 0 ? r->closed : c->o->cull_back)) {
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
  } else {
    glDisable(GL_CULL_FACE);
  }
}

/* Whether the shadow map is culled (opts.shadow_cull; -1: the mesh is closed). */
int cvr_scene_shadow_culled(const cvr_ctx *c, const cvr_scene *r) {
  return c->o->shadow_cull < 0 ? r->closed : c->o->shadow_cull != 0;
}

/* Binds buf_idx_sun to GL_ELEMENT_ARRAY_BUFFER (VAO 0 bound), giving it its
 * storage (3 nt indices) the first time: a split or an imported one is then
 * written into the same storage (no reallocation, no fresh pages). */
void cvr_scene_parts_bind(cvr_scene *r) {
  glBindVertexArray(0);
  const int fresh = !r->buf_idx_sun;
  if (fresh) glGenBuffers(1, &r->buf_idx_sun);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->buf_idx_sun);
  if (fresh)
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(3 * r->nt * sizeof(uint32_t) + 4), NULL,
                 GL_DYNAMIC_DRAW);
}

/* Unit winding normals of the uploaded triangles (those of cv_sun_direct
 * and prt.frag's n_t), built on the first split: 12 bytes a triangle. */
int cvr_scene_tri_normals(cvr_scene *r) {
  if (r->tri_n) return CV_OK;
  r->tri_n = malloc(3 * r->nt * sizeof *r->tri_n + 4);
  if (!r->tri_n) return CV_ERR_NOMEM;
  cvr_unit_normals(r->pos_cpu, r->idx_cpu, r->nt, r->tri_n);
  return CV_OK;
}


size_t cvr_scene_view_triangles(const cvr_ctx *ctx, const cvr_scene *r, const float mvp[16]) {
  size_t n = 0;
  for (size_t c = 0; c < r->nchunks; c++)
    if (!ctx->o->cull_frustum || !cvr_box_outside(mvp, r->chunk_box + 6 * c, r->chunk_box + 6 * c + 3))
      n += (c + 1) * CHUNK > r->nt ? r->nt - c * CHUNK : CHUNK;
  return n;
}

/* The Morton order of the opaque triangles (into idx, original indices)
 * with their chunks' boxes. */
static int morton_order(cvr_scene *r, const cv_prt *p, uint32_t *idx) {
  uint64_t *order = malloc(r->nt * sizeof *order + 8);
  if (!order) return CV_ERR_NOMEM;
  const size_t nt = r->nt;
  size_t k = 0;
  for (size_t t = 0; t < p->nt; t++) {
    if (p->mats[p->tri_mat[t]].flags & CV_MAT_WINDOW) continue;
    uint32_t q[3];
    for (int j = 0; j < 3; j++) {
      double c = (p->pos[3 * p->tri[3 * t] + j] + p->pos[3 * p->tri[3 * t + 1] + j] +
                  p->pos[3 * p->tri[3 * t + 2] + j]) / 3;
      double ext = r->hi[j] - r->lo[j];
      double u = ext > 0 ? (c - r->lo[j]) / ext : 0;
      q[j] = (uint32_t)fmin(fmax(u * 1023.0, 0), 1023);
    }
    order[k++] = (cvr_morton3(q[0], q[1], q[2]) << 32) | (uint64_t)t;
  }
  qsort(order, nt, sizeof *order, cvr_cmp_u64);
  for (k = 0; k < nt; k++) {
    const size_t t = (size_t)(order[k] & 0xffffffffu);
    const uint32_t *v = p->tri + 3 * t;
    for (int j = 0; j < 3; j++) idx[3 * k + j] = v[j]; /* renumbered below */
    float *box = r->chunk_box + 6 * (k / CHUNK);
    if (k % CHUNK == 0)
      for (int j = 0; j < 3; j++) box[j] = INFINITY, box[3 + j] = -INFINITY;
    for (int i = 0; i < 3; i++)
      for (int j = 0; j < 3; j++) {
        float x = p->pos[3 * v[i] + j];
        if (x < box[j]) box[j] = x;
        if (x > box[3 + j]) box[3 + j] = x;
      }
  }
  free(order);
  return CV_OK;
}

int cvr_scene_order(cvr_scene *r, const cv_prt *p, uint32_t **idx_out, uint32_t **old_out, cv_err *err) {
  *idx_out = NULL, *old_out = NULL;
  r->closed = mesh_closed(p);
  r->nc = (int)(p->bands * p->bands);
  r->nv = p->nv;
  size_t nt = 0;
  for (size_t t = 0; t < p->nt; t++)
    if (!(p->mats[p->tri_mat[t]].flags & CV_MAT_WINDOW)) nt++;
  r->nt = nt;
  /* Bounds first (Morton codes are relative to them). */
  for (int j = 0; j < 3; j++) r->lo[j] = INFINITY, r->hi[j] = -INFINITY;
  for (size_t v = 0; v < p->nv; v++)
    for (int j = 0; j < 3; j++) {
      if (p->pos[3 * v + j] < r->lo[j]) r->lo[j] = p->pos[3 * v + j];
      if (p->pos[3 * v + j] > r->hi[j]) r->hi[j] = p->pos[3 * v + j];
    }
  r->nchunks = (nt + CHUNK - 1) / CHUNK;
  r->chunk_box = malloc(6 * r->nchunks * sizeof *r->chunk_box + 4);
  r->run = malloc(2 * r->nchunks * sizeof *r->run + 4);
  uint32_t *idx = malloc(3 * nt * sizeof *idx + 4);
  uint32_t *old_of = malloc(p->nv * sizeof *old_of + 4), *new_of = malloc(p->nv * sizeof *new_of + 4);
  if (!r->chunk_box || !r->run || !idx || !old_of || !new_of || morton_order(r, p, idx)) {
    free(idx), free(old_of), free(new_of);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory uploading the scene");
  }
  /* Vertices renumbered in order of first use by the sorted triangles, so
   * each draw segment references a compact index range (llvmpipe's vertex
   * cache is indexed by vertex number; a GPU's post-transform cache also
   * likes it).  Vertices of no opaque triangle go last. */
  for (size_t v = 0; v < p->nv; v++) new_of[v] = UINT32_MAX;
  uint32_t next = 0;
  for (size_t i = 0; i < 3 * nt; i++) {
    if (new_of[idx[i]] == UINT32_MAX) {
      old_of[next] = idx[i];
      new_of[idx[i]] = next++;
    }
    idx[i] = new_of[idx[i]];
  }
  r->nv_used = next;
  for (size_t v = 0; v < p->nv; v++)
    if (new_of[v] == UINT32_MAX) {
      old_of[next] = (uint32_t)v;
      new_of[v] = next++;
    }
  free(new_of);
  *idx_out = idx, *old_out = old_of;
  return CV_OK;
}

/* An attribute buffer of n floats a vertex at location loc of the bound VAO. */
static GLuint attribute(GLuint loc, int n, size_t nv, const float *data, GLenum usage) {
  GLuint b;
  glGenBuffers(1, &b);
  glBindBuffer(GL_ARRAY_BUFFER, b);
  glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(n * nv * sizeof(float)), data, usage);
  glVertexAttribPointer(loc, n, GL_FLOAT, GL_FALSE, 0, 0);
  glEnableVertexAttribArray(loc);
  return b;
}

int cvr_scene_upload(cvr_scene *r, const cv_prt *p, const uint32_t *old_of, const float *usc,
                     const float *uvl, uint32_t *idx, cv_err *err) {
  r->idx_cpu = idx; /* kept for the sun split */
  float *pos = malloc(3 * p->nv * sizeof *pos + 4), *alb = malloc(3 * p->nv * sizeof *alb + 4);
  if (!pos || !alb) {
    free(pos), free(alb);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory uploading the scene");
  }
  for (size_t v = 0; v < p->nv; v++)
    for (int j = 0; j < 3; j++) {
      pos[3 * v + j] = p->pos[3 * old_of[v] + j];
      alb[3 * v + j] = p->albedo[3 * old_of[v] + j] * usc[3 * old_of[v] + j];
    }
  glGenVertexArrays(1, &r->vao_geom);
  glBindVertexArray(r->vao_geom);
  r->buf_pos = attribute(0, 3, p->nv, pos, GL_STATIC_DRAW);
  r->buf_rad = attribute(1, 4, p->nv, NULL, GL_DYNAMIC_COPY);
  r->buf_alb = attribute(2, 3, p->nv, alb, GL_STATIC_DRAW);
  if (uvl) r->buf_uvl = attribute(3, 3, p->nv, uvl, GL_STATIC_DRAW);
  glGenBuffers(1, &r->buf_idx);
  glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->buf_idx);
  glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(3 * r->nt * sizeof *idx + 4), idx, GL_STATIC_DRAW);
  glBindVertexArray(0);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  free(alb);
  r->pos_cpu = pos;
  r->chunk_nf = malloc(r->nchunks * sizeof *r->chunk_nf + 4);
  r->chunk_na = malloc(r->nchunks * sizeof *r->chunk_na + 4);
  r->md_count = malloc(r->nchunks * sizeof *r->md_count + 4);
  r->md_off = malloc(r->nchunks * sizeof *r->md_off + 8);
  if (!r->chunk_nf || !r->chunk_na || !r->md_count || !r->md_off)
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory uploading the scene");
  int st = cvr_build("geom.vert", "depth.frag", "#define DEPTH_ONLY\n", NULL, &r->prog_depth, err);
  return st ? st : cvr_gl_check("scene upload", err);
}

void cvr_scene_free(cvr_scene *r) {
  GLuint bufs[] = {r->buf_pos, r->buf_rad, r->buf_idx, r->buf_alb, r->buf_idx_sun, r->buf_uvl};
  glDeleteBuffers(6, bufs);
  glDeleteVertexArrays(1, &r->vao_geom);
  glDeleteProgram(r->prog_depth);
  r->prog_depth = 0;
  r->buf_pos = r->buf_rad = r->buf_idx = r->buf_alb = r->buf_idx_sun = r->buf_uvl = r->vao_geom = 0;
}

void cvr_scene_free_cpu(cvr_scene *r) {
  free(r->chunk_box), free(r->run), free(r->idx_cpu), free(r->pos_cpu), free(r->tri_n);
  free(r->chunk_na), free(r->chunk_nf), free(r->md_count), free(r->md_off);
  r->chunk_box = r->tri_n = r->pos_cpu = NULL;
  r->run = r->idx_cpu = r->chunk_na = r->chunk_nf = NULL;
  r->md_count = NULL, r->md_off = NULL;
}
