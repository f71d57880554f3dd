/* Split window lights in the wall-eye renderer (cv_renderer_set_split,
 * renderer.h): what `cave shade --split` adds on the CPU, handed to the GPU
 * relight as a per-vertex direct term and an SH term for the
 * interreflected transfer. */
#include "render/render_split.h"

#include "sh/sh.h"

/* Texture unit of u_split (relight.vert), past the renderer's U_* units. */
#define U_SPLIT 7

int cvr_split_set(const cvr_ctx *ctx, cvr_split *r, int nc, size_t nv, int on_cpu,
                  const cv_dir_light *lights, int n, const float *direct_rgb, cv_err *err) {
  if (n < 0 || (n > 0 && (!lights || !direct_rgb)))
    return cv_err_set(err, CV_ERR_INVALID, "renderer: split lights: NULL or n = %d", n);
  if (n == 0) {
    r->n = 0;
    memset(r->sh, 0, sizeof r->sh);
    return CV_OK;
  }
  const int bands = (int)lround(sqrt(nc));
  double sh[3 * CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS] = {0};
  for (int k = 0; k < n; k++) {
    const double *d = lights[k].dir, *E = lights[k].E;
    const double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(len > 0) || !isfinite(len))
      return cv_err_set(err, CV_ERR_INVALID, "split light %d: direction has no length", k);
    for (int c = 0; c < 3; c++)
      if (!isfinite(E[c]) || E[c] < 0)
        return cv_err_set(err, CV_ERR_NONFINITE, "split light %d: irradiance[%d] is %g", k, c, E[c]);
    const double u[3] = {d[0] / len, d[1] / len, d[2] / len};
    double y[CV_PRT_MAX_BANDS * CV_PRT_MAX_BANDS];
    cv_sh_eval_d(bands, u, y);
    for (int i = 0; i < nc; i++)
      for (int c = 0; c < 3; c++) sh[3 * i + c] += E[c] * y[i];
  }
  float *rgba = malloc(4 * nv * sizeof *rgba + 4);
  if (!rgba || !r->src) {
    free(rgba);
    return cv_err_set(err, CV_ERR_NOMEM, "out of memory for the split lights");
  }
  for (size_t v = 0; v < nv; v++) { /* renderer vertex v shows PRT vertex wl_src[v] */
    float *o = rgba + 4 * v;
    const size_t src = r->src[v];
    for (int c = 0; c < 3; c++) {
      const float x = direct_rgb[3 * src + c];
      if (!isfinite(x)) {
        free(rgba);
        return cv_err_set(err, CV_ERR_NONFINITE, "split lights: direct light of vertex %zu is %g",
                          src, (double)x);
      }
      o[c] = r->usc ? x * r->usc[3 * v + c] : x;
    }
    o[3] = 0;
  }
  if (cv_egl_make_current(ctx->egl)) {
    free(rgba);
    return cv_err_set(err, CV_ERR_BACKEND, "eglMakeCurrent failed");
  }
  if (on_cpu) { /* render_relight.c reads it */
    free(r->cpu);
    r->cpu = rgba;
    rgba = NULL;
  } else if (!r->tex) {
    r->tex = cvr_make_tbo(&r->buf, GL_RGBA32F, rgba, 4 * nv * sizeof *rgba);
  } else {
    glBindBuffer(GL_TEXTURE_BUFFER, r->buf);
    glBufferSubData(GL_TEXTURE_BUFFER, 0, (GLsizeiptr)(4 * nv * sizeof *rgba), rgba);
    glBindBuffer(GL_TEXTURE_BUFFER, 0);
  }
  free(rgba);
  r->n = n;
  memcpy(r->sh, sh, sizeof sh);
  return cvr_gl_check("split lights upload", err);
}

/* Binds the split lights for the relight program p (in use). */
void cvr_split_bind(const cvr_split *r, GLuint p) {
  const int on = r->n > 0 && r->tex;
  glUniform1i(glGetUniformLocation(p, "u_split_on"), on);
  glUniform1i(glGetUniformLocation(p, "u_split"), U_SPLIT);
  glActiveTexture(GL_TEXTURE0 + U_SPLIT);
  glBindTexture(GL_TEXTURE_BUFFER, on ? r->tex : 0);
  glActiveTexture(GL_TEXTURE0);
}

void cvr_split_free(cvr_split *r) {
  if (r->tex) glDeleteTextures(1, &r->tex);
  if (r->buf) glDeleteBuffers(1, &r->buf);
  r->tex = r->buf = 0;
}

void cvr_split_free_cpu(cvr_split *r) {
  free(r->src), free(r->usc), free(r->cpu);
  r->src = NULL, r->usc = r->cpu = NULL;
}

void cvr_split_map(cvr_split *r, const cv_prt *p, const uint32_t *old_of, const float *usc,
                   const uint32_t *orig) {
  /* the split window lights' direct light gets the textures' factors (by renderer vertex) */
  if ((p->flags & CV_PRT_TEXTURED) && (r->usc = malloc(3 * p->nv * sizeof *r->usc + 4)))
    for (size_t v = 0; v < p->nv; v++)
      for (int c = 0; c < 3; c++) r->usc[3 * v + c] = usc[3 * old_of[v] + c];
  /* each renderer vertex's PRT vertex */
  r->src = malloc(p->nv * sizeof *r->src + 4);
  if (r->src)
    for (size_t v = 0; v < p->nv; v++) r->src[v] = orig ? orig[old_of[v]] : old_of[v];
}
