/* The master's LCD aggregation: rounds from the render ranks' idle threads
 * arrive in per-source messages; the gather ranks' rounds arrive as sums of
 * a non-blocking allreduce (lcdreduce.c) that the master tests each time it
 * drains.  Both are summed in fixed point (cv_lcd_progress), so the sum is
 * the same bits in any arrival order and for any rank count; the current
 * image goes to the render ranks (shown on the dashboard) and to
 * lcd.exr/png at the end. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "comm.h"
#include "lcdreduce.h"
#include "io/exr.h"
#include "lcd/gather.h"
#include "lcd/lcd_config.h"
#include "lcd/light_level.h"
#include "lcd/readability.h"
#include "master_internal.h"
#include "view/label.h"

/* ---- LCD ---------------------------------------------------------------- */

/* Sums rounds (n, listed; acc holds their sum) of one key, taken at frame:
 * into the current image when the key is the current one, else into the
 * estimate of an earlier key when they are of its key or of a newer
 * snapshot (each round completes with the head and lighting it started
 * with).  Rounds summed before are rejected, older snapshots counted late. */
static const char *lcd_verdict_text(master *m);

static void lcd_take(master *m, const cv_lcd_key *key, uint32_t frame, const uint32_t *round,
                     uint32_t n, const cv_lcd_accum *acc) {
  const int budget = m->s->o.lcd_budget;
  const uint64_t sk = cv_service_lcd_key(key->eye_q, key->light_hash);
  int ok = n > 0 && acc->w == m->s->o.lcd_w && acc->h == m->s->o.lcd_h &&
           acc->n == cv_lcd_accum_words(acc->w, acc->h) && acc->clamp > 0 && isfinite(acc->clamp);
  if (sk == m->lcd_key) {
    for (uint32_t i = 0; ok && i < n; i++)
      if (round[i] >= (uint32_t)budget || m->seen[round[i]]) ok = 0;
    if (!ok || cv_lcd_progress_submit(&m->prog, key, acc, NULL) != CV_OK) {
      m->lcd_rejected += n;
      return;
    }
    for (uint32_t i = 0; i < n; i++) m->seen[round[i]] = 1;
    m->lcd_rounds += n;
    return;
  }
  if (m->mot.prog.acc && !cv_lcd_key_equal(&m->mot.prog.key, key)) {
    if (frame < m->mot.frame) {
      m->lcd_late += n; /* an older snapshot than the estimate held */
      return;
    }
    cv_lcd_progress_free(&m->mot.prog); /* a newer snapshot starts over */
    memset(m->mot.seen, 0, (size_t)budget);
    m->mot.rounds = 0;
  }
  for (uint32_t i = 0; ok && i < n; i++)
    if (round[i] >= (uint32_t)budget || m->mot.seen[round[i]]) ok = 0;
  if (!ok || cv_lcd_progress_submit(&m->mot.prog, key, acc, NULL) != CV_OK) {
    m->lcd_rejected += n;
    return;
  }
  for (uint32_t i = 0; i < n; i++) m->mot.seen[round[i]] = 1;
  m->mot.rounds += n;
  m->mot.key = sk;
  if (m->mot.rounds == n || frame > m->mot.frame) m->mot.frame = frame;
}

void lcd_key_change(master *m, uint64_t key, uint32_t frame) {
  const size_t budget = (size_t)m->s->o.lcd_budget;
  const int back = m->mot.prog.acc && m->mot.key == key; /* an earlier key again */
  if (m->prog.acc && m->lcd_rounds > 0) { /* the old image: prog <-> mot */
    cv_lcd_progress t = m->mot.prog;
    m->mot.prog = m->prog;
    m->prog = t;
    uint64_t mk = m->mot.key;
    uint32_t mf = m->mot.frame, mr = m->mot.rounds;
    m->mot.key = m->lcd_key;
    m->mot.frame = m->lcd_key_frame;
    m->mot.rounds = m->lcd_rounds;
    for (size_t i = 0; i < budget; i++) {
      uint8_t v = m->mot.seen[i];
      m->mot.seen[i] = m->seen[i];
      m->seen[i] = v;
    }
    m->lcd_key = mk; /* what prog now holds */
    m->lcd_key_frame = mf;
    m->lcd_rounds = mr;
  } else if (back) {
    cv_lcd_progress_free(&m->prog);
    m->prog = m->mot.prog;
    memset(&m->mot.prog, 0, sizeof m->mot.prog);
    memcpy(m->seen, m->mot.seen, budget);
    memset(m->mot.seen, 0, budget);
    m->lcd_rounds = m->mot.rounds;
    m->mot.rounds = 0;
    m->mot.key = 0;
    m->lcd_key = key;
  }
  if (m->lcd_key != key || !back) { /* a new image */
    cv_lcd_progress_free(&m->prog);
    memset(m->seen, 0, budget);
    m->lcd_rounds = 0;
  }
  m->lcd_key = key;
  m->lcd_key_frame = frame;
  m->lcd_sent_rounds = 0;
}

/* An allreduce epoch's sum. */
static void lcd_reduced(const cv_lcd_reduce_sum *sum, void *user) {
  lcd_take(user, &sum->key, sum->frame, sum->round, sum->rounds, sum->acc);
}

/* Tests the allreduce in flight (never waits) and starts the next epoch
 * (at most every 0.1 s), asking for the current key. */
static void lcd_reduce_poll(master *m) {
  if (!m->lcd_red || m->lcd_red_abandoned) return;
  cv_lcd_reduce_announce(m->lcd_red, m->lcd_key, 0);
  cv_lcd_reduce_poll(m->lcd_red, cv_service_now(), 0.1, lcd_reduced, m);
}

void lcd_reduce_finish(master *m) {
  if (!m->lcd_red || m->lcd_red_abandoned) return;
  cv_lcd_reduce_announce(m->lcd_red, m->lcd_key, 1);
  const double t0 = cv_service_now();
  while (!cv_lcd_reduce_poll(m->lcd_red, cv_service_now(), 0, lcd_reduced, m) &&
         cv_service_now() - t0 < 10) {
    cv_comm_progress();
    struct timespec ts = {0, 1000000};
    nanosleep(&ts, NULL);
  }
  if (cv_lcd_reduce_in_flight(m->lcd_red)) { /* its buffers stay MPI's; no MPI_Finalize */
    fprintf(stderr, "cave run: master: the last LCD sum did not finish in 10 s: given up\n");
    cv_lcd_reduce_abandon(m->lcd_red);
    m->lcd_red_abandoned = 1;
  }
}

void lcd_reduce_metrics(master *m, cv_metrics_line *ml, const char *name) {
  if (!m->lcd_red) return;
  cv_lcd_reduce_stats st;
  cv_lcd_reduce_get_stats(m->lcd_red, &st);
  cv_metrics_object_begin(ml, name);
  cv_metrics_uint(ml, "members", (uint64_t)m->s->lcd_members);
  cv_metrics_uint(ml, "epochs", st.epochs);
  cv_metrics_uint(ml, "data_epochs", st.data_epochs);
  cv_metrics_uint(ml, "rounds", st.rounds);
  cv_metrics_double(ml, "epoch_ms_mean", st.mean_ms);
  /* the master's polls of the sum (docs/metrics.md), and the gather ranks' rounds */
  cv_metrics_uint(ml, "polls", st.polls);
  cv_metrics_double(ml, "poll_ms", st.poll_ms);
  cv_metrics_double(ml, "poll_cpu_ms", st.poll_cpu_ms);
  cv_metrics_double(ml, "poll_ms_max", st.poll_ms_max);
  cv_metrics_double(ml, "poll_cpu_ms_max", st.poll_cpu_ms_max);
  cv_metrics_uint(ml, "gather_rounds", st.gather_rounds);
  cv_metrics_double(ml, "gather_round_ms", st.gather_rounds ? st.gather_ms / (double)st.gather_rounds : 0);
  cv_metrics_double(ml, "gather_round_cpu_ms", st.gather_rounds ? st.gather_cpu_ms / (double)st.gather_rounds : 0);
  cv_metrics_double(ml, "gather_cpu_ms", st.gather_cpu_ms);
  cv_metrics_double(ml, "gather_comm_cpu_ms", st.gather_comm_cpu_ms);
  cv_metrics_double(ml, "gather_comm_cpu_ms_max", st.gather_comm_cpu_ms_max);
  cv_metrics_bool(ml, "abandoned", m->lcd_red_abandoned); /* a member died: rounds point-to-point */
  cv_metrics_uint(ml, "p2p_rounds", m->lcd_gather_p2p);   /* gather ranks' rounds taken point-to-point */
  cv_metrics_uint(ml, "shared_rounds", m->lcd_shared);   /* dead gather ranks' rounds from others */
  cv_metrics_uint(ml, "duplicate_rounds", m->lcd_dup);   /* rounds that came again, dropped */
  cv_metrics_object_end(ml);
}

/* Takes every LCD round that has arrived; sums those of the current key. */
void lcd_drain(master *m) {
  lcd_reduce_poll(m);
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
    if (h.n != cv_lcd_accum_words(h.w, h.h) || !(h.clamp > 0) || !isfinite(h.clamp)) {
      m->lcd_rejected++;
      continue;
    }
    /* A view of the message (the values start sizeof h, a multiple of 8,
     * bytes into a malloc'ed buffer: 8-byte aligned); the sum adds in place,
     * the first round of a key is copied. */
    cv_lcd_accum view = {.w = h.w, .h = h.h, .clamp = h.clamp,
                         .unit = cv_lcd_unit_for_clamp(h.clamp), .n = h.n,
                         .data = (int64_t *)(void *)(uintptr_t)(data + sizeof h)};
    /* a round summed already (rendered again after a gather rank died) */
    if (h.round < (uint32_t)m->s->o.lcd_budget && m->seen[h.round] &&
        cv_service_lcd_key(h.key.eye_q, h.key.light_hash) == m->lcd_key) {
      m->lcd_dup++;
      continue;
    }
    const uint32_t had = m->lcd_rounds + m->mot.rounds;
    lcd_take(m, &h.key, h.frame, &h.round, 1, &view);
    if (m->lcd_rounds + m->mot.rounds == had) continue;
    /* a gather rank's round point-to-point: the allreduce was given up */
    if (from > m->s->n_render) m->lcd_gather_p2p++;
    if (h.round % (uint32_t)m->s->n_contributors != h.contributor) m->lcd_shared++; /* a dead one's */
  }
}

/* Sends the current LCD image to the wall-eyes when it has new rounds
 * (at most every 0.25 s). */
void lcd_publish(master *m, int force) {
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
    int dests[CV_CAVE_MAX_OUTPUTS];
    for (int r = 1; r <= m->s->n_render; r++) dests[r - 1] = r;
    cv_comm_send_multi(buf, n, dests, m->s->n_render, CV_TAG_LCDIMG);
    free(buf);
  }
  cv_image_destroy(img);
  m->lcd_last_send = now;
  m->lcd_sent_rounds = m->lcd_rounds;
}

/* The figures of every panel, as `cave lcd` computes them: the reflection
 * from the panel's rows of the stacked sum, the veil from the rounds (each
 * contributor traced it from the key's eye: lcdwork.c); the adaptation is
 * the shared (Pattanaik) one. */
void lcd_readability_update(master *m) {
  /* the current key's estimate when it has rounds, else the newest
   * snapshot of an earlier key (while the head or the lighting moves) */
  const cv_lcd_accum *acc = m->prog.acc;
  uint64_t key = m->lcd_key;
  uint32_t rounds = m->lcd_rounds, frame = m->lcd_key_frame;
  if (!acc || rounds == 0) {
    acc = m->mot.prog.acc;
    key = m->mot.key;
    rounds = m->mot.rounds;
    frame = m->mot.frame;
  }
  if (!acc || rounds == 0 || (m->lread.valid && m->lread.key == key && m->lread.rounds == rounds))
    return;
  const cv_lcd_config *lc = &m->s->lcd;
  const cv_lcd_layout *L = &m->s->lcd_layout;
  for (int i = 0; i < L->n; i++) {
    cv_lcd_read_params rp;
    cv_lcd_read_params_default(&rp);
    rp.white = lc->panels[i].content_luminance;
    rp.black = lc->panels[i].black_luminance;
    rp.cr_min = lc->cr_min;
    rp.adaptation = m->adf.s.initialised ? cv_adapt_lwa(&m->adf.s) : 0;
    cv_lcd_accum *crop = NULL;
    cv_lcd_figure lv = {0, 0};
    cv_lcd_readability rd;
    cv_err err;
    if (cv_lcd_layout_crop(L, acc, i, &crop) != CV_OK) return;
    m->lread.veil = cv_lcd_accum_veil(crop, 0, &lv.value, &lv.se);
    const int st = cv_lcd_readability_compute(crop, &rp, &lv, &rd, &err);
    cv_lcd_accum_destroy(crop);
    if (st != CV_OK) return;
    m->lread.p[i].L_r = rd.L_r;
    m->lread.p[i].L_v = rd.L_v;
    m->lread.p[i].cr = rd.cr_mean;
    m->lread.p[i].area = rd.frac_ok;
    m->lread.p[i].vl = rd.vl;
    m->lread.p[i].L_a = rd.L_a.value;
    m->lread.cr_min = rd.cr_min;
    if (i == 0) master_http_heatmap(m, &rd, frame); /* the console's heat map (at most every 2 s) */
    cv_lcd_readability_free(&rd);
  }
  m->lread.have_light = cv_lcd_accum_light(acc, m->lread.light);
  m->lread.valid = 1;
  m->lread.key = key;
  m->lread.rounds = rounds;
  m->lread.frame = frame;
  m->lcd_verdict = lcd_verdict_text(m); /* for the console */
  /* its age: since the frame whose head and lighting it is of started */
  m->lread.t = frame < m->cap && m->frame_t[frame] > 0 ? m->frame_t[frame] : cv_service_now();
}

/* The calibration of the service's light: the drive's (every state of a
 * drive has the same; docs/readability.md, "Absolute light or no verdict"). */
static void lcd_calibration(const master *m, cv_lcd_calib *cal) {
  cv_drive_state ds;
  cv_light_spec spec;
  char origin[CV_PATHLEN + 16];
  cv_drive_eval(m->s->drive, 0, &ds);
  cv_drive_to_light_spec(m->s->drive, &ds, &spec);
  snprintf(origin, sizeof origin, "drive %s",
           m->s->o.drive_path[0] ? m->s->o.drive_path : "(built-in default)");
  cv_lcd_calibration(&spec, origin, cal);
}

/* The light level and its source (lx when calibrated). */
static void light_metrics(master *m, cv_metrics_line *ml, const cv_lcd_calib *cal) {
  cv_metrics_bool(ml, "calibrated", cal->absolute);
  cv_metrics_bool(ml, "light_assumed", cal->assumed);
  cv_metrics_string(ml, "light_source", cal->source);
  cv_metrics_string(ml, "illuminance_unit", cal->absolute ? "lx" : "relative");
  if (!m->lread.have_light) return;
  cv_metrics_double(ml, "outdoor_horizontal_illuminance", m->lread.light[0]);
  cv_metrics_double(ml, "eye_horizontal_illuminance", m->lread.light[1]);
  cv_metrics_double(ml, "eye_vertical_illuminance", m->lread.light[2]);
}

/* Panel i's verdict from its stored figures: "uncalibrated" without
 * absolute light (light_level.h). */
static const char *panel_verdict(const master *m, int i, int absolute) {
  cv_lcd_read_params rp;
  cv_lcd_read_params_default(&rp);
  rp.cr_min = m->lread.cr_min;
  cv_lcd_readability rd;
  memset(&rd, 0, sizeof rd);
  rd.cr_mean = m->lread.p[i].cr;
  rd.frac_ok = m->lread.p[i].area;
  rd.vl = m->lread.p[i].vl;
  return cv_lcd_verdict_name(cv_lcd_verdict(&rd, &rp, absolute, NULL, 0));
}

static const char *lcd_verdict_text(master *m) {
  if (!m->lread.valid) return "";
  cv_lcd_calib cal;
  lcd_calibration(m, &cal);
  return panel_verdict(m, 0, cal.absolute);
}

/* One panel's figures (cd/m2, ratios, shares; docs/metrics.md). */
static void panel_metrics(master *m, cv_metrics_line *ml, int i) {
  cv_metrics_double(ml, "reflected_luminance", m->lread.p[i].L_r.value);
  cv_metrics_double(ml, "reflected_luminance_se", m->lread.p[i].L_r.se);
  cv_metrics_double(ml, "veiling_luminance", m->lread.p[i].L_v.value);
  cv_metrics_double(ml, "veiling_luminance_se", m->lread.p[i].L_v.se);
  cv_metrics_double(ml, "contrast_ratio", m->lread.p[i].cr.value);
  cv_metrics_double(ml, "contrast_ratio_se", m->lread.p[i].cr.se);
  cv_metrics_double(ml, "area_meeting_cr_min", m->lread.p[i].area.value);
  cv_metrics_double(ml, "area_meeting_cr_min_se", m->lread.p[i].area.se);
  cv_metrics_double(ml, "visibility_level", m->lread.p[i].vl.value);
  cv_metrics_double(ml, "visibility_level_se", m->lread.p[i].vl.se);
  cv_metrics_double(ml, "adaptation_luminance", m->lread.p[i].L_a);
}

void lcd_readability_metrics(master *m, cv_metrics_line *ml, const char *name) {
  if (!m->lread.valid) return;
  char kb[32];
  snprintf(kb, sizeof kb, "%016llx", (unsigned long long)m->lread.key);
  cv_metrics_object_begin(ml, name);
  cv_metrics_string(ml, "key", kb);
  cv_metrics_uint(ml, "rounds", m->lread.rounds);
  cv_metrics_uint(ml, "frame", m->lread.frame);
  cv_metrics_double(ml, "age_s", cv_service_now() - m->lread.t);
  cv_metrics_bool(ml, "current", m->lread.key == m->lcd_key);
  cv_metrics_double(ml, "cr_min", m->lread.cr_min);
  cv_metrics_bool(ml, "veil_included", m->lread.veil);
  cv_lcd_calib cal;
  lcd_calibration(m, &cal);
  light_metrics(m, ml, &cal);
  /* the first panel's figures here too (one-panel scenes read them here) */
  panel_metrics(m, ml, 0);
  cv_metrics_string(ml, "verdict", panel_verdict(m, 0, cal.absolute));
  cv_metrics_object_begin(ml, "panels");
  for (int i = 0; i < m->s->lcd_layout.n; i++) {
    cv_metrics_object_begin(ml, m->s->lcd.panels[i].name);
    panel_metrics(m, ml, i);
    cv_metrics_string(ml, "verdict", panel_verdict(m, i, cal.absolute));
    cv_metrics_object_end(ml);
  }
  cv_metrics_object_end(ml);
  cv_metrics_object_end(ml);
}

void lcd_write(master *m, const char *stem) {
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
  dg.lwa = cv_adapt_lwa(&m->adf.s); /* 1 before the first target */
  dg.lwmax = m->lwmax > 0 ? m->lwmax : 100 * dg.lwa;
  cv_image *tm;
  if (cv_image_create(img->w, img->h, 3, &tm) == CV_OK) {
    uint64_t inv = 0;
    cv_drago_image(img, &dg, 1, tm, &inv);
    /* each panel's name at its top-left (the PNG only: the EXR is data) */
    static const uint8_t fg[3] = {255, 255, 160};
    const cv_lcd_layout *L = &m->s->lcd_layout;
    for (int i = 0; i < L->n && L->y0[i] + L->h[i] <= tm->h; i++)
      cv_label_draw_image(tm, 1 + tm->w / 200, L->y0[i] + 1 + tm->w / 200, 1 + tm->w / 200, m->s->lcd.panels[i].name, fg);
    snprintf(path, sizeof path, "%s/%s.png", m->s->o.out_dir, stem);
    if (cv_service_write_png01(path, tm, &err)) fprintf(stderr, "cave run: %s\n", err.msg);
    cv_image_destroy(tm);
  }
  cv_image_destroy(img);
}


void lcd_ready_metrics(master *m, cv_metrics_line *ml) {
  const cv_service *s = m->s;
  if (!s->o.lcd) return;
  char txt[2 * CV_PATHLEN + 96];
  if (s->o.scene_config[0])
    snprintf(txt, sizeof txt, "scene config %s", s->o.scene_config);
  else if (s->lcd.source[0])
    snprintf(txt, sizeof txt, "%s (the lcd block baked with %s)", s->lcd.source, s->o.scene_path);
  else
    snprintf(txt, sizeof txt, "defaults: %s has no lcd block", s->o.scene_path);
  cv_metrics_string(ml, "lcd_panels", txt);
  if (!s->o.quiet) printf("cave run: ready: LCD panels: %s\n", txt);
}

void lcd_drive_tally(master *m, uint32_t frame, double t, double dt_s, int held) {
  if (held) return;
  if (m->ldrive.frames == 0)
    for (int i = 0; i < CV_LCD_MAX_PANELS; i++) m->ldrive.p[i].cr_min = INFINITY;
  m->ldrive.frames++;
  m->ldrive.time += dt_s;
  if (!m->lread.valid) return;
  m->ldrive.with_figure++;
  if (m->lread.frame + 2 >= frame) m->ldrive.fresh++;
  for (int i = 0; i < m->s->lcd_layout.n; i++) {
    const double cr = m->lread.p[i].cr.value;
    if (cr < m->ldrive.p[i].cr_min) {
      m->ldrive.p[i].cr_min = cr;
      m->ldrive.p[i].cr_min_frame = frame;
      m->ldrive.p[i].cr_min_of = m->lread.frame;
      m->ldrive.p[i].cr_min_t = t;
    }
    if (cr < m->lread.cr_min) {
      m->ldrive.p[i].below++;
      m->ldrive.p[i].below_s += dt_s;
    }
  }
}

void lcd_drive_summary(master *m, cv_metrics_line *ml, const char *name) {
  if (m->ldrive.frames == 0) return;
  cv_lcd_calib cal;
  lcd_calibration(m, &cal);
  cv_metrics_object_begin(ml, name);
  cv_metrics_uint(ml, "frames", m->ldrive.frames);
  cv_metrics_uint(ml, "frames_with_figures", m->ldrive.with_figure);
  cv_metrics_uint(ml, "frames_with_figures_at_most_2_old", m->ldrive.fresh);
  cv_metrics_double(ml, "time_s", m->ldrive.time);
  cv_metrics_bool(ml, "calibrated", cal.absolute);
  cv_metrics_double(ml, "cr_min", m->lread.valid ? m->lread.cr_min : m->s->lcd.cr_min);
  cv_metrics_object_begin(ml, "panels");
  for (int i = 0; i < m->s->lcd_layout.n && m->ldrive.with_figure > 0; i++) {
    cv_metrics_object_begin(ml, m->s->lcd.panels[i].name);
    cv_metrics_double(ml, "contrast_ratio_min", m->ldrive.p[i].cr_min);
    cv_metrics_uint(ml, "contrast_ratio_min_frame", m->ldrive.p[i].cr_min_frame);
    cv_metrics_double(ml, "contrast_ratio_min_t", m->ldrive.p[i].cr_min_t);
    cv_metrics_uint(ml, "contrast_ratio_min_of_frame", m->ldrive.p[i].cr_min_of);
    cv_metrics_uint(ml, "frames_below_cr_min", m->ldrive.p[i].below);
    cv_metrics_double(ml, "time_below_cr_min_s", m->ldrive.p[i].below_s);
    cv_metrics_double(ml, "time_share_below_cr_min",
                      m->ldrive.time > 0 ? m->ldrive.p[i].below_s / m->ldrive.time : 0);
    cv_metrics_object_end(ml);
  }
  cv_metrics_object_end(ml);
  cv_metrics_object_end(ml);
}
