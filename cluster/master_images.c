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
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "comm.h"
#include "io/filewriter.h"
#include "compensate/resample.h"
#include "master_internal.h"
#include "service/console.h"
#include "service/index_html.h"
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
  /* the image thread (normal priority: the viewer metric must keep up): three written
   * frames may wait for it */
  pthread_mutex_init(&m->img_mu, NULL);
  m->img_mu_on = 1;
  return cv_filewriter_create(3, 0, &m->fw, err);
}

void master_images_free(master *m) {
  cv_filewriter_destroy(m->fw); /* first: its jobs use the master */
  m->fw = NULL;
  if (m->img_mu_on) pthread_mutex_destroy(&m->img_mu);
  m->img_mu_on = 0;
  for (int w = 0; m->img_mb && w < m->s->n_walls; w++) cv_mailbox_close(m->img_mb[w]);
  for (int w = 0; m->mont && w < m->s->n_walls; w++) cv_image_destroy(m->mont[w]);
  for (int w = 0; m->mont_unc && w < m->s->n_walls; w++) cv_image_destroy(m->mont_unc[w]);
  free(m->img_mb);
  free(m->mont);
  free(m->mont_unc);
}

/* A written frame's left-eye images, handed to the master's image thread
 * (m->fw, io/filewriter.h): the montages (with --present files) and the
 * viewer simulation (always: its error is a metric) run there, off the
 * master's thread, which keeps collecting reports (the simulation took
 * ~1 s on 2 busy cores and stalled the frame it ran in). */
typedef struct frame_images {
  master *m;
  uint32_t frame;
  double time; /* the frame's drive time (s) */
  int n_walls, complete, files;
  cv_image *mont[CV_CAVE_MAX_WALLS], *unc[CV_CAVE_MAX_WALLS];
} frame_images;

static void frame_images_free(void *p) {
  frame_images *f = p;
  for (int w = 0; w < CV_CAVE_MAX_WALLS; w++) cv_image_destroy(f->mont[w]), cv_image_destroy(f->unc[w]);
  free(f);
}

/* Display-linear images -> the transfer-applied values the montage writer
 * quantises (the PNGs' codes / 255), written whole (a temporary name, then
 * renamed).  CV_OK when written. */
static const char *variant_name(const master *m, const char *suffix) {
  if (!strcmp(suffix, "")) return m->disp ? "projector (compensated)" : "rendered (no compensation)";
  if (!strcmp(suffix, "_uncompensated")) return "rendered (uncompensated)";
  if (!strcmp(suffix, "_viewer")) return "viewer, compensated";
  return "viewer, uncompensated";
}

static int write_montage(const frame_images *f, const char *suffix, cv_image **imgs, cv_err *err) {
  const master *m = f->m;
  const cv_service *s = m->s;
  cv_image *tr[CV_CAVE_MAX_WALLS] = {0};
  int st = CV_OK;
  for (int w = 0; w < f->n_walls && !st; w++) {
    if (!imgs[w]) continue;
    const size_t n = 3 * (size_t)imgs[w]->w * imgs[w]->h;
    st = cv_image_create(imgs[w]->w, imgs[w]->h, 3, &tr[w]);
    for (size_t i = 0; !st && i < n; i++) tr[w]->px[i] = cv_rec709_code(&m->lut, imgs[w]->px[i]) / 255.0f;
  }
  char path[CV_PATHLEN + 96], tmp[CV_PATHLEN + 112];
  snprintf(path, sizeof path, "%s/montage%05u_L%s.png", s->o.out_dir, f->frame, suffix);
  snprintf(tmp, sizeof tmp, "%s.tmp", path);
  if (st) st = cv_err_set(err, st, "montage %s: out of memory", path);
  char caption[160];
  snprintf(caption, sizeof caption, "frame %u  t %.3f s\n%s\nleft eye", f->frame, f->time, variant_name(m, suffix));
  if (!st) st = cv_montage_write_labelled(tmp, &s->cave, tr, caption, err);
  if (!st && rename(tmp, path)) st = cv_err_set(err, CV_ERR_IO, "%s: cannot rename %s into place", path, tmp);
  if (st) remove(tmp);
  for (int w = 0; w < f->n_walls; w++) cv_image_destroy(tr[w]);
  return st;
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

/* The viewer simulation of a frame (its images in f): two more montages
 * (with files) and the two RMS figures, published under m->img_mu. */
static int viewer_simulation(frame_images *f, cv_err *err) {
  master *m = f->m;
  const double t0 = cv_service_now();
  const size_t n = cv_display_patch_count(m->disp);
  double *xc = calloc(3 * n, sizeof *xc), *xu = calloc(3 * n, sizeof *xu);
  double *vc = calloc(3 * n, sizeof *vc), *vu = calloc(3 * n, sizeof *vu);
  cv_image *oc[CV_CAVE_MAX_WALLS] = {0}, *ou[CV_CAVE_MAX_WALLS] = {0};
  int st = CV_OK;
  if (xc && xu && vc && vu && !patch_means(m, f->mont, xc) && !patch_means(m, f->unc, xu) &&
      !viewer_patches(m, xc, vc) && !viewer_patches(m, xu, vu) && !viewer_images(m, f->mont, xc, vc, oc) &&
      !viewer_images(m, f->unc, xu, vu, ou)) {
    pthread_mutex_lock(&m->img_mu);
    m->viewer_rms = rms_diff(vc, xu, 3 * n);     /* seen with compensation vs the target */
    m->viewer_rms_unc = rms_diff(vu, xu, 3 * n); /* seen without vs the target */
    m->have_viewer = 1;
    m->viewer_ms = (cv_service_now() - t0) * 1e3;
    pthread_mutex_unlock(&m->img_mu);
    master_http_montage(m, CV_IMG_VIEWER, f->frame, oc); /* the console's (in memory) */
    if (f->files && !(st = write_montage(f, "_viewer", oc, err))) st = write_montage(f, "_viewer_uncompensated", ou, err);
  } else {
    fprintf(stderr, "cave run: master: viewer simulation of frame %u failed\n", f->frame);
  }
  for (int w = 0; w < f->n_walls; w++) {
    cv_image_destroy(oc[w]);
    cv_image_destroy(ou[w]);
  }
  free(xc), free(xu), free(vc), free(vu);
  return st;
}

static int frame_images_run(void *p, cv_err *err) {
  frame_images *f = p;
  master *m = f->m;
  int st = CV_OK;
  master_http_montage(m, CV_IMG_PROJECTOR, f->frame, f->mont); /* the console's (in memory) */
  master_http_montage(m, CV_IMG_UNCOMPENSATED, f->frame, f->unc);
  if (f->files) {
    st = write_montage(f, "", f->mont, err);
    pthread_mutex_lock(&m->img_mu);
    m->montages += st == CV_OK;
    pthread_mutex_unlock(&m->img_mu);
    if (!st && m->disp) st = write_montage(f, "_uncompensated", f->unc, err);
  }
  if (m->disp && f->complete) {
    cv_err e2;
    const int vs = viewer_simulation(f, &e2);
    if (!st && vs) st = vs, *err = e2;
  }
  if (f->files && !st) st = cv_index_html_write(m->s->o.out_dir, err); /* the newest montages shown */
  return st;
}

/* The gathered images of m->mont_frame to the image thread (ownership
 * moves); a full queue drops them (counted in the summary's files_dropped). */
void montage_flush(master *m) {
  if (!m->mont_have) return;
  frame_images *f = calloc(1, sizeof *f);
  if (f) {
    f->m = m;
    f->frame = m->mont_frame;
    f->time = master_frame_time(m, m->mont_frame);
    f->n_walls = m->s->n_walls;
    f->complete = m->mont_have >= m->s->n_walls;
    f->files = (m->s->o.present & CV_PRESENT_FILES) != 0;
  }
  for (int w = 0; w < m->s->n_walls; w++) {
    if (f) f->mont[w] = m->mont[w], f->unc[w] = m->mont_unc[w];
    else cv_image_destroy(m->mont[w]), cv_image_destroy(m->mont_unc[w]);
    m->mont[w] = m->mont_unc[w] = NULL;
  }
  m->mont_have = 0;
  m->mont_flushed++;
  if (f) cv_filewriter_submit(m->fw, (cv_write_job){frame_images_run, frame_images_free, f});
  cv_filewriter_stats st; /* a montage that could not be written stops the run (master_out.c) */
  cv_filewriter_stats_get(m->fw, &st);
  master_out_files_failed(m, 0, st.failed, st.first_error);
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
