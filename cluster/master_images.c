/* Montages of the written frames and the viewer simulation (issue 11,
 * "what people need to see").
 *
 * The left-eye render ranks send, on written frames, the projector image
 * (compensated, display-linear) and the uncompensated tone-mapped image.
 * Once every wall of a frame is in, the master writes the unfolded CAVE:
 *   montageNNNNN_L.png                      what the projectors get
 *   montageNNNNN_L_uncompensated.png        what was rendered (the target)
 *   montageNNNNN_L_viewer.png               what a viewer sees with compensation
 *   montageNNNNN_L_viewer_uncompensated.png what a viewer would see without
 * The viewer simulation puts the projector images through the display's
 * scattering model (Bimber et al. 2006, B = D + K B, solved by
 * cv_scatter_physics on the patches): per patch, the light a viewer gets in
 * image units v = (B - E M) / (F M); per pixel, the image plus the
 * up-sampled difference v - down(image) (equation 7's patch-to-pixel rule).
 * Its error against the target, RMS over the patches of every wall and
 * channel (display-linear), says whether compensation worked:
 * viewer_rms (compensated) against viewer_rms_uncompensated. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "comm.h"
#include "io/filewriter.h"
#include "compensate/resample.h"
#include "master_internal.h"
#include "view/montage.h"

int master_images_setup(master *m, cv_err *err) {
  cv_service *s = m->s;
  m->img_mb = calloc((size_t)s->n_walls, sizeof *m->img_mb);
  m->mont = calloc((size_t)s->n_walls, sizeof *m->mont);
  m->mont_unc = calloc((size_t)s->n_walls, sizeof *m->mont_unc);
  if (!m->img_mb || !m->mont || !m->mont_unc) return cv_err_set(err, CV_ERR_NOMEM, "master: out of memory");
  for (int w = 0; w < s->n_walls; w++) {
    const int px = s->cave.walls[w].res[0] * s->cave.walls[w].res[1]; /* --size applied */
    m->img_mb[w] = cv_mailbox_open(cv_cave_walleye_rank(&s->cave, w, 0), CV_TAG_IMAGE,
                                   sizeof(cv_patch_msg) + 2 * sizeof(int32_t) + 2 * 3 * (size_t)px * sizeof(float));
    if (!m->img_mb[w]) return cv_err_set(err, CV_ERR_NOMEM, "master: cannot post receives");
  }
  cv_rec709_lut_init(&m->lut);
  m->viewer_rms = m->viewer_rms_unc = NAN;
  /* files only when asked; montages of up to two frames (4 each) may wait */
  if (s->o.present & CV_PRESENT_FILES) return cv_filewriter_create(8, &m->fw, err);
  return CV_OK;
}

void master_images_free(master *m) {
  cv_filewriter_destroy(m->fw);
  m->fw = NULL;
  for (int w = 0; m->img_mb && w < m->s->n_walls; w++) cv_mailbox_close(m->img_mb[w]);
  for (int w = 0; m->mont && w < m->s->n_walls; w++) cv_image_destroy(m->mont[w]);
  for (int w = 0; m->mont_unc && w < m->s->n_walls; w++) cv_image_destroy(m->mont_unc[w]);
  free(m->img_mb);
  free(m->mont);
  free(m->mont_unc);
}

/* A montage for the master's writer thread (--present files): its walls'
 * transfer-applied values and the path; written to a temporary name, then
 * renamed (whole files only). */
typedef struct montage_job {
  char path[CV_PATHLEN + 96];
  const cv_cave *cave;
  cv_image *tr[CV_CAVE_MAX_WALLS];
} montage_job;

static void montage_job_free(void *p) {
  montage_job *j = p;
  for (int w = 0; w < CV_CAVE_MAX_WALLS; w++) cv_image_destroy(j->tr[w]);
  free(j);
}

static int montage_job_write(void *p, cv_err *err) {
  montage_job *j = p;
  char tmp[CV_PATHLEN + 128];
  snprintf(tmp, sizeof tmp, "%s.tmp", j->path);
  int st = cv_montage_write(tmp, j->cave, j->tr, err);
  if (!st && rename(tmp, j->path)) st = cv_err_set(err, CV_ERR_IO, "%s: cannot rename %s into place", j->path, tmp);
  if (st) remove(tmp);
  return st;
}

/* Display-linear images -> the transfer-applied values the montage writer
 * quantises (the PNGs' codes / 255), handed to the writer thread; nothing
 * without --present files.  CV_OK when queued. */
static int write_montage(master *m, const char *suffix, cv_image **imgs) {
  cv_service *s = m->s;
  if (!m->fw) return CV_ERR_INVALID;
  montage_job *j = calloc(1, sizeof *j);
  if (!j) return CV_ERR_NOMEM;
  j->cave = &s->cave;
  snprintf(j->path, sizeof j->path, "%s/montage%05u_L%s.png", s->o.out_dir, m->mont_frame, suffix);
  int st = CV_OK;
  for (int w = 0; w < s->n_walls && !st; w++) {
    if (!imgs[w]) continue;
    const size_t n = 3 * (size_t)imgs[w]->w * imgs[w]->h;
    st = cv_image_create(imgs[w]->w, imgs[w]->h, 3, &j->tr[w]);
    for (size_t i = 0; !st && i < n; i++) j->tr[w]->px[i] = cv_rec709_code(&m->lut, imgs[w]->px[i]) / 255.0f;
  }
  if (st) {
    montage_job_free(j);
    return st;
  }
  return cv_filewriter_submit(m->fw, (cv_write_job){montage_job_write, montage_job_free, j}) ? CV_ERR_IO : CV_OK;
}

/* Patch means of every wall's image into x (3n, display patch order). */
static int patch_means(master *m, cv_image **imgs, double *x) {
  for (int w = 0; w < m->s->n_walls; w++) {
    const cv_display_surface *S = cv_display_surface_at(m->disp, (size_t)w);
    if (!imgs[w] || cv_downsample_to_patches(imgs[w], S->nu, S->nv, S->edge_u, S->edge_v, x + 3 * S->offset))
      return -1;
  }
  return 0;
}

/* What a viewer sees, per patch in image units, for patch images x. */
static int viewer_patches(master *m, const double *x, double *v) {
  const size_t n = cv_display_patch_count(m->disp);
  float *I = malloc(3 * n * sizeof *I);
  double *B = malloc(3 * n * sizeof *B);
  int st = I && B ? CV_OK : CV_ERR_NOMEM;
  for (size_t i = 0; !st && i < 3 * n; i++) I[i] = (float)x[i];
  if (!st) st = cv_scatter_physics(&m->sys, I, B, 1e-6, NULL);
  for (size_t i = 0; !st && i < n; i++)
    for (int c = 0; c < 3; c++) {
      const size_t p = 3 * i + c;
      const double fm = (double)m->sys.proj[i] * m->sys.refl[p];
      v[p] = fm > 0 ? (B[p] - (double)m->sys.env[p] * m->sys.refl[p]) / fm : x[p];
    }
  free(I);
  free(B);
  return st;
}

/* Per wall: image + up(v - down(image)), into out[w] (new images). */
static int viewer_images(master *m, cv_image **imgs, const double *x, const double *v, cv_image **out) {
  for (int w = 0; w < m->s->n_walls; w++) {
    const cv_display_surface *S = cv_display_surface_at(m->disp, (size_t)w);
    const size_t np = (size_t)S->nu * S->nv;
    double *delta = malloc(3 * np * sizeof *delta);
    if (!delta || cv_image_create(imgs[w]->w, imgs[w]->h, 3, &out[w])) {
      free(delta);
      return CV_ERR_NOMEM;
    }
    /* cv_apply_patch_delta computes I0 - up(delta), clamped to [0, 1]: the
     * clamp is what a viewer's eye would not do, but the PNG cannot hold
     * more; the RMS below is computed on the patches, unclamped. */
    for (size_t i = 0; i < 3 * np; i++) delta[i] = x[3 * S->offset + i] - v[3 * S->offset + i];
    cv_apply_patch_delta(imgs[w], delta, S->nu, S->nv, S->edge_u, S->edge_v, out[w]);
    free(delta);
  }
  return CV_OK;
}

static double rms_diff(const double *a, const double *b, size_t n) {
  double s = 0;
  for (size_t i = 0; i < n; i++) s += (a[i] - b[i]) * (a[i] - b[i]);
  return n ? sqrt(s / (double)n) : 0;
}

/* The viewer simulation of the montage's frame: two more montages and the
 * two RMS figures. */
static void viewer_simulation(master *m) {
  const double t0 = cv_service_now();
  const size_t n = cv_display_patch_count(m->disp);
  double *xc = calloc(3 * n, sizeof *xc), *xu = calloc(3 * n, sizeof *xu);
  double *vc = calloc(3 * n, sizeof *vc), *vu = calloc(3 * n, sizeof *vu);
  cv_image *oc[CV_CAVE_MAX_WALLS] = {0}, *ou[CV_CAVE_MAX_WALLS] = {0};
  if (xc && xu && vc && vu && !patch_means(m, m->mont, xc) && !patch_means(m, m->mont_unc, xu) &&
      !viewer_patches(m, xc, vc) && !viewer_patches(m, xu, vu) && !viewer_images(m, m->mont, xc, vc, oc) &&
      !viewer_images(m, m->mont_unc, xu, vu, ou)) {
    m->viewer_rms = rms_diff(vc, xu, 3 * n);     /* seen with compensation vs the target */
    m->viewer_rms_unc = rms_diff(vu, xu, 3 * n); /* seen without vs the target */
    m->have_viewer = 1;
    write_montage(m, "_viewer", oc);
    write_montage(m, "_viewer_uncompensated", ou);
  } else {
    fprintf(stderr, "cave run: master: viewer simulation of frame %u failed\n", m->mont_frame);
  }
  for (int w = 0; w < m->s->n_walls; w++) {
    cv_image_destroy(oc[w]);
    cv_image_destroy(ou[w]);
  }
  free(xc);
  free(xu);
  free(vc);
  free(vu);
  m->viewer_ms = (cv_service_now() - t0) * 1e3;
}

void montage_flush(master *m) {
  if (!m->mont_have) return;
  if (write_montage(m, "", m->mont) == CV_OK) m->montages++;
  if (m->disp) {
    write_montage(m, "_uncompensated", m->mont_unc);
    if (m->mont_have >= m->s->n_walls) viewer_simulation(m);
  }
  for (int w = 0; w < m->s->n_walls; w++) {
    cv_image_destroy(m->mont[w]);
    cv_image_destroy(m->mont_unc[w]);
    m->mont[w] = m->mont_unc[w] = NULL;
  }
  m->mont_have = 0;
}

/* Takes the left eye's written images; a montage is written once every wall
 * of a frame arrived (or a later frame starts arriving). */
void montage_drain(master *m) {
  for (int w = 0; w < m->s->n_walls; w++) {
    const uint8_t *data;
    long len;
    while ((len = cv_mailbox_take(m->img_mb[w], &data, NULL)) >= 0) {
      cv_patch_msg pm;
      int32_t wh[2];
      if ((size_t)len < sizeof pm + sizeof wh) continue;
      memcpy(&pm, data, sizeof pm);
      memcpy(wh, data + sizeof pm, sizeof wh);
      const size_t npx = 3 * (size_t)wh[0] * wh[1];
      if ((size_t)len != sizeof pm + sizeof wh + 2 * npx * sizeof(float)) continue;
      if (m->mont_have && pm.frame != m->mont_frame) montage_flush(m);
      cv_image *img, *unc;
      if (cv_image_create(wh[0], wh[1], 3, &img)) continue;
      if (cv_image_create(wh[0], wh[1], 3, &unc)) {
        cv_image_destroy(img);
        continue;
      }
      memcpy(img->px, data + sizeof pm + sizeof wh, npx * sizeof(float));
      memcpy(unc->px, data + sizeof pm + sizeof wh + npx * sizeof(float), npx * sizeof(float));
      if (!m->mont[w]) m->mont_have++;
      cv_image_destroy(m->mont[w]);
      cv_image_destroy(m->mont_unc[w]);
      m->mont[w] = img;
      m->mont_unc[w] = unc;
      m->mont_frame = pm.frame;
      if (m->mont_have >= m->s->n_walls) montage_flush(m);
    }
  }
}
