/* Mesh import through assimp's C API (see mesh_import.h). */
#include "io/mesh_import.h"

#include "io/child_guard.h"
#include "io/texture.h"
#include "io/texture_embed.h"

#include <assimp/cimport.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* The limits: from CAVE_IMPORT_TIMEOUT / CAVE_IMPORT_MEMORY_MB, else the
 * defaults (memory: 3/4 of the RAM, at most CV_IMPORT_DEFAULT_MEMORY_MB). */
void cv_import_limits_default(cv_import_opts *o) {
  long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  double ram_mb = (pages > 0 && page > 0) ? (double)pages * (double)page / 1048576.0 : 0;
  o->limit_seconds = cv_child_env_limit("CAVE_IMPORT_TIMEOUT", CV_IMPORT_DEFAULT_SECONDS);
  double mb = ram_mb * 0.75;
  if (mb <= 0 || mb > CV_IMPORT_DEFAULT_MEMORY_MB) mb = CV_IMPORT_DEFAULT_MEMORY_MB;
  o->limit_memory_mb = cv_child_env_limit("CAVE_IMPORT_MEMORY_MB", mb);
}

void cv_import_opts_default(cv_import_opts *o) {
  memset(o, 0, sizeof *o);
  o->default_albedo[0] = o->default_albedo[1] = o->default_albedo[2] = 0.5f;
  o->scale = 1.0;
  cv_import_limits_default(o);
}

static int starts_with_ci(const char *s, const char *prefix) {
  for (; *prefix; s++, prefix++)
    if (tolower((unsigned char)*s) != tolower((unsigned char)*prefix)) return 0;
  return 1;
}

static int ends_with_ci(const char *s, const char *suffix) {
  size_t n = strlen(s), k = strlen(suffix);
  return n >= k && starts_with_ci(s + n - k, suffix);
}

/* ---------------- OBJ pre-scan ---------------- */
/* assimp reads garbage numbers as 0 and may skip or reject bad indices
 * depending on the version; check the file ourselves so the user gets the
 * line.  Pass 1 counts v/vt/vn (positive indices may point forward, as
 * assimp allows); pass 2 checks numbers and indices (negative indices are
 * relative to the elements defined so far). */
typedef struct obj_counts {
  long v, vt, vn;
} obj_counts;

static char *next_tok(char **s) {
  char *p = *s;
  while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n') p++;
  if (!*p) return NULL;
  char *start = p;
  while (*p && *p != ' ' && *p != '\t' && *p != '\r' && *p != '\n') p++;
  if (*p) *p++ = '\0';
  *s = p;
  return start;
}

static int check_index(const char *path, long line, const char *tok, const char *what, long n,
                       cv_err *err) {
  char *end;
  errno = 0;
  long i = strtol(tok, &end, 10);
  if (end == tok || *end || errno)
    return cv_err_set(err, CV_ERR_FORMAT, "%s:%ld: %s index '%s' is not an integer", path, line,
                      what, tok);
  if (i == 0 || i > n || i < -n)
    return cv_err_set(err, CV_ERR_FORMAT, "%s:%ld: %s index %ld out of range (%ld defined)", path,
                      line, what, i, n);
  return CV_OK;
}

static int obj_scan(const char *path, FILE *f, cv_err *err) {
  obj_counts tot = {0, 0, 0}, cur = {0, 0, 0};
  long nf = 0, nl = 0, np = 0;
  char *buf = NULL;
  size_t cap = 0;
  int st = CV_OK;
  for (int pass = 0; pass < 2 && !st; pass++) {
    rewind(f);
    long line = 0;
    while (!st && getline(&buf, &cap, f) >= 0) {
      line++;
      char *s = buf, *kw = next_tok(&s);
      if (!kw || kw[0] == '#') continue;
      int is_v = !strcmp(kw, "v"), is_vt = !strcmp(kw, "vt"), is_vn = !strcmp(kw, "vn");
      if (is_v || is_vt || is_vn) {
        if (pass == 0) {
          tot.v += is_v, tot.vt += is_vt, tot.vn += is_vn;
          continue;
        }
        int need = is_vt ? 1 : 3, n = 0;
        for (char *t; (t = next_tok(&s)) != NULL; n++) {
          char *end;
          double x = strtod(t, &end);
          if (end == t || *end || !isfinite(x)) {
            st = cv_err_set(err, CV_ERR_FORMAT, "%s:%ld: '%s' expects finite numbers, got '%s'",
                            path, line, kw, t);
            break;
          }
        }
        if (!st && n < need)
          st = cv_err_set(err, CV_ERR_FORMAT, "%s:%ld: '%s' expects %d numbers, got %d", path,
                          line, kw, need, n);
        cur.v += is_v, cur.vt += is_vt, cur.vn += is_vn;
      } else if (pass == 1 && (!strcmp(kw, "f") || !strcmp(kw, "l") || !strcmp(kw, "p"))) {
        int n = 0;
        nf += kw[0] == 'f', nl += kw[0] == 'l', np += kw[0] == 'p';
        for (char *t; (t = next_tok(&s)) != NULL && !st; n++) {
          /* v, v/vt, v//vn, v/vt/vn */
          char *part[3] = {t, NULL, NULL};
          char *sl = strchr(t, '/');
          if (sl) {
            *sl = '\0';
            part[1] = sl + 1;
            char *sl2 = strchr(part[1], '/');
            if (sl2) {
              *sl2 = '\0';
              part[2] = sl2 + 1;
            }
          }
          long lim[3] = {tot.v, tot.vt, tot.vn};
          long rel[3] = {cur.v, cur.vt, cur.vn};
          static const char *what[3] = {"vertex", "texture", "normal"};
          for (int k = 0; k < 3 && !st; k++) {
            if (!part[k] || (k > 0 && !*part[k])) continue;
            /* negative indices count back from the elements seen so far */
            long n_ok = part[k][0] == '-' ? rel[k] : lim[k];
            st = check_index(path, line, part[k], what[k], n_ok, err);
          }
        }
        if (!st && kw[0] == 'f' && n < 3)
          st = cv_err_set(err, CV_ERR_FORMAT, "%s:%ld: face with %d vertices, expected >= 3",
                          path, line, n);
      }
    }
  }
  free(buf);
  /* assimp's own messages for these ("too small", "validation failed")
   * would not say what is missing */
  if (!st && nf == 0)
    st = cv_err_set(err, CV_ERR_EMPTY, "%s: no faces (%ld vertices, %ld lines, %ld points)", path,
                    tot.v, nl, np);
  return st;
}

/* ---------------- materials ---------------- */
static float clamp01(float x, size_t *nclamp) {
  if (x >= 0.0f && x <= 1.0f) return x;
  (*nclamp)++;
  return x > 1.0f ? 1.0f : 0.0f; /* NaN and negatives -> 0 */
}

/* Mean linear RGB of the PNG or JPEG texture at path (cv_texture_load).
 * Returns 0 and fills mean[3], or -1 (*e: missing, unreadable). */
static int texture_mean(const char *path, double mean[3], cv_err *e) {
  cv_image *im = NULL;
  if (cv_texture_load(path, &im, e) != CV_OK) return -1;
  double acc[3] = {0, 0, 0};
  const size_t n = (size_t)im->w * (size_t)im->h;
  for (size_t i = 0; i < n; i++)
    for (int k = 0; k < 3; k++) acc[k] += im->px[3 * i + k];
  for (int k = 0; k < 3; k++) mean[k] = acc[k] / (double)n;
  cv_image_destroy(im);
  return 0;
}

/* The material's diffuse texture (glTF base colour, else diffuse) resolved
 * against the model's folder into out; 0 if the material has none.  An
 * embedded texture ("*N", or a name the scene's embedded textures carry
 * and no file has) is written to the texture cache and out names that file
 * (io/texture_embed.h; s->textures_embedded); -1 if that fails (*e). */
static int texture_path(const struct aiScene *sc, const struct aiMaterial *am, const char *model,
                        char *out, size_t n, cv_import_stats *s, cv_err *e) {
  struct aiString tp;
  if (aiGetMaterialTexture(am, aiTextureType_BASE_COLOR, 0, &tp, NULL, NULL, NULL, NULL, NULL,
                           NULL) != aiReturn_SUCCESS &&
      aiGetMaterialTexture(am, aiTextureType_DIFFUSE, 0, &tp, NULL, NULL, NULL, NULL, NULL,
                           NULL) != aiReturn_SUCCESS)
    return 0;
  if (sc->mNumTextures || tp.data[0] == '*') {
    int emb = cv_texture_embedded_file(sc, tp.data, out, n, e);
    if (emb) {
      s->textures_embedded += emb > 0;
      return emb;
    }
  }
  const char *slash = strrchr(model, '/');
  int dir = slash ? (int)(slash - model) + 1 : 0;
  if (tp.data[0] == '/' || dir == 0) snprintf(out, n, "%s", tp.data);
  else snprintf(out, n, "%.*s%s", dir, model, tp.data);
  if (access(out, F_OK) != 0 && strchr(tp.data, '\\')) {
    /* Windows separators (".\\wood.jpg" in MTL files written on Windows) */
    const size_t off = strlen(out) - strlen(tp.data);
    for (char *p = out + off; *p; p++)
      if (*p == '\\') *p = '/';
  }
  char abs[PATH_MAX]; /* absolute, so that a .prt works from any directory */
  if (realpath(out, abs) && strlen(abs) < n) memcpy(out, abs, strlen(abs) + 1);
  return 1;
}

/* Counts an unread texture, keeping the first reason. */
static void texture_unread(cv_import_stats *s, const char *nm, const char *why) {
  if (s->textures_unread++) return;
  char line[640];
  snprintf(line, sizeof line, "material '%.40s': %.512s", nm, why);
  snprintf(s->texture_error, sizeof s->texture_error, "%.319s", line);
}

static int add_material(cv_mesh *m, const struct aiScene *sc, const struct aiMaterial *am,
                        const char *model, const cv_import_opts *o, uint8_t *ov_used,
                        cv_import_stats *s) {
  struct aiString name;
  char nm[64] = "unnamed";
  if (aiGetMaterialString(am, AI_MATKEY_NAME, &name) == aiReturn_SUCCESS) {
    size_t n = name.length < sizeof nm - 1 ? name.length : sizeof nm - 1;
    memcpy(nm, name.data, n);
    nm[n] = '\0';
  }
  struct aiColor4D c;
  float alb[3];
  if (aiGetMaterialColor(am, AI_MATKEY_BASE_COLOR, &c) == aiReturn_SUCCESS ||
      aiGetMaterialColor(am, AI_MATKEY_COLOR_DIFFUSE, &c) == aiReturn_SUCCESS) {
    alb[0] = c.r, alb[1] = c.g, alb[2] = c.b;
  } else {
    alb[0] = alb[1] = alb[2] = -1.0f; /* none yet */
  }
  char tex[4096];
  double mean[3];
  int textured = 0, tp;
  cv_err e;
  cv_err_clear(&e);
  if ((tp = texture_path(sc, am, model, tex, sizeof tex, s, &e)) < 0) {
    texture_unread(s, nm, e.msg);
  } else if (tp) {
    if (strlen(tex) >= CV_TEX_PATH_MAX) {
      texture_unread(s, nm, "texture path longer than 255 bytes"); /* too long to keep */
    } else if (texture_mean(tex, mean, &e) == 0) {
      textured = 1;
      /* the colour factor multiplies the texture (glTF 2.0 spec; MTL Kd x map_Kd) */
      for (int k = 0; k < 3; k++) alb[k] = (float)((alb[k] < 0 ? 1.0 : alb[k]) * mean[k]);
      s->textures_averaged++;
    } else {
      texture_unread(s, nm, e.msg);
    }
  }
  if (alb[0] < 0) {
    memcpy(alb, o->default_albedo, sizeof alb);
    s->albedo_defaulted++;
  }
  uint32_t flags = 0;
  if (starts_with_ci(nm, "window")) flags |= CV_MAT_WINDOW;
  if (starts_with_ci(nm, "lcd")) flags |= CV_MAT_LCD;
  for (size_t i = 0; i < o->n_overrides; i++) {
    const cv_material_override *ov = &o->overrides[i];
    if (strncmp(ov->name, nm, sizeof ov->name) != 0) continue;
    if (ov->has_albedo) memcpy(alb, ov->albedo, sizeof alb);
    if (ov->has_flags) flags = ov->flags;
    if (!ov_used[i]) s->overrides_applied++;
    ov_used[i] = 1;
  }
  for (int k = 0; k < 3; k++) alb[k] = clamp01(alb[k], &s->albedo_clamped);
  uint32_t idx;
  int st = cv_mesh_add_material(m, nm, alb, flags, &idx);
  if (!st && textured) st = cv_mesh_set_texture(m, idx, tex);
  return st;
}

/* ---------------- the file's own units and up axis ---------------- */
static int meta_number(const struct aiScene *sc, const char *key, double *out) {
  const struct aiMetadata *md = sc->mMetaData;
  for (unsigned i = 0; md && i < md->mNumProperties; i++) {
    if (strcmp(md->mKeys[i].data, key)) continue;
    const struct aiMetadataEntry *e = &md->mValues[i];
    switch (e->mType) {
    case AI_INT32: *out = *(const int32_t *)e->mData; return 1;
    case AI_FLOAT: *out = *(const float *)e->mData; return 1;
    case AI_DOUBLE: *out = *(const double *)e->mData; return 1;
    default: return 0;
    }
  }
  return 0;
}

static void read_frame(const char *path, const struct aiScene *sc, cv_file_frame *fr) {
  memset(fr, 0, sizeof *fr);
  double usf, upx, sign = 1;
  if (ends_with_ci(path, ".gltf") || ends_with_ci(path, ".glb")) {
    fr->unit_m = 1.0, fr->up = 'y', fr->source = "glTF specification (metres, Y up)";
  } else if (ends_with_ci(path, ".dae")) {
    fr->unit_m = 1.0, fr->up = 'y', fr->source = "COLLADA <unit>/<up_axis>, applied by assimp";
  } else if (ends_with_ci(path, ".ifc")) {
    fr->unit_m = 1.0, fr->up = 'y', fr->source = "IFC units and Z up, converted by assimp";
  } else if (ends_with_ci(path, ".fbx") && meta_number(sc, "UnitScaleFactor", &usf)) {
    if (isfinite(usf) && usf > 0) fr->unit_m = usf * 0.01; /* FBX: centimetres per unit */
    meta_number(sc, "UpAxisSign", &sign);
    if (meta_number(sc, "UpAxis", &upx) && sign > 0)
      fr->up = upx == 1 ? 'y' : upx == 2 ? 'z' : 0;
    fr->source = "FBX UnitScaleFactor/UpAxis";
  }
}

/* ---------------- import ---------------- */
/* Pass 1: which materials triangles use (matmap[i] = 0 for those, -1 for
 * the others) and the vertex and triangle counts; points and lines are
 * counted as dropped.  Returns the status. */
static int count_scene(const char *path, const struct aiScene *sc, int32_t *matmap, size_t *nv_out,
                       size_t *nt_out, cv_import_stats *s, cv_err *err) {
  size_t nv = 0, nt = 0;
  for (unsigned i = 0; i <= sc->mNumMaterials; i++) matmap[i] = -1;
  s->meshes = sc->mNumMeshes;
  for (unsigned i = 0; i < sc->mNumMeshes; i++) {
    const struct aiMesh *am = sc->mMeshes[i];
    size_t ntri = 0;
    for (unsigned fi = 0; fi < am->mNumFaces; fi++) {
      unsigned k = am->mFaces[fi].mNumIndices;
      if (k == 3)
        ntri++;
      else if (k == 1)
        s->points_dropped++;
      else if (k == 2)
        s->lines_dropped++;
      else
        return cv_err_set(err, CV_ERR_FORMAT, "%s: mesh %u face %u has %u indices after "
                          "triangulation", path, i, fi, k);
    }
    if (!ntri) continue;
    if (am->mMaterialIndex >= sc->mNumMaterials)
      return cv_err_set(err, CV_ERR_FORMAT, "%s: mesh %u refers to material %u of %u", path, i,
                        am->mMaterialIndex, sc->mNumMaterials);
    matmap[am->mMaterialIndex] = 0;
    nv += am->mNumVertices;
    nt += ntri;
  }
  if (nt == 0)
    return cv_err_set(err, CV_ERR_EMPTY, "%s: no triangles (%zu points and %zu lines dropped)",
                      path, s->points_dropped, s->lines_dropped);
  if (nv >= UINT32_MAX || nt >= UINT32_MAX)
    return cv_err_set(err, CV_ERR_RANGE, "%s: too large (%zu vertices, %zu triangles)", path, nv,
                      nt);
  *nv_out = nv;
  *nt_out = nt;
  return CV_OK;
}

/* Pass 2 for assimp mesh i (with triangles): its vertices (scaled, finite)
 * and its triangles (indices checked independently of assimp, corner UVs
 * of the first channel when some material has a texture).  Returns the
 * status. */
static int add_scene_mesh(const char *path, const struct aiMesh *am, unsigned i, double scale,
                          const int32_t *matmap, cv_mesh *m, cv_err *err) {
  uint32_t base = (uint32_t)m->nv;
  for (unsigned vi = 0; vi < am->mNumVertices; vi++) {
    double p[3] = {am->mVertices[vi].x, am->mVertices[vi].y, am->mVertices[vi].z};
    for (int k = 0; k < 3; k++) {
      p[k] *= scale;
      if (!isfinite(p[k]) || fabs(p[k]) > 3.0e38)
        return cv_err_set(err, CV_ERR_NONFINITE, "%s: mesh %u vertex %u has a non-finite "
                          "coordinate", path, i, vi);
    }
    cv_mesh_add_vertex(m, (float)p[0], (float)p[1], (float)p[2], NULL);
  }
  const struct aiVector3D *uv = am->mTextureCoords[0];
  if (m->mat_tex && cv_mesh_enable_uv(m)) return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  for (unsigned fi = 0; fi < am->mNumFaces; fi++) {
    const struct aiFace *fc = &am->mFaces[fi];
    if (fc->mNumIndices != 3) continue;
    for (int k = 0; k < 3; k++)
      if (fc->mIndices[k] >= am->mNumVertices)
        return cv_err_set(err, CV_ERR_FORMAT, "%s: mesh %u face %u index %u out of range (%u "
                          "vertices)", path, i, fi, fc->mIndices[k], am->mNumVertices);
    cv_mesh_add_tri(m, base + fc->mIndices[0], base + fc->mIndices[1], base + fc->mIndices[2],
                    (uint32_t)matmap[am->mMaterialIndex]);
    for (int k = 0; m->tri_uv && uv && k < 3; k++) {
      const struct aiVector3D *t = &uv[fc->mIndices[k]];
      if (!isfinite(t->x) || !isfinite(t->y))
        return cv_err_set(err, CV_ERR_NONFINITE, "%s: mesh %u vertex %u has a non-finite "
                          "texture coordinate", path, i, fc->mIndices[k]);
      m->tri_uv[6 * (m->nt - 1) + 2 * k] = t->x;
      m->tri_uv[6 * (m->nt - 1) + 2 * k + 1] = t->y;
    }
  }
  return CV_OK;
}

/* The imported scene into m: counts, materials (with the overrides), then
 * every mesh with triangles.  Returns the status. */
static int build_mesh(const char *path, const struct aiScene *sc, const cv_import_opts *opts,
                      cv_mesh *m, cv_import_stats *s, cv_err *err) {
  int32_t *matmap = malloc((sc->mNumMaterials + 1) * sizeof *matmap);
  uint8_t *ov_used = calloc(opts->n_overrides + 1, 1);
  size_t nv = 0, nt = 0;
  int st = (!matmap || !ov_used) ? cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path)
                                 : count_scene(path, sc, matmap, &nv, &nt, s, err);
  if (!st && cv_mesh_reserve(m, nv, nt)) st = cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  for (unsigned i = 0; !st && i < sc->mNumMaterials; i++) {
    if (matmap[i] < 0) continue;
    matmap[i] = (int32_t)m->nm;
    if (add_material(m, sc, sc->mMaterials[i], path, opts, ov_used, s))
      st = cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  }
  for (unsigned i = 0; !st && i < sc->mNumMeshes; i++) {
    const struct aiMesh *am = sc->mMeshes[i];
    int has_tri = 0;
    for (unsigned fi = 0; fi < am->mNumFaces && !has_tri; fi++)
      has_tri = am->mFaces[fi].mNumIndices == 3;
    if (has_tri) st = add_scene_mesh(path, am, i, opts->scale, matmap, m, err);
  }
  if (!st) {
    s->triangles = m->nt;
    read_frame(path, sc, &s->frame);
    for (size_t i = 0; i < opts->n_overrides; i++) s->overrides_unused += !ov_used[i];
  }
  free(matmap);
  free(ov_used);
  return st;
}

int cv_mesh_import_direct(const char *path, const cv_import_opts *opts, cv_mesh **out,
                          cv_import_stats *stats, cv_err *err) {
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "mesh import: out is NULL");
  *out = NULL;
  if (!path) return cv_err_set(err, CV_ERR_INVALID, "mesh import: path is NULL");
  cv_import_opts def;
  if (!opts) {
    cv_import_opts_default(&def);
    opts = &def;
  }
  cv_import_stats local;
  cv_import_stats *s = stats ? stats : &local;
  memset(s, 0, sizeof *s);
  if (!(isfinite(opts->scale) && opts->scale > 0))
    return cv_err_set(err, CV_ERR_INVALID, "%s: import scale %g, expected a positive number",
                      path, opts->scale);
  if (opts->n_overrides && !opts->overrides)
    return cv_err_set(err, CV_ERR_INVALID, "%s: %zu overrides but no array", path,
                      opts->n_overrides);

  FILE *f = fopen(path, "rb");
  if (!f) return cv_err_set(err, CV_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
  int st = CV_OK;
  if (ends_with_ci(path, ".obj")) st = obj_scan(path, f, err);
  fclose(f);
  if (st) return st;

  const unsigned flags = aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                         aiProcess_SortByPType | aiProcess_PreTransformVertices |
                         aiProcess_ValidateDataStructure;
  const struct aiScene *sc = aiImportFile(path, flags);
  if (!sc) return cv_err_set(err, CV_ERR_FORMAT, "%s: assimp: %s", path, aiGetErrorString());
  cv_mesh *m = NULL;
  st = cv_mesh_create(&m) ? cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path)
                          : build_mesh(path, sc, opts, m, s, err);
  if (!st) {
    st = cv_mesh_validate(m, err);
    if (st) cv_err_prefix(err, "%s", path);
  }
  aiReleaseImport(sc);
  if (st) {
    cv_mesh_destroy(m);
    return st;
  }
  *out = m;
  return CV_OK;
}
