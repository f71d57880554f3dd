/* Rank 0, the master: every frame it advances the simulated time, evaluates
 * the scripted drive (car pose, lighting) and the head tracker, projects the
 * lighting into SH when its key changes, runs the adaptation model on the
 * foveal statistics of the previous frame, sends one fixed-layout frame
 * state to every rank, collects the wall-eyes' reports and patch images
 * until the deadline, solves the scattering compensation and sends each
 * wall its correction, sums the LCD rounds that arrived (fixed point), and
 * writes a metrics line.
 *
 * Adaptation latency: the frame state carries the adaptation computed from
 * the previous frame's luminance passes, so a frame needs one round trip to
 * the master instead of two.  One frame (33 ms) is small against the
 * neural time constants (80 ms cones, 150 ms rods).  Frame 0 starts from the
 * CAVE's first report: the state is initialised in steady state at the
 * first measured foveal luminance (frame 0 itself uses 1 cd/m2). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "comm.h"
#include "compensate/formfactor.h"
#include "compensate/solve.h"
#include "core/hash.h"
#include "core/outfile.h"
#include "io/exr.h"
#include "io/png.h"
#include "lcd/gather.h"
#include "service.h"
#include "service/metrics.h"
#include "service_internal.h"
#include "tonemap/adapt.h"
#include "tonemap/drago.h"
#include "tonemap/foveal.h"
#include "view/montage.h"
#include <time.h>

typedef struct wall_in {
  int got;                /* eyes that reported this frame */
  double *r;              /* 3 np: sum over eyes of the patch images */
} wall_in;

typedef struct master {
  cv_service *s;
  int bands;
  cv_head_path *path;
  cv_dtrack_receiver *dtr;
  cv_head_pose pose;
  double pose_time;
  cv_tracker_stats trk;
  cv_adapt_params ap;
  cv_adapt_state ad;
  int have_adapt;
  double pending_dt;      /* simulated time since the last adaptation update */
  cv_lumstats stats;      /* previous frame's merged foveal statistics */
  int have_stats;
  double lwmax;
  uint64_t light_key;
  int have_light;
  cv_lighting lighting;
  cv_lightmix *mix;       /* map drives: per-frame lighting from preprocessed maps */
  /* compensation */
  cv_display *disp;
  cv_ffmatrix *F;
  cv_scatter_system sys;
  cv_scatter_workspace *ws;
  float *T, *I;
  double *r;              /* 3n: current patch images (eyes averaged) */
  wall_in *walls;
  cv_scatter_stats cst;
  int comp_ok;
  /* LCD */
  cv_mailbox *lcd_mb;
  uint64_t lcd_key;
  int32_t lcd_eye_q[3];
  cv_lcd_progress prog;
  uint8_t *seen;          /* budget flags: round already summed */
  uint32_t lcd_rounds;
  uint64_t lcd_rejected, lcd_late;
  double lcd_last_send;
  uint32_t lcd_sent_rounds;
  cv_image *lcd_content;
  /* wall-eyes */
  cv_mailbox **rep_mb;
  uint32_t *last_frame_seen;
  uint64_t late_reports;
  uint64_t sent_hash;     /* FNV-1a of this frame's packed state */
  int state_mismatch;     /* reports of this frame rendered with other bytes */
  uint64_t state_mismatch_total;
  /* montage of the left eye (written frames) */
  cv_mailbox **img_mb;
  cv_image **mont;        /* per wall: image of frame mont_frame */
  uint32_t mont_frame;
  int mont_have;
  uint64_t montages;
  /* metrics */
  FILE *mf;
  cv_metrics_line *ml;
  double *frame_ms, *overhead_ms;
  size_t nframes_done;
} master;

static size_t walleye_msg_cap(const master *m, int wall) {
  const cv_display_surface *S = cv_display_surface_at(m->disp, (size_t)wall);
  return CV_WALLEYE_REPORT_BYTES + sizeof(cv_patch_msg) + 3 * (size_t)S->nu * S->nv * sizeof(float);
}

static void master_free(master *m) {
  cv_head_path_destroy(m->path);
  cv_lightmix_destroy(m->mix);
  cv_dtrack_receiver_close(m->dtr);
  cv_scatter_workspace_destroy(m->ws);
  cv_ffmatrix_destroy(m->F);
  if (m->walls)
    for (int w = 0; w < m->s->n_walls; w++) free(m->walls[w].r);
  free(m->walls);
  cv_display_destroy(m->disp);
  free(m->T);
  free(m->I);
  free(m->r);
  cv_mailbox_close(m->lcd_mb);
  cv_lcd_progress_free(&m->prog);
  free(m->seen);
  cv_image_destroy(m->lcd_content);
  if (m->rep_mb)
    for (int k = 0; k < m->s->n_walleyes; k++) cv_mailbox_close(m->rep_mb[k]);
  free(m->rep_mb);
  free(m->last_frame_seen);
  if (m->img_mb)
    for (int w = 0; w < m->s->n_walls; w++) cv_mailbox_close(m->img_mb[w]);
  free(m->img_mb);
  if (m->mont)
    for (int w = 0; w < m->s->n_walls; w++) cv_image_destroy(m->mont[w]);
  free(m->mont);
  if (m->mf) fclose(m->mf);
  cv_metrics_line_destroy(m->ml);
  free(m->frame_ms);
  free(m->overhead_ms);
}

/* ---- montage --------------------------------------------------------------- */

static void montage_flush(master *m) {
  if (!m->mont_have) return;
  char path[CV_PATHLEN + 64];
  snprintf(path, sizeof path, "%s/montage%05u_L.png", m->s->o.out_dir, m->mont_frame);
  cv_err err;
  if (cv_montage_write(path, &m->s->cave, m->mont, &err))
    fprintf(stderr, "cave run: montage: %s\n", err.msg);
  else
    m->montages++;
  for (int w = 0; w < m->s->n_walls; w++) {
    cv_image_destroy(m->mont[w]);
    m->mont[w] = NULL;
  }
  m->mont_have = 0;
}

/* Takes the left eye's written images; a montage is written once every wall
 * of a frame arrived (or a later frame starts arriving). */
static void montage_drain(master *m) {
  for (int w = 0; w < m->s->n_walls; w++) {
    const uint8_t *data;
    long len;
    while ((len = cv_mailbox_take(m->img_mb[w], &data, NULL)) >= 0) {
      cv_patch_msg pm;
      int32_t wh[2];
      if ((size_t)len < sizeof pm + sizeof wh) continue;
      memcpy(&pm, data, sizeof pm);
      memcpy(wh, data + sizeof pm, sizeof wh);
      if ((size_t)len != sizeof pm + sizeof wh + 3 * (size_t)wh[0] * wh[1] * sizeof(float)) continue;
      if (m->mont_have && pm.frame != m->mont_frame) montage_flush(m);
      cv_image *img;
      if (cv_image_create(wh[0], wh[1], 3, &img)) continue;
      memcpy(img->px, data + sizeof pm + sizeof wh, 3 * (size_t)wh[0] * wh[1] * sizeof(float));
      cv_image_destroy(m->mont[w]);
      m->mont[w] = img;
      m->mont_frame = pm.frame;
      m->mont_have++;
      if (m->mont_have >= m->s->n_walls) montage_flush(m);
    }
  }
}

/* ---- LCD ---------------------------------------------------------------- */

/* Takes every LCD round that has arrived; sums those of the current key. */
static void lcd_drain(master *m) {
  if (!m->lcd_mb) return;
  const uint8_t *data;
  int from;
  long len;
  while ((len = cv_mailbox_take(m->lcd_mb, &data, &from)) >= 0) {
    cv_lcd_msg h;
    if ((size_t)len < sizeof h) {
      m->lcd_rejected++;
      continue;
    }
    memcpy(&h, data, sizeof h);
    if ((size_t)len != sizeof h + h.n * sizeof(int64_t) || h.w != m->s->o.lcd_w ||
        h.h != m->s->o.lcd_h) {
      m->lcd_rejected++;
      continue;
    }
    if (cv_service_lcd_key(h.key.eye_q, h.key.light_hash) != m->lcd_key) {
      m->lcd_late++; /* rendered for an earlier camera or lighting */
      continue;
    }
    if (h.round >= (uint32_t)m->s->o.lcd_budget || m->seen[h.round]) {
      m->lcd_rejected++;
      continue;
    }
    if (h.n != cv_lcd_accum_words(h.w, h.h) || !(h.clamp > 0) || !isfinite(h.clamp)) {
      m->lcd_rejected++;
      continue;
    }
    /* A view of the message (the values start 64 bytes into a malloc'ed
     * buffer: 8-byte aligned); the sum adds in place, the first round of a
     * key is copied. */
    cv_lcd_accum view = {.w = h.w, .h = h.h, .clamp = h.clamp,
                         .unit = cv_lcd_unit_for_clamp(h.clamp), .n = h.n,
                         .data = (int64_t *)(void *)(uintptr_t)(data + sizeof h)};
    int restarted = 0;
    if (cv_lcd_progress_submit(&m->prog, &h.key, &view, &restarted) == CV_OK) {
      m->seen[h.round] = 1;
      m->lcd_rounds++;
    } else {
      m->lcd_rejected++;
    }
    (void)from;
  }
}

/* Sends the current LCD image to the wall-eyes when it has new rounds
 * (at most every 0.25 s). */
static void lcd_publish(master *m, int force) {
  if (!m->prog.acc || m->lcd_rounds == m->lcd_sent_rounds) return;
  const double now = cv_service_now();
  if (!force && now - m->lcd_last_send < 0.25) return;
  cv_image *img;
  if (cv_lcd_accum_to_image(m->prog.acc, m->lcd_content, &img)) return;
  const size_t npx = 3 * (size_t)img->w * img->h;
  size_t n = sizeof(cv_lcdimg_msg) + npx * sizeof(float);
  uint8_t *buf = malloc(n);
  if (buf) {
    cv_lcdimg_msg h = {.lcd_key = m->lcd_key, .rounds = m->lcd_rounds, .w = img->w, .h = img->h};
    memcpy(buf, &h, sizeof h);
    memcpy(buf + sizeof h, img->px, npx * sizeof(float));
    int dests[2 * CV_CAVE_MAX_WALLS];
    for (int r = 1; r <= m->s->n_walleyes; r++) dests[r - 1] = r;
    cv_comm_send_multi(buf, n, dests, m->s->n_walleyes, CV_TAG_LCDIMG);
    free(buf);
  }
  cv_image_destroy(img);
  m->lcd_last_send = now;
  m->lcd_sent_rounds = m->lcd_rounds;
}

static void lcd_write(master *m, const char *stem) {
  if (!m->prog.acc) return;
  cv_image *img;
  if (cv_lcd_accum_to_image(m->prog.acc, m->lcd_content, &img)) return;
  char path[CV_PATHLEN + 64];
  cv_err err;
  snprintf(path, sizeof path, "%s/%s.exr", m->s->o.out_dir, stem);
  if (cv_exr_write(path, img, 1, CV_EXR_ZIP, &err)) fprintf(stderr, "cave run: %s\n", err.msg);
  /* Drago with the current adaptation for a view of what the driver sees. */
  cv_drago dg;
  cv_drago_default(&dg);
  dg.bias = m->s->cave.drago_bias;
  dg.ldmax = m->s->cave.drago_ldmax;
  dg.lwa = m->have_adapt ? cv_adapt_lwa(&m->ad) : 1.0;
  dg.lwmax = m->lwmax > 0 ? m->lwmax : 100 * dg.lwa;
  cv_image *tm;
  if (cv_image_create(img->w, img->h, 3, &tm) == CV_OK) {
    uint64_t inv = 0;
    cv_drago_image(img, &dg, 1, tm, &inv);
    snprintf(path, sizeof path, "%s/%s.png", m->s->o.out_dir, stem);
    if (cv_service_write_png01(path, tm, &err)) fprintf(stderr, "cave run: %s\n", err.msg);
    cv_image_destroy(tm);
  }
  cv_image_destroy(img);
}

/* ---- set-up -------------------------------------------------------------- */

static int master_setup(master *m, cv_err *err) {
  cv_service *s = m->s;
  /* SH bands of the scene (the wall-eyes relight with them). */
  cv_prt *prt;
  int st = cv_prt_read(s->o.scene_path, &prt, err);
  if (st) return st;
  m->bands = (int)prt->bands;
  cv_prt_destroy(prt);
  st = cv_service_lightmix(s, m->bands, &m->mix, err);
  if (st) return st;
  if (s->o.head_path[0]) {
    st = cv_head_path_load(s->o.head_path, &m->path, err);
    if (st) return st;
  }
  if (s->o.dtrack_port > 0) {
    st = cv_dtrack_receiver_open(s->o.dtrack_host, s->o.dtrack_port, s->o.dtrack_body, &m->dtr, err);
    if (st) return st;
  }
  memcpy(m->pose.pos, s->cave.head, sizeof m->pose.pos);
  memcpy(m->pose.gaze, s->cave.gaze, sizeof m->pose.gaze);
  m->pose.valid = 1;
  cv_adapt_default_params(&m->ap);
  m->ap.t0_cone = s->cave.t0_cone;
  m->ap.t0_rod = s->cave.t0_rod;
  m->ap.tau_cone = s->cave.tau_cone;
  m->ap.tau_rod = s->cave.tau_rod;
  /* Compensation. */
  if (s->o.compensate) {
    st = cv_service_display(s, &m->disp, err);
    if (st) return st;
    cv_ff_params fp;
    cv_ff_params_default(&fp);
    fp.quiet = 1;
    st = cv_formfactors_build(m->disp, &fp, &m->F, NULL, err);
    if (st) return st;
    cv_display_scatter_system(m->disp, m->F, &m->sys);
    st = cv_scatter_workspace_create_ex(&m->sys, CV_SCATTER_WS_COMPRESS, &m->ws, err);
    if (st) return st;
    const size_t n = cv_display_patch_count(m->disp);
    m->T = malloc(3 * n * sizeof *m->T);
    m->I = malloc(3 * n * sizeof *m->I);
    m->r = calloc(3 * n, sizeof *m->r);
    m->walls = calloc((size_t)s->n_walls, sizeof *m->walls);
    if (!m->T || !m->I || !m->r || !m->walls) return cv_err_set(err, CV_ERR_NOMEM, "master: out of memory");
    for (int w = 0; w < s->n_walls; w++) {
      const cv_display_surface *S = cv_display_surface_at(m->disp, (size_t)w);
      m->walls[w].r = calloc(3 * (size_t)S->nu * S->nv, sizeof(double));
      if (!m->walls[w].r) return cv_err_set(err, CV_ERR_NOMEM, "master: out of memory");
    }
  }
  /* Mailboxes of the wall-eyes (report + patch image). */
  m->rep_mb = calloc((size_t)s->n_walleyes, sizeof *m->rep_mb);
  m->last_frame_seen = calloc((size_t)s->n_walleyes, sizeof *m->last_frame_seen);
  if (!m->rep_mb || !m->last_frame_seen) return cv_err_set(err, CV_ERR_NOMEM, "master: out of memory");
  for (int k = 0; k < s->n_walleyes; k++) {
    size_t cap = CV_WALLEYE_REPORT_BYTES + sizeof(cv_patch_msg) + 4096 * 4096 * 3 * sizeof(float);
    if (m->disp) cap = walleye_msg_cap(m, k / 2);
    else cap = CV_WALLEYE_REPORT_BYTES + sizeof(cv_patch_msg);
    m->rep_mb[k] = cv_mailbox_open(k + 1, CV_TAG_REPORT, cap);
    if (!m->rep_mb[k]) return cv_err_set(err, CV_ERR_NOMEM, "master: cannot post receives");
  }
  m->img_mb = calloc((size_t)s->n_walls, sizeof *m->img_mb);
  m->mont = calloc((size_t)s->n_walls, sizeof *m->mont);
  if (!m->img_mb || !m->mont) return cv_err_set(err, CV_ERR_NOMEM, "master: out of memory");
  for (int w = 0; w < s->n_walls; w++) {
    const int px = s->o.size > 0 ? s->o.size * s->o.size : s->cave.walls[w].res[0] * s->cave.walls[w].res[1];
    m->img_mb[w] = cv_mailbox_open(1 + 2 * w, CV_TAG_IMAGE,
                                   sizeof(cv_patch_msg) + 2 * sizeof(int32_t) + 3 * (size_t)px * sizeof(float));
    if (!m->img_mb[w]) return cv_err_set(err, CV_ERR_NOMEM, "master: cannot post receives");
  }
  if (s->o.lcd && s->n_contributors > 0) {
    size_t n = cv_lcd_accum_words(s->o.lcd_w, s->o.lcd_h);
    m->lcd_mb = cv_mailbox_open(-1, CV_TAG_LCD, sizeof(cv_lcd_msg) + n * sizeof(int64_t));
    m->seen = calloc((size_t)s->o.lcd_budget, 1);
    if (!m->lcd_mb || !m->seen) return cv_err_set(err, CV_ERR_NOMEM, "master: out of memory");
    st = cv_lcd_content_load(s->o.lcd_content, s->o.lcd_w, s->o.lcd_h, s->o.lcd_luminance,
                             &m->lcd_content, err);
    if (st) return st;
  }
  /* Metrics. */
  char mp[CV_PATHLEN + 32];
  if (s->o.metrics_path[0]) snprintf(mp, sizeof mp, "%s", s->o.metrics_path);
  else snprintf(mp, sizeof mp, "%s/metrics.jsonl", s->o.out_dir);
  m->mf = fopen(mp, "w");
  if (!m->mf) return cv_err_set(err, CV_ERR_IO, "%s: cannot write the metrics", mp);
  if (cv_metrics_line_create(&m->ml)) return cv_err_set(err, CV_ERR_NOMEM, "metrics: out of memory");
  return CV_OK;
}

/* ---- one frame ------------------------------------------------------------ */

static void merge_report(master *m, int k, const uint8_t *data, long len, uint32_t frame,
                         cv_lumstats *acc, double *lwmax, cv_walleye_report *rep_out, int *got) {
  cv_walleye_report rep;
  cv_err err;
  if (len < (long)CV_WALLEYE_REPORT_BYTES ||
      cv_walleye_report_unpack(data, CV_WALLEYE_REPORT_BYTES, &rep, &err)) {
    fprintf(stderr, "cave run: master: bad report from rank %d dropped\n", k + 1);
    return;
  }
  if (rep.frame != frame) { /* an old frame's report arriving late */
    m->late_reports++;
    return;
  }
  got[k] = 1;
  rep_out[k] = rep;
  if (rep.state_hash != m->sent_hash) {
    m->state_mismatch++;
    m->state_mismatch_total++;
  }
  cv_lumstats ls = {.sum_log = rep.sum_log, .weight = rep.weight, .max_l = rep.max_l,
                    .n_pixels = rep.n_pixels, .n_invalid = rep.n_invalid};
  cv_lumstats_merge(acc, &ls);
  if (rep.max_l > *lwmax) *lwmax = rep.max_l;
  /* Patch image. */
  if (!m->disp) return;
  const int w = k / 2;
  const cv_display_surface *S = cv_display_surface_at(m->disp, (size_t)w);
  const size_t np = (size_t)S->nu * S->nv;
  cv_patch_msg pm;
  if ((size_t)len != CV_WALLEYE_REPORT_BYTES + sizeof pm + 3 * np * sizeof(float)) return;
  memcpy(&pm, data + CV_WALLEYE_REPORT_BYTES, sizeof pm);
  if (pm.frame != frame || pm.n != np) return;
  const float *px = (const float *)(const void *)(data + CV_WALLEYE_REPORT_BYTES + sizeof pm);
  for (size_t i = 0; i < 3 * np; i++) {
    float v;
    memcpy(&v, px + i, sizeof v);
    m->walls[w].r[i] += isfinite(v) ? (double)v : 0.0;
  }
  m->walls[w].got++;
}

/* Compensation solve on the walls that reported; walls without a report keep
 * last frame's images.  Sends each wall-eye its wall's correction. */
static void compensate_frame(master *m, uint32_t frame) {
  const int nw = m->s->n_walls;
  for (int w = 0; w < nw; w++) {
    const cv_display_surface *S = cv_display_surface_at(m->disp, (size_t)w);
    const size_t np = (size_t)S->nu * S->nv;
    if (m->walls[w].got > 0)
      for (size_t i = 0; i < 3 * np; i++)
        m->r[3 * S->offset + i] = m->walls[w].r[i] / m->walls[w].got;
    memset(m->walls[w].r, 0, 3 * np * sizeof(double));
    m->walls[w].got = 0;
  }
  const size_t n = cv_display_patch_count(m->disp);
  for (size_t i = 0; i < n; i++)
    for (int c = 0; c < 3; c++) {
      const size_t p = 3 * i + c;
      m->T[p] = (float)(m->sys.proj[i] * m->sys.refl[p] * m->r[p] + m->sys.env[p] * m->sys.refl[p]);
    }
  cv_scatter_opts o;
  cv_scatter_opts_default(&o);
  o.warm_start = 1;                   /* from the previous frame's clipped patches */
  o.time_ms = m->s->o.compensation_ms; /* the paper's time slot: best so far when it runs out */
  cv_err err;
  m->comp_ok = cv_scatter_solve(m->ws, m->T, &o, m->I, &m->cst, &err) == CV_OK;
  if (!m->comp_ok) {
    fprintf(stderr, "cave run: master: compensation: %s\n", err.msg);
    return;
  }
  for (int w = 0; w < nw; w++) {
    const cv_display_surface *S = cv_display_surface_at(m->disp, (size_t)w);
    const size_t np = (size_t)S->nu * S->nv;
    size_t len = sizeof(cv_patch_msg) + 3 * np * sizeof(float);
    uint8_t *buf = malloc(len);
    if (!buf) continue;
    cv_patch_msg pm = {.frame = frame, .n = (uint32_t)np};
    memcpy(buf, &pm, sizeof pm);
    float *d = (float *)(void *)(buf + sizeof pm);
    for (size_t i = 0; i < 3 * np; i++) {
      const size_t p = 3 * S->offset + i;
      d[i] = (float)(m->r[p] - m->I[p]); /* equation 7's delta = down(I0) - I_P */
    }
    for (int e = 0; e < 2; e++) cv_comm_send(buf, len, 1 + 2 * w + e, CV_TAG_CORR);
    free(buf);
  }
}

int cv_master_run(cv_service *s) {
  master M;
  memset(&M, 0, sizeof M);
  M.s = s;
  master *m = &M;
  cv_err err;
  cv_err_clear(&err);
  int rc = master_setup(m, &err);
  /* Every rank reports its set-up; the first failure ends the run. */
  int ready_fail = 0;
  char why[600] = "";
  if (rc) {
    ready_fail = 1;
    snprintf(why, sizeof why, "rank 0 (master): %s", err.msg);
  }
  {
    cv_mailbox *rb = cv_mailbox_open(-1, CV_TAG_READY, 512);
    int ready = 0;
    const double t0 = cv_service_now();
    while (rb && ready < s->size - 1) {
      const uint8_t *data;
      int from;
      long len = cv_mailbox_take(rb, &data, &from);
      if (len > 0) {
        ready++;
        if (data[0] != 'O' && !ready_fail) {
          ready_fail = 1;
          snprintf(why, sizeof why, "rank %d: %.*s", from, (int)(len - 1), (const char *)data + 1);
        }
        continue;
      }
      cv_comm_progress();
      if (*s->stop) break;
      if (cv_service_now() - t0 > s->o.startup_timeout_s) {
        ready_fail = 1;
        snprintf(why, sizeof why, "only %d of %d ranks were ready after %.0f s", ready, s->size - 1,
                 s->o.startup_timeout_s);
        break;
      }
    }
    cv_mailbox_close(rb);
  }
  cv_frame_state fs;
  uint8_t buf[CV_FRAME_STATE_BYTES];
  if (ready_fail || *s->stop) {
    if (ready_fail) fprintf(stderr, "cave run: set-up failed: %s\n", why);
    memset(&fs, 0, sizeof fs);
    fs.flags = CV_FS_QUIT;
    if (cv_frame_state_pack(&fs, buf) == CV_OK)
      for (int r = 1; r < s->size; r++) cv_comm_send(buf, sizeof buf, r, CV_TAG_STATE);
    cv_comm_flush(5);
    master_free(m);
    return ready_fail ? 1 : 0;
  }
  const int nframes = s->o.frames;
  size_t cap = nframes > 0 ? (size_t)nframes : 4096;
  m->frame_ms = calloc(cap, sizeof *m->frame_ms);
  m->overhead_ms = calloc(cap, sizeof *m->overhead_ms);
  cv_walleye_report *reps = calloc((size_t)s->n_walleyes, sizeof *reps);
  int *got = calloc((size_t)s->n_walleyes, sizeof *got);
  if (!m->frame_ms || !m->overhead_ms || !reps || !got) {
    fprintf(stderr, "cave run: master: out of memory\n");
    cv_comm_abort(1, NULL);
  }
  if (!s->o.quiet)
    printf("cave run: %d ranks: master, %d wall-eyes (%d walls x 2 eyes), %d gather-only; LCD from %d "
           "contributors\n",
           s->size, s->n_walleyes, s->n_walls, s->n_gather, s->n_contributors);
  const double run_t0 = cv_service_now();
  uint32_t f;
  for (f = 0;; f++) {
    if (*s->stop) break;
    /* After the drive's frames, --lcd-wait holds the time (the head and the
     * lighting stand still, as while the driver reads the panel) and goes on
     * rendering until the LCD image has its budget. */
    const int holding = nframes > 0 && f >= (uint32_t)nframes;
    if (holding && !(m->lcd_mb && s->o.lcd_wait && m->lcd_rounds < (uint32_t)s->o.lcd_budget))
      break;
    const double tf0 = cv_service_now();
    memset(&fs, 0, sizeof fs);
    fs.frame = f;
    fs.dt = holding ? 0 : s->o.dt;
    fs.time = (holding ? (uint32_t)nframes - 1 : f) * s->o.dt;
    /* Drive and lighting. */
    cv_drive_eval(s->drive, fs.time, &fs.drive);
    cv_service_quantise_drive(&fs.drive);
    const uint64_t lk = cv_service_light_key(&fs.drive);
    if (!m->have_light || lk != m->light_key) {
      cv_lighting nl;
      if (cv_service_lighting(s, m->mix, &fs.drive, m->bands, &nl, 0, NULL, &err) == CV_OK) {
        m->lighting = nl;
        m->light_key = lk;
        m->have_light = 1;
        fs.flags |= CV_FS_NEW_LIGHT;
      } else {
        fprintf(stderr, "cave run: lighting: %s (keeping the previous lighting)\n", err.msg);
      }
    }
    fs.light_key = m->light_key;
    fs.bands = m->lighting.bands;
    memcpy(fs.sh, m->lighting.sh, sizeof fs.sh);
    fs.has_sun = m->lighting.has_sun;
    memcpy(fs.sun_dir, m->lighting.sun_dir, sizeof fs.sun_dir);
    memcpy(fs.sun_E, m->lighting.sun_E, sizeof fs.sun_E);
    /* Head. */
    const double now = cv_service_now();
    if (m->dtr) {
      cv_head_pose p = m->pose;
      if (cv_dtrack_receiver_poll(m->dtr, now, &p, &m->trk) == 1) {
        m->pose = p;
        m->pose_time = now;
      }
      fs.tracker_age = m->pose_time > 0 ? now - m->pose_time : now - run_t0;
    } else if (m->path) {
      cv_head_path_eval(m->path, fs.time, 1, &m->pose);
      fs.tracker_age = 0;
    }
    memcpy(fs.head, m->pose.pos, sizeof fs.head);
    memcpy(fs.gaze, m->pose.gaze, sizeof fs.gaze);
    /* Adaptation from the previous frame's statistics. */
    m->pending_dt += f ? fs.dt : 0;
    double lwa_f = 0;
    if (m->have_stats && cv_lumstats_lwa(&m->stats, &lwa_f) == 1) {
      if (!m->have_adapt) {
        cv_adapt_init(&m->ad, &m->ap, lwa_f);
        m->have_adapt = 1;
      } else {
        cv_adapt_step(&m->ad, &m->ap, lwa_f, m->pending_dt);
      }
      m->pending_dt = 0;
    }
    fs.lwa = m->have_adapt ? cv_adapt_lwa(&m->ad) : 1.0;
    fs.lwmax = m->lwmax > 0 ? m->lwmax : 100 * fs.lwa;
    fs.adapt[0] = m->ad.a_cone;
    fs.adapt[1] = m->ad.a_rod;
    fs.adapt[2] = m->ad.b_cone;
    fs.adapt[3] = m->ad.b_rod;
    fs.adapt[4] = m->ad.time;
    fs.adapt[5] = m->ad.initialised;
    /* LCD key: quantised eye (car frame) and lighting. */
    if (m->lcd_mb) {
      float eye[3];
      for (int a = 0; a < 3; a++) eye[a] = (float)(fs.head[a] + s->cave.scene_offset[a]);
      cv_lcd_key k;
      if (cv_lcd_key_make(eye, s->o.lcd_tolerance, m->light_key, 0, &k) == CV_OK) {
        const uint64_t key = cv_service_lcd_key(k.eye_q, m->light_key);
        if (key != m->lcd_key) {
          cv_lcd_progress_free(&m->prog);
          memset(&m->prog, 0, sizeof m->prog);
          memset(m->seen, 0, (size_t)s->o.lcd_budget);
          m->lcd_rounds = m->lcd_sent_rounds = 0;
          m->lcd_key = key;
          memcpy(m->lcd_eye_q, k.eye_q, sizeof k.eye_q);
        }
      }
      fs.lcd_key = m->lcd_key;
      fs.lcd_rounds = m->lcd_rounds;
    }
    const int last = nframes > 0 && f + 1 == (uint32_t)nframes;
    if (holding) fs.flags |= CV_FS_HOLD;
    if (last || (s->o.write_every > 0 && f % (uint32_t)s->o.write_every == 0)) fs.flags |= CV_FS_WRITE;
    if (cv_frame_state_pack(&fs, buf)) {
      fprintf(stderr, "cave run: master: frame %u state not finite, frame skipped\n", f);
      continue;
    }
    {
      int *dests = malloc((size_t)s->size * sizeof *dests);
      if (dests) {
        for (int r = 1; r < s->size; r++) dests[r - 1] = r;
        cv_comm_send_multi(buf, sizeof buf, dests, s->size - 1, CV_TAG_STATE);
        free(dests);
      }
    }
    const double t_sent = cv_service_now();
    m->sent_hash = cv_hash64(buf, sizeof buf);
    m->state_mismatch = 0;
    /* Collect the wall-eyes' reports until all arrived or the deadline. */
    cv_lumstats acc;
    memset(&acc, 0, sizeof acc);
    double lwmax = 0;
    memset(got, 0, (size_t)s->n_walleyes * sizeof *got);
    int ngot = 0;
    /* Frame 0 also pays every rank's first lighting (relight, shadow map,
     * background from the maps): allow it the start-up time. */
    const double deadline =
        t_sent + (f == 0 ? fmax(s->o.timeout_ms * 1e-3, s->o.startup_timeout_s) : s->o.timeout_ms * 1e-3);
    double t_wait = 0;
    while (ngot < s->n_walleyes) {
      int progressed = 0;
      for (int k = 0; k < s->n_walleyes; k++) {
        if (got[k]) continue;
        const uint8_t *data;
        long len;
        while (!got[k] && (len = cv_mailbox_take(m->rep_mb[k], &data, NULL)) >= 0) {
          merge_report(m, k, data, len, f, &acc, &lwmax, reps, got);
          progressed = 1;
          if (got[k]) ngot++;
        }
      }
      /* LCD sums and the LCD image for the wall-eyes overlap their
       * rendering: off the frame's critical path. */
      lcd_drain(m);
      lcd_publish(m, 0);
      montage_drain(m);
      cv_comm_progress();
      if (ngot == s->n_walleyes || *s->stop) break;
      if (cv_service_now() > deadline) break;
      if (!progressed) {
        struct timespec ts = {0, 200000};
        nanosleep(&ts, NULL);
      }
    }
    t_wait = cv_service_now();
    const int late = s->n_walleyes - ngot;
    if (acc.weight > 0) {
      m->stats = acc;
      m->have_stats = 1;
      m->lwmax = lwmax;
    } else {
      m->have_stats = 0; /* empty foveal region or all late: keep the adaptation */
    }
    const double tc0 = cv_service_now();
    if (m->disp) compensate_frame(m, f);
    const double tc1 = cv_service_now();
    lcd_drain(m);
    const double tf1 = cv_service_now();
    /* Metrics. */
    cv_metrics_line *ml = m->ml;
    cv_metrics_begin(ml);
    cv_metrics_string(ml, "type", "frame");
    cv_metrics_uint(ml, "frame", f);
    cv_metrics_double(ml, "t", fs.time);
    cv_metrics_double(ml, "frame_ms", (tf1 - tf0) * 1e3);
    /* The master's own work (state, statistics, LCD sums), without waiting
     * and without the compensation solve (reported apart). */
    const double overhead = ((t_sent - tf0) + (tc0 - t_wait) + (tf1 - tc1)) * 1e3;
    cv_metrics_double(ml, "master_ms", overhead);
    cv_metrics_double(ml, "wait_ms", (t_wait - t_sent) * 1e3);
    cv_metrics_int(ml, "late_walleyes", late);
    cv_metrics_int(ml, "state_mismatch", m->state_mismatch);
    cv_metrics_object_begin(ml, "adaptation");
    cv_metrics_double(ml, "lwa", fs.lwa);
    cv_metrics_double(ml, "lwmax", fs.lwmax);
    cv_metrics_double(ml, "foveal_lwa", acc.weight > 0 ? exp(acc.sum_log / acc.weight) : 0);
    cv_metrics_double(ml, "foveal_sr", acc.weight);
    cv_metrics_uint(ml, "invalid_pixels", acc.n_invalid);
    cv_metrics_doubles(ml, "state", fs.adapt, 6);
    cv_metrics_object_end(ml);
    cv_metrics_object_begin(ml, "drive");
    cv_metrics_double(ml, "yaw", fs.drive.yaw_deg);
    cv_metrics_doubles(ml, "weights", fs.drive.weights, (size_t)fs.drive.n_maps);
    cv_metrics_bool(ml, "new_light", (fs.flags & CV_FS_NEW_LIGHT) != 0);
    cv_metrics_object_end(ml);
    cv_metrics_object_begin(ml, "tracker");
    cv_metrics_doubles(ml, "head", fs.head, 3);
    cv_metrics_doubles(ml, "gaze", fs.gaze, 3);
    cv_metrics_double(ml, "age_s", fs.tracker_age);
    if (m->dtr) {
      cv_metrics_uint(ml, "packets", m->trk.packets);
      cv_metrics_uint(ml, "malformed", m->trk.malformed);
    }
    cv_metrics_object_end(ml);
    if (m->lcd_mb) {
      cv_metrics_object_begin(ml, "lcd");
      char kb[32];
      snprintf(kb, sizeof kb, "%016llx", (unsigned long long)m->lcd_key);
      cv_metrics_string(ml, "key", kb);
      cv_metrics_uint(ml, "rounds", m->lcd_rounds);
      cv_metrics_uint(ml, "spp", (uint64_t)m->lcd_rounds * (uint64_t)s->o.lcd_spp);
      cv_metrics_uint(ml, "late_rounds", m->lcd_late);
      cv_metrics_uint(ml, "rejected", m->lcd_rejected);
      if (m->prog.acc) {
        cv_lcd_error le;
        if (cv_lcd_accum_error(m->prog.acc, &le) == CV_OK) cv_metrics_double(ml, "rel_rms", le.rel_rms);
        cv_metrics_uint(ml, "clamped", (uint64_t)m->prog.acc->data[CV_LCD_ACC_CLAMPED]);
      }
      cv_metrics_object_end(ml);
    }
    if (m->disp) {
      cv_metrics_object_begin(ml, "compensation");
      cv_metrics_bool(ml, "ok", m->comp_ok);
      cv_metrics_string(ml, "solver", cv_scatter_solver_name(m->cst.solver));
      cv_metrics_double(ml, "residual", m->cst.residual);
      cv_metrics_uint(ml, "clipped_patches", m->cst.clipped_patches);
      cv_metrics_int(ml, "iterations", m->cst.iterations);
      cv_metrics_bool(ml, "time_slot_hit", m->cst.exit == CV_SCATTER_EXIT_TIME);
      cv_metrics_double(ml, "ms", m->cst.ms);
      cv_metrics_double(ml, "frame_ms", (tc1 - tc0) * 1e3);
      cv_metrics_object_end(ml);
    }
    cv_metrics_object_begin(ml, "ranks");
    for (int k = 0; k < s->n_walleyes; k++) {
      char key[16];
      snprintf(key, sizeof key, "%d", k + 1);
      cv_metrics_object_begin(ml, key);
      if (got[k]) {
        cv_metrics_double(ml, "lum_ms", reps[k].ms_lum);
        cv_metrics_double(ml, "depth_ms", reps[k].ms_depth);
        cv_metrics_double(ml, "shade_ms", reps[k].ms_shade);
        cv_metrics_double(ml, "read_ms", reps[k].ms_read);
        cv_metrics_double(ml, "total_ms", reps[k].ms_total);
        cv_metrics_double(ml, "lcd_ms", reps[k].ms_lcd);
        cv_metrics_uint(ml, "lcd_rounds", reps[k].lcd_rounds_done);
      } else {
        cv_metrics_bool(ml, "late", 1);
      }
      cv_metrics_object_end(ml);
    }
    cv_metrics_object_end(ml);
    cv_metrics_write(ml, m->mf);
    if (m->nframes_done < cap) {
      m->frame_ms[m->nframes_done] = (tf1 - tf0) * 1e3;
      m->overhead_ms[m->nframes_done] = overhead;
    }
    m->nframes_done++;
    if (!s->o.quiet)
      printf("frame %u: %.0f ms (master %.2f ms), lwa %.3g cd/m2, %d late, LCD %u rounds\n", f,
             (tf1 - tf0) * 1e3, overhead, fs.lwa, late, m->lcd_rounds);
    fflush(stdout);
    if (s->o.barrier) cv_comm_barrier();
    /* Pacing: held frames at one a second (the LCD threads run only on
     * cores the renderers leave idle, SCHED_IDLE), others at --max-fps. */
    const double period = holding ? 1.0 : (s->o.max_fps > 0 ? 1.0 / s->o.max_fps : 0);
    if (period > 0) {
      while (cv_service_now() - tf0 < period && !*s->stop &&
             !(holding && m->lcd_rounds >= (uint32_t)s->o.lcd_budget)) {
        lcd_drain(m);
        cv_comm_progress();
        struct timespec ts = {0, 2000000};
        nanosleep(&ts, NULL);
      }
    }
  }
  /* Quit: tell every rank, then the last LCD image and the summary. */
  memset(&fs, 0, sizeof fs);
  fs.frame = f;
  fs.flags = CV_FS_QUIT;
  if (cv_frame_state_pack(&fs, buf) == CV_OK)
    for (int r = 1; r < s->size; r++) cv_comm_send(buf, sizeof buf, r, CV_TAG_STATE);
  lcd_drain(m);
  if (!*s->stop) lcd_publish(m, 1);
  if (m->lcd_mb) lcd_write(m, "lcd");
  /* the last written frame's images are on their way (not waited for when
   * interrupted: mpirun follows its SIGTERM with SIGKILL) */
  for (const double t0 = cv_service_now();
       !*s->stop && cv_service_now() - t0 < s->o.timeout_ms * 1e-3;) {
    montage_drain(m);
    cv_comm_progress();
    if (!m->mont_have && m->montages > 0 && f > 0 &&
        m->mont_frame + 1 >= f) break;
    struct timespec ts = {0, 1000000};
    nanosleep(&ts, NULL);
  }
  montage_flush(m);
  cv_metrics_line *ml = m->ml;
  cv_metrics_begin(ml);
  cv_metrics_string(ml, "type", "summary");
  cv_metrics_uint(ml, "frames", m->nframes_done);
  cv_metrics_uint(ml, "held_frames", nframes > 0 && f > (uint32_t)nframes ? f - (uint32_t)nframes : 0);
  cv_metrics_bool(ml, "interrupted", *s->stop != 0);
  cv_metrics_double(ml, "seconds", cv_service_now() - run_t0);
  /* Percentiles without frame 0 (warm-up: every rank's first lighting and
   * the first round trip), when there are later frames. */
  const size_t nall = m->nframes_done < cap ? m->nframes_done : cap;
  const size_t skip = nall > 1 ? 1 : 0, nd = nall - skip;
  const double ps[3] = {50, 99, 100};
  double q[3];
  cv_metrics_uint(ml, "warmup_frames_excluded", skip);
  if (nd && cv_percentiles(m->frame_ms + skip, nd, ps, 3, q, NULL) == CV_OK) {
    cv_metrics_double(ml, "frame_ms_p50", q[0]);
    cv_metrics_double(ml, "frame_ms_p99", q[1]);
    cv_metrics_double(ml, "fps", q[0] > 0 ? 1e3 / q[0] : 0);
  }
  if (nd && cv_percentiles(m->overhead_ms + skip, nd, ps, 3, q, NULL) == CV_OK) {
    cv_metrics_double(ml, "master_ms_p50", q[0]);
    cv_metrics_double(ml, "master_ms_p99", q[1]);
    cv_metrics_double(ml, "master_ms_max", q[2]);
  }
  cv_metrics_uint(ml, "late_reports", m->late_reports);
  cv_metrics_uint(ml, "state_mismatch", m->state_mismatch_total);
  cv_metrics_uint(ml, "montages", m->montages);
  if (m->lcd_mb) {
    cv_metrics_uint(ml, "lcd_rounds", m->lcd_rounds);
    cv_metrics_uint(ml, "lcd_spp", (uint64_t)m->lcd_rounds * (uint64_t)s->o.lcd_spp);
    if (m->prog.acc) {
      cv_lcd_error le;
      if (cv_lcd_accum_error(m->prog.acc, &le) == CV_OK) cv_metrics_double(ml, "lcd_rel_rms", le.rel_rms);
    }
  }
  cv_metrics_uint(ml, "nonfinite_metrics", cv_metrics_nonfinite(ml));
  cv_metrics_write(ml, m->mf);
  if (!s->o.quiet) printf("cave run: %zu frames; metrics in the out folder\n", m->nframes_done);
  cv_comm_flush(10);
  free(reps);
  free(got);
  master_free(m);
  return 0;
}
