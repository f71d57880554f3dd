/* Lighting shared by the roles: the drive state quantised to its key, so
 * every rank that sees a key builds bit-identical lighting (the LCD sums of
 * different contributors may then be added), and the rank layout. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "io/png.h"
#include "lcd/lcd_config.h"

#include "http/http.h"
#include "service.h"
#include "service_internal.h"

void cv_run_opts_default(cv_run_opts *o) {
  memset(o, 0, sizeof *o);
  snprintf(o->dtrack_host, sizeof o->dtrack_host, "127.0.0.1");
  snprintf(o->http_addr, sizeof o->http_addr, "127.0.0.1"); /* the console: loopback only */
  o->http_port = CV_HTTP_DEFAULT_PORT;
  o->dtrack_body = 1;
  o->frames = 30;
  o->dt = 1.0 / 30.0;
  o->write_every = 10;
  o->metrics_every = 1;
  o->metrics_max_mb = 512;
  o->metrics_keep = 4;
  o->timeout_ms = 2000;
  o->gather_timeout_s = 10;
  o->startup_timeout_s = 300;
  o->compensate = 1;
  o->patches = 0; /* the config's screens.patches */
  o->reflectance = -1; /* the config's screens.reflectance */
  o->compensation_ms = 20;
  o->compensation_lag = 1;
  o->post = CV_POST_AUTO;
  o->lcd = 1;
  /* the LCD model is the scene config's lcd block, as in `cave lcd` (run.c) */
  o->lcd_w = 0;
  o->lcd_h = 0;
  o->lcd_spp = 0;
  o->lcd_budget = 64;
  o->lcd_tolerance = 0;
  o->lcd_luminance = -1;
  o->lcd_idle = 1;
  o->share_lighting = 4; /* CV_SHARE_AUTO */
  o->half_transfer = -1;
  o->seed = 1;
  o->present = CV_PRESENT_FILES;
  o->desktop_view = -1;
  o->desktop_fps = 30;
  o->gpu = CV_GPU_UNSET;
  o->clock = -1;
  o->predict = 1;
  o->swap_sync = CV_SWAP_SCHEDULED;
  o->swap_margin_ms = 3;
  o->predict_horizon = 0.1;
}

int cv_service_contributor(const cv_service *s, int rank) {
  if (!s->o.lcd || rank <= 0 || rank >= s->size) return -1;
  if (rank <= s->n_render) return s->o.lcd_idle ? rank - 1 : -1;
  return (s->o.lcd_idle ? s->n_render : 0) + (rank - 1 - s->n_render);
}

static double snap(double v, double step) { return step * floor(v / step + 0.5); }

void cv_service_quantise_drive(cv_drive_state *s) {
  s->t = 0; /* the lighting does not depend on time itself */
  s->yaw_deg = fmod(snap(s->yaw_deg, 1.0), 360.0);
  if (s->yaw_deg < 0) s->yaw_deg += 360.0;
  s->pitch_deg = snap(s->pitch_deg, 1.0);
  s->roll_deg = snap(s->roll_deg, 1.0);
  double sum = 0;
  for (int i = 0; i < s->n_maps; i++) {
    s->weights[i] = snap(s->weights[i], 0.01);
    sum += s->weights[i];
  }
  if (!(sum > 0) && s->n_maps > 0) s->weights[0] = 1; /* all snapped to 0: keep the first */
  s->turbidity = snap(s->turbidity, 0.1);
  s->sun_elevation_deg = snap(s->sun_elevation_deg, 0.5);
  s->sun_azimuth_deg = snap(s->sun_azimuth_deg, 0.5);
}

uint64_t cv_service_light_key(const cv_drive_state *q) {
  /* FNV-1a over the quantised fields (steps already applied). */
  uint64_t h = 1469598103934665603ull;
  const double v[] = {q->yaw_deg, q->pitch_deg, q->roll_deg, q->turbidity,
                      q->sun_elevation_deg, q->sun_azimuth_deg, (double)q->is_sky,
                      (double)q->n_maps};
  for (size_t i = 0; i < sizeof v / sizeof v[0]; i++) {
    int64_t k = (int64_t)llround(v[i] * 100);
    for (int b = 0; b < 8; b++) {
      h ^= (uint64_t)((k >> (8 * b)) & 0xff);
      h *= 1099511628211ull;
    }
  }
  for (int i = 0; i < q->n_maps; i++) {
    int64_t k = (int64_t)llround(q->weights[i] * 100);
    for (int b = 0; b < 8; b++) {
      h ^= (uint64_t)((k >> (8 * b)) & 0xff);
      h *= 1099511628211ull;
    }
  }
  return h;
}

int cv_service_build_lighting(const cv_service *s, const cv_drive_state *q, int bands,
                              cv_scene_light **out, cv_err *err) {
  cv_light_spec spec;
  cv_drive_to_light_spec(s->drive, q, &spec);
  return cv_scene_light_build(&spec, bands, out, err);
}

uint64_t cv_service_lcd_key(const int32_t eye_q[3], uint64_t light_key) {
  uint64_t h = 1469598103934665603ull;
  uint64_t v[4] = {(uint64_t)(uint32_t)eye_q[0], (uint64_t)(uint32_t)eye_q[1],
                   (uint64_t)(uint32_t)eye_q[2], light_key};
  for (int i = 0; i < 4; i++)
    for (int b = 0; b < 8; b++) {
      h ^= (v[i] >> (8 * b)) & 0xff;
      h *= 1099511628211ull;
    }
  return h;
}

double cv_service_now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int cv_service_write_png01(const char *path, const cv_image *img, cv_err *err) {
  if (!img || img->c < 3) return cv_err_set(err, CV_ERR_INVALID, "%s: no RGB image", path);
  const size_t n = (size_t)img->w * img->h;
  uint8_t *px = malloc(3 * n);
  if (!px) return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  for (size_t i = 0; i < n; i++)
    for (int k = 0; k < 3; k++) {
      float v = img->px[i * img->c + k];
      v = v > 0 ? (v < 1 ? v : 1) : 0;
      px[3 * i + k] = (uint8_t)lrintf(v * 255.0f);
    }
  int st = cv_png_write(path, img->w, img->h, 3, px, err);
  free(px);
  return st;
}

int cv_service_lightmix(const cv_service *s, int bands, cv_lightmix **out, cv_err *err) {
  *out = NULL;
  const int n = cv_drive_n_maps(s->drive);
  if (n <= 0) return CV_OK; /* sky drive */
  const char *paths[CV_MAX_ENV_MAPS];
  for (int i = 0; i < n; i++) paths[i] = cv_drive_map_path(s->drive, i);
  cv_drive_state st0;
  cv_drive_eval(s->drive, 0, &st0);
  cv_light_spec spec;
  cv_drive_to_light_spec(s->drive, &st0, &spec);
  return cv_lightmix_create_calibrated(paths, n, spec.scale > 0 ? spec.scale : 1.0,
                                       spec.illuminance, bands, out, err);
}

int cv_service_lighting(const cv_service *s, const cv_lightmix *mix, const cv_drive_state *q,
                        int bands, cv_lighting *l, int bg_width, cv_image **bg, cv_err *err) {
  if (bg) *bg = NULL;
  if (mix) {
    int st = l ? cv_lightmix_lighting(mix, q->weights, q->yaw_deg, q->pitch_deg, q->roll_deg, l) : CV_OK;
    if (st) return cv_err_set(err, st, "lighting: bad blend weights");
    if (bg && (st = cv_lightmix_background(mix, q->weights, q->yaw_deg, q->pitch_deg, q->roll_deg,
                                           bg_width, bg)))
      return cv_err_set(err, st, "lighting: background table");
    return CV_OK;
  }
  cv_scene_light *sl;
  int st = cv_service_build_lighting(s, q, l ? bands : 0, &sl, err);
  if (st) return st;
  if (l) *l = cv_scene_light_sh(sl);
  if (bg && (st = cv_render_background_image(sl, bg_width, bg)))
    st = cv_err_set(err, st, "lighting: background table");
  cv_scene_light_destroy(sl);
  return st;
}
