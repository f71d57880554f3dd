/* The master's LCD aggregation: rounds from the render ranks' idle threads
 * and the gather ranks arrive in per-source messages and are summed in
 * fixed point (cv_lcd_progress), so the sum is the same bits in any arrival
 * order and for any rank count; the current image goes to the render ranks
 * (shown on the dashboard) and to lcd.exr/png at the end. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "comm.h"
#include "io/exr.h"
#include "lcd/gather.h"
#include "lcd/lcd_config.h"
#include "lcd/readability.h"
#include "master_internal.h"

/* ---- LCD ---------------------------------------------------------------- */

/* Takes every LCD round that has arrived; sums those of the current key. */
void lcd_drain(master *m) {
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

/* The figures from the reflection alone: the veil needs the eye's view
 * traced (cave lcd does it), which the master, holding no geometry, does
 * not; the adaptation is the shared (Pattanaik) one. */
void lcd_readability_update(master *m) {
  if (!m->prog.acc || (m->lread.valid && m->lread.key == m->lcd_key &&
                       m->lread.rounds == m->lcd_rounds))
    return;
  cv_lcd_read_params rp;
  cv_lcd_read_params_default(&rp);
  rp.white = m->s->o.lcd_luminance;
  rp.black = CV_LCD_BLACK_LEVEL * rp.white;
  rp.adaptation = m->have_adapt ? cv_adapt_lwa(&m->ad) : 0;
  const cv_lcd_figure no_veil = {0, 0};
  cv_lcd_readability rd;
  cv_err err;
  if (cv_lcd_readability_compute(m->prog.acc, &rp, &no_veil, &rd, &err) != CV_OK) return;
  m->lread.valid = 1;
  m->lread.key = m->lcd_key;
  m->lread.rounds = m->lcd_rounds;
  m->lread.t = cv_service_now();
  m->lread.L_r = rd.L_r;
  m->lread.cr = rd.cr_mean;
  m->lread.area = rd.frac_ok;
  m->lread.vl = rd.vl;
  m->lread.L_a = rd.L_a.value;
  m->lread.cr_min = rd.cr_min;
  cv_lcd_readability_free(&rd);
}

void lcd_readability_metrics(master *m, cv_metrics_line *ml) {
  if (!m->lread.valid) return;
  char kb[32];
  snprintf(kb, sizeof kb, "%016llx", (unsigned long long)m->lread.key);
  cv_metrics_object_begin(ml, "readability");
  cv_metrics_string(ml, "key", kb);
  cv_metrics_uint(ml, "rounds", m->lread.rounds);
  cv_metrics_double(ml, "age_s", cv_service_now() - m->lread.t);
  cv_metrics_bool(ml, "current", m->lread.key == m->lcd_key);
  cv_metrics_double(ml, "reflected_luminance", m->lread.L_r.value);
  cv_metrics_double(ml, "reflected_luminance_se", m->lread.L_r.se);
  cv_metrics_double(ml, "contrast_ratio", m->lread.cr.value);
  cv_metrics_double(ml, "contrast_ratio_se", m->lread.cr.se);
  cv_metrics_double(ml, "cr_min", m->lread.cr_min);
  cv_metrics_double(ml, "area_meeting_cr_min", m->lread.area.value);
  cv_metrics_double(ml, "area_meeting_cr_min_se", m->lread.area.se);
  cv_metrics_double(ml, "visibility_level", m->lread.vl.value);
  cv_metrics_double(ml, "visibility_level_se", m->lread.vl.se);
  cv_metrics_double(ml, "adaptation_luminance", m->lread.L_a);
  cv_metrics_bool(ml, "veil_included", 0);
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

