/* The master's metrics lines (docs/metrics.md), composed here and written
 * by master_metrics_put (master_out.c): the ready line, one line per frame
 * (every --metrics-every K-th written; the line is composed every frame,
 * since composing it also updates the LCD readability and drive tallies),
 * and the summary. */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "comm.h"
#include "lcdreduce.h"
#include "lcd/gather.h"
#include "master_internal.h"
#include "service.h"

/* This thread's CPU time (ms): with more ranks than cores the wall time of
 * the master's work also holds the time it waited for a core. */
double master_thread_cpu_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

/* The first line: where the master runs, its options, every rank's ready
 * line (lines[1..size-1]). */
void master_metrics_ready(master *m, const char *host, const char *const *lines) {
  cv_service *s = m->s;
  cv_metrics_line *ml = m->ml;
  cv_metrics_begin(ml);
  cv_metrics_string(ml, "type", "ready");
  cv_metrics_string(ml, "master_host", host);
  cv_metrics_string(ml, "clock", m->wall_clock ? "wall" : "sim");
  cv_metrics_bool(ml, "windows", (s->o.present & CV_PRESENT_WINDOW) != 0);
  cv_metrics_bool(ml, "desktop", m->desk != NULL);
  cv_metrics_bool(ml, "swap_lock", s->o.swap_lock);
  cv_metrics_string(ml, "hardware_swap_sync", "none");
  cv_metrics_string(ml, "share_lighting", cv_share_lighting_name(s->o.share_lighting));
  cv_metrics_uint(ml, "metrics_every", (uint64_t)s->o.metrics_every);
  cv_metrics_double(ml, "metrics_max_mb", s->o.metrics_max_mb);
  master_http_metrics(m, ml);
  lcd_ready_metrics(m, ml);
  cv_metrics_object_begin(ml, "ranks");
  for (int r = 1; r < s->size; r++) {
    char k[16];
    snprintf(k, sizeof k, "%d", r);
    cv_metrics_string(ml, k, lines[r] ? lines[r] : "?");
  }
  cv_metrics_object_end(ml);
  master_metrics_put(m);
}

/* The render ranks' lighting steps (CV_TAG_LIGHT) that came so far. */
static void light_drain(master *m) {
  const uint8_t *data;
  int from;
  long len;
  while ((len = cv_mailbox_take(m->light_mb, &data, &from)) >= 0) {
    if (len != (long)sizeof(cv_light_msg) || from < 1 || from > m->s->n_render) continue;
    memcpy(&m->light[from - 1], data, sizeof(cv_light_msg));
    m->light_have[from - 1] = 1;
  }
}

static const char *light_name(uint32_t what) {
  static const char *names[] = {"computed", "led", "imported", "late_leader", "dead_leader", "torn"};
  return what < 6 ? names[what] : "?";
}

/* A rank's lighting step of frame f, in its object of the frame line. */
static void light_metrics(master *m, cv_metrics_line *ml, int rank, uint32_t f) {
  const cv_light_msg *l = &m->light[rank - 1];
  if (!m->light_have[rank - 1] || l->frame != f) return;
  cv_metrics_string(ml, "light", light_name(l->what));
  if (l->what == CV_LIGHT_LED) cv_metrics_bool(ml, "light_prefetched", l->prefetched != 0);
  cv_metrics_double(ml, "light_ms", l->ms);
  cv_metrics_double(ml, "light_cpu_ms", l->cpu_ms);
  cv_metrics_double(ml, "light_wait_ms", l->wait_ms);
  cv_metrics_double(ml, "cpu_s", l->cpu_s);
}

/* Summary: lighting changes per kind, summed over the render ranks. */
static void light_summary(master *m, cv_metrics_line *ml) {
  light_drain(m);
  uint64_t c[6] = {0};
  for (int i = 0; i < m->s->n_render; i++)
    for (int k = 0; k < 6; k++) c[k] += m->light_have[i] ? m->light[i].count[k] : 0;
  cv_metrics_object_begin(ml, "shared_lighting");
  const int mode = m->s->o.share_lighting;
  cv_metrics_string(ml, "mode", cv_share_lighting_name(mode));
  for (int k = 0; k < 6; k++) cv_metrics_uint(ml, light_name((uint32_t)k), c[k]);
  uint64_t p[2] = {0, 0};
  for (int i = 0; i < m->s->n_render; i++)
    for (int k = 0; k < 2; k++) p[k] += m->light_have[i] ? m->light[i].prefetch[k] : 0;
  cv_metrics_uint(ml, "prefetched", p[0]);
  cv_metrics_uint(ml, "prefetch_missed", p[1]);
  cv_metrics_object_end(ml);
}

void master_metrics_frame(master *m, uint32_t f, const cv_frame_state *fs, const cv_lumstats *acc,
                          int late, const frame_times *t, double overhead, double overhead_cpu) {
  cv_service *s = m->s;
  cv_metrics_line *ml = m->ml;
  light_drain(m);
  cv_metrics_begin(ml);
  cv_metrics_string(ml, "type", "frame");
  cv_metrics_uint(ml, "frame", f);
  cv_metrics_double(ml, "t", fs->time);
  cv_metrics_double(ml, "dt", fs->dt);
  cv_metrics_double(ml, "frame_ms", (t->tf1 - t->tf0) * 1e3);
  cv_metrics_double(ml, "master_ms", overhead);
  cv_metrics_double(ml, "master_cpu_ms", overhead_cpu);
  cv_metrics_double(ml, "wait_ms", (t->t_wait - t->t_sent) * 1e3);
  cv_metrics_int(ml, "late_walleyes", late);
  master_health_metrics(m, ml);
  if (s->o.swap_lock && s->o.swap_sync == CV_SWAP_SCHEDULED) {
    cv_metrics_double(ml, "swap_release_wait_ms", m->release_ms);
    cv_metrics_int(ml, "swap_release_late", m->release_late);
  }
  cv_metrics_int(ml, "state_mismatch", m->state_mismatch);
  cv_metrics_object_begin(ml, "adaptation");
  cv_metrics_double(ml, "lwa", fs->lwa);
  cv_metrics_double(ml, "lwmax", fs->lwmax);
  cv_metrics_double(ml, "foveal_lwa", acc->weight > 0 ? exp(acc->sum_log / acc->weight) : 0);
  cv_metrics_double(ml, "foveal_sr", acc->weight);
  cv_metrics_uint(ml, "invalid_pixels", acc->n_invalid);
  cv_metrics_doubles(ml, "state", fs->adapt, 6);
  cv_metrics_object_end(ml);
  cv_metrics_object_begin(ml, "drive");
  cv_metrics_double(ml, "yaw", fs->drive.yaw_deg);
  cv_metrics_doubles(ml, "weights", fs->drive.weights, (size_t)fs->drive.n_maps);
  cv_metrics_bool(ml, "new_light", (fs->flags & CV_FS_NEW_LIGHT) != 0);
  cv_metrics_object_end(ml);
  cv_metrics_object_begin(ml, "tracker");
  cv_metrics_string(ml, "source", m->has_tcal ? "dtrack-calibrated" : m->dtr ? "dtrack" : m->path ? "path" : m->desk_source ? "desktop" : "fixed");
  cv_metrics_doubles(ml, "head", fs->head, 3);
  cv_metrics_doubles(ml, "gaze", fs->gaze, 3);
  cv_metrics_double(ml, "age_s", fs->tracker_age);
  if (m->dtr) {
    cv_metrics_uint(ml, "packets", m->trk.packets);
    cv_metrics_uint(ml, "malformed", m->trk.malformed);
    cv_metrics_uint(ml, "no_body", m->trk.no_body);
    cv_metrics_uint(ml, "held_outside", m->gate.outside); /* implausible poses held (master_sync.c) */
    cv_metrics_uint(ml, "held_too_fast", m->gate.too_fast);
  }
  if (fs->has_eyes) cv_metrics_doubles(ml, "eyes", &fs->eyes[0][0], 6);
  cv_metrics_object_end(ml);
  master_sync_metrics(m, ml);
  master_desktop_metrics(m, ml);
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
    lcd_reduce_metrics(m, ml, "allreduce");
    lcd_readability_update(m);
    lcd_readability_metrics(m, ml, "readability");
    lcd_drive_tally(m, f, fs->time, m->wall_clock ? fs->dt : s->o.dt, (fs->flags & CV_FS_HOLD) != 0);
    cv_metrics_object_end(ml);
  }
  if (m->disp) master_comp_metrics(m, ml, (t->tc1 - t->tc0) * 1e3);
  cv_metrics_object_begin(ml, "ranks");
  for (int k = 0; k < s->n_walleyes; k++) {
    const int rank = cv_cave_walleye_rank(&s->cave, k / 2, k % 2);
    const int packed = s->cave.outputs[rank - 1].eyes == 3;
    char key[24];
    if (packed) snprintf(key, sizeof key, "%d%s", rank, k % 2 ? "R" : "L");
    else snprintf(key, sizeof key, "%d", rank);
    cv_metrics_object_begin(ml, key);
    if (m->got[k]) {
      const cv_walleye_report *r = &m->reps[k];
      cv_metrics_double(ml, "lum_ms", r->ms_lum);
      cv_metrics_double(ml, "depth_ms", r->ms_depth);
      cv_metrics_double(ml, "shade_ms", r->ms_shade);
      cv_metrics_double(ml, "read_ms", r->ms_read);
      cv_metrics_double(ml, "total_ms", r->ms_total);
      cv_metrics_double(ml, "present_ms", r->ms_present);
      cv_metrics_double(ml, "barrier_ms", r->ms_barrier);
      cv_metrics_double(ml, "lcd_ms", r->ms_lcd);
      cv_metrics_uint(ml, "lcd_rounds", r->lcd_rounds_done);
      cv_metrics_uint(ml, "read_bytes", r->bytes_read);
      cv_metrics_uint(ml, "upload_bytes", r->bytes_up);
      cv_metrics_double(ml, "cpu_ms", r->ms_cpu);
      if (r->ms_gpu >= 0) cv_metrics_double(ml, "gpu_ms", r->ms_gpu);
      cv_metrics_double(ml, "corr_wait_ms", r->ms_corr_wait);
      cv_metrics_int(ml, "corr_frame", r->corr_frame == 0xffffffffu ? -1 : (int64_t)r->corr_frame);
      cv_metrics_uint(ml, "late_corr", r->late_corr);
      if (r->files_dropped) cv_metrics_uint(ml, "files_dropped", r->files_dropped);
      if (r->files_failed) cv_metrics_uint(ml, "files_failed", r->files_failed);
      light_metrics(m, ml, rank, f);
    } else {
      cv_metrics_bool(ml, "late", 1);
    }
    cv_metrics_object_end(ml);
  }
  cv_metrics_object_end(ml);
  if (f % (uint32_t)s->o.metrics_every == 0) master_metrics_put(m);
  else cv_metrics_begin(ml); /* composed (the tallies above), not written: --metrics-every */
}

void master_metrics_summary(master *m, uint32_t f, double run_t0) {
  cv_service *s = m->s;
  const int nframes = s->o.frames;
  cv_metrics_line *ml = m->ml;
  cv_metrics_begin(ml);
  cv_metrics_string(ml, "type", "summary");
  cv_metrics_uint(ml, "frames", m->nframes_done);
  cv_metrics_uint(ml, "held_frames", nframes > 0 && f > (uint32_t)nframes ? f - (uint32_t)nframes : 0);
  cv_metrics_bool(ml, "interrupted", *s->stop != 0 || m->stop_code != 0);
  if (m->stop_code) cv_metrics_string(ml, "stop_reason", m->stop_reason);
  cv_metrics_string(ml, "clock", m->wall_clock ? "wall" : "sim");
  cv_metrics_double(ml, "seconds", cv_service_now() - run_t0);
  /* Percentiles without frame 0 (warm-up: every rank's first lighting and
   * the first round trip), when there are later frames. */
  const size_t nall = m->nframes_done < m->cap ? m->nframes_done : m->cap;
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
  if (nd && cv_percentiles(m->overhead_cpu_ms + skip, nd, ps, 3, q, NULL) == CV_OK) {
    cv_metrics_double(ml, "master_cpu_ms_p50", q[0]);
    cv_metrics_double(ml, "master_cpu_ms_p99", q[1]);
    cv_metrics_double(ml, "master_cpu_ms_max", q[2]);
  }
  cv_metrics_double(ml, "master_thread_cpu_s", (master_thread_cpu_ms() - m->run_cpu0_ms) * 1e-3);
  master_sync_summary(m, ml);
  cv_metrics_uint(ml, "late_reports", m->late_reports);
  cv_metrics_uint(ml, "master_stalls", m->stalls);
  cv_metrics_double(ml, "master_stalled_s", m->stalled_s);
  master_path_summary(m, ml);
  light_summary(m, ml);
  master_health_metrics(m, ml);
  cv_metrics_uint(ml, "state_mismatch", m->state_mismatch_total);
  cv_metrics_uint(ml, "montages", m->montages);
  master_desktop_summary(m, ml);
  master_http_summary(m, ml);
  pthread_mutex_lock(&m->img_mu); /* the image thread has ended its jobs (drained above) */
  if (m->have_viewer) {
    cv_metrics_double(ml, "viewer_rms", m->viewer_rms);
    cv_metrics_double(ml, "viewer_rms_uncompensated", m->viewer_rms_unc);
  }
  pthread_mutex_unlock(&m->img_mu);
  if (m->lcd_mb) {
    cv_metrics_uint(ml, "lcd_rounds", m->lcd_rounds);
    cv_metrics_uint(ml, "lcd_spp", (uint64_t)m->lcd_rounds * (uint64_t)s->o.lcd_spp);
    if (m->prog.acc) {
      cv_lcd_error le;
      if (cv_lcd_accum_error(m->prog.acc, &le) == CV_OK) cv_metrics_double(ml, "lcd_rel_rms", le.rel_rms);
    }
    lcd_reduce_metrics(m, ml, "lcd_allreduce");
    lcd_readability_update(m);
    lcd_readability_metrics(m, ml, "lcd_readability");
    lcd_drive_summary(m, ml, "lcd_drive");
  }
  cv_metrics_uint(ml, "metrics_rotations", m->metrics_rotations);
  cv_metrics_uint(ml, "nonfinite_metrics", cv_metrics_nonfinite(ml));
  master_metrics_put(m);
}
