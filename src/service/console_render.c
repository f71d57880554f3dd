/* The console's state as Prometheus text and as JSON (console.h; the
 * metrics are documented in docs/metrics.md, "Prometheus"). */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "service/console.h"

static const char *const k_role[3] = {"master", "wall-eye", "gather"};

static const char *role_name(int r) { return r >= 0 && r < 3 ? k_role[r] : "?"; }

/* ---- Prometheus text format ------------------------------------------------ */

typedef struct sbuf {
  char *p;
  size_t n, cap;
  int oom;
} sbuf;

static void sb_printf(sbuf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void sb_printf(sbuf *b, const char *fmt, ...) {
  if (b->oom) return;
  for (;;) {
    va_list ap;
    va_start(ap, fmt);
    const int w = vsnprintf(b->p + b->n, b->cap - b->n, fmt, ap);
    va_end(ap);
    if (w < 0) {
      b->oom = 1;
      return;
    }
    if ((size_t)w < b->cap - b->n) {
      b->n += (size_t)w;
      return;
    }
    size_t cap = b->cap * 2 + (size_t)w + 1;
    char *np = realloc(b->p, cap);
    if (!np) {
      b->oom = 1;
      return;
    }
    b->p = np;
    b->cap = cap;
  }
}

/* A label value escaped as the format asks (backslash, quote, newline). */
static void sb_label(sbuf *b, const char *v) {
  for (const char *c = v; *c; c++) {
    if (*c == '\\') sb_printf(b, "\\\\");
    else if (*c == '"') sb_printf(b, "\\\"");
    else if (*c == '\n') sb_printf(b, "\\n");
    else sb_printf(b, "%c", *c);
  }
}

static void sb_value(sbuf *b, double v) {
  if (isnan(v)) sb_printf(b, " NaN\n");
  else if (isinf(v)) sb_printf(b, " %sInf\n", v > 0 ? "+" : "-");
  else sb_printf(b, " %.9g\n", v);
}

static void head(sbuf *b, const char *name, const char *type, const char *help) {
  sb_printf(b, "# HELP %s %s\n# TYPE %s %s\n", name, help, name, type);
}

/* One sample without labels. */
static void plain(sbuf *b, const char *name, const char *type, const char *help, double v) {
  head(b, name, type, help);
  sb_printf(b, "%s", name);
  sb_value(b, v);
}

static void rank_labels(sbuf *b, const cv_console_rank *r) {
  sb_printf(b, "{rank=\"%d\",host=\"", r->rank);
  sb_label(b, r->host);
  sb_printf(b, "\",role=\"%s\"}", role_name(r->role));
}

static void prom_ranks(sbuf *b, const cv_console_state *st) {
  head(b, "cave_rank_up", "gauge", "1 while the rank is alive, 0 once declared dead (docs/dead-rank.md)");
  for (int i = 0; i < st->n_ranks; i++) {
    sb_printf(b, "cave_rank_up");
    rank_labels(b, &st->ranks[i]);
    sb_value(b, st->ranks[i].dead ? 0 : 1);
  }
  head(b, "cave_rank_late_frames_total", "counter", "frames whose report from the rank missed --timeout-ms");
  for (int i = 0; i < st->n_ranks; i++) {
    if (st->ranks[i].role != CV_ROLE_NAME_WALLEYE) continue;
    sb_printf(b, "cave_rank_late_frames_total");
    rank_labels(b, &st->ranks[i]);
    sb_value(b, (double)st->ranks[i].late);
  }
  head(b, "cave_rank_frames_per_second", "gauge", "reports a second the master got from the render rank, over the last seconds");
  for (int i = 0; i < st->n_ranks; i++) {
    if (st->ranks[i].role != CV_ROLE_NAME_WALLEYE) continue;
    sb_printf(b, "cave_rank_frames_per_second");
    rank_labels(b, &st->ranks[i]);
    sb_value(b, st->ranks[i].fps);
  }
}

static void prom_frames(sbuf *b, const cv_console_state *st) {
  head(b, "cave_info", "gauge", "always 1: the master's host, its clock and where the console is");
  sb_printf(b, "cave_info{master_host=\"");
  sb_label(b, st->master_host);
  sb_printf(b, "\",clock=\"");
  sb_label(b, st->clock);
  sb_printf(b, "\",console=\"");
  sb_label(b, st->url);
  sb_printf(b, "\"} 1\n");
  plain(b, "cave_frames_total", "counter", "frames rendered (every wall-eye once)", (double)st->frames_total);
  plain(b, "cave_frame", "gauge", "number of the last frame finished", (double)st->frame);
  head(b, "cave_frame_seconds", "histogram", "frame time at the master, start of a frame to the start of the next");
  for (int k = 0; k < CV_CONSOLE_BUCKETS; k++) {
    if (isinf(cv_console_buckets[k])) sb_printf(b, "cave_frame_seconds_bucket{le=\"+Inf\"}");
    else sb_printf(b, "cave_frame_seconds_bucket{le=\"%g\"}", cv_console_buckets[k]);
    sb_value(b, (double)st->frame_hist[k]);
  }
  sb_printf(b, "cave_frame_seconds_sum");
  sb_value(b, st->frame_sum_s);
  sb_printf(b, "cave_frame_seconds_count");
  sb_value(b, (double)st->frames_total);
  plain(b, "cave_master_work_p99_seconds", "gauge", "p99 of the master's own work per frame over the last 600 frames", st->master_s_p99);
  plain(b, "cave_run_seconds", "gauge", "wall time since the first frame", st->run_seconds);
  plain(b, "cave_drive_time_seconds", "gauge", "the drive's clock (stands still while paused)", st->drive_time_s);
  plain(b, "cave_paused", "gauge", "1 while the console holds the drive's clock", st->paused);
  plain(b, "cave_late_reports_total", "counter", "wall-eye reports that came after their frame ended", (double)st->late_reports_total);
  plain(b, "cave_late_walleyes_total", "counter", "wall-eye reports missing at their frame's deadline, summed over frames", (double)st->late_walleyes_total);
  plain(b, "cave_state_mismatch_total", "counter", "reports rendered with other frame-state bytes", (double)st->state_mismatch_total);
  plain(b, "cave_files_dropped_total", "counter", "written frames' files dropped by a full writer queue", (double)st->files_dropped_total);
  plain(b, "cave_files_failed_total", "counter", "written frames' files that could not be written", (double)st->files_failed_total);
  plain(b, "cave_montages_total", "counter", "unfolded-CAVE montages written", (double)st->montages_total);
}

static void prom_view(sbuf *b, const cv_console_state *st) {
  if (isfinite(st->skew_us)) plain(b, "cave_swap_skew_seconds", "gauge", "the last measured swap skew over the render ranks", st->skew_us * 1e-6);
  if (isfinite(st->mtp_ms)) plain(b, "cave_motion_to_photon_seconds", "gauge", "the last measured motion-to-photon latency", st->mtp_ms * 1e-3);
  plain(b, "cave_adaptation_luminance_cd_m2", "gauge", "the shared adaptation luminance (cd/m2)", st->lwa);
  head(b, "cave_head_position_metres", "gauge", "the head position the last frame was rendered with (CAVE coordinates)");
  for (int a = 0; a < 3; a++) {
    sb_printf(b, "cave_head_position_metres{axis=\"%c\"}", "xyz"[a]);
    sb_value(b, st->head[a]);
  }
  plain(b, "cave_car_yaw_degrees", "gauge", "the car's heading", st->yaw_deg);
  if (st->sky) {
    plain(b, "cave_sun_elevation_degrees", "gauge", "the sky's sun elevation", st->sun_elevation_deg);
    plain(b, "cave_sun_azimuth_degrees", "gauge", "the sky's sun azimuth (clockwise from -Z seen from above)", st->sun_azimuth_deg);
    plain(b, "cave_sky_turbidity", "gauge", "the sky's turbidity (2..10)", st->turbidity);
  }
  if (st->lcd) {
    plain(b, "cave_lcd_rounds", "gauge", "LCD rounds summed for the current camera/lighting key", st->lcd_rounds);
    plain(b, "cave_lcd_budget_rounds", "gauge", "rounds per key (--lcd-budget)", st->lcd_budget);
    head(b, "cave_lcd_contrast_ratio", "gauge", "each LCD panel's mean contrast ratio (ISO 15008), of the newest estimate");
    for (int p = 0; p < st->n_panels && p < CV_CONSOLE_PANELS; p++) {
      if (!isfinite(st->cr[p])) continue;
      sb_printf(b, "cave_lcd_contrast_ratio{panel=\"");
      sb_label(b, st->panel_name[p]);
      sb_printf(b, "\"}");
      sb_value(b, st->cr[p]);
    }
  }
  if (st->compensation && isfinite(st->viewer_rms)) {
    head(b, "cave_viewer_rms", "gauge", "viewer simulation: RMS over patches of what a viewer sees minus the target (display-linear)");
    sb_printf(b, "cave_viewer_rms{compensated=\"true\"}");
    sb_value(b, st->viewer_rms);
    sb_printf(b, "cave_viewer_rms{compensated=\"false\"}");
    sb_value(b, st->viewer_rms_unc);
  }
  head(b, "cave_console_controls_total", "counter", "controls from the console, applied or rejected by the master");
  sb_printf(b, "cave_console_controls_total{result=\"applied\"}");
  sb_value(b, (double)st->controls_applied);
  sb_printf(b, "cave_console_controls_total{result=\"rejected\"}");
  sb_value(b, (double)st->controls_rejected);
}

int cv_console_prometheus(const cv_console_state *st, char **out, size_t *len) {
  sbuf b = {malloc(16384), 0, 16384, 0};
  if (!b.p) return CV_ERR_NOMEM;
  prom_frames(&b, st);
  prom_ranks(&b, st);
  prom_view(&b, st);
  if (b.oom) {
    free(b.p);
    return CV_ERR_NOMEM;
  }
  *out = b.p;
  *len = b.n;
  return CV_OK;
}

/* ---- JSON ------------------------------------------------------------------- */

static void num(cJSON *o, const char *k, double v) { cJSON_AddItemToObject(o, k, cJSON_CreateNumber(v)); }

static void vec(cJSON *o, const char *k, const double *v, int n) {
  cJSON *a = cJSON_AddArrayToObject(o, k);
  for (int i = 0; a && i < n; i++) cJSON_AddItemToArray(a, cJSON_CreateNumber(v[i]));
}

static cJSON *json_ranks(const cv_console_state *st) {
  cJSON *a = cJSON_CreateArray();
  for (int i = 0; a && i < st->n_ranks; i++) {
    const cv_console_rank *r = &st->ranks[i];
    cJSON *o = cJSON_CreateObject();
    if (!o) continue;
    num(o, "rank", r->rank);
    cJSON_AddStringToObject(o, "role", role_name(r->role));
    cJSON_AddStringToObject(o, "host", r->host);
    cJSON_AddStringToObject(o, "view", r->view);
    cJSON_AddStringToObject(o, "gpu", r->gpu);
    num(o, "fps", r->fps);
    num(o, "late", (double)r->late);
    cJSON_AddBoolToObject(o, "dead", r->dead != 0);
    cJSON_AddStringToObject(o, "error", r->error);
    cJSON_AddItemToArray(a, o);
  }
  return a;
}

static cJSON *json_state(const cv_console_state *st) {
  cJSON *o = cJSON_CreateObject();
  if (!o) return NULL;
  cJSON_AddStringToObject(o, "master_host", st->master_host);
  cJSON_AddStringToObject(o, "url", st->url);
  cJSON_AddStringToObject(o, "clock", st->clock);
  cJSON_AddBoolToObject(o, "files", st->files != 0);
  cJSON_AddBoolToObject(o, "images", st->images != 0);
  cJSON_AddBoolToObject(o, "lcd", st->lcd != 0);
  cJSON_AddBoolToObject(o, "paused", st->paused != 0);
  cJSON_AddBoolToObject(o, "quitting", st->quitting != 0);
  num(o, "frame", st->frame);
  num(o, "frames_total", (double)st->frames_total);
  num(o, "run_s", st->run_seconds);
  num(o, "drive_time_s", st->drive_time_s);
  num(o, "late_walleyes_total", (double)st->late_walleyes_total);
  num(o, "lwa", st->lwa);
  num(o, "lwmax", st->lwmax);
  cJSON_AddStringToObject(o, "head_source", st->head_source);
  vec(o, "head", st->head, 3);
  vec(o, "gaze", st->gaze, 3);
  cJSON_AddBoolToObject(o, "sky", st->sky != 0);
  num(o, "yaw", st->yaw_deg);
  num(o, "turbidity", st->turbidity);
  num(o, "sun_elevation", st->sun_elevation_deg);
  num(o, "sun_azimuth", st->sun_azimuth_deg);
  vec(o, "weights", st->weights, st->n_maps < 0 ? 0 : st->n_maps > 8 ? 8 : st->n_maps);
  cJSON_AddBoolToObject(o, "override_sky", st->override_sky != 0);
  cJSON_AddBoolToObject(o, "override_yaw", st->override_yaw != 0);
  num(o, "lcd_rounds", st->lcd_rounds);
  num(o, "lcd_budget", st->lcd_budget);
  cJSON *p = cJSON_AddArrayToObject(o, "panels");
  for (int i = 0; p && i < st->n_panels && i < CV_CONSOLE_PANELS; i++) {
    cJSON *q = cJSON_CreateObject();
    cJSON_AddStringToObject(q, "name", st->panel_name[i]);
    num(q, "cr", st->cr[i]);
    cJSON_AddItemToArray(p, q);
  }
  num(o, "cr_min", st->cr_min);
  cJSON_AddStringToObject(o, "verdict", st->verdict);
  num(o, "viewer_rms", st->viewer_rms);
  num(o, "viewer_rms_uncompensated", st->viewer_rms_unc);
  num(o, "skew_us", st->skew_us);
  num(o, "mtp_ms", st->mtp_ms);
  num(o, "controls_applied", (double)st->controls_applied);
  num(o, "controls_rejected", (double)st->controls_rejected);
  cJSON_AddStringToObject(o, "last_control", st->last_control);
  cJSON_AddItemToObject(o, "ranks", json_ranks(st));
  return o;
}

/* Samples as columns (compact): {"frame": [...], "t": [...], ...}. */
static cJSON *json_samples(const cv_console_state *st, const cv_console_sample *ring, size_t n, int64_t since) {
  cJSON *o = cJSON_CreateObject();
  const char *names[6] = {"frame", "t", "frame_ms", "master_ms", "skew_us", "mtp_ms"};
  cJSON *col[6];
  for (int k = 0; k < 6; k++) col[k] = cJSON_AddArrayToObject(o, names[k]);
  cJSON *cr = cJSON_AddArrayToObject(o, "cr");
  const int np = st->n_panels < CV_CONSOLE_PANELS ? st->n_panels : CV_CONSOLE_PANELS;
  cJSON *crp[CV_CONSOLE_PANELS] = {0};
  for (int p = 0; p < np; p++) {
    crp[p] = cJSON_CreateArray();
    cJSON_AddItemToArray(cr, crp[p]);
  }
  for (size_t i = 0; i < n; i++) {
    const cv_console_sample *s = &ring[i];
    if (since >= 0 && (int64_t)s->frame <= since) continue;
    const double v[6] = {s->frame, s->t, s->frame_s * 1e3, s->master_s * 1e3, s->skew_s * 1e6, s->mtp_s * 1e3};
    for (int k = 0; k < 6; k++) cJSON_AddItemToArray(col[k], cJSON_CreateNumber(v[k]));
    for (int p = 0; p < np; p++) cJSON_AddItemToArray(crp[p], cJSON_CreateNumber(s->cr[p]));
  }
  return o;
}

int cv_console_json(const cv_console_state *st, const cv_console_sample *ring, size_t n, int64_t since,
                    char **out, size_t *len) {
  cJSON *root = cJSON_CreateObject();
  if (!root) return CV_ERR_NOMEM;
  cJSON_AddItemToObject(root, "state", json_state(st));
  cJSON_AddItemToObject(root, "samples", json_samples(st, ring, n, since));
  char *txt = cJSON_PrintUnformatted(root);
  cJSON_Delete(root);
  if (!txt) return CV_ERR_NOMEM;
  *out = txt;
  *len = strlen(txt);
  return CV_OK;
}
