/* The master's view of time across the cluster (issue 11, swap lock and
 * real-time clock):
 *   - clock probes: every render rank's clock offset to the master, NTP
 *     style (service/clocksync.h), at start and every 0.25 s, answered from
 *     the ranks' idle loops; the smallest-round-trip sample of the last 10 s;
 *   - swap skew: each report carries the rank's previous swap time; mapped
 *     to the master's clock, max - min over the render ranks is the frame's
 *     swap skew (microseconds), reported with the offset uncertainty that
 *     bounds its error;
 *   - latency: tracker age at swap = last swap - the pose's sample time;
 *     motion-to-photon estimate = that + one refresh period (vsync: the
 *     frame is scanned out during the next refresh, 1 / the config's rate);
 *   - head prediction (wall clock): constant velocity from the last two
 *     tracker samples to the expected scan-out (the running mean of the
 *     measured pose-to-scan-out time), at most --predict-horizon ahead; with
 *     a recorded head path (a tracker whose truth is known) the error of the
 *     predicted and of the held pose at scan-out is measured;
 *   - stop requests: a render rank whose window was closed, got Escape or
 *     lost its X connection, and the same from the desktop preview window
 *     (master_desktop.c). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "comm.h"
#include "master_internal.h"
#include "render/window.h"

int master_sync_setup(master *m, cv_err *err) {
  const int nr = m->s->n_render;
  const size_t cap = m->cap;
  m->clk = calloc((size_t)nr, sizeof *m->clk);
  m->last_ping = calloc((size_t)nr, sizeof *m->last_ping);
  m->skew_hist = calloc(cap, sizeof(double));
  m->mtp_hist = calloc(cap, sizeof(double));
  m->age_hist = calloc(cap, sizeof(double));
  m->pred_hist = calloc(cap, sizeof(double));
  m->held_hist = calloc(cap, sizeof(double));
  m->pong_mb = cv_mailbox_open(-1, CV_TAG_PONG, 3 * sizeof(double));
  m->stop_mb = cv_mailbox_open(-1, CV_TAG_STOPREQ, 512);
  m->ready_mb = cv_mailbox_open(-1, CV_TAG_SWAPREADY, sizeof(double));
  m->swap_ready = calloc((size_t)nr, 1);
  if (!m->clk || !m->last_ping || !m->skew_hist || !m->mtp_hist || !m->age_hist || !m->pred_hist ||
      !m->held_hist || !m->pong_mb || !m->stop_mb || !m->ready_mb || !m->swap_ready)
    return cv_err_set(err, CV_ERR_NOMEM, "master: out of memory");
  for (int i = 0; i < nr; i++) cv_clock_est_init(&m->clk[i], 10.0);
  m->skew_us = m->mtp_ms = m->age_ms = m->pred_err_mm = m->held_err_mm = NAN;
  return CV_OK;
}

void master_sync_free(master *m) {
  free(m->clk);
  free(m->last_ping);
  free(m->skew_hist);
  free(m->mtp_hist);
  free(m->age_hist);
  free(m->pred_hist);
  free(m->held_hist);
  cv_mailbox_close(m->pong_mb);
  cv_mailbox_close(m->stop_mb);
  cv_mailbox_close(m->ready_mb);
  free(m->swap_ready);
}

static void take_pongs(master *m);

void master_release_swaps(master *m, uint32_t f) {
  cv_service *s = m->s;
  m->release_ms = 0;
  m->release_late = 0;
  if (!s->o.swap_lock || s->o.swap_sync != CV_SWAP_SCHEDULED) return;
  const int nr = s->n_render;
  memset(m->swap_ready, 0, (size_t)nr);
  int n = 0;
  const double t0 = cv_service_now(), deadline = t0 + s->o.timeout_ms * 1e-3;
  while (n < nr) {
    const uint8_t *data;
    int from;
    long len;
    while ((len = cv_mailbox_take(m->ready_mb, &data, &from)) >= 0) {
      double fr;
      if (len != sizeof fr || from < 1 || from > nr) continue;
      memcpy(&fr, data, sizeof fr);
      if ((uint32_t)fr == f && !m->swap_ready[from - 1]) {
        m->swap_ready[from - 1] = 1;
        n++;
      }
    }
    if (n == nr || *s->stop || cv_service_now() > deadline) break;
    take_pongs(m);
    lcd_drain(m);
    cv_comm_progress();
    struct timespec ts = {0, 50000};
    nanosleep(&ts, NULL);
  }
  m->release_late = nr - n;
  /* One instant for all, in each rank's clock; a rank that is late gets it
   * too and swaps as soon as it is ready. */
  const double go = cv_service_now() + s->o.swap_margin_ms * 1e-3;
  for (int i = 0; i < nr; i++) {
    double off = 0, u;
    cv_clock_est_get(&m->clk[i], go, &off, &u);
    const double msg[2] = {(double)f, go + off};
    cv_comm_send(msg, sizeof msg, i + 1, CV_TAG_GO);
  }
  m->release_ms = (cv_service_now() - t0) * 1e3;
}

static void take_pongs(master *m) {
  const uint8_t *data;
  int from;
  long len;
  while ((len = cv_mailbox_take(m->pong_mb, &data, &from)) >= 0) {
    const double t3 = cv_service_now();
    if (len != 3 * sizeof(double) || from < 1 || from > m->s->n_render) continue;
    double v[3];
    memcpy(v, data, sizeof v);
    cv_clock_sample smp = {v[0], v[1], v[2], t3};
    cv_clock_est_add(&m->clk[from - 1], &smp);
    master_health_seen(m, from); /* alive (waiting, e.g. in the swap barrier for a dead one) */
  }
}

static void ping(master *m, int i) {
  const double t0 = cv_service_now();
  cv_comm_send(&t0, sizeof t0, i + 1, CV_TAG_PING);
  m->last_ping[i] = t0;
}

void master_sync_initial(master *m, int rounds) {
  for (int k = 0; k < rounds; k++)
    for (int i = 0; i < m->s->n_render; i++) {
      const int before = m->clk[i].n;
      ping(m, i);
      for (const double t0 = cv_service_now(); m->clk[i].n == before && cv_service_now() - t0 < 0.5;) {
        take_pongs(m);
        cv_comm_progress();
      }
    }
}

void master_sync_poll(master *m) {
  const double now = cv_service_now();
  for (int i = 0; i < m->s->n_render; i++)
    if (now - m->last_ping[i] > 0.25) ping(m, i);
  take_pongs(m);
}

int master_stop_poll(master *m) {
  /* the desktop window's events at most every 5 ms here (the frame's head
   * reads them at once, master_head) */
  const double now = cv_service_now();
  if (m->desk && now - m->desk_polled >= 0.005) master_desktop_poll(m, now);
  const uint8_t *data;
  long len;
  while ((len = cv_mailbox_take(m->stop_mb, &data, NULL)) > 1) {
    if (m->stop_code) continue;
    if (data[0] == 'S' && *m->s->stop) continue; /* the whole job was signalled: not one rank's stop */
    const int code = data[0] - '0';
    m->stop_code = data[0] == 'S' ? MASTER_STOP_SIGNAL
                   : code >= CV_WIN_CLOSED && code <= CV_WIN_LOST ? code : CV_WIN_CLOSED;
    snprintf(m->stop_reason, sizeof m->stop_reason, "%.*s", (int)(len - 2), (const char *)data + 2);
    fprintf(stderr, "cave run: stopping: %s\n", m->stop_reason);
  }
  return m->stop_code != 0;
}

void master_pose_record(master *m, uint32_t f, double t_sample, double t_target, const double pos[3]) {
  pose_rec *p = &m->poses[f % POSE_RING];
  p->frame = f;
  p->valid = 1;
  p->t_sample = t_sample;
  p->t_target = t_target;
  memcpy(p->pos, pos, sizeof p->pos);
}

static double dist_mm(const double a[3], const double b[3]) {
  return 1e3 * sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

void master_swap_stats(master *m, uint32_t f) {
  m->skew_us = m->mtp_ms = m->age_ms = m->pred_err_mm = m->held_err_mm = NAN;
  if (f == 0) return;
  const uint32_t pf = f - 1;
  double lo = INFINITY, hi = -INFINITY, unc = 0;
  int n = 0;
  const double now = cv_service_now();
  /* One swap per render rank: the report of its first eye. */
  for (int i = 0; i < m->s->n_render; i++) {
    const cv_output *o = &m->s->cave.outputs[i];
    const int e = (o->eyes & 1) ? 0 : 1;
    const int k = 2 * o->wall + e;
    if (!m->got[k] || m->reps[k].swap_frame != pf) continue;
    double off, u;
    if (!cv_clock_est_get(&m->clk[i], now, &off, &u)) continue;
    const double t = m->reps[k].swap_t - off;
    lo = fmin(lo, t);
    hi = fmax(hi, t);
    unc = fmax(unc, u);
    n++;
  }
  m->offset_unc_max = unc;
  if (n < m->s->n_render) return; /* a rank late or without an offset: not measured */
  m->skew_us = (hi - lo) * 1e6;
  if (m->n_skew < m->cap) m->skew_hist[m->n_skew++] = m->skew_us;
  const pose_rec *p = &m->poses[pf % POSE_RING];
  if (!p->valid || p->frame != pf) return;
  m->age_ms = (hi - p->t_sample) * 1e3;
  const double scanout = 1.0 / m->s->cave.rate;
  m->mtp_ms = m->age_ms + scanout * 1e3;
  if (m->n_lat < m->cap) {
    m->age_hist[m->n_lat] = m->age_ms;
    m->mtp_hist[m->n_lat++] = m->mtp_ms;
  }
  /* the expected pose -> scan-out time, for the next predictions */
  const double lat = hi + scanout - p->t_sample;
  m->latency_est = m->latency_est > 0 ? 0.8 * m->latency_est + 0.2 * lat : lat;
  if (m->path && m->wall_clock) {
    /* the truth at scan-out, from the path the "tracker" replays */
    cv_head_pose truth, held;
    cv_head_path_eval(m->path, hi + scanout - m->t_start, 1, &truth);
    cv_head_path_eval(m->path, p->t_sample - m->t_start, 1, &held);
    m->pred_err_mm = dist_mm(p->pos, truth.pos);
    m->held_err_mm = dist_mm(held.pos, truth.pos);
    if (m->n_pred < m->cap) {
      m->pred_hist[m->n_pred] = m->pred_err_mm;
      m->held_hist[m->n_pred++] = m->held_err_mm;
    }
  }
}

/* A DTrack pose outside the config's tracking volume or faster than
 * max_head_speed is held (issue 35, defect 8): counted (tracker.held_*),
 * said on stderr at most every 5 s.  0 when held. */
static int pose_plausible(master *m, const double pos[3], double now) {
  const cv_cave *c = &m->s->cave;
  if (!m->gate_on) {
    cv_pose_gate_init(&m->gate, c->track_lo, c->track_hi, c->max_head_speed);
    m->gate_on = 1;
  }
  double v = 0;
  const int why = cv_pose_gate_check(&m->gate, pos, now, &v);
  if (why == CV_POSE_OK) return 1;
  if (now - m->gate_warn_t >= 5.0) {
    const uint64_t held = m->gate.outside + m->gate.too_fast;
    m->gate_warn_t = now;
    if (why == CV_POSE_OUTSIDE)
      fprintf(stderr, "cave run: master: tracked head (%.2f, %.2f, %.2f) m outside the tracking volume "
              "[%.2f..%.2f, %.2f..%.2f, %.2f..%.2f]: held at the last good pose (%llu held since the last "
              "warning; tracker.held_outside)\n", pos[0], pos[1], pos[2], c->track_lo[0], c->track_hi[0],
              c->track_lo[1], c->track_hi[1], c->track_lo[2], c->track_hi[2],
              (unsigned long long)(held - m->gate_warned));
    else
      fprintf(stderr, "cave run: master: tracked head jumped to (%.2f, %.2f, %.2f) m at %.3g m/s, faster "
              "than max_head_speed %g m/s: held at the last good pose (%llu held since the last warning; "
              "tracker.held_too_fast)\n", pos[0], pos[1], pos[2], v, c->max_head_speed,
              (unsigned long long)(held - m->gate_warned));
    m->gate_warned = held;
  }
  return 0;
}

void master_head(master *m, double now, double frame_time, double head[3], double gaze[3],
                 double *t_sample, double *t_target) {
  cv_service *s = m->s;
  if (m->dtr) {
    cv_head_pose p = m->pose;
    cv_dtrack_frame fr;
    cv_tracked_head th;
    int got = cv_dtrack_receiver_poll_frame(m->dtr, now, &p, &fr, &m->trk);
    if (got == 1 && m->has_tcal) { /* calibrated: the eyes' midpoint and gaze, CAVE frame */
      if (cv_tracker_head(&m->tcal, &fr, &th) == CV_OK) {
        memcpy(p.pos, th.center, sizeof p.pos);
        memcpy(p.gaze, th.gaze, sizeof p.gaze);
        for (int e = 0; e < 2; e++)
          for (int k = 0; k < 3; k++) m->eye_rel[e][k] = th.eye[e][k] - th.center[k];
        m->have_eyes = 1;
      } else {
        got = 0;
      }
    }
    if (got == 1 && !pose_plausible(m, p.pos, now)) got = 0; /* the last good pose is kept */
    if (got == 1) {
      m->prev_pose = m->pose;
      m->prev_pose_time = m->pose_time;
      m->pose = p;
      m->pose_time = now;
    }
  } else if (m->desk_source) {
    /* keyboard and mouse: m->pose moves as their events are taken */
    master_desktop_poll(m, now);
  } else if (m->path) {
    /* a recorded path stands in for a tracker sampled now (wall clock) or
     * at the frame's simulated time */
    m->prev_pose = m->pose;
    m->prev_pose_time = m->pose_time;
    cv_head_path_eval(m->path, frame_time, 1, &m->pose);
    m->pose_time = now;
  }
  *t_sample = m->pose_time > 0 ? m->pose_time : now;
  *t_target = *t_sample;
  memcpy(head, m->pose.pos, 3 * sizeof *head);
  memcpy(gaze, m->pose.gaze, 3 * sizeof *gaze);
  /* key steps and drags are jumps, not motion: never extrapolated */
  if (m->wall_clock && s->o.predict && !m->desk_source && m->prev_pose_time > 0 && m->latency_est > 0) {
    *t_target = now + m->latency_est;
    cv_head_predict(m->prev_pose.pos, m->prev_pose.gaze, m->prev_pose_time, m->pose.pos, m->pose.gaze,
                    m->pose_time, *t_target, s->o.predict_horizon, head, gaze);
  }
}

void master_sync_metrics(master *m, cv_metrics_line *ml) {
  cv_metrics_object_begin(ml, "sync");
  if (isfinite(m->skew_us)) cv_metrics_double(ml, "swap_skew_us", m->skew_us);
  cv_metrics_double(ml, "offset_uncertainty_us", m->offset_unc_max * 1e6);
  if (isfinite(m->age_ms)) cv_metrics_double(ml, "tracker_age_at_swap_ms", m->age_ms);
  if (isfinite(m->mtp_ms)) cv_metrics_double(ml, "motion_to_photon_ms", m->mtp_ms);
  if (isfinite(m->pred_err_mm)) {
    cv_metrics_double(ml, "prediction_error_mm", m->pred_err_mm);
    cv_metrics_double(ml, "held_pose_error_mm", m->held_err_mm);
  }
  cv_metrics_object_end(ml);
}

void master_sync_summary(master *m, cv_metrics_line *ml) {
  cv_metrics_uint(ml, "swap_skew_frames", m->n_skew);
  cv_metrics_percentiles(ml, "swap_skew_us", m->skew_hist, m->n_skew);
  double unc = 0, now = cv_service_now();
  for (int i = 0; i < m->s->n_render; i++) {
    double o, u;
    if (cv_clock_est_get(&m->clk[i], now, &o, &u)) unc = fmax(unc, u);
  }
  cv_metrics_double(ml, "offset_uncertainty_us", unc * 1e6);
  cv_metrics_percentiles(ml, "tracker_age_at_swap_ms", m->age_hist, m->n_lat);
  cv_metrics_percentiles(ml, "motion_to_photon_ms", m->mtp_hist, m->n_lat);
  cv_metrics_percentiles(ml, "prediction_error_mm", m->pred_hist, m->n_pred);
  cv_metrics_percentiles(ml, "held_pose_error_mm", m->held_hist, m->n_pred);
}
