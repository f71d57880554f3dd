/* Rank 0, the master: every frame, as named phases (cv_master_run),
 *   frame_clock      the frame's time: fixed --dt steps (--clock sim) or the
 *                    real time since the first frame (--clock wall);
 *   frame_lighting   the scripted drive (car pose, lighting) at that time,
 *                    projected into SH when its key changes;
 *   master_head      the tracked head, predicted to the expected scan-out
 *                    on the wall clock (master_sync.c);
 *   frame_adaptation the adaptation model on the previous frame's foveal
 *                    statistics;
 *   frame_lcd_key    the LCD image's camera/lighting key;
 *   send_state       one fixed-layout frame state to every rank;
 *   collect_reports  the render ranks' reports and patch images until all
 *                    arrived or the deadline, while clock probes, LCD rounds,
 *                    montages, desktop preview images and input, and stop
 *                    requests are served;
 *   master_swap_stats swap skew and latency of the previous frame;
 *   compensate_frame the scattering compensation, each wall its correction;
 *   master_metrics_frame (master_metrics.c), pace.
 *
 * Adaptation latency: the frame state carries the adaptation computed from
 * the previous frame's luminance images, so a frame needs one round trip to
 * the master instead of two.  One frame (33 ms) is small against the
 * neural time constants (80 ms cones, 150 ms rods).  Frame 0 starts from the
 * CAVE's first luminance: before frame 0 a priming round (CV_FS_MEASURE,
 * master_prime_adaptation) has every wall-eye render frame 0's luminance
 * passes and report their foveal statistics only, and the state is
 * initialised in steady state at that luminance, so frame 0 is tone-mapped
 * for its own light instead of 1 cd/m2. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "comm.h"
#include "lcdreduce.h"
#include "core/hash.h"
#include "lcd/gather.h"
#include "lcd/lcd_config.h"
#include "master_internal.h"
#include "render/window.h"
#include "service.h"

static size_t walleye_msg_cap(const master *m, int wall) {
  if (!m->disp) return CV_WALLEYE_REPORT_BYTES + sizeof(cv_patch_msg);
  const cv_display_surface *S = cv_display_surface_at(m->disp, (size_t)wall);
  return CV_WALLEYE_REPORT_BYTES + sizeof(cv_patch_msg) + 3 * (size_t)S->nu * S->nv * sizeof(float);
}

static void master_free(master *m) {
  master_comp_free(m); /* first: its thread uses the workspace */
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
  cv_lcd_reduce_destroy(m->lcd_red);
  master_health_free(m);
  cv_lcd_progress_free(&m->prog);
  free(m->seen);
  cv_lcd_progress_free(&m->mot.prog);
  free(m->mot.seen);
  cv_image_destroy(m->lcd_content);
  if (m->rep_mb)
    for (int k = 0; k < m->s->n_render; k++) cv_mailbox_close(m->rep_mb[k]);
  free(m->rep_mb);
  cv_mailbox_close(m->light_mb);
  free(m->light);
  free(m->light_have);
  free(m->reps);
  free(m->got);
  master_sync_free(m);
  master_images_free(m);
  master_http_free(m); /* after the image thread, which hands it the montages */
  master_desktop_free(m);
  if (m->mf) fclose(m->mf);
  cv_metrics_line_destroy(m->ml);
  free(m->frame_ms);
  free(m->frame_t);
  free(m->frame_sim_t);
  free(m->overhead_ms);
  free(m->overhead_cpu_ms);
}

/* ---- set-up -------------------------------------------------------------- */

static int master_setup(master *m, cv_err *err) {
  cv_service *s = m->s;
  m->wall_clock = s->o.clock == 1;
  /* SH bands of the scene (the wall-eyes relight with them). */
  cv_prt *prt;
  int st = cv_prt_read(s->o.scene_path, &prt, err);
  if (st) return st;
  m->bands = (int)prt->bands;
  m->prt_hash = prt->meta.file_hash;
  cv_mesh *pm = NULL;
  cv_lcd_panel pn;
  if (!cv_prt_to_mesh(prt, &pm) && !cv_lcd_panel_from_mesh(pm, &pn, NULL))
    m->lcd_aspect = (double)pn.size[0] / pn.size[1]; /* content placed without stretch */
  cv_mesh_destroy(pm);
  cv_prt_destroy(prt);
  st = cv_service_lightmix(s, m->bands, &m->mix, err);
  if (st) return st;
  if (s->o.head_path[0]) {
    st = cv_head_path_load(s->o.head_path, &m->path, err);
    if (st) return st;
  }
  if (s->o.tracker_path[0]) {
    if ((st = cv_tracker_config_load(s->o.tracker_path, &m->tcal, err))) return st;
    if ((st = cv_tracker_open(&m->tcal, -1, &m->dtr, err))) return st;
    m->has_tcal = 1;
  } else if (s->o.dtrack_port > 0) {
    st = cv_dtrack_receiver_open(s->o.dtrack_host, s->o.dtrack_port, s->o.dtrack_body, &m->dtr, err);
    if (st) return st;
  }
  memcpy(m->pose.pos, s->cave.head, sizeof m->pose.pos);
  memcpy(m->pose.gaze, s->cave.gaze, sizeof m->pose.gaze);
  m->pose.valid = 1;
  if ((st = master_desktop_setup(m, err))) return st;
  cv_adapt_default_params(&m->ap);
  m->ap.t0_cone = s->cave.t0_cone;
  m->ap.t0_rod = s->cave.t0_rod;
  m->ap.tau_cone = s->cave.tau_cone;
  m->ap.tau_rod = s->cave.tau_rod;
  if (s->o.compensate && (st = master_comp_setup(m, err))) return st;
  /* Mailboxes of the render ranks (reports + patch images, one per eye). */
  m->rep_mb = calloc((size_t)s->n_render, sizeof *m->rep_mb);
  m->reps = calloc((size_t)s->n_walleyes, sizeof *m->reps);
  m->got = calloc((size_t)s->n_walleyes, sizeof *m->got);
  m->light = calloc((size_t)s->n_render, sizeof *m->light);
  m->light_have = calloc((size_t)s->n_render, 1);
  m->light_mb = cv_mailbox_open(-1, CV_TAG_LIGHT, sizeof(cv_light_msg));
  if (!m->rep_mb || !m->reps || !m->got || !m->light || !m->light_have || !m->light_mb)
    return cv_err_set(err, CV_ERR_NOMEM, "master: out of memory");
  for (int i = 0; i < s->n_render; i++) {
    m->rep_mb[i] = cv_mailbox_open(i + 1, CV_TAG_REPORT, walleye_msg_cap(m, s->cave.outputs[i].wall));
    if (!m->rep_mb[i]) return cv_err_set(err, CV_ERR_NOMEM, "master: cannot post receives");
  }
  if ((st = master_images_setup(m, err))) return st;
  if (master_health_setup(m)) return cv_err_set(err, CV_ERR_NOMEM, "master: out of memory (heartbeats)");
  if (s->o.lcd && s->n_contributors > 0) {
    size_t n = cv_lcd_accum_words(s->o.lcd_w, s->o.lcd_h);
    m->lcd_mb = cv_mailbox_open(-1, CV_TAG_LCD, sizeof(cv_lcd_msg) + n * sizeof(int64_t));
    m->seen = calloc((size_t)s->o.lcd_budget, 1);
    m->mot.seen = calloc((size_t)s->o.lcd_budget, 1);
    if (!m->lcd_mb || !m->seen || !m->mot.seen) return cv_err_set(err, CV_ERR_NOMEM, "master: out of memory");
    if (s->lcd_me == 0 && s->lcd_members >= 2 &&
        cv_lcd_reduce_create(s->o.lcd_w, s->o.lcd_h, s->o.lcd_budget, s->n_contributors,
                             s->lcd_members, 0, &m->lcd_red))
      return cv_err_set(err, CV_ERR_NOMEM, "master: out of memory (LCD reduction)");
    /* every panel's content at its white and black, stacked (lcd/panels.h) */
    st = cv_lcd_layout_content(&s->lcd, &s->lcd_layout, &m->lcd_content, err);
    if (st) return st;
  }
  m->cap = s->o.frames > 0 ? (size_t)s->o.frames + 64 : 1u << 16;
  m->frame_ms = calloc(m->cap, sizeof *m->frame_ms);
  m->frame_t = calloc(m->cap, sizeof *m->frame_t);
  m->frame_sim_t = calloc(m->cap, sizeof *m->frame_sim_t);
  m->overhead_ms = calloc(m->cap, sizeof *m->overhead_ms);
  m->overhead_cpu_ms = calloc(m->cap, sizeof *m->overhead_cpu_ms);
  if (!m->frame_ms || !m->overhead_ms || !m->overhead_cpu_ms || !m->frame_t || !m->frame_sim_t) return cv_err_set(err, CV_ERR_NOMEM, "master: out of memory");
  if ((st = master_sync_setup(m, err))) return st;
  if ((st = master_http_setup(m, err))) return st; /* a port in use stops the start-up */
  /* Metrics. */
  if ((st = master_out_open(m, err))) return st;
  if (cv_metrics_line_create(&m->ml)) return cv_err_set(err, CV_ERR_NOMEM, "metrics: out of memory");
  return CV_OK;
}

/* Every rank reports its set-up (where it runs, its GL renderer) or why it
 * failed; the master prints the ready table and writes it as the first
 * metrics line.  Returns 0 when all are ready. */
static int wait_ready(master *m, int setup_rc, const cv_err *setup_err, char *why, size_t cap) {
  cv_service *s = m->s;
  int fail = 0;
  if (setup_rc) {
    fail = 1;
    snprintf(why, cap, "rank 0 (master): %s", setup_err->msg);
  }
  char **lines = calloc((size_t)s->size, sizeof *lines);
  cv_mailbox *rb = cv_mailbox_open(-1, CV_TAG_READY, 2048);
  int ready = 0;
  const double t0 = cv_service_now();
  while (rb && lines && ready < s->size - 1) {
    const uint8_t *data;
    int from;
    long len = cv_mailbox_take(rb, &data, &from);
    if (len > 0) {
      ready++;
      const int tl = len > 9 ? (int)(len - 9) : 0; /* flag, .prt hash, text */
      master_prt_check(m, from, data, len);
      if (from > 0 && from < s->size && !lines[from]) {
        lines[from] = malloc((size_t)tl + 1);
        if (lines[from]) snprintf(lines[from], (size_t)tl + 1, "%.*s", tl, (const char *)data + 9);
        master_health_host(m, from, lines[from]);
      }
      if (data[0] != 'O' && !fail) {
        fail = 1;
        snprintf(why, cap, "%.*s", tl, (const char *)data + 9);
      }
      continue;
    }
    cv_comm_progress();
    if (*s->stop) break;
    if (cv_service_now() - t0 > s->o.startup_timeout_s) {
      fail = 1;
      snprintf(why, cap, "only %d of %d ranks were ready after %.0f s", ready, s->size - 1, s->o.startup_timeout_s);
      break;
    }
  }
  cv_mailbox_close(rb);
  if (!fail) fail = master_prt_mismatch(m, why, cap);
  if (!fail && lines) {
    char host[128];
    cv_comm_host(host, sizeof host);
    if (!s->o.quiet) {
      printf("cave run: ready: %d ranks; rank 0 on %s: master", s->size, host);
      if (m->desk)
        printf(", desktop preview %dx%d (window %dx%d) on X display '%s'%s", m->desk_w, m->desk_h,
               m->desk_win_k * m->desk_w, m->desk_win_k * m->desk_h,
               cv_desktop_display_name(m->desk), m->desk_source ? ", keyboard and mouse steer the head" : "");
      printf("\n");
      for (int r = 1; r < s->size; r++) printf("cave run: ready: %s\n", lines[r] ? lines[r] : "?");
    }
    master_http_ready(m, lines);
    master_metrics_ready(m, host, (const char *const *)lines);
    fflush(stdout);
  }
  for (int r = 0; lines && r < s->size; r++) free(lines[r]);
  free(lines);
  return fail;
}

/* ---- phases of a frame ------------------------------------------------------ */

static void quit_all(master *m, uint32_t f) {
  cv_frame_state fs;
  uint8_t buf[CV_FRAME_STATE_BYTES];
  memset(&fs, 0, sizeof fs);
  fs.frame = f;
  fs.flags = CV_FS_QUIT;
  if (cv_frame_state_pack(&fs, buf) == CV_OK)
    for (int r = 1; r < m->s->size; r++) cv_comm_send(buf, sizeof buf, r, CV_TAG_STATE);
}

/* The frame's time: simulated steps, or the real time since the first frame. */
static void frame_clock(master *m, uint32_t f, int holding, double *prev_t, cv_frame_state *fs) {
  const cv_service *s = m->s;
  const int nframes = s->o.frames;
  /* the console's pause holds the drive's clock (master_http.c) */
  if (m->wall_clock) {
    const double now = cv_service_now();
    if (f == 0) m->t_start = now;
    fs->time = holding ? *prev_t : master_http_drive_time(m, now - m->t_start);
    fs->dt = f ? fs->time - *prev_t : 0;
  } else {
    fs->dt = holding || m->paused ? 0 : s->o.dt;
    fs->time = holding ? ((uint32_t)nframes - 1) * s->o.dt : master_http_drive_time(m, f * s->o.dt);
  }
  *prev_t = fs->time;
  if (f < m->cap) m->frame_sim_t[f] = fs->time; /* the montages' captions */
}

static void frame_lighting(master *m, cv_frame_state *fs) {
  cv_service *s = m->s;
  cv_drive_eval(s->drive, fs->time, &fs->drive);
  master_http_drive(m, &fs->drive); /* the console's sky and heading, when it set them */
  cv_service_quantise_drive(&fs->drive);
  const uint64_t lk = cv_service_light_key(&fs->drive);
  if (!m->have_light || lk != m->light_key) {
    cv_lighting nl;
    cv_err err;
    if (cv_service_lighting(s, m->mix, &fs->drive, m->bands, &nl, 0, NULL, &err) == CV_OK) {
      m->lighting = nl;
      m->light_key = lk;
      m->have_light = 1;
      fs->flags |= CV_FS_NEW_LIGHT;
    } else {
      fprintf(stderr, "cave run: lighting: %s (keeping the previous lighting)\n", err.msg);
    }
  }
  fs->light_key = m->light_key;
  fs->bands = m->lighting.bands;
  memcpy(fs->sh, m->lighting.sh, sizeof fs->sh);
  fs->has_sun = m->lighting.has_sun;
  memcpy(fs->sun_dir, m->lighting.sun_dir, sizeof fs->sun_dir);
  memcpy(fs->sun_E, m->lighting.sun_E, sizeof fs->sun_E);
}

/* The adaptation of the frame: the policy cave render shares
 * (cv_adapt_feed_frame), the target being the foveal log-average of the
 * last reports (the priming round's for frame 0). */
static void frame_adaptation(master *m, uint32_t f, cv_frame_state *fs) {
  double lwa_f = 0;
  const int have_g = m->have_stats && cv_lumstats_lwa(&m->stats, &lwa_f) == 1;
  cv_adapt_feed_frame(&m->adf, &m->ap, f ? fs->dt : 0, have_g, lwa_f);
  const cv_adapt_state *ad = &m->adf.s;
  fs->lwa = cv_adapt_lwa(ad); /* 1 cd/m2 until the first target */
  fs->lwmax = m->lwmax > 0 ? m->lwmax : 100 * fs->lwa;
  fs->adapt[0] = ad->a_cone;
  fs->adapt[1] = ad->a_rod;
  fs->adapt[2] = ad->b_cone;
  fs->adapt[3] = ad->b_rod;
  fs->adapt[4] = ad->time;
  fs->adapt[5] = ad->initialised;
}

/* LCD key: quantised eye (car frame) and lighting. */
static void frame_lcd_key(master *m, cv_frame_state *fs) {
  if (!m->lcd_mb) return;
  cv_service *s = m->s;
  float eye[3];
  for (int a = 0; a < 3; a++) eye[a] = (float)(fs->head[a] + s->cave.scene_offset[a]);
  cv_lcd_key k;
  if (cv_lcd_key_make(eye, s->o.lcd_tolerance, m->light_key, 0, &k) == CV_OK) {
    const uint64_t key = cv_service_lcd_key(k.eye_q, m->light_key);
    if (key != m->lcd_key) {
      lcd_key_change(m, key, fs->frame);
      memcpy(m->lcd_eye_q, k.eye_q, sizeof k.eye_q);
    }
  }
  fs->lcd_key = m->lcd_key;
  fs->lcd_rounds = m->lcd_rounds;
  fs->lcd_dead = master_health_lcd_dead(m); /* their rounds shared (docs/dead-rank.md) */
  fs->lcd_dead_floor = master_health_lcd_floor(m);
}

static int send_state(master *m, const cv_frame_state *fs) {
  uint8_t buf[CV_FRAME_STATE_BYTES];
  if (cv_frame_state_pack(fs, buf)) return -1;
  int dests[1024];
  const int n = m->s->size - 1 < 1024 ? m->s->size - 1 : 1024;
  for (int r = 1; r <= n; r++) dests[r - 1] = r;
  cv_comm_send_multi(buf, sizeof buf, dests, n, CV_TAG_STATE);
  if (m->health_armed) master_health_sent(m);
  m->sent_hash = cv_hash64(buf, sizeof buf);
  m->state_mismatch = 0;
  return 0;
}

static void merge_report(master *m, int from, const uint8_t *data, long len, uint32_t frame,
                         cv_lumstats *acc, double *lwmax, int *ngot) {
  cv_walleye_report rep;
  cv_err err;
  if (len < (long)CV_WALLEYE_REPORT_BYTES ||
      cv_walleye_report_unpack(data, CV_WALLEYE_REPORT_BYTES, &rep, &err)) {
    fprintf(stderr, "cave run: master: bad report from rank %d dropped\n", from);
    return;
  }
  if (rep.frame != frame) { /* an old frame's report arriving late */
    m->late_reports++;
    return;
  }
  const cv_output *o = &m->s->cave.outputs[from - 1];
  if (rep.wall != o->wall || rep.eye < 0 || rep.eye > 1 || !(o->eyes >> rep.eye & 1)) {
    fprintf(stderr, "cave run: master: rank %d reported wall %d eye %d, not its output; dropped\n", from,
            rep.wall, rep.eye);
    return;
  }
  const int k = 2 * rep.wall + rep.eye;
  master_health_seen(m, from);
  if (m->got[k]) return;
  m->got[k] = 1;
  master_path_sample(m, from, &rep);
  (*ngot)++;
  m->reps[k] = rep;
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
  const int w = rep.wall;
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

/* Collects this frame's reports until all wall-eyes reported or the
 * deadline; serves clock probes, LCD rounds, montages and stop requests
 * meanwhile.  Returns the wall-eyes that reported. */
static int collect_reports(master *m, uint32_t f, double t_sent, cv_lumstats *acc, double *lwmax) {
  cv_service *s = m->s;
  memset(acc, 0, sizeof *acc);
  *lwmax = 0;
  memset(m->got, 0, (size_t)s->n_walleyes * sizeof *m->got);
  int ngot = 0;
  /* Frame 0 also pays every rank's first lighting (relight, shadow map,
   * background from the maps): allow it the start-up time. */
  double deadline =
      t_sent + (f == 0 || f == CV_FRAME_MEASURE ? fmax(s->o.timeout_ms * 1e-3, s->o.startup_timeout_s) : s->o.timeout_ms * 1e-3);
  m->stall_last = t_sent; /* a stop right after the send counts too */
  while (ngot < s->n_walleyes) {
    int progressed = 0;
    deadline += master_stall_check(m); /* a stopped master does not make the wall-eyes late */
    for (int i = 0; i < s->n_render; i++) {
      const uint8_t *data;
      long len;
      while ((len = cv_mailbox_take(m->rep_mb[i], &data, NULL)) >= 0) {
        merge_report(m, i + 1, data, len, f, acc, lwmax, &ngot);
        progressed = 1;
      }
    }
    /* LCD sums and the LCD image for the render ranks overlap their
     * rendering: off the frame's critical path. */
    master_comp_poll(m); /* lag 1: the last frame's solve, while the wall-eyes render */
    lcd_drain(m);
    lcd_publish(m, 0);
    montage_drain(m);
    master_desktop_drain(m);
    master_sync_poll(m);
    master_stop_poll(m);
    master_health_poll(m);
    cv_comm_progress();
    if (ngot == s->n_walleyes || *s->stop || m->stop_code) break;
    /* a stop that landed in the polls above moves the deadline too, before it is judged */
    deadline += master_stall_check(m);
    if (cv_service_now() > deadline) break;
    if (!progressed) {
      struct timespec ts = {0, 200000};
      nanosleep(&ts, NULL);
    }
  }
  return ngot;
}



/* Held frames at one a second (the LCD threads run only on cores the
 * renderers leave idle, SCHED_IDLE); others at --max-fps or, on the wall
 * clock, the config's rate. */
static void pace(master *m, double tf0, int holding) {
  cv_service *s = m->s;
  double period = holding ? 1.0 : (s->o.max_fps > 0 ? 1.0 / s->o.max_fps : 0);
  if (!holding && m->wall_clock && s->o.max_fps <= 0) period = 1.0 / s->cave.rate;
  if (period <= 0) return;
  m->stall_last = cv_service_now();
  while (master_stall_check(m), cv_service_now() - tf0 < period && !*s->stop && !m->stop_code &&
         !(holding && m->lcd_rounds >= (uint32_t)s->o.lcd_budget)) {
    /* a pending solve fits the pause: done now instead of after the next state */
    if (period - (cv_service_now() - tf0) > 2e-3 * m->cst.ms + 0.005) master_comp_poll(m);
    lcd_drain(m);
    master_desktop_drain(m);
    master_sync_poll(m);
    master_stop_poll(m);
    cv_comm_progress();
    struct timespec ts = {0, 1000000};
    nanosleep(&ts, NULL);
  }
}


/* Priming round before frame 0 (see the top of this file): the wall-eyes
 * render frame 0's state flagged CV_FS_MEASURE and report; the merged foveal
 * statistics become the first adaptation target.  Patch images and swap data
 * of the round are discarded.  Returns the wall-eyes that reported. */
static int master_prime_adaptation(master *m, cv_frame_state fs) {
  fs.frame = CV_FRAME_MEASURE;
  fs.flags = CV_FS_MEASURE;
  if (send_state(m, &fs)) return 0;
  cv_lumstats acc;
  double lwmax;
  const int ngot = collect_reports(m, CV_FRAME_MEASURE, cv_service_now(), &acc, &lwmax);
  if (acc.weight > 0) {
    m->stats = acc;
    m->have_stats = 1;
    m->lwmax = lwmax;
  }
  for (int w = 0; m->disp && w < m->s->n_walls; w++) {
    const cv_display_surface *S = cv_display_surface_at(m->disp, (size_t)w);
    memset(m->walls[w].r, 0, 3 * (size_t)S->nu * S->nv * sizeof(double));
    m->walls[w].got = 0;
  }
  double lwa = 0;
  if (!m->s->o.quiet) {
    if (m->have_stats && cv_lumstats_lwa(&m->stats, &lwa) == 1)
      printf("cave run: adaptation primed at %.4g cd/m2 (frame 0's foveal luminance, %d of %d "
             "wall-eyes)\n", lwa, ngot, m->s->n_walleyes);
    else
      printf("cave run: adaptation priming got no foveal luminance; frame 0 starts at 1 cd/m2\n");
  }
  return ngot;
}

int cv_master_run(cv_service *s) {
  master M;
  memset(&M, 0, sizeof M);
  M.s = s;
  master *m = &M;
  cv_err err;
  cv_err_clear(&err);
  int rc = master_setup(m, &err);
  char why[1100] = "";
  const int ready_fail = wait_ready(m, rc, &err, why, sizeof why);
  if (ready_fail || *s->stop) {
    if (ready_fail) fprintf(stderr, "cave run: set-up failed: %s\n", why);
    quit_all(m, 0);
    cv_comm_flush(5);
    master_free(m);
    return ready_fail ? 1 : 0;
  }
  master_sync_initial(m, 8);
  if (!s->o.quiet)
    printf("cave run: %d ranks: master, %d render ranks for %d wall-eyes (%d walls), %d gather-only; LCD "
           "from %d contributors; clock %s%s\n",
           s->size, s->n_render, s->n_walleyes, s->n_walls, s->n_gather, s->n_contributors,
           m->wall_clock ? "wall" : "sim", s->o.swap_lock ? ", swap lock" : "");
  const int nframes = s->o.frames;
  const double run_t0 = cv_service_now();
  m->run_cpu0_ms = master_thread_cpu_ms();
  double prev_t = 0;
  uint32_t f;
  for (f = 0;; f++) {
    master_http_controls(m); /* the console's, queued since the last frame */
    if (*s->stop || m->stop_code) break;
    /* After the drive's frames, --lcd-wait holds the time (the head and the
     * lighting stand still, as while the driver reads the panel) and goes on
     * rendering until the LCD image has its budget. */
    const int holding = nframes > 0 && f >= (uint32_t)nframes;
    if (holding && !(m->lcd_mb && s->o.lcd_wait && m->lcd_rounds < (uint32_t)s->o.lcd_budget)) break;
    if (f == 1) master_health_arm(m); /* frame 0 has the start-up time */
    frame_times t;
    memset(&t, 0, sizeof t);
    t.tf0 = cv_service_now();
    t.cf0 = master_thread_cpu_ms();
    if (f < m->cap) m->frame_t[f] = t.tf0;
    cv_frame_state fs;
    memset(&fs, 0, sizeof fs);
    fs.frame = f;
    frame_clock(m, f, holding, &prev_t, &fs);
    frame_lighting(m, &fs);
    double t_sample, t_target;
    const double now = cv_service_now();
    master_head(m, now, fs.time, fs.head, fs.gaze, &t_sample, &t_target);
    fs.tracker_age = now - t_sample;
    master_pose_record(m, f, t_sample, t_target, fs.head);
    if (m->have_eyes) { /* calibrated: the (predicted) midpoint plus the newest eye offsets */
      fs.has_eyes = 1;
      for (int e = 0; e < 2; e++)
        for (int k = 0; k < 3; k++) fs.eyes[e][k] = fs.head[k] + m->eye_rel[e][k];
    }
    if (f == 0 && !m->adf.s.initialised) {
      cv_frame_state pf = fs;
      frame_adaptation(m, f, &pf); /* 1 cd/m2: only the HDR image (its luminance) is used */
      master_prime_adaptation(m, pf);
    }
    frame_adaptation(m, f, &fs);
    frame_lcd_key(m, &fs);
    const int last = nframes > 0 && f + 1 == (uint32_t)nframes;
    if (holding) fs.flags |= CV_FS_HOLD;
    if (last || (s->o.write_every > 0 && f % (uint32_t)s->o.write_every == 0)) fs.flags |= CV_FS_WRITE;
    if (master_desktop_mark(m, f, fs.head, fs.gaze)) fs.flags |= CV_FS_PREVIEW;
    if (send_state(m, &fs)) {
      fprintf(stderr, "cave run: master: frame %u state not finite, frame skipped\n", f);
      continue;
    }
    t.t_sent = cv_service_now();
    t.c_sent = master_thread_cpu_ms();
    cv_lumstats acc;
    double lwmax;
    const int ngot = collect_reports(m, f, t.t_sent, &acc, &lwmax);
    t.t_wait = cv_service_now();
    t.c_wait = master_thread_cpu_ms();
    master_swap_stats(m, f);
    const int late = s->n_walleyes - ngot;
    if (acc.weight > 0) {
      m->stats = acc;
      m->have_stats = 1;
      m->lwmax = lwmax;
    } else {
      m->have_stats = 0; /* empty foveal region or all late: keep the adaptation */
    }
    t.tc0 = cv_service_now();
    t.cc0 = master_thread_cpu_ms();
    if (m->disp) master_comp_frame(m, f);
    t.tc1 = cv_service_now();
    t.cc1 = master_thread_cpu_ms();
    master_release_swaps(m, f);
    /* No LCD here: its sums are taken in the wait loops (collect_reports,
     * pace), where a round arriving costs the frame nothing while the
     * wall-eyes render; on this path an image-sized add (4.8 MB at
     * 400 x 300) was the master's p99 (docs/benchmarks.md, gather farm). */
    t.tf1 = cv_service_now();
    t.cf1 = master_thread_cpu_ms();
    /* The master's own work (state, statistics), without waiting and
     * without the compensation solve (reported apart). */
    const double overhead = ((t.t_sent - t.tf0) + (t.tc0 - t.t_wait) + (t.tf1 - t.tc1)) * 1e3;
    const double overhead_cpu = (t.c_sent - t.cf0) + (t.cc0 - t.c_wait) + (t.cf1 - t.cc1);
    master_metrics_frame(m, f, &fs, &acc, late, &t, overhead, overhead_cpu);
    master_http_publish(m, &fs, t.tf1 - t.tf0, overhead * 1e-3);
    if (m->nframes_done < m->cap) {
      m->frame_ms[m->nframes_done] = (t.tf1 - t.tf0) * 1e3;
      m->overhead_ms[m->nframes_done] = overhead;
      m->overhead_cpu_ms[m->nframes_done] = overhead_cpu;
    }
    m->nframes_done++;
    if (!s->o.quiet) {
      printf("frame %u: %.0f ms (master %.2f ms), lwa %.3g cd/m2, %d late, LCD %u rounds", f, (t.tf1 - t.tf0) * 1e3,
             overhead, fs.lwa, late, m->lcd_rounds);
      if (isfinite(m->skew_us)) printf(", swap skew %.0f us", m->skew_us);
      printf("\n");
    }
    fflush(stdout);
    pace(m, t.tf0, holding);
  }
  /* Quit: tell every rank, then the last LCD image and the summary. */
  quit_all(m, f);
  lcd_reduce_finish(m);
  lcd_drain(m);
  if (!*s->stop) lcd_publish(m, 1);
  if (m->lcd_mb && (s->o.present & CV_PRESENT_FILES)) lcd_write(m, "lcd"); /* files only when asked */
  /* the last written frame's images are on their way (not waited for when
   * interrupted by a signal: mpirun follows its SIGTERM with SIGKILL) */
  for (const double t0 = cv_service_now(); !*s->stop && cv_service_now() - t0 < s->o.timeout_ms * 1e-3;) {
    montage_drain(m);
    cv_comm_progress();
    if (!m->mont_have && m->mont_flushed > 0 && f > 0 && m->mont_frame + 1 >= f) break;
    struct timespec ts = {0, 1000000};
    nanosleep(&ts, NULL);
  }
  montage_flush(m);
  master_metrics_summary(m, f, run_t0);
  master_out_final_line(m);
  if (m->stop_code)
    printf("cave run: stopped on request: %s\n", m->stop_reason);
  /* with a dead rank the others leave without MPI_Finalize: a large send
   * (rendezvous) to one that quit before taking it never completes */
  cv_comm_flush(cv_comm_dead_count() > 0 ? 2 : 10);
  /* an operator's quit from the console ends the run as asked: status 0 */
  const int lost = m->stop_code == CV_WIN_LOST ||
                   (m->stop_code >= MASTER_STOP_DEAD && m->stop_code != MASTER_STOP_CONSOLE);
  master_free(m);
  return lost ? 1 : 0;
}
