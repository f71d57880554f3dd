/* The master's scattering compensation (Bimber et al. 2006, equation 5 on
 * the patches, equation 7's delta to the walls), off the frame's path:
 *   --compensation-lag 0: each frame's patch images are solved when every
 *     wall-eye reported, and the wall-eyes wait for their wall's delta
 *     before they present (the solve is on every frame's path);
 *   --compensation-lag 1 (default): the frame's patch images are kept, the
 *     master sends the next frame's state at once, and solves them while
 *     the wall-eyes render that frame (the first thing it does while it
 *     waits for their reports, master_comp_poll); the delta of frame N goes
 *     out then, and the wall-eyes apply it to frame N + 1.  The solve runs
 *     on the master's thread that is already running: a thread woken for it
 *     waited 50 ms for a core on a 2-core host with 11 busy ranks.
 * Also the wall-eyes' frame-path samples (issue 29) and their summary.
 *
 * CAVE_TEST_SOLVE_DELAY_MS (tests only, docs/service.md): each solve's
 * deltas after frame 0's are held back this long (the master goes on, and solves the next
 * patch images only after they went out), to make corrections late on
 * purpose. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "comm.h"
#include "io/filewriter.h"
#include "master_internal.h"
#include "service/metrics.h"

/* ---- set-up ---------------------------------------------------------------- */

int master_comp_setup(master *m, cv_err *err) {
  cv_service *s = m->s;
  m->comp_frame = m->comp_pending = 0xffffffffu;
  const char *d = getenv("CAVE_TEST_SOLVE_DELAY_MS");
  m->comp_delay_ms = d ? atof(d) : 0;
  int st = cv_service_display(s, &m->disp, err);
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
  return CV_OK;
}

void master_comp_free(master *m) {
  free(m->comp_hold);
  m->comp_hold = NULL;
  free(m->path_read), free(m->path_cpu), free(m->path_gpu), free(m->path_wait), free(m->late_corr);
  free(m->files_dropped), free(m->files_failed);
  m->path_read = m->path_cpu = m->path_gpu = m->path_wait = NULL;
  m->late_corr = m->files_dropped = m->files_failed = NULL;
}

/* ---- the solve --------------------------------------------------------------- */

/* The solve of target T into I (warm-started from the previous one). */
static int solve(master *m, const float *T, float *I, cv_scatter_stats *cst, cv_err *err) {
  cv_scatter_opts o;
  cv_scatter_opts_default(&o);
  o.warm_start = 1;                   /* from the previous frame's clipped patches */
  o.time_ms = m->s->o.compensation_ms; /* the paper's time slot: best so far when it runs out */
  return cv_scatter_solve(m->ws, T, &o, I, cst, err);
}

/* Each wall's delta = down(I0) - I_P (equation 7) to its render ranks
 * (r NULL: I holds the deltas already). */
static void send_deltas(master *m, uint32_t frame, const double *r, const float *I) {
  const int nw = m->s->n_walls;
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
      d[i] = r ? (float)(r[p] - I[p]) : I[p];
    }
    /* each render rank of the wall once (a packed-stereo rank has both eyes) */
    for (int i = 0; i < m->s->n_render; i++)
      if (m->s->cave.outputs[i].wall == w) cv_comm_send(buf, len, i + 1, CV_TAG_CORR);
    free(buf);
  }
}

/* The frame's patch images (eyes averaged; walls without a report keep the
 * last frame's) into m->r and the target T. */
static void gather_target(master *m) {
  const int nw = m->s->n_walls;
  for (int w = 0; w < nw; w++) {
    const cv_display_surface *S = cv_display_surface_at(m->disp, (size_t)w);
    const size_t np = (size_t)S->nu * S->nv;
    if (m->walls[w].got > 0)
      for (size_t i = 0; i < 3 * np; i++) m->r[3 * S->offset + i] = m->walls[w].r[i] / m->walls[w].got;
    memset(m->walls[w].r, 0, 3 * np * sizeof(double));
    m->walls[w].got = 0;
  }
  const size_t n = cv_display_patch_count(m->disp);
  for (size_t i = 0; i < n; i++)
    for (int c = 0; c < 3; c++) {
      const size_t p = 3 * i + c;
      m->T[p] = (float)(m->sys.proj[i] * m->sys.refl[p] * m->r[p] + m->sys.env[p] * m->sys.refl[p]);
    }
}

/* Solves m->T (frame `frame`'s) and sends the deltas. */
static void solve_and_send(master *m, uint32_t frame, double t_in) {
  cv_err err;
  m->comp_ok = solve(m, m->T, m->I, &m->cst, &err) == CV_OK;
  if (!m->comp_ok) {
    fprintf(stderr, "cave run: master: compensation: %s\n", err.msg);
    return;
  }
  if (m->comp_delay_ms > 0 && frame > 0) { /* the test hook: the deltas held back, the master not blocked */
    const size_t n = cv_display_patch_count(m->disp);
    if (!m->comp_hold && !(m->comp_hold = malloc(3 * n * sizeof *m->comp_hold))) return;
    for (size_t i = 0; i < 3 * n; i++) m->comp_hold[i] = (float)(m->r[i] - m->I[i]);
    m->comp_hold_frame = frame;
    m->comp_hold_due = cv_service_now() + m->comp_delay_ms * 1e-3;
    m->comp_t_in = t_in;
    return;
  }
  send_deltas(m, frame, m->r, m->I);
  m->comp_frame = frame, m->comp_solves++;
  m->comp_lag_ms = (cv_service_now() - t_in) * 1e3;
}

void master_comp_frame(master *m, uint32_t frame) {
  gather_target(m);
  if (m->s->o.compensation_lag == 0) {
    solve_and_send(m, frame, cv_service_now());
  } else {
    m->comp_pending = frame; /* solved while the next frame renders */
    m->comp_t_in = cv_service_now();
  }
}

void master_comp_poll(master *m) {
  if (!m->disp) return;
  if (m->comp_hold_due > 0) { /* CAVE_TEST_SOLVE_DELAY_MS */
    if (cv_service_now() < m->comp_hold_due) return;
    send_deltas(m, m->comp_hold_frame, NULL, m->comp_hold);
    m->comp_frame = m->comp_hold_frame, m->comp_solves++;
    m->comp_lag_ms = (cv_service_now() - m->comp_t_in) * 1e3;
    m->comp_hold_due = 0;
  }
  if (m->comp_pending == 0xffffffffu) return;
  const uint32_t f = m->comp_pending;
  m->comp_pending = 0xffffffffu;
  solve_and_send(m, f, m->comp_t_in);
}

void master_comp_metrics(master *m, cv_metrics_line *ml, double frame_ms) {
  cv_metrics_object_begin(ml, "compensation");
  cv_metrics_bool(ml, "ok", m->comp_ok);
  cv_metrics_int(ml, "lag", m->s->o.compensation_lag);
  cv_metrics_string(ml, "solver", cv_scatter_solver_name(m->cst.solver));
  cv_metrics_double(ml, "residual", m->cst.residual);
  cv_metrics_uint(ml, "clipped_patches", m->cst.clipped_patches);
  cv_metrics_int(ml, "iterations", m->cst.iterations);
  cv_metrics_bool(ml, "time_slot_hit", m->cst.exit == CV_SCATTER_EXIT_TIME);
  cv_metrics_double(ml, "ms", m->cst.ms);
  cv_metrics_double(ml, "frame_ms", frame_ms);
  cv_metrics_int(ml, "solved_frame", m->comp_frame == 0xffffffffu ? -1 : (int64_t)m->comp_frame);
  cv_metrics_double(ml, "solve_lag_ms", m->comp_lag_ms);
  pthread_mutex_lock(&m->img_mu); /* set by the image thread (master_images.c) */
  if (m->have_viewer) {
    cv_metrics_double(ml, "viewer_rms", m->viewer_rms);
    cv_metrics_double(ml, "viewer_rms_uncompensated", m->viewer_rms_unc);
    cv_metrics_double(ml, "viewer_ms", m->viewer_ms);
  }
  pthread_mutex_unlock(&m->img_mu);
  cv_metrics_object_end(ml);
}

/* ---- the wall-eyes' frame path ------------------------------------------------ */

static int grow(master *m) {
  if (m->path_n < m->path_cap) return 0;
  const size_t cap = m->path_cap ? 2 * m->path_cap : 1024;
  double **arr[4] = {&m->path_read, &m->path_cpu, &m->path_gpu, &m->path_wait};
  for (int k = 0; k < 4; k++) {
    double *p = realloc(*arr[k], cap * sizeof *p);
    if (!p) return -1;
    *arr[k] = p;
  }
  m->path_cap = cap;
  return 0;
}

void master_path_sample(master *m, int from, const cv_walleye_report *r) {
  if (from >= 1 && from <= m->s->n_render) { /* the ranks' own counts: the latest */
    const size_t n = (size_t)m->s->n_render;
    if (!m->late_corr) m->late_corr = calloc(n, sizeof *m->late_corr);
    if (!m->files_dropped) m->files_dropped = calloc(n, sizeof *m->files_dropped);
    if (!m->files_failed) m->files_failed = calloc(n, sizeof *m->files_failed);
    if (m->late_corr && r->late_corr > m->late_corr[from - 1]) m->late_corr[from - 1] = r->late_corr;
    if (m->files_dropped && r->files_dropped > m->files_dropped[from - 1]) m->files_dropped[from - 1] = r->files_dropped;
    if (m->files_failed && r->files_failed > m->files_failed[from - 1]) m->files_failed[from - 1] = r->files_failed;
    master_out_files_failed(m, from, r->files_failed, NULL); /* stops the run (master_out.c) */
  }
  /* the figures are of the rank's previous frame; frames 0 and 1 pay the start */
  if (r->frame < 2 || grow(m)) return;
  m->path_read[m->path_n] = (double)r->bytes_read;
  m->path_cpu[m->path_n] = r->ms_cpu;
  m->path_gpu[m->path_n] = r->ms_gpu;
  m->path_wait[m->path_n] = r->ms_corr_wait;
  m->path_n++;
}

void master_path_summary(master *m, cv_metrics_line *ml) {
  cv_metrics_object_begin(ml, "frame_path");
  cv_metrics_uint(ml, "samples", m->path_n);
  cv_metrics_percentiles(ml, "read_bytes", m->path_read, m->path_n);
  cv_metrics_percentiles(ml, "cpu_ms", m->path_cpu, m->path_n);
  size_t ng = 0; /* GPU times where a timer query ran */
  for (size_t i = 0; i < m->path_n; i++)
    if (m->path_gpu[i] >= 0) m->path_gpu[ng++] = m->path_gpu[i];
  cv_metrics_percentiles(ml, "gpu_ms", m->path_gpu, ng);
  cv_metrics_percentiles(ml, "corr_wait_ms", m->path_wait, m->path_n);
  uint64_t late = 0;
  for (int i = 0; m->late_corr && i < m->s->n_render; i++) late += m->late_corr[i];
  cv_metrics_uint(ml, "late_corrections", late);
  cv_metrics_uint(ml, "solves", m->comp_solves);
  cv_metrics_object_end(ml);
  /* --present files: written frames' files the writer threads dropped or
   * failed (the wall-eyes' and the master's montages; final after the drain) */
  cv_filewriter_stats st;
  cv_filewriter_drain(m->fw, &st);
  uint64_t dropped = st.dropped, failed = st.failed;
  for (int i = 0; i < m->s->n_render; i++) {
    dropped += m->files_dropped ? m->files_dropped[i] : 0;
    failed += m->files_failed ? m->files_failed[i] : 0;
  }
  cv_metrics_bool(ml, "files", (m->s->o.present & CV_PRESENT_FILES) != 0);
  cv_metrics_uint(ml, "files_dropped", dropped);
  cv_metrics_uint(ml, "files_failed", failed);
  if (st.failed) fprintf(stderr, "cave run: master: %llu montages not written; first: %s\n",
                         (unsigned long long)st.failed, st.first_error);
  master_out_files_failed(m, 0, st.failed, st.first_error); /* the last montage's failure: exit status 1 */
}
