/* PRT file format, version 2 (reads 1; documented in docs/prt-format.md).
 * Little-endian; a fixed 128-byte header, then the payload arrays in a fixed
 * order; the header carries an FNV-1a hash of the payload so truncation and
 * corruption are detected, and the input hash of the bake. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/hash.h"
#include "core/outfile.h"
#include "prt/prt.h"

static const char MAGIC[8] = {'C', 'A', 'V', 'E', 'P', 'R', 'T', '\0'};
#define HEADER_SIZE 128

typedef struct {
  char magic[8];
  uint32_t version, header_size, bands, flags;
  uint64_t nv, nt, nm;
  uint64_t input_hash, payload_hash;
  uint32_t rays, bounces, seed;
  float est_error, spread;
} header;

int cv_prt_alloc(uint32_t bands, size_t nv, size_t nt, size_t nm, int has_indirect,
                 cv_prt **out) {
  *out = NULL;
  if (bands < 1 || bands > CV_PRT_MAX_BANDS) return CV_ERR_RANGE;
  cv_prt *p = calloc(1, sizeof *p);
  if (!p) return CV_ERR_NOMEM;
  size_t nc = (size_t)bands * bands;
  p->bands = bands;
  p->nv = nv;
  p->nt = nt;
  p->nm = nm;
  p->flags = has_indirect ? CV_PRT_HAS_INDIRECT : 0;
  p->pos = calloc(3 * nv + 1, sizeof(float));
  p->nrm = calloc(3 * nv + 1, sizeof(float));
  p->albedo = calloc(3 * nv + 1, sizeof(float));
  p->tri = calloc(3 * nt + 1, sizeof(uint32_t));
  p->tri_mat = calloc(nt + 1, sizeof(uint32_t));
  p->mats = calloc(nm + 1, sizeof(cv_material));
  p->td = calloc(nv * nc + 1, sizeof(float));
  if (has_indirect) p->ti = calloc(3 * nv * nc + 1, sizeof(float));
  p->meta.est_error = -1.0f;
  if (!p->pos || !p->nrm || !p->albedo || !p->tri || !p->tri_mat || !p->mats || !p->td ||
      (has_indirect && !p->ti)) {
    cv_prt_destroy(p);
    return CV_ERR_NOMEM;
  }
  *out = p;
  return CV_OK;
}

void cv_prt_destroy(cv_prt *p) {
  if (!p) return;
  free(p->pos);
  free(p->nrm);
  free(p->albedo);
  free(p->tri);
  free(p->tri_mat);
  free(p->mats);
  free(p->td);
  free(p->ti);
  free(p->tri_uv);
  free(p->mat_tex);
  free(p);
}

int cv_prt_alloc_textures(cv_prt *p) {
  if (!p->tri_uv) p->tri_uv = calloc(6 * p->nt + 1, sizeof(float));
  if (!p->mat_tex) p->mat_tex = calloc(p->nm + 1, CV_TEX_PATH_MAX);
  if (!p->tri_uv || !p->mat_tex) return CV_ERR_NOMEM;
  p->flags |= CV_PRT_TEXTURED;
  return CV_OK;
}

int cv_prt_mat_textured(const cv_prt *p, size_t i) {
  return p->mat_tex && i < p->nm && p->mat_tex[i][0] != '\0';
}

int cv_prt_untextured_scale(const cv_prt *p, float *scale) {
  for (size_t i = 0; i < 3 * p->nv; i++) scale[i] = 1.0f;
  if (!(p->flags & CV_PRT_TEXTURED)) return CV_OK;
  double *acc = calloc(4 * p->nv + 1, sizeof(double));
  if (!acc) return CV_ERR_NOMEM;
  for (size_t t = 0; t < p->nt; t++) {
    const float *a = p->mats[p->tri_mat[t]].albedo;
    for (int j = 0; j < 3; j++) {
      double *q = acc + 4 * (size_t)p->tri[3 * t + j];
      for (int c = 0; c < 3; c++) q[c] += a[c];
      q[3] += 1;
    }
  }
  for (size_t v = 0; v < p->nv; v++)
    for (int c = 0; c < 3; c++) {
      double r = p->albedo[3 * v + c], n = acc[4 * v + 3];
      if (r > 0 && n > 0) scale[3 * v + c] = (float)(acc[4 * v + c] / n / r);
    }
  free(acc);
  return CV_OK;
}

int cv_prt_fold_texture_means(const cv_prt *p, float *rad) {
  if (!(p->flags & CV_PRT_TEXTURED)) return CV_OK;
  float *s = malloc(3 * p->nv * sizeof(float) + 1);
  if (!s) return CV_ERR_NOMEM;
  cv_prt_untextured_scale(p, s);
  for (size_t i = 0; i < 3 * p->nv; i++) rad[i] *= s[i];
  free(s);
  return CV_OK;
}

/* The payload as a list of (pointer, bytes) in file order. */
typedef struct {
  void *ptr;
  size_t bytes;
} chunk;

static int payload_chunks(const cv_prt *p, chunk c[10]) {
  size_t nc = (size_t)p->bands * p->bands;
  int k = 0;
  c[k++] = (chunk){p->pos, 3 * p->nv * sizeof(float)};
  c[k++] = (chunk){p->nrm, 3 * p->nv * sizeof(float)};
  c[k++] = (chunk){p->albedo, 3 * p->nv * sizeof(float)};
  c[k++] = (chunk){p->tri, 3 * p->nt * sizeof(uint32_t)};
  c[k++] = (chunk){p->tri_mat, p->nt * sizeof(uint32_t)};
  c[k++] = (chunk){p->mats, p->nm * sizeof(cv_material)};
  c[k++] = (chunk){p->td, p->nv * nc * sizeof(float)};
  if (p->flags & CV_PRT_HAS_INDIRECT) c[k++] = (chunk){p->ti, 3 * p->nv * nc * sizeof(float)};
  if (p->flags & CV_PRT_TEXTURED) {
    c[k++] = (chunk){p->tri_uv, 6 * p->nt * sizeof(float)};
    c[k++] = (chunk){p->mat_tex, p->nm * (size_t)CV_TEX_PATH_MAX};
  }
  return k;
}

/* The format is defined as little-endian with IEEE floats and the cv_material
 * layout {char[64], float[3], uint32}; this build writes its memory directly,
 * which matches on every little-endian target we support. */
_Static_assert(sizeof(cv_material) == 80, "cv_material layout is part of the PRT format");
_Static_assert(sizeof(header) <= HEADER_SIZE, "header fits");

int cv_prt_write(const char *path, const cv_prt *p, cv_err *err) {
  chunk c[10];
  int nchunks = payload_chunks(p, c);
  header h;
  memset(&h, 0, sizeof h);
  memcpy(h.magic, MAGIC, 8);
  h.version = CV_PRT_VERSION;
  h.header_size = HEADER_SIZE;
  h.bands = p->bands;
  h.flags = p->flags;
  h.nv = p->nv;
  h.nt = p->nt;
  h.nm = p->nm;
  h.input_hash = p->meta.input_hash;
  h.rays = p->meta.rays;
  h.bounces = p->meta.bounces;
  h.seed = p->meta.seed;
  h.est_error = p->meta.est_error;
  h.spread = p->meta.spread;
  uint64_t ph = cv_hash64_init();
  for (int i = 0; i < nchunks; i++) ph = cv_hash64_update(ph, c[i].ptr, c[i].bytes);
  h.payload_hash = ph;

  cv_outfile of;
  int st = cv_outfile_open(&of, path, 1, err);
  if (st) return st;
  unsigned char hb[HEADER_SIZE];
  memset(hb, 0, sizeof hb);
  memcpy(hb, &h, sizeof h);
  int ok = fwrite(hb, 1, HEADER_SIZE, of.f) == HEADER_SIZE;
  for (int i = 0; ok && i < nchunks; i++)
    ok = c[i].bytes == 0 || fwrite(c[i].ptr, 1, c[i].bytes, of.f) == c[i].bytes;
  if (!ok) {
    cv_outfile_abort(&of);
    return cv_err_set(err, CV_ERR_IO, "%s: write failed: %s", path, strerror(errno));
  }
  return cv_outfile_commit(&of, err);
}

static int read_header(FILE *f, const char *path, header *h, cv_err *err) {
  unsigned char hb[HEADER_SIZE];
  if (fread(hb, 1, HEADER_SIZE, f) != HEADER_SIZE)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: truncated header (expected %d bytes)", path,
                      HEADER_SIZE);
  memcpy(h, hb, sizeof *h);
  if (memcmp(h->magic, MAGIC, 8) != 0)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: not a CAVE PRT file (bad magic)", path);
  if (h->version != 1 && h->version != CV_PRT_VERSION)
    return cv_err_set(err, CV_ERR_UNSUPPORTED, "%s: PRT version %u, this build reads 1..%d", path,
                      h->version, CV_PRT_VERSION);
  if (h->version == 1 && (h->flags & CV_PRT_TEXTURED))
    return cv_err_set(err, CV_ERR_FORMAT, "%s: flags 0x%x: version 1 has no textures", path,
                      h->flags);
  if (h->header_size != HEADER_SIZE || h->bands < 1 || h->bands > CV_PRT_MAX_BANDS ||
      h->nv == 0 || h->nt == 0 || h->nv > (1ull << 32) || h->nt > (1ull << 32) ||
      h->nm > (1ull << 20))
    return cv_err_set(err, CV_ERR_FORMAT,
                      "%s: implausible header (bands %u, %llu vertices, %llu triangles)", path,
                      h->bands, (unsigned long long)h->nv, (unsigned long long)h->nt);
  return CV_OK;
}

/* Payload bytes the header's counts call for, from the counts alone (read_header
 * bounds them: nv, nt <= 2^32, nm <= 2^20, bands <= 8, so no overflow in 64 bits). */
static uint64_t payload_bytes(const header *h) {
  uint64_t nc = (uint64_t)h->bands * h->bands;
  uint64_t per_vertex = 9 * sizeof(float) + nc * sizeof(float) +
                        ((h->flags & CV_PRT_HAS_INDIRECT) ? 3 * nc * sizeof(float) : 0);
  uint64_t tex = (h->flags & CV_PRT_TEXTURED)
                     ? h->nt * 6 * sizeof(float) + h->nm * (uint64_t)CV_TEX_PATH_MAX
                     : 0;
  return h->nv * per_vertex + h->nt * 4 * sizeof(uint32_t) + h->nm * sizeof(cv_material) + tex;
}

/* The header's counts against the file's size, before anything is allocated:
 * a 2 KB file claiming 2^30 vertices is refused at once, naming the counts. */
static int check_counts(FILE *f, const char *path, const header *h, cv_err *err) {
  struct stat sb;
  if (fstat(fileno(f), &sb) != 0 || !S_ISREG(sb.st_mode))
    return cv_err_set(err, CV_ERR_IO, "%s: not a regular file", path);
  uint64_t have = (uint64_t)sb.st_size - HEADER_SIZE, want = payload_bytes(h);
  if (have == want) return CV_OK;
  return cv_err_set(err, CV_ERR_FORMAT,
                    "%s: header counts (nv %llu vertices, nt %llu triangles, nm %llu materials, "
                    "bands %u%s) need a %llu-byte payload, the file has %llu after the header",
                    path, (unsigned long long)h->nv, (unsigned long long)h->nt,
                    (unsigned long long)h->nm, h->bands,
                    (h->flags & CV_PRT_HAS_INDIRECT) ? ", indirect" : "", (unsigned long long)want,
                    (unsigned long long)have);
}

int cv_prt_read_input_hash(const char *path, uint64_t *hash, cv_err *err) {
  FILE *f = fopen(path, "rb");
  if (!f) {
    if (errno == ENOENT) return cv_err_set(err, CV_ERR_NOT_FOUND, "%s: no such file", path);
    return cv_err_set(err, CV_ERR_IO, "%s: %s", path, strerror(errno));
  }
  header h;
  int st = read_header(f, path, &h, err);
  if (!st) st = check_counts(f, path, &h, err); /* a stat: a truncated file is no match */
  fclose(f);
  if (st) return st;
  *hash = h.input_hash;
  return CV_OK;
}

/* Per-vertex records: finite position, transfer, albedo in [0, 1], normal
 * unit (within CV_PRT_NORMAL_TOL) or exactly zero (a vertex no triangle
 * faces, as the bake writes it).  Names the first bad record. */
static int check_records(const cv_prt *p, const char *path, cv_err *err) {
  size_t nc = (size_t)p->bands * p->bands;
  static const char *axis = "xyz", *chan = "rgb";
  for (size_t v = 0; v < p->nv; v++) {
    const float *x = p->pos + 3 * v, *n = p->nrm + 3 * v, *a = p->albedo + 3 * v;
    for (int k = 0; k < 3; k++) {
      if (!isfinite(x[k]))
        return cv_err_set(err, CV_ERR_NONFINITE, "%s: vertex %zu position.%c is %g, expected finite",
                          path, v, axis[k], (double)x[k]);
      if (!isfinite(n[k]))
        return cv_err_set(err, CV_ERR_NONFINITE, "%s: vertex %zu normal.%c is %g, expected finite",
                          path, v, axis[k], (double)n[k]);
      if (!(a[k] >= 0.0f && a[k] <= 1.0f))
        return cv_err_set(err, isfinite(a[k]) ? CV_ERR_RANGE : CV_ERR_NONFINITE,
                          "%s: vertex %zu albedo.%c is %g, expected in [0, 1]", path, v, chan[k],
                          (double)a[k]);
    }
    double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
    if (len != 0.0 && fabs(len - 1.0) > CV_PRT_NORMAL_TOL)
      return cv_err_set(err, CV_ERR_RANGE,
                        "%s: vertex %zu normal (%g, %g, %g) has length %g, expected 1 +- %g (or 0)",
                        path, v, (double)n[0], (double)n[1], (double)n[2], len, CV_PRT_NORMAL_TOL);
    for (size_t i = 0; i < nc; i++)
      if (!isfinite(p->td[v * nc + i]))
        return cv_err_set(err, CV_ERR_NONFINITE,
                          "%s: vertex %zu direct transfer coefficient %zu is %g, expected finite",
                          path, v, i, (double)p->td[v * nc + i]);
    for (size_t i = 0; p->ti && i < 3 * nc; i++)
      if (!isfinite(p->ti[3 * v * nc + i]))
        return cv_err_set(err, CV_ERR_NONFINITE,
                          "%s: vertex %zu indirect transfer %c coefficient %zu is %g, expected finite",
                          path, v, chan[i / nc], i % nc, (double)p->ti[3 * v * nc + i]);
  }
  for (size_t t = 0; t < p->nt; t++) {
    for (int j = 0; j < 3; j++)
      if (p->tri[3 * t + j] >= p->nv)
        return cv_err_set(err, CV_ERR_FORMAT, "%s: triangle %zu vertex %d is %u, expected < nv %zu",
                          path, t, j, p->tri[3 * t + j], p->nv);
    if (p->tri_mat[t] >= p->nm)
      return cv_err_set(err, CV_ERR_FORMAT, "%s: triangle %zu material is %u, expected < nm %zu",
                        path, t, p->tri_mat[t], p->nm);
    for (int j = 0; p->tri_uv && j < 6; j++)
      if (!isfinite(p->tri_uv[6 * t + j]))
        return cv_err_set(err, CV_ERR_NONFINITE, "%s: triangle %zu uv[%d] is %g, expected finite",
                          path, t, j, (double)p->tri_uv[6 * t + j]);
  }
  return CV_OK;
}

int cv_prt_read(const char *path, cv_prt **out, cv_err *err) {
  *out = NULL;
  FILE *f = fopen(path, "rb");
  if (!f) return cv_err_set(err, CV_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
  header h;
  int st = read_header(f, path, &h, err);
  if (!st) st = check_counts(f, path, &h, err);
  if (st) {
    fclose(f);
    return st;
  }
  cv_prt *p;
  st = cv_prt_alloc(h.bands, h.nv, h.nt, h.nm, (h.flags & CV_PRT_HAS_INDIRECT) != 0, &p);
  if (st) {
    fclose(f);
    return cv_err_set(err, st, "%s: cannot allocate %llu-byte payload (%llu vertices, %llu triangles)",
                      path, (unsigned long long)payload_bytes(&h), (unsigned long long)h.nv,
                      (unsigned long long)h.nt);
  }
  p->meta.input_hash = h.input_hash;
  p->meta.rays = h.rays;
  p->meta.bounces = h.bounces;
  p->meta.seed = h.seed;
  p->meta.est_error = h.est_error;
  p->meta.spread = h.spread;
  if ((h.flags & CV_PRT_TEXTURED) && cv_prt_alloc_textures(p)) {
    fclose(f);
    cv_prt_destroy(p);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory for textures", path);
  }
  chunk c[10];
  int nchunks = payload_chunks(p, c);
  uint64_t ph = cv_hash64_init();
  for (int i = 0; i < nchunks; i++) {
    if (c[i].bytes && fread(c[i].ptr, 1, c[i].bytes, f) != c[i].bytes) {
      fclose(f);
      cv_prt_destroy(p);
      return cv_err_set(err, CV_ERR_FORMAT, "%s: truncated payload (section %d of %d)", path,
                        i + 1, nchunks);
    }
    ph = cv_hash64_update(ph, c[i].ptr, c[i].bytes);
  }
  int extra = fgetc(f) != EOF;
  fclose(f);
  if (extra || ph != h.payload_hash) {
    cv_prt_destroy(p);
    return cv_err_set(err, CV_ERR_FORMAT, "%s: payload %s (hash mismatch)", path,
                      extra ? "has trailing bytes" : "is corrupt");
  }
  p->meta.file_hash = cv_hash64_u64(cv_hash64_update(cv_hash64_init(), &h, sizeof h), ph);
  for (size_t i = 0; i < p->nm; i++) p->mats[i].name[sizeof p->mats[i].name - 1] = '\0';
  for (size_t i = 0; p->mat_tex && i < p->nm; i++) p->mat_tex[i][CV_TEX_PATH_MAX - 1] = '\0';
  st = check_records(p, path, err);
  if (st) {
    cv_prt_destroy(p);
    return st;
  }
  *out = p;
  return CV_OK;
}

int cv_prt_to_mesh(const cv_prt *p, cv_mesh **out) {
  cv_mesh *m;
  *out = NULL;
  if (cv_mesh_create(&m)) return CV_ERR_NOMEM;
  if (cv_mesh_reserve(m, p->nv, p->nt)) goto fail;
  memcpy(m->pos, p->pos, 3 * p->nv * sizeof(float));
  memcpy(m->tri, p->tri, 3 * p->nt * sizeof(uint32_t));
  memcpy(m->tri_mat, p->tri_mat, p->nt * sizeof(uint32_t));
  m->nv = p->nv;
  m->nt = p->nt;
  for (size_t i = 0; i < p->nm; i++)
    if (cv_mesh_add_material(m, p->mats[i].name, p->mats[i].albedo, p->mats[i].flags, NULL))
      goto fail;
  if (p->tri_uv) {
    if (cv_mesh_enable_uv(m)) goto fail;
    memcpy(m->tri_uv, p->tri_uv, 6 * p->nt * sizeof(float));
  }
  for (size_t i = 0; p->mat_tex && i < p->nm; i++)
    if (cv_mesh_set_texture(m, (uint32_t)i, p->mat_tex[i])) goto fail;
  *out = m;
  return CV_OK;
fail:
  cv_mesh_destroy(m);
  return CV_ERR_NOMEM;
}
