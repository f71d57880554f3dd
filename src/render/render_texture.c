/* Diffuse albedo textures in the renderer (a .prt with CV_PRT_TEXTURED; see
 * docs/prt-format.md).  The PRT stores a textured receiver's transfer
 * without its own albedo, so a pixel on a textured triangle is
 * texture(uv) x L(x), as in `cave shade --view` (the texture scaled so that
 * its mean is the material's stored albedo: the model's colour factor,
 * cv_texture_match_mean):
 *
 *  - the UVs are per triangle corner; vertices are split where the corners
 *    that share them differ in (u, v, texture), each copy carrying the
 *    vertex's transfer (split_vertices): a vec3 attribute (u, v, layer),
 *    layer -1 on untextured triangles (shaders/geom.vert, prt.frag TEXTURE);
 *  - every textured material (one per texture file and albedo) is a layer of
 *    a GL_TEXTURE_2D_ARRAY in GL_SRGB8_ALPHA8 (the GL decodes sRGB to linear
 *    before filtering, with the IEC 61966-2-1 curve of cv_texture_load;
 *    measured against it: docs/architecture.md), mipmapped (trilinear),
 *    repeat wrapping, row order flipped so that v = 0 is the image's bottom
 *    row as in cv_texture_sample.  The layers share one size, that of the
 *    largest texture; smaller ones are resampled bilinearly (in linear RGB,
 *    cv_texture_sample at the layer's texel centres).  The size is halved
 *    until the array fits CVR_TEX_BUDGET bytes and the GL's limits;
 *  - a texture that cannot be read is a counted warning (cv_renderer_textures):
 *    its layer is filled with the material's albedo (the texture's mean, as
 *    stored by the bake), so the surface shows its mean instead of a hole. */
#include "render/render_texture.h"

#include "io/texture.h"

#define CVR_TEX_BUDGET ((size_t)1 << 30) /* bytes of level 0 over all layers */

typedef struct corner_key {
  uint32_t v;     /* original vertex */
  int32_t layer;  /* -1: untextured */
  uint32_t u, w;  /* the UV's float bits (0 when untextured) */
  uint32_t corner;/* 3 t + k */
} corner_key;

static int cmp_key(const void *a, const void *b) {
  const corner_key *x = a, *y = b;
  if (x->v != y->v) return x->v < y->v ? -1 : 1;
  if (x->layer != y->layer) return x->layer < y->layer ? -1 : 1;
  if (x->u != y->u) return x->u < y->u ? -1 : 1;
  if (x->w != y->w) return x->w < y->w ? -1 : 1;
  return 0;
}

static uint32_t float_bits(float f) {
  uint32_t b;
  if (f == 0.0f) f = 0.0f; /* -0 and +0 are one UV */
  memcpy(&b, &f, sizeof b);
  return b;
}

static uint8_t linear_to_srgb8(float x) {
  double v = x <= 0 ? 0 : x >= 1 ? 1 : x;
  v = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055;
  return (uint8_t)lrint(v * 255.0);
}

/* The split PRT: one vertex per distinct (vertex, layer, u, v) among the
 * triangle corners (vertices no triangle uses are kept once, untextured),
 * each a copy of the original's records; *uvl gets (u, v, layer) per new
 * vertex.  layer_of[m] is material m's layer or -1. */
static int split_vertices(const cv_prt *p, const int *layer_of, cv_prt **out, float **uvl,
                          uint32_t **orig, cv_err *err) {
  const size_t nk = 3 * p->nt;
  corner_key *keys = malloc(nk * sizeof *keys + 1);
  uint8_t *used = calloc(p->nv + 1, 1);
  uint32_t *new_of_corner = malloc(nk * sizeof *new_of_corner + 1);
  if (!keys || !used || !new_of_corner) {
    free(keys), free(used), free(new_of_corner);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory splitting textured vertices");
  }
  for (size_t t = 0; t < p->nt; t++) {
    const int layer = layer_of[p->tri_mat[t]];
    for (int k = 0; k < 3; k++) {
      corner_key *c = keys + 3 * t + k;
      c->v = p->tri[3 * t + k];
      c->layer = layer;
      c->u = layer < 0 ? 0 : float_bits(p->tri_uv[6 * t + 2 * k]);
      c->w = layer < 0 ? 0 : float_bits(p->tri_uv[6 * t + 2 * k + 1]);
      c->corner = (uint32_t)(3 * t + k);
      used[c->v] = 1;
    }
  }
  qsort(keys, nk, sizeof *keys, cmp_key);
  size_t nv2 = 0;
  for (size_t i = 0; i < nk; i++)
    if (i == 0 || cmp_key(keys + i - 1, keys + i)) nv2++;
  for (size_t v = 0; v < p->nv; v++) nv2 += !used[v];
  cv_prt *q = NULL;
  float *uv = NULL;
  if (nv2 > 0xffffffffu || cv_prt_alloc(p->bands, nv2, p->nt, p->nm, p->ti != NULL, &q) ||
      !(uv = malloc(3 * nv2 * sizeof *uv + 1)) || !(*orig = malloc(nv2 * sizeof **orig + 1))) {
    free(uv);
    free(keys), free(used), free(new_of_corner), cv_prt_destroy(q);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory splitting textured vertices");
  }
  const size_t nc = (size_t)p->bands * p->bands;
  size_t n = 0;
  /* copy vertex v of p as vertex n of q, with (u, v, layer) */
  #define COPY_VERTEX(V, U, W, L)                                                          \
    do {                                                                                   \
      memcpy(q->pos + 3 * n, p->pos + 3 * (size_t)(V), 3 * sizeof(float));                 \
      memcpy(q->nrm + 3 * n, p->nrm + 3 * (size_t)(V), 3 * sizeof(float));                 \
      memcpy(q->albedo + 3 * n, p->albedo + 3 * (size_t)(V), 3 * sizeof(float));           \
      memcpy(q->td + nc * n, p->td + nc * (size_t)(V), nc * sizeof(float));                \
      if (p->ti) memcpy(q->ti + 3 * nc * n, p->ti + 3 * nc * (size_t)(V), 3 * nc * sizeof(float)); \
      uv[3 * n] = (U), uv[3 * n + 1] = (W), uv[3 * n + 2] = (float)(L);                    \
      (*orig)[n] = (uint32_t)(V);                                                          \
      n++;                                                                                 \
    } while (0)
  size_t i = 0;
  for (uint32_t v = 0; v < p->nv; v++) {
    if (!used[v]) {
      COPY_VERTEX(v, 0.0f, 0.0f, -1);
      continue;
    }
    for (; i < nk && keys[i].v == v; i++) {
      if (i == 0 || cmp_key(keys + i - 1, keys + i)) {
        const corner_key *c = keys + i;
        float u = 0, w = 0;
        if (c->layer >= 0) memcpy(&u, &c->u, sizeof u), memcpy(&w, &c->w, sizeof w);
        COPY_VERTEX(v, u, w, c->layer);
      }
      new_of_corner[keys[i].corner] = (uint32_t)(n - 1);
    }
  }
  #undef COPY_VERTEX
  for (size_t k = 0; k < nk; k++) q->tri[k] = new_of_corner[k];
  memcpy(q->tri_mat, p->tri_mat, p->nt * sizeof *q->tri_mat);
  memcpy(q->mats, p->mats, p->nm * sizeof *q->mats);
  q->flags = p->flags & ~(uint32_t)CV_PRT_TEXTURED;
  q->meta = p->meta;
  free(keys), free(used), free(new_of_corner);
  *out = q;
  *uvl = uv;
  return CV_OK;
}

/* Fills layer `dst` (w x h RGBA sRGB8, GL row order: row 0 = v 0 = the
 * image's bottom) from the linear texture t, resampled when its size
 * differs; t NULL: the constant albedo. */
static void fill_layer(uint8_t *dst, int w, int h, const cv_image *t, const float albedo[3]) {
  uint8_t cst[3];
  for (int c = 0; c < 3; c++) cst[c] = linear_to_srgb8(albedo[c]);
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      uint8_t *o = dst + 4 * ((size_t)y * w + x);
      o[3] = 255;
      if (!t) {
        memcpy(o, cst, 3);
      } else if (t->w == w && t->h == h) {
        const float *s = cv_image_at(t, x, h - 1 - y);
        for (int c = 0; c < 3; c++) o[c] = linear_to_srgb8(s[c]);
      } else {
        float s[3];
        cv_texture_sample(t, (x + 0.5) / w, (y + 0.5) / h, s);
        for (int c = 0; c < 3; c++) o[c] = linear_to_srgb8(s[c]);
      }
    }
}

/* Loads every textured material's image (a failure: counted, the layer
 * filled with the material's albedo), uploads the array. */
static int upload_layers(cvr_texture *r, const cv_prt *p, const int *layer_of, int nlayers,
                         cv_err *err) {
  cv_image **img = calloc((size_t)nlayers + 1, sizeof *img);
  const float **alb = calloc((size_t)nlayers + 1, sizeof *alb);
  if (!img || !alb) {
    free(img), free(alb);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory loading textures");
  }
  int w = 1, h = 1;
  for (size_t m = 0; m < p->nm; m++) {
    const int l = layer_of[m];
    if (l < 0 || alb[l]) continue; /* untextured, or a layer shared with an earlier material */
    alb[l] = p->mats[m].albedo;
    cv_err e;
    cv_err_clear(&e);
    if (cv_texture_load(p->mat_tex[m], &img[l], &e)) {
      if (!r->missing++)
        snprintf(r->msg, sizeof r->msg, "material '%.63s' texture: %.200s", p->mats[m].name,
                 e.msg);
      continue;
    }
    cv_texture_match_mean(img[l], alb[l]); /* the colour factor (io/texture.h) */
    if (img[l]->w > w) w = img[l]->w;
    if (img[l]->h > h) h = img[l]->h;
  }
  GLint max_size = 0, max_layers = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  glGetIntegerv(GL_MAX_ARRAY_TEXTURE_LAYERS, &max_layers);
  int st = CV_OK;
  if (nlayers > max_layers) {
    st = cv_err_set(err, CV_ERR_RANGE, "%d textured materials, this GL holds %d texture layers",
                    nlayers, (int)max_layers);
  } else {
    while ((w > max_size || h > max_size ||
            (size_t)w * (size_t)h * 4 * (size_t)nlayers > CVR_TEX_BUDGET) && (w > 1 || h > 1)) {
      w = w > 1 ? w / 2 : 1;
      h = h > 1 ? h / 2 : 1;
    }
    uint8_t *px = malloc((size_t)w * h * 4 * nlayers + 1);
    if (!px) {
      st = cv_err_set(err, CV_ERR_NOMEM, "out of memory for %d textures of %d x %d", nlayers, w, h);
    } else {
      for (int l = 0; l < nlayers; l++)
        fill_layer(px + (size_t)w * h * 4 * l, w, h, img[l], alb[l]);
      glGenTextures(1, &r->tex);
      glBindTexture(GL_TEXTURE_2D_ARRAY, r->tex);
      glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
      glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_SRGB8_ALPHA8, w, h, nlayers, 0, GL_RGBA,
                   GL_UNSIGNED_BYTE, px);
      glGenerateMipmap(GL_TEXTURE_2D_ARRAY);
      glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
      glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
      glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_S, GL_REPEAT);
      glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_T, GL_REPEAT);
      glBindTexture(GL_TEXTURE_2D_ARRAY, 0);
      free(px);
      r->layers = nlayers, r->w = w, r->h = h;
      st = cvr_gl_check("texture upload", err);
    }
  }
  for (int l = 0; l < nlayers; l++) cv_image_destroy(img[l]);
  free(img), free(alb);
  return st;
}

static const cv_prt *sort_prt; /* qsort has no context argument */

/* Materials ordered by (texture file, albedo), then index. */
static int cmp_mat(const void *a, const void *b) {
  const uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
  int c = strcmp(sort_prt->mat_tex[x], sort_prt->mat_tex[y]);
  if (!c) c = memcmp(sort_prt->mats[x].albedo, sort_prt->mats[y].albedo, sizeof(float[3]));
  return c ? c : (x > y) - (x < y);
}

/* layer_of[m]: material m's layer, -1 if untextured (or a window).  Materials
 * with the same texture file and albedo share a layer (CAD exports repeat
 * materials).  Returns the layer count, -1 out of memory. */
static int assign_layers(const cv_prt *p, int *layer_of) {
  uint32_t *ord = malloc(p->nm * sizeof *ord + 1);
  if (!ord) return -1;
  size_t n = 0;
  for (size_t m = 0; m < p->nm; m++) {
    layer_of[m] = -1;
    if (cv_prt_mat_textured(p, m) && !(p->mats[m].flags & CV_MAT_WINDOW)) ord[n++] = (uint32_t)m;
  }
  sort_prt = p;
  qsort(ord, n, sizeof *ord, cmp_mat);
  int nlayers = 0;
  for (size_t i = 0; i < n; i++) {
    const uint32_t m = ord[i], q = i ? ord[i - 1] : 0;
    const int same = i && !strcmp(p->mat_tex[m], p->mat_tex[q]) &&
                     !memcmp(p->mats[m].albedo, p->mats[q].albedo, sizeof(float[3]));
    layer_of[m] = same ? layer_of[q] : nlayers++;
  }
  free(ord);
  return nlayers;
}

int cvr_texture_prepare(cvr_texture *r, const cv_prt *p, cv_prt **split, cv_err *err) {
  *split = NULL;
  if (!(p->flags & CV_PRT_TEXTURED) || !p->tri_uv || !p->mat_tex) return CV_OK;
  int *layer_of = malloc(p->nm * sizeof *layer_of + 1);
  const int nlayers = layer_of ? assign_layers(p, layer_of) : -1;
  if (nlayers < 0) {
    free(layer_of);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory loading textures");
  }
  int st = CV_OK;
  if (nlayers) {
    st = upload_layers(r, p, layer_of, nlayers, err);
    if (!st) st = split_vertices(p, layer_of, split, &r->uvl, &r->orig, err);
    if (!st) r->split = (*split)->nv - p->nv;
  }
  free(layer_of);
  return st;
}

int cvr_texture_info(const cvr_texture *r, cv_render_tex_info *info) {
  memset(info, 0, sizeof *info);
  info->layers = r->layers;
  info->w = r->w;
  info->h = r->h;
  info->unread = r->missing;
  info->split_vertices = r->split;
  snprintf(info->first_error, sizeof info->first_error, "%s", r->msg);
  return r->layers;
}

void cvr_texture_free_upload(cvr_texture *t) {
  free(t->uvl), free(t->orig);
  t->uvl = NULL, t->orig = NULL;
}

void cvr_texture_free(cvr_texture *t) {
  glDeleteTextures(1, &t->tex);
  t->tex = 0;
}
