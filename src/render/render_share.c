/* Shared lighting (renderer.h, "Shared lighting"): the products of
 * cv_renderer_set_lighting copied out of one renderer into a byte buffer
 * and into another renderer of the same scene on the same kind of GL, which
 * then draws exactly what it would have drawn after computing them itself:
 * the relit vertex colours (buf_rad), the sun's shadow map (depth texels,
 * its matrices, bias and sun), the sun split (buf_idx_sun and its chunk
 * counts) and the sun's irradiance.  Float bits are copied, never
 * converted.
 *
 * Layout (native byte order, 8-byte aligned parts):
 *   share_hdr                              the state below
 *   rad     4 nv floats                    buf_rad
 *   shadow  w h floats (room for res^2)    the map's texels of the depth texture
 *                                          (GL_DEPTH_COMPONENT32F), rows of w
 *   idx     3 nt uint32 (+4 to 8 bytes)    buf_idx_sun
 *   na, nf  nchunks uint32 each (+pad)     chunk_na, chunk_nf
 * The shadow map and the split are written only when they changed since the
 * buffer last got them (share_hdr.shadow_gen / split_gen against the
 * renderer's counters), so a buffer one renderer keeps exporting into costs
 * the relit colours per lighting change plus what was redrawn. */
#include "render/render_share.h"

#include "core/hash.h"

#define SHARE_MAGIC 0x4c485343u /* "CSHL" */
#define SHARE_VERSION 2u

typedef struct share_hdr {
  uint32_t magic, version;
  uint64_t scene;          /* cv_renderer_lighting_scene: the same mesh, vertices, chunks */
  uint64_t nv, nt, nchunks;
  int32_t shadow_res;      /* opts.shadow_res of the exported map (0: none) */
  int32_t shadow_w, shadow_h; /* its texels (render_light.c: the beam's shorter side fewer) */
  int32_t lit, has_sun, sun_split, shadow_valid, split_valid, shadow_detsign;
  float sun_e[3], shadow_q[16], shadow_k[4], shadow_bias, pad1;
  double shadow_s[3], shadow_texel, split_s[3];
  uint64_t shadow_gen, split_gen; /* the exporter's counters of the parts held (0: none) */
} share_hdr;
_Static_assert(sizeof(share_hdr) % 8 == 0, "parts after the header must stay 8-byte aligned");

static size_t pad8(size_t n) { return (n + 7) & ~(size_t)7; }

/* Offsets of the parts for r's sizes and the map of res texels. */
typedef struct share_layout {
  size_t rad, shadow, idx, na, nf, total;
} share_layout;

static share_layout layout(const cvr_scene *sc, int res) {
  share_layout L;
  L.rad = sizeof(share_hdr);
  L.shadow = L.rad + pad8(4 * sc->nv * sizeof(float));
  L.idx = L.shadow + pad8((size_t)res * res * sizeof(float));
  L.na = L.idx + pad8(3 * sc->nt * sizeof(uint32_t));
  L.nf = L.na + pad8(sc->nchunks * sizeof(uint32_t));
  L.total = L.nf + pad8(sc->nchunks * sizeof(uint32_t));
  return L;
}

size_t cvr_share_bytes(const cvr_ctx *c, const cvr_scene *sc) {
  return layout(sc, c->o->shadow_res).total;
}

uint64_t cvr_share_scene(const cvr_ctx *c, cvr_share *sh, const cvr_scene *sc, const cvr_relight *rl) {
  if (!sh->scene) {
    uint64_t h = cv_hash64_init();
    h = cv_hash64_u64(h, sc->nv);
    h = cv_hash64_u64(h, sc->nt);
    h = cv_hash64_u64(h, sc->nchunks);
    h = cv_hash64_u64(h, (uint64_t)c->o->shadow_res);
    h = cv_hash64_update(h, &c->o->shadow_casters, sizeof c->o->shadow_casters);
    h = cv_hash64_u64(h, (uint64_t)rl->on_cpu); /* the two relights differ in the last bits */
    h = cv_hash64_u64(h, (uint64_t)rl->half_on);        /* so do half and float transfers */
    h = cv_hash64_update(h, sc->pos_cpu, 3 * sc->nv_used * sizeof *sc->pos_cpu);
    h = cv_hash64_update(h, sc->idx_cpu, 3 * sc->nt * sizeof *sc->idx_cpu);
    sh->scene = h | 1; /* never 0: "not computed" */
  }
  return sh->scene;
}

int cvr_share_export(const cvr_ctx *c, cvr_share *sh, const cvr_scene *sc, const cvr_relight *rl,
                     cvr_light *lt, void *buf, size_t cap, cv_err *err) {
  if (!buf) return cv_err_set(err, CV_ERR_INVALID, "lighting export: NULL");
  if (!lt->lit) return cv_err_set(err, CV_ERR_INVALID, "lighting export: no lighting set yet");
  const int res = lt->shadow.valid ? lt->shadow.res : 0;
  const share_layout L = layout(sc, c->o->shadow_res);
  if (cap < L.total || res > c->o->shadow_res)
    return cv_err_set(err, CV_ERR_RANGE, "lighting export: %zu bytes needed, buffer has %zu", L.total, cap);
  if (cv_egl_make_current(c->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  uint8_t *b = buf;
  share_hdr h;
  memcpy(&h, b, sizeof h); /* what the buffer holds already */
  const int fresh = h.magic != SHARE_MAGIC || h.version != SHARE_VERSION || h.scene != cvr_share_scene(c, sh, sc, rl);
  glBindBuffer(GL_ARRAY_BUFFER, sc->buf_rad);
  glGetBufferSubData(GL_ARRAY_BUFFER, 0, (GLsizeiptr)(4 * sc->nv * sizeof(float)), b + L.rad);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  if (res && (fresh || h.shadow_gen != lt->shadow.gen || h.shadow_res != res ||
              h.shadow_w != lt->shadow.w || h.shadow_h != lt->shadow.h)) {
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    if (lt->shadow.from_import) { /* an imported map, in its R32F texture: read through an FBO */
      if (!lt->shadow.fbo_imp) {
        glGenFramebuffers(1, &lt->shadow.fbo_imp);
        glBindFramebuffer(GL_READ_FRAMEBUFFER, lt->shadow.fbo_imp);
        glFramebufferTexture2D(GL_READ_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, lt->shadow.tex_imp, 0);
      }
      glBindFramebuffer(GL_READ_FRAMEBUFFER, lt->shadow.fbo_imp);
      glReadBuffer(GL_COLOR_ATTACHMENT0);
      glReadPixels(0, 0, lt->shadow.w, lt->shadow.h, GL_RED, GL_FLOAT, b + L.shadow);
      glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    } else {
      /* glReadPixels of the depth attachment: Mesa copies Z32F rows as they
       * are (glGetTexImage of a depth texture converts texel by texel) */
      glBindFramebuffer(GL_READ_FRAMEBUFFER, lt->shadow.fbo);
      glReadPixels(0, 0, lt->shadow.w, lt->shadow.h, GL_DEPTH_COMPONENT, GL_FLOAT, b + L.shadow);
      glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    }
  }
  if (lt->split.valid && (fresh || h.split_gen != lt->split.gen)) {
    glBindBuffer(GL_ARRAY_BUFFER, sc->buf_idx_sun);
    glGetBufferSubData(GL_ARRAY_BUFFER, 0, (GLsizeiptr)(3 * sc->nt * sizeof(uint32_t)), b + L.idx);
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    memcpy(b + L.na, sc->chunk_na, sc->nchunks * sizeof(uint32_t));
    memcpy(b + L.nf, sc->chunk_nf, sc->nchunks * sizeof(uint32_t));
  }
  const int st = cvr_gl_check("lighting export", err);
  if (st) return st;
  memset(&h, 0, sizeof h);
  h.magic = SHARE_MAGIC;
  h.version = SHARE_VERSION;
  h.scene = cvr_share_scene(c, sh, sc, rl);
  h.nv = sc->nv, h.nt = sc->nt, h.nchunks = sc->nchunks;
  h.shadow_res = res;
  h.shadow_w = res ? lt->shadow.w : 0, h.shadow_h = res ? lt->shadow.h : 0;
  h.lit = lt->lit, h.has_sun = lt->has_sun, h.sun_split = lt->sun_split;
  h.shadow_valid = lt->shadow.valid, h.split_valid = lt->split.valid;
  h.shadow_detsign = lt->shadow.detsign;
  memcpy(h.sun_e, lt->sun_e, sizeof h.sun_e);
  memcpy(h.shadow_q, lt->shadow.q, sizeof h.shadow_q);
  memcpy(h.shadow_k, lt->shadow.k, sizeof h.shadow_k);
  h.shadow_bias = lt->shadow.bias;
  memcpy(h.shadow_s, lt->shadow.s, sizeof h.shadow_s);
  h.shadow_texel = lt->shadow.texel;
  memcpy(h.split_s, lt->split.s, sizeof h.split_s);
  h.shadow_gen = res ? lt->shadow.gen : 0;
  h.split_gen = lt->split.valid ? lt->split.gen : 0;
  memcpy(b, &h, sizeof h);
  return CV_OK;
}

int cvr_share_import(const cvr_ctx *c, cvr_share *sh, cvr_scene *sc, const cvr_relight *rl,
                     cvr_light *lt, const void *buf, size_t len, cv_frame_timing *t, cv_err *err) {
  if (!buf) return cv_err_set(err, CV_ERR_INVALID, "lighting import: NULL");
  share_hdr h;
  if (len < sizeof h) return cv_err_set(err, CV_ERR_FORMAT, "lighting import: %zu bytes, not a lighting", len);
  const uint8_t *b = buf;
  memcpy(&h, b, sizeof h);
  if (h.magic != SHARE_MAGIC || h.version != SHARE_VERSION)
    return cv_err_set(err, CV_ERR_FORMAT, "lighting import: not an exported lighting (version %u)", h.version);
  if (h.scene != cvr_share_scene(c, sh, sc, rl) || h.nv != sc->nv || h.nt != sc->nt || h.nchunks != sc->nchunks)
    return cv_err_set(err, CV_ERR_INVALID, "lighting import: exported for another scene or shadow size");
  const share_layout L = layout(sc, c->o->shadow_res);
  if (len < L.total || h.shadow_res < 0 || h.shadow_res > c->o->shadow_res || !h.lit ||
      (h.shadow_res > 0 && (h.shadow_w < 2 || h.shadow_h < 2 || h.shadow_w > h.shadow_res ||
                            h.shadow_h > h.shadow_res)))
    return cv_err_set(err, CV_ERR_FORMAT, "lighting import: truncated or inconsistent (%zu of %zu bytes)", len, L.total);
  if (cv_egl_make_current(c->egl)) return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  const double t0 = cvr_tick(c);
  glBindBuffer(GL_ARRAY_BUFFER, sc->buf_rad);
  glBufferSubData(GL_ARRAY_BUFFER, 0, (GLsizeiptr)(4 * sc->nv * sizeof(float)), b + L.rad);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  int st;
  const double t1 = cvr_tick(c);
  /* the split, unless this renderer holds that one already */
  if (h.split_valid && !(lt->split.valid && lt->split.import == h.split_gen)) {
    cvr_scene_parts_bind(sc);
    glBufferSubData(GL_ELEMENT_ARRAY_BUFFER, 0, (GLsizeiptr)(3 * sc->nt * sizeof(uint32_t)), b + L.idx);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, 0);
    memcpy(sc->chunk_na, b + L.na, sc->nchunks * sizeof(uint32_t));
    memcpy(sc->chunk_nf, b + L.nf, sc->nchunks * sizeof(uint32_t));
    memcpy(lt->split.s, h.split_s, sizeof lt->split.s);
    lt->split.valid = 1;
    lt->split.import = h.split_gen;
    lt->split.gen++; /* new contents here: a later export of it must write it */
  } else if (!h.split_valid) {
    lt->split.valid = 0; /* as the exporter: the next sun makes its own */
  }
  const double t2 = cvr_tick(c);
  /* the shadow map, likewise */
  const int new_shadow = h.shadow_res > 0 && !(lt->shadow.valid && lt->shadow.import == h.shadow_gen);
  if (new_shadow) {
    /* into an R32F texture (tex_shadow_imp): the shader reads .r of either */
    if (!lt->shadow.tex_imp) glGenTextures(1, &lt->shadow.tex_imp);
    glBindTexture(GL_TEXTURE_2D, lt->shadow.tex_imp);
    if (lt->shadow.imp_res != h.shadow_res) {
      glTexImage2D(GL_TEXTURE_2D, 0, GL_R32F, h.shadow_res, h.shadow_res, 0, GL_RED, GL_FLOAT, NULL);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
      lt->shadow.imp_res = h.shadow_res;
    }
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, h.shadow_w, h.shadow_h, GL_RED, GL_FLOAT, b + L.shadow);
    glBindTexture(GL_TEXTURE_2D, 0);
    lt->shadow.res = h.shadow_res;
    lt->shadow.w = h.shadow_w, lt->shadow.h = h.shadow_h;
    lt->shadow.from_import = 1;
    memcpy(lt->shadow.s, h.shadow_s, sizeof lt->shadow.s);
    lt->shadow.texel = h.shadow_texel;
    lt->shadow.valid = h.shadow_valid;
    lt->shadow.import = h.shadow_gen;
    lt->shadow.gen++;
  } else if (h.shadow_res <= 0) {
    lt->shadow.valid = 0;
  }
  memcpy(lt->shadow.q, h.shadow_q, sizeof lt->shadow.q);
  memcpy(lt->shadow.k, h.shadow_k, sizeof lt->shadow.k);
  lt->shadow.bias = h.shadow_bias;
  lt->shadow.detsign = h.shadow_detsign;
  memcpy(lt->sun_e, h.sun_e, sizeof lt->sun_e);
  lt->has_sun = h.has_sun;
  lt->sun_split = h.sun_split;
  lt->lit = 1;
  if ((st = cvr_gl_check("lighting import", err))) return st;
  const double t3 = cvr_tick(c);
  if (t) {
    t->relight_ms = t1 - t0;
    t->split_ms = t2 - t1;
    t->shadow_ms = t3 - t2;
    t->shadow_reused = h.shadow_res > 0 && !new_shadow;
  }
  return CV_OK;
}
