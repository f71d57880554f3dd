/* PRT file format, version 1 (documented in docs/prt-format.md).
 * Little-endian; a fixed 128-byte header, then the payload arrays in a fixed
 * order; the header carries an FNV-1a hash of the payload so truncation and
 * corruption are detected, and the input hash of the bake. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
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
  free(p);
}

/* The payload as a list of (pointer, bytes) in file order. */
typedef struct {
  void *ptr;
  size_t bytes;
} chunk;

static int payload_chunks(const cv_prt *p, chunk c[8]) {
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
  return k;
}

/* The format is defined as little-endian with IEEE floats and the cv_material
 * layout {char[64], float[3], uint32}; this build writes its memory directly,
 * which matches on every little-endian target we support. */
_Static_assert(sizeof(cv_material) == 80, "cv_material layout is part of the PRT format");
_Static_assert(sizeof(header) <= HEADER_SIZE, "header fits");

int cv_prt_write(const char *path, const cv_prt *p, cv_err *err) {
  chunk c[8];
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
  if (h->version != CV_PRT_VERSION)
    return cv_err_set(err, CV_ERR_UNSUPPORTED, "%s: PRT version %u, this build reads %d", path,
                      h->version, CV_PRT_VERSION);
  if (h->header_size != HEADER_SIZE || h->bands < 1 || h->bands > CV_PRT_MAX_BANDS ||
      h->nv == 0 || h->nt == 0 || h->nv > (1ull << 32) || h->nt > (1ull << 32) ||
      h->nm > (1ull << 20))
    return cv_err_set(err, CV_ERR_FORMAT,
                      "%s: implausible header (bands %u, %llu vertices, %llu triangles)", path,
                      h->bands, (unsigned long long)h->nv, (unsigned long long)h->nt);
  return CV_OK;
}

int cv_prt_read_input_hash(const char *path, uint64_t *hash, cv_err *err) {
  FILE *f = fopen(path, "rb");
  if (!f) {
    if (errno == ENOENT) return cv_err_set(err, CV_ERR_NOT_FOUND, "%s: no such file", path);
    return cv_err_set(err, CV_ERR_IO, "%s: %s", path, strerror(errno));
  }
  header h;
  int st = read_header(f, path, &h, err);
  fclose(f);
  if (st) return st;
  *hash = h.input_hash;
  return CV_OK;
}

int cv_prt_read(const char *path, cv_prt **out, cv_err *err) {
  *out = NULL;
  FILE *f = fopen(path, "rb");
  if (!f) return cv_err_set(err, CV_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
  header h;
  int st = read_header(f, path, &h, err);
  if (st) {
    fclose(f);
    return st;
  }
  cv_prt *p;
  st = cv_prt_alloc(h.bands, h.nv, h.nt, h.nm, (h.flags & CV_PRT_HAS_INDIRECT) != 0, &p);
  if (st) {
    fclose(f);
    return cv_err_set(err, st, "%s: cannot allocate %llu vertices", path,
                      (unsigned long long)h.nv);
  }
  p->meta.input_hash = h.input_hash;
  p->meta.rays = h.rays;
  p->meta.bounces = h.bounces;
  p->meta.seed = h.seed;
  p->meta.est_error = h.est_error;
  p->meta.spread = h.spread;
  chunk c[8];
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
  size_t nc = (size_t)p->bands * p->bands;
  for (size_t i = 0; i < 3 * p->nt; i++)
    if (p->tri[i] >= p->nv) {
      cv_prt_destroy(p);
      return cv_err_set(err, CV_ERR_FORMAT, "%s: triangle %zu has vertex index out of range",
                        path, i / 3);
    }
  for (size_t t = 0; t < p->nt; t++)
    if (p->tri_mat[t] >= p->nm) {
      cv_prt_destroy(p);
      return cv_err_set(err, CV_ERR_FORMAT, "%s: triangle %zu has material out of range", path, t);
    }
  for (size_t i = 0; i < p->nm; i++) p->mats[i].name[sizeof p->mats[i].name - 1] = '\0';
  size_t nf = p->nv * nc, nfi = (p->flags & CV_PRT_HAS_INDIRECT) ? 3 * nf : 0;
  for (size_t i = 0; i < nf; i++)
    if (!isfinite(p->td[i])) goto nonfinite;
  for (size_t i = 0; i < nfi; i++)
    if (!isfinite(p->ti[i])) goto nonfinite;
  for (size_t i = 0; i < 3 * p->nv; i++)
    if (!isfinite(p->pos[i]) || !isfinite(p->albedo[i])) goto nonfinite;
  *out = p;
  return CV_OK;
nonfinite:
  cv_prt_destroy(p);
  return cv_err_set(err, CV_ERR_NONFINITE, "%s: non-finite value in the payload", path);
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
  *out = m;
  return CV_OK;
fail:
  cv_mesh_destroy(m);
  return CV_ERR_NOMEM;
}
