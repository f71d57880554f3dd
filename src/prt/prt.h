/* Per-vertex precomputed radiance transfer (Sloan et al. 2002; Dmitriev et
 * al. 2004, section 4.1) and its versioned file format (docs/prt-format.md).
 *
 * For each vertex x the bake stores
 *   td(x)[i]    direct transfer, mono, albedo NOT applied:
 *               (1/pi) * integral of y_i(w) V(x,w) max(n.w,0) dw,
 *               V = 1 only where the ray leaves the car through a window;
 *   ti(x)[c][i] interreflected transfer, RGB (bounces 1..B, albedos applied).
 * Exit radiance under SH lighting l (RGB, l[i][c]):
 *   L_c(x) = sum_i l_i,c * (albedo_c(x) * td_i(x) + ti_c,i(x))
 * (times the texture at the pixel on a textured material, CV_PRT_TEXTURED).
 * Keeping the direct part separate lets a sun that was split out of the
 * lighting (exact visibility) still light the interior through ti. */
#ifndef CV_PRT_PRT_H
#define CV_PRT_PRT_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"
#include "mesh/mesh.h"

#define CV_PRT_VERSION 2 /* 1: no textures (still read) */
#define CV_PRT_MAX_BANDS 8
/* Tolerance on a stored normal's length (the reader refuses others). */
#define CV_PRT_NORMAL_TOL 1e-3

enum {
  CV_PRT_HAS_INDIRECT = 1u << 0,    /* ti present */
  CV_PRT_WINDOW_SAMPLING = 1u << 1, /* direct pass used window importance sampling */
  CV_PRT_TEXTURED = 1u << 2,        /* version 2: tri_uv and mat_tex present; textured
                                       receivers' albedo and ti exclude their own albedo */
};

typedef struct cv_prt_meta {
  uint64_t input_hash;   /* fingerprint of the cleaned mesh and the bake settings */
  uint32_t rays;         /* rays per vertex per pass */
  uint32_t bounces;      /* interreflection bounces (0 = direct only) */
  uint32_t seed;
  float spread;          /* fraction of each vertex's fan covered by ray origins */
  float est_error;       /* estimated relative error (auto mode), or -1 */
  double bake_seconds;   /* in memory only: the file holds no timing, so the same
                            inputs and seed give the same bytes */
  uint64_t file_hash;    /* in memory only (cv_prt_read): FNV-1a of the header's bytes
                            and the payload's hash, as read: two ranks that loaded
                            different files have different values (0: not read) */
} cv_prt_meta;

typedef struct cv_prt {
  uint32_t bands; /* SH bands n; n*n coefficients */
  uint32_t flags; /* CV_PRT_* */
  size_t nv, nt, nm;
  float *pos;       /* 3*nv */
  float *nrm;       /* 3*nv, unit, area-weighted */
  float *albedo;    /* 3*nv, hat-weighted mean albedo of the vertex's fan */
  uint32_t *tri;    /* 3*nt */
  uint32_t *tri_mat;/* nt */
  cv_material *mats;/* nm */
  float *td;        /* nv * n*n */
  float *ti;        /* nv * 3 * n*n ([v][c][i]), NULL without CV_PRT_HAS_INDIRECT */
  /* With CV_PRT_TEXTURED (else NULL): corner UVs (6*nt, as cv_mesh.tri_uv) and
   * each material's texture file ("" none).  A textured material's triangles
   * count as albedo 1 for their own vertices (albedo and ti above), so that
   * L = texture(uv) * sum_i l_i (albedo td_i + ti_i) per pixel; other
   * surfaces see them with the material's albedo (the texture's mean). */
  float *tri_uv;
  char (*mat_tex)[CV_TEX_PATH_MAX];
  cv_prt_meta meta;
} cv_prt;

/* Allocates a zeroed cv_prt with arrays for the given sizes; *out owned by
 * the caller (cv_prt_destroy).  has_indirect selects whether ti exists. */
int cv_prt_alloc(uint32_t bands, size_t nv, size_t nt, size_t nm, int has_indirect,
                 cv_prt **out);
void cv_prt_destroy(cv_prt *p);

/* Writes the file (temp file + rename: never a partial file).  err names the path. */
int cv_prt_write(const char *path, const cv_prt *p, cv_err *err);
/* Reads and validates a file: magic, version, the header's counts against the
 * file's size (before allocating), payload hash, then every record (finite
 * values, unit or zero normals, albedo in [0, 1], indices in range).  The
 * message names the file, the field, its value and what was expected.
 * *out owned by the caller. */
int cv_prt_read(const char *path, cv_prt **out, cv_err *err);
/* Reads only the header's input hash (to skip re-baking an unchanged scene),
 * after checking the header's counts against the file's size as cv_prt_read
 * does (a stat, no payload read: a truncated file is refused with the same
 * message).  Returns CV_ERR_NOT_FOUND if the file does not exist. */
int cv_prt_read_input_hash(const char *path, uint64_t *hash, cv_err *err);

/* Gives p the texture arrays (zeroed) and sets CV_PRT_TEXTURED. */
int cv_prt_alloc_textures(cv_prt *p);
/* Nonzero if material i has a texture. */
int cv_prt_mat_textured(const cv_prt *p, size_t i);
/* For consumers that do not sample textures: per-vertex RGB factors (3*nv)
 * that turn a textured receiver's albedo and ti back into the untextured
 * ones (mean albedo of the materials around the vertex / stored albedo; 1
 * where nothing is textured or the stored albedo is 0). */
int cv_prt_untextured_scale(const cv_prt *p, float *scale);
/* Multiplies per-vertex radiance (3*nv, from cv_prt_relight) by those
 * factors: per-vertex outputs (PLY, the LCD's gather) show textured
 * surfaces with their mean albedo. */
int cv_prt_fold_texture_means(const cv_prt *p, float *rad);

/* A view of the PRT's geometry as a cv_mesh (copies); *out owned by the caller. */
int cv_prt_to_mesh(const cv_prt *p, cv_mesh **out);

#endif
