/* The master's side of the live console (issue 33; docs/service.md "Live
 * console"): it starts the HTTP server (src/http, no MPI there), fills the
 * console's state from its own once per frame and publishes it without
 * waiting (service/console.h), and applies the console's controls at the
 * start of a frame through the paths a tracker or a drive use:
 *   pause / resume  the drive's clock stands still, and a recorded head
 *                   path's with it (frames go on rendering, a live tracker's
 *                   head still moves): frame_clock's time minus the time held;
 *   quit            a stop request, as SIGTERM or Escape: the frame ends,
 *                   every rank quits, the summary says "console: quit";
 *   head            a tracker sample at that time (the desktop's keyboard
 *                   head moves on from it; a live tracker or a head path
 *                   replaces it with its next sample);
 *   sky, yaw        hold those values of the drive state (sun elevation,
 *                   azimuth, turbidity of a sky drive; the car's heading of
 *                   any drive) until "drive" gives them back: every rank
 *                   gets them with the frame state, as the drive's own. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "comm.h"
#include "http/http.h"
#include "master_internal.h"
#include "service/console.h"
#include "view/montage.h"

int master_http_setup(master *m, cv_err *err) {
  const cv_run_opts *o = &m->s->o;
  if (o->http_off) return CV_OK;
  const int n = m->s->size;
  m->con_reports = calloc((size_t)n, sizeof *m->con_reports);
  m->con_rep0 = calloc((size_t)n, sizeof *m->con_rep0);
  m->con_st = calloc(1, sizeof *m->con_st);
  m->con_ms = calloc(m->cap ? m->cap : 1, sizeof *m->con_ms);
  if (!m->con_reports || !m->con_rep0 || !m->con_st || !m->con_ms || cv_console_create(&m->con))
    return cv_err_set(err, CV_ERR_NOMEM, "master: out of memory (console)");
  cv_http_opts ho;
  cv_http_opts_default(&ho);
  snprintf(ho.addr, sizeof ho.addr, "%s", o->http_addr);
  ho.port = o->http_port;
  if (o->http_token_path[0]) {
    int st = cv_http_load_token(o->http_token_path, ho.token, sizeof ho.token, err);
    if (st) return st;
  }
  int st = cv_http_start(&ho, m->con, &m->http, err);
  if (st) return st;
  cv_console_state *cs = m->con_st;
  cv_comm_host(cs->master_host, sizeof cs->master_host);
  snprintf(cs->url, sizeof cs->url, "http://%s:%d/", o->http_addr, cv_http_port(m->http));
  snprintf(cs->clock, sizeof cs->clock, "%s", m->wall_clock ? "wall" : "sim");
  cs->files = (o->present & CV_PRESENT_FILES) != 0;
  cs->images = 1;
  cs->lcd = m->lcd_mb != NULL;
  cs->compensation = m->disp != NULL;
  cs->lcd_budget = (uint32_t)o->lcd_budget;
  cs->n_panels = m->lcd_mb ? (m->s->lcd_layout.n < CV_CONSOLE_PANELS ? m->s->lcd_layout.n : CV_CONSOLE_PANELS) : 0;
  for (int i = 0; i < cs->n_panels; i++) {
    snprintf(cs->panel_name[i], sizeof cs->panel_name[i], "%s", m->s->lcd.panels[i].name);
    cs->cr[i] = NAN;
  }
  cs->viewer_rms = cs->viewer_rms_unc = cs->skew_us = cs->mtp_ms = NAN;
  return CV_OK;
}

void master_http_free(master *m) {
  cv_http_stop(m->http); /* first: its threads read the console */
  m->http = NULL;
  cv_console_destroy(m->con);
  m->con = NULL;
  free(m->con_st);
  free(m->con_reports);
  free(m->con_rep0);
  free(m->con_ms);
}

/* "rank N on HOST: ..." -> HOST; "GL RENDERER (" -> RENDERER. */
static void ready_fields(const char *line, char *host, size_t hcap, char *gpu, size_t gcap) {
  host[0] = gpu[0] = 0;
  const char *on = line ? strstr(line, " on ") : NULL;
  if (on) {
    on += 4;
    size_t l = strcspn(on, ": ");
    snprintf(host, hcap, "%.*s", (int)l, on);
  }
  const char *gl = line ? strstr(line, "; GL ") : NULL;
  if (gl) {
    gl += 5;
    const char *end = strstr(gl, " (");
    snprintf(gpu, gcap, "%.*s", (int)(end ? end - gl : (long)strlen(gl)), gl);
  }
}

void master_http_ready(master *m, char *const *lines) {
  if (!m->con) return;
  cv_service *s = m->s;
  cv_console_state *cs = m->con_st;
  cs->n_ranks = s->size < CV_CONSOLE_MAX_RANKS ? s->size : CV_CONSOLE_MAX_RANKS;
  for (int r = 0; r < cs->n_ranks; r++) {
    cv_console_rank *row = &cs->ranks[r];
    row->rank = r;
    if (r == 0) {
      row->role = CV_ROLE_NAME_MASTER;
      snprintf(row->host, sizeof row->host, "%s", cs->master_host);
      continue;
    }
    ready_fields(lines ? lines[r] : NULL, row->host, sizeof row->host, row->gpu, sizeof row->gpu);
    if (r <= s->n_render) {
      const cv_output *o = &s->cave.outputs[r - 1];
      row->role = CV_ROLE_NAME_WALLEYE;
      snprintf(row->view, sizeof row->view, "%s %s", s->cave.walls[o->wall].name,
               o->eyes == 3 ? "L+R" : o->eyes == 1 ? "L" : "R");
    } else {
      row->role = CV_ROLE_NAME_GATHER;
      snprintf(row->view, sizeof row->view, "LCD rounds");
    }
  }
  if (!s->o.quiet)
    printf("cave run: ready: console %s%s\n", cs->url,
           s->o.http_token_path[0] ? " (token required: ?token=... or Authorization: Bearer)" : "");
}

/* ---- controls -------------------------------------------------------------------- */

static void set_head(master *m, const cv_console_ctl *c, double now) {
  m->prev_pose = m->pose;
  m->prev_pose_time = m->pose_time;
  memcpy(m->pose.pos, c->v, 3 * sizeof(double));
  if (c->mask) memcpy(m->pose.gaze, c->v + 3, 3 * sizeof(double));
  m->pose.t = now;
  m->pose_time = now;
  if (m->desk_source) m->nav.pose = m->pose; /* the keyboard moves on from here */
  m->head_console = 1;
}

/* Applies one control; 0 applied, else why not in `why`. */
static int apply(master *m, const cv_console_ctl *c, char *why, size_t cap) {
  const double now = cv_service_now();
  switch (c->kind) {
  case CV_CTL_PAUSE: m->paused = 1; return 0;
  case CV_CTL_RESUME: m->paused = 0; return 0;
  case CV_CTL_QUIT:
    if (!m->stop_code) {
      m->stop_code = MASTER_STOP_CONSOLE;
      snprintf(m->stop_reason, sizeof m->stop_reason, "console: quit requested");
      fprintf(stderr, "cave run: stopping: %s\n", m->stop_reason);
    }
    return 0;
  case CV_CTL_HEAD: {
    cv_err err;
    if (cv_cave_check_eye(&m->s->cave, c->v, &err)) {
      snprintf(why, cap, "head rejected: %.250s", err.msg);
      return -1;
    }
    set_head(m, c, now);
    return 0;
  }
  case CV_CTL_SKY:
    if (!cv_drive_is_sky(m->s->drive)) {
      snprintf(why, cap, "sky rejected: the drive lights the scene with environment maps (a sky drive's sun "
               "and turbidity can be set; yaw works with any drive)");
      return -1;
    }
    for (int k = 0; k < 3; k++)
      if (c->mask >> k & 1) m->sky[k] = c->v[k];
    m->sky_mask |= c->mask;
    m->ovr_sky = 1;
    return 0;
  case CV_CTL_YAW: m->yaw = c->v[0], m->ovr_yaw = 1; return 0;
  case CV_CTL_DRIVE: m->ovr_sky = m->ovr_yaw = 0, m->sky_mask = 0; return 0;
  default: snprintf(why, cap, "unknown control"); return -1;
  }
}

void master_http_controls(master *m) {
  if (!m->con) return;
  const double t0 = cv_service_now();
  cv_console_ctl c;
  cv_console_state *cs = m->con_st;
  while (cv_console_take(m->con, &c)) {
    char txt[120], why[300] = "";
    cv_console_ctl_text(&c, txt, sizeof txt);
    if (apply(m, &c, why, sizeof why) == 0) {
      cs->controls_applied++;
      snprintf(cs->last_control, sizeof cs->last_control, "%s (frame %zu)", txt, m->nframes_done);
    } else {
      cs->controls_rejected++;
      snprintf(cs->last_control, sizeof cs->last_control, "%.150s", why);
      fprintf(stderr, "cave run: console: %s\n", why);
    }
  }
  m->con_ms_frame = (cv_service_now() - t0) * 1e3;
}

double master_http_drive_time(master *m, double raw) {
  if (m->paused && m->nframes_done > 0) m->held_s += raw - m->raw_prev;
  m->raw_prev = raw;
  return raw - m->held_s;
}

void master_http_drive(master *m, cv_drive_state *d) {
  if (m->ovr_yaw) d->yaw_deg = m->yaw;
  if (m->ovr_sky && d->is_sky) {
    if (m->sky_mask & 1) d->sun_elevation_deg = m->sky[0];
    if (m->sky_mask & 2) d->sun_azimuth_deg = m->sky[1];
    if (m->sky_mask & 4) d->turbidity = m->sky[2];
  }
}

/* ---- the state ------------------------------------------------------------------- */

static void rank_rows(master *m, uint32_t f, double now) {
  cv_service *s = m->s;
  cv_console_state *cs = m->con_st;
  const int fps_due = now - m->con_fps_t >= 1.0;
  for (int r = 1; r < cs->n_ranks; r++) {
    cv_console_rank *row = &cs->ranks[r];
    if (m->dead && m->dead[r] && !row->dead) {
      row->dead = 1;
      snprintf(row->error, sizeof row->error, "declared dead at frame %u: silent longer than --gather-timeout %g s", f,
               s->o.gather_timeout_s);
    }
    if (r > s->n_render) continue;
    const cv_output *o = &s->cave.outputs[r - 1];
    int all = 1;
    for (int e = 0; e < 2; e++)
      if (o->eyes >> e & 1) all &= m->got[2 * o->wall + e] != 0;
    if (all) m->con_reports[r]++;
    else {
      row->late++;
      if (!row->dead) snprintf(row->error, sizeof row->error, "report late at frame %u (--timeout-ms %g)", f, s->o.timeout_ms);
    }
    if (m->files_failed && m->files_failed[r - 1])
      snprintf(row->error, sizeof row->error, "%llu written frames' files failed", (unsigned long long)m->files_failed[r - 1]);
    if (fps_due && m->con_fps_t > 0) row->fps = (double)(m->con_reports[r] - m->con_rep0[r]) / (now - m->con_fps_t);
    if (fps_due) m->con_rep0[r] = m->con_reports[r];
  }
  if (fps_due) m->con_fps_t = now;
  if (m->stop_code) snprintf(cs->ranks[0].error, sizeof cs->ranks[0].error, "%.150s", m->stop_reason);
}

static void view_state(master *m, const cv_frame_state *fs) {
  cv_console_state *cs = m->con_st;
  cs->lwa = fs->lwa;
  cs->lwmax = fs->lwmax;
  memcpy(cs->head, fs->head, sizeof cs->head);
  memcpy(cs->gaze, fs->gaze, sizeof cs->gaze);
  snprintf(cs->head_source, sizeof cs->head_source, "%s",
           m->has_tcal ? "dtrack-calibrated" : m->dtr ? "dtrack" : m->path ? "path" : m->desk_source ? "desktop" :
           m->head_console ? "console" : "fixed");
  cs->sky = fs->drive.is_sky;
  cs->yaw_deg = fs->drive.yaw_deg;
  cs->pitch_deg = fs->drive.pitch_deg;
  cs->roll_deg = fs->drive.roll_deg;
  cs->turbidity = fs->drive.turbidity;
  cs->sun_elevation_deg = fs->drive.sun_elevation_deg;
  cs->sun_azimuth_deg = fs->drive.sun_azimuth_deg;
  cs->n_maps = fs->drive.n_maps < 8 ? fs->drive.n_maps : 8;
  memcpy(cs->weights, fs->drive.weights, (size_t)cs->n_maps * sizeof(double));
  cs->override_sky = m->ovr_sky;
  cs->override_yaw = m->ovr_yaw;
  cs->paused = m->paused;
  cs->quitting = m->stop_code != 0 || *m->s->stop;
  cs->drive_time_s = fs->time;
  cs->lcd_rounds = m->lcd_rounds;
  for (int i = 0; i < cs->n_panels; i++) cs->cr[i] = m->lread.valid ? m->lread.p[i].cr.value : NAN;
  cs->cr_min = m->lread.valid ? m->lread.cr_min : NAN;
  snprintf(cs->verdict, sizeof cs->verdict, "%s", m->lcd_mb && m->lcd_verdict ? m->lcd_verdict : "");
  cs->skew_us = m->skew_us;
  cs->mtp_ms = m->mtp_ms;
}

static void totals(master *m, double now) {
  cv_console_state *cs = m->con_st;
  cs->late_reports_total = m->late_reports;
  cs->state_mismatch_total = m->state_mismatch_total;
  uint64_t drop = 0, fail = 0;
  for (int i = 0; i < m->s->n_render; i++) {
    drop += m->files_dropped ? m->files_dropped[i] : 0;
    fail += m->files_failed ? m->files_failed[i] : 0;
  }
  cs->files_dropped_total = drop;
  cs->files_failed_total = fail;
  pthread_mutex_lock(&m->img_mu);
  cs->montages_total = m->montages;
  cs->viewer_rms = m->have_viewer ? m->viewer_rms : NAN;
  cs->viewer_rms_unc = m->have_viewer ? m->viewer_rms_unc : NAN;
  pthread_mutex_unlock(&m->img_mu);
  cs->run_seconds = now - m->frame_t[0];
  if (now - m->con_p99_t >= 1.0 && m->nframes_done > 1) { /* over the last 600 frames, once a second */
    const size_t n = m->nframes_done < m->cap ? m->nframes_done : m->cap;
    const size_t k = n - 1 < CV_CONSOLE_RING ? n - 1 : CV_CONSOLE_RING;
    const double p = 99;
    double q;
    if (cv_percentiles(m->overhead_ms + n - k, k, &p, 1, &q, NULL) == CV_OK) cs->master_s_p99 = q * 1e-3;
    m->con_p99_t = now;
  }
}

void master_http_publish(master *m, const cv_frame_state *fs, double frame_s, double master_s) {
  if (!m->con) return;
  const double t0 = cv_service_now();
  cv_console_state *cs = m->con_st;
  cs->frame = fs->frame;
  cv_console_hist_add(cs, frame_s);
  for (int k = 0; k < m->s->n_walleyes; k++) cs->late_walleyes_total += m->got[k] == 0;
  rank_rows(m, fs->frame, t0);
  view_state(m, fs);
  totals(m, t0);
  cv_console_sample smp;
  memset(&smp, 0, sizeof smp);
  smp.frame = fs->frame;
  smp.t = t0 - m->frame_t[0];
  smp.frame_s = frame_s;
  smp.master_s = master_s;
  smp.skew_s = m->skew_us * 1e-6;
  smp.mtp_s = m->mtp_ms * 1e-3;
  for (int i = 0; i < CV_CONSOLE_PANELS; i++) smp.cr[i] = i < cs->n_panels ? cs->cr[i] : NAN;
  cv_console_publish(m->con, cs, &smp);
  const double ms = m->con_ms_frame + (cv_service_now() - t0) * 1e3;
  if (m->con_n < m->cap) m->con_ms[m->con_n++] = ms;
  m->con_ms_frame = 0;
}

/* ---- images -------------------------------------------------------------------- */

void master_http_montage(master *m, int which, uint32_t frame, cv_image *const *walls) {
  if (!m->con) return;
  const cv_service *s = m->s;
  int ws[CV_CAVE_MAX_WALLS], hs[CV_CAVE_MAX_WALLS], x[CV_CAVE_MAX_WALLS], y[CV_CAVE_MAX_WALLS], W, H;
  for (int w = 0; w < s->n_walls; w++) {
    ws[w] = walls[w] ? walls[w]->w : s->cave.walls[w].res[0];
    hs[w] = walls[w] ? walls[w]->h : s->cave.walls[w].res[1];
  }
  cv_err err;
  if (cv_montage_layout(&s->cave, ws, hs, x, y, &W, &H, &err)) return;
  uint8_t *px = calloc(3 * (size_t)W * H, 1);
  if (!px) return;
  for (int w = 0; w < s->n_walls; w++) {
    const cv_image *im = walls[w];
    if (!im) continue;
    for (int j = 0; j < im->h; j++)
      for (int i = 0; i < im->w; i++)
        for (int c = 0; c < 3; c++)
          px[3 * ((size_t)(y[w] + j) * W + x[w] + i) + c] =
              cv_rec709_code(&m->lut, im->px[((size_t)j * im->w + i) * im->c + c]);
  }
  int mw = 0; /* the wall names, as on the montage files (the page captions frame and variant) */
  for (int w = 0; w < s->n_walls; w++) mw = ws[w] > mw ? ws[w] : mw;
  cv_montage_label_walls(px, W, H, &s->cave, x, y, cv_montage_label_scale(mw));
  cv_console_set_image(m->con, which, frame, W, H, px, 1); /* the image thread: may wait */
  free(px);
}

void master_http_heatmap(master *m, const cv_lcd_readability *rd, uint32_t frame) {
  if (!m->con) return;
  const double now = cv_service_now();
  if (now - m->con_heat_t < 2.0 || rd->w < 1 || rd->h < 1) return;
  m->con_heat_t = now;
  const int bar = rd->h / 8 > 8 ? rd->h / 8 : 8;
  uint8_t *px = malloc(3 * (size_t)rd->w * (rd->h + bar));
  if (!px) return;
  if (cv_lcd_heatmap_rgb(rd, bar, px) == CV_OK)
    cv_console_set_image(m->con, CV_IMG_HEATMAP, frame, rd->w, rd->h + bar, px, 0); /* never waits */
  free(px);
}

/* ---- metrics --------------------------------------------------------------------- */

void master_http_metrics(master *m, cv_metrics_line *ml) {
  if (!m->con) {
    cv_metrics_string(ml, "console", "off");
    return;
  }
  cv_metrics_string(ml, "console", m->con_st->url);
  cv_metrics_bool(ml, "console_token", m->s->o.http_token_path[0] != 0);
}

void master_http_summary(master *m, cv_metrics_line *ml) {
  if (!m->con) return;
  cv_metrics_object_begin(ml, "console");
  cv_metrics_string(ml, "url", m->con_st->url);
  unsigned long long req, unauth, refused;
  cv_http_counts(m->http, &req, &unauth, &refused);
  cv_metrics_uint(ml, "requests", req);
  cv_metrics_uint(ml, "unauthorized", unauth);
  cv_metrics_uint(ml, "refused", refused);
  cv_metrics_uint(ml, "controls_applied", m->con_st->controls_applied);
  cv_metrics_uint(ml, "controls_rejected", m->con_st->controls_rejected);
  cv_metrics_percentiles(ml, "master_thread_ms", m->con_ms, m->con_n);
  cv_metrics_object_end(ml);
}
