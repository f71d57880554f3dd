/* Pack/unpack of the frame state and the wall-eye report (framestate.h):
 * explicit little-endian byte order through a small cursor, so the layout
 * never depends on the compiler's struct padding or the host's endianness. */
#include "service/framestate.h"

#include <math.h>
#include <string.h>

/* --- writer ------------------------------------------------------------- */

typedef struct wr {
  uint8_t *p;
  size_t off;
  int nonfinite; /* a double was not finite */
} wr;

static void put_u32(wr *w, uint32_t v) {
  for (int i = 0; i < 4; i++) w->p[w->off++] = (uint8_t)(v >> (8 * i));
}
static void put_u64(wr *w, uint64_t v) {
  for (int i = 0; i < 8; i++) w->p[w->off++] = (uint8_t)(v >> (8 * i));
}
static void put_i32(wr *w, int32_t v) { put_u32(w, (uint32_t)v); }
static void put_f64(wr *w, double v) {
  uint64_t b;
  memcpy(&b, &v, sizeof b); /* IEEE-754 binary64 on every supported host */
  if (!isfinite(v)) w->nonfinite = 1;
  put_u64(w, b);
}
static void put_f64s(wr *w, const double *v, int n) {
  for (int i = 0; i < n; i++) put_f64(w, v[i]);
}

/* --- reader ------------------------------------------------------------- */

typedef struct rd {
  const uint8_t *p;
  size_t off;
  const char *bad; /* first non-finite field, NULL if none */
  int bad_index;
} rd;

static uint32_t get_u32(rd *r) {
  uint32_t v = 0;
  for (int i = 0; i < 4; i++) v |= (uint32_t)r->p[r->off++] << (8 * i);
  return v;
}
static uint64_t get_u64(rd *r) {
  uint64_t v = 0;
  for (int i = 0; i < 8; i++) v |= (uint64_t)r->p[r->off++] << (8 * i);
  return v;
}
static int32_t get_i32(rd *r) {
  uint32_t u = get_u32(r);
  int32_t v;
  memcpy(&v, &u, sizeof v); /* two's complement, no implementation-defined cast */
  return v;
}
static double get_f64_named(rd *r, const char *name, int index) {
  uint64_t b = get_u64(r);
  double v;
  memcpy(&v, &b, sizeof v);
  if (!isfinite(v) && !r->bad) {
    r->bad = name;
    r->bad_index = index;
  }
  return v;
}
#define GET_F64(r, name) get_f64_named((r), (name), -1)
static void get_f64s(rd *r, const char *name, double *v, int n) {
  for (int i = 0; i < n; i++) v[i] = get_f64_named(r, name, i);
}

/* --- drive state -------------------------------------------------------- */

static void put_drive(wr *w, const cv_drive_state *d) {
  put_f64(w, d->t);
  put_f64(w, d->yaw_deg);
  put_f64(w, d->pitch_deg);
  put_f64(w, d->roll_deg);
  put_i32(w, d->n_maps);
  put_f64s(w, d->weights, CV_MAX_ENV_MAPS);
  put_i32(w, d->is_sky);
  put_f64(w, d->turbidity);
  put_f64(w, d->sun_elevation_deg);
  put_f64(w, d->sun_azimuth_deg);
}

static void get_drive(rd *r, cv_drive_state *d) {
  d->t = GET_F64(r, "drive.t");
  d->yaw_deg = GET_F64(r, "drive.yaw_deg");
  d->pitch_deg = GET_F64(r, "drive.pitch_deg");
  d->roll_deg = GET_F64(r, "drive.roll_deg");
  d->n_maps = get_i32(r);
  get_f64s(r, "drive.weights", d->weights, CV_MAX_ENV_MAPS);
  d->is_sky = get_i32(r);
  d->turbidity = GET_F64(r, "drive.turbidity");
  d->sun_elevation_deg = GET_F64(r, "drive.sun_elevation_deg");
  d->sun_azimuth_deg = GET_F64(r, "drive.sun_azimuth_deg");
}

/* --- frame state -------------------------------------------------------- */

int cv_frame_state_pack(const cv_frame_state *s, uint8_t buf[CV_FRAME_STATE_BYTES]) {
  if (!s || !buf) return CV_ERR_INVALID;
  if (s->bands < 0 || s->bands > 8 || s->drive.n_maps < 0 ||
      s->drive.n_maps > CV_MAX_ENV_MAPS || (s->drive.is_sky != 0 && s->drive.is_sky != 1) ||
      (s->has_sun != 0 && s->has_sun != 1) || (s->has_eyes != 0 && s->has_eyes != 1))
    return CV_ERR_RANGE;
  wr w = {buf, 0, 0};
  put_u32(&w, CV_FRAME_STATE_MAGIC);
  put_u32(&w, CV_FRAME_STATE_VERSION);
  put_u32(&w, s->frame);
  put_u32(&w, s->flags);
  put_f64(&w, s->time);
  put_f64(&w, s->dt);
  put_f64s(&w, s->head, 3);
  put_f64s(&w, s->gaze, 3);
  put_f64(&w, s->tracker_age);
  put_drive(&w, &s->drive);
  put_u64(&w, s->light_key);
  put_i32(&w, s->bands);
  put_f64s(&w, s->sh, CV_FRAME_STATE_SH_MAX);
  put_i32(&w, s->has_sun);
  put_f64s(&w, s->sun_dir, 3);
  put_f64s(&w, s->sun_E, 3);
  put_f64(&w, s->lwa);
  put_f64(&w, s->lwmax);
  put_f64s(&w, s->adapt, 6);
  put_u64(&w, s->lcd_key);
  put_u32(&w, s->lcd_rounds);
  put_i32(&w, s->has_eyes);
  put_f64s(&w, &s->eyes[0][0], 6);
  put_u64(&w, s->lcd_dead);
  put_u32(&w, s->lcd_dead_floor);
  if (w.off != CV_FRAME_STATE_BYTES) return CV_ERR_INVALID; /* layout bug: caught by tests */
  return w.nonfinite ? CV_ERR_NONFINITE : CV_OK;
}

static int nonfinite_err(const rd *r, const char *what, cv_err *err) {
  if (r->bad_index >= 0)
    return cv_err_set(err, CV_ERR_NONFINITE, "%s: %s[%d] is not finite", what, r->bad,
                      r->bad_index);
  return cv_err_set(err, CV_ERR_NONFINITE, "%s: %s is not finite", what, r->bad);
}

int cv_frame_state_unpack(const uint8_t *buf, size_t len, cv_frame_state *out, cv_err *err) {
  static const char *what = "frame state";
  if (!buf || !out) return cv_err_set(err, CV_ERR_INVALID, "%s: NULL buffer", what);
  if (len != CV_FRAME_STATE_BYTES)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: %zu bytes, expected %d", what, len,
                      (int)CV_FRAME_STATE_BYTES);
  rd r = {buf, 0, NULL, -1};
  uint32_t magic = get_u32(&r), version = get_u32(&r);
  if (magic != CV_FRAME_STATE_MAGIC)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: magic 0x%08x, expected 0x%08x", what,
                      (unsigned)magic, (unsigned)CV_FRAME_STATE_MAGIC);
  if (version != CV_FRAME_STATE_VERSION)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: version %u, expected %u", what,
                      (unsigned)version, (unsigned)CV_FRAME_STATE_VERSION);
  cv_frame_state s;
  memset(&s, 0, sizeof s);
  s.frame = get_u32(&r);
  s.flags = get_u32(&r);
  s.time = GET_F64(&r, "time");
  s.dt = GET_F64(&r, "dt");
  get_f64s(&r, "head", s.head, 3);
  get_f64s(&r, "gaze", s.gaze, 3);
  s.tracker_age = GET_F64(&r, "tracker_age");
  get_drive(&r, &s.drive);
  s.light_key = get_u64(&r);
  s.bands = get_i32(&r);
  get_f64s(&r, "sh", s.sh, CV_FRAME_STATE_SH_MAX);
  s.has_sun = get_i32(&r);
  get_f64s(&r, "sun_dir", s.sun_dir, 3);
  get_f64s(&r, "sun_E", s.sun_E, 3);
  s.lwa = GET_F64(&r, "lwa");
  s.lwmax = GET_F64(&r, "lwmax");
  get_f64s(&r, "adapt", s.adapt, 6);
  s.lcd_key = get_u64(&r);
  s.lcd_rounds = get_u32(&r);
  s.has_eyes = get_i32(&r);
  get_f64s(&r, "eyes", &s.eyes[0][0], 6);
  s.lcd_dead = get_u64(&r);
  s.lcd_dead_floor = get_u32(&r);
  if (r.off != CV_FRAME_STATE_BYTES)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: layout read %zu bytes", what, r.off);
  if (s.flags & ~(CV_FS_QUIT | CV_FS_WRITE | CV_FS_NEW_LIGHT | CV_FS_HOLD | CV_FS_PREVIEW | CV_FS_MEASURE))
    return cv_err_set(err, CV_ERR_FORMAT, "%s: unknown flags 0x%x", what, (unsigned)s.flags);
  if (s.bands < 0 || s.bands > 8)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: bands %d outside [0, 8]", what, (int)s.bands);
  if (s.drive.n_maps < 0 || s.drive.n_maps > CV_MAX_ENV_MAPS)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: drive.n_maps %d outside [0, %d]", what,
                      s.drive.n_maps, CV_MAX_ENV_MAPS);
  if (s.drive.is_sky != 0 && s.drive.is_sky != 1)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: drive.is_sky %d, expected 0 or 1", what,
                      s.drive.is_sky);
  if (s.has_sun != 0 && s.has_sun != 1)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: has_sun %d, expected 0 or 1", what,
                      (int)s.has_sun);
  if (s.has_eyes != 0 && s.has_eyes != 1)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: has_eyes %d, expected 0 or 1", what,
                      (int)s.has_eyes);
  if (r.bad) return nonfinite_err(&r, what, err);
  *out = s;
  return CV_OK;
}

/* --- wall-eye report ---------------------------------------------------- */

int cv_walleye_report_pack(const cv_walleye_report *rp, uint8_t *buf) {
  if (!rp || !buf) return CV_ERR_INVALID;
  wr w = {buf, 0, 0};
  put_u32(&w, CV_WALLEYE_REPORT_MAGIC);
  put_u32(&w, CV_WALLEYE_REPORT_VERSION);
  put_u32(&w, rp->frame);
  put_i32(&w, rp->rank);
  put_i32(&w, rp->wall);
  put_i32(&w, rp->eye);
  put_f64(&w, rp->sum_log);
  put_f64(&w, rp->weight);
  put_f64(&w, rp->max_l);
  put_u64(&w, rp->n_pixels);
  put_u64(&w, rp->n_invalid);
  put_f64(&w, rp->ms_lum);
  put_f64(&w, rp->ms_depth);
  put_f64(&w, rp->ms_shade);
  put_f64(&w, rp->ms_read);
  put_f64(&w, rp->ms_total);
  put_f64(&w, rp->ms_lcd);
  put_u64(&w, rp->lcd_rounds_done);
  put_u64(&w, rp->state_hash);
  put_u32(&w, rp->swap_frame);
  put_f64(&w, rp->swap_t);
  put_f64(&w, rp->ms_present);
  put_f64(&w, rp->ms_barrier);
  put_u64(&w, rp->bytes_read);
  put_u64(&w, rp->bytes_up);
  put_f64(&w, rp->ms_cpu);
  put_f64(&w, rp->ms_gpu);
  put_f64(&w, rp->ms_corr_wait);
  put_u32(&w, rp->corr_frame);
  put_u64(&w, rp->late_corr);
  put_u64(&w, rp->files_dropped);
  put_u64(&w, rp->files_failed);
  if (w.off != CV_WALLEYE_REPORT_BYTES) return CV_ERR_INVALID;
  return w.nonfinite ? CV_ERR_NONFINITE : CV_OK;
}

int cv_walleye_report_unpack(const uint8_t *buf, size_t len, cv_walleye_report *out,
                             cv_err *err) {
  static const char *what = "wall-eye report";
  if (!buf || !out) return cv_err_set(err, CV_ERR_INVALID, "%s: NULL buffer", what);
  if (len != CV_WALLEYE_REPORT_BYTES)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: %zu bytes, expected %d", what, len,
                      (int)CV_WALLEYE_REPORT_BYTES);
  rd r = {buf, 0, NULL, -1};
  uint32_t magic = get_u32(&r), version = get_u32(&r);
  if (magic != CV_WALLEYE_REPORT_MAGIC)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: magic 0x%08x, expected 0x%08x", what,
                      (unsigned)magic, (unsigned)CV_WALLEYE_REPORT_MAGIC);
  if (version != CV_WALLEYE_REPORT_VERSION)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: version %u, expected %u", what,
                      (unsigned)version, (unsigned)CV_WALLEYE_REPORT_VERSION);
  cv_walleye_report p;
  memset(&p, 0, sizeof p);
  p.frame = get_u32(&r);
  p.rank = get_i32(&r);
  p.wall = get_i32(&r);
  p.eye = get_i32(&r);
  p.sum_log = GET_F64(&r, "sum_log");
  p.weight = GET_F64(&r, "weight");
  p.max_l = GET_F64(&r, "max_l");
  p.n_pixels = get_u64(&r);
  p.n_invalid = get_u64(&r);
  p.ms_lum = GET_F64(&r, "ms_lum");
  p.ms_depth = GET_F64(&r, "ms_depth");
  p.ms_shade = GET_F64(&r, "ms_shade");
  p.ms_read = GET_F64(&r, "ms_read");
  p.ms_total = GET_F64(&r, "ms_total");
  p.ms_lcd = GET_F64(&r, "ms_lcd");
  p.lcd_rounds_done = get_u64(&r);
  p.state_hash = get_u64(&r);
  p.swap_frame = get_u32(&r);
  p.swap_t = GET_F64(&r, "swap_t");
  p.ms_present = GET_F64(&r, "ms_present");
  p.ms_barrier = GET_F64(&r, "ms_barrier");
  p.bytes_read = get_u64(&r);
  p.bytes_up = get_u64(&r);
  p.ms_cpu = GET_F64(&r, "ms_cpu");
  p.ms_gpu = GET_F64(&r, "ms_gpu");
  p.ms_corr_wait = GET_F64(&r, "ms_corr_wait");
  p.corr_frame = get_u32(&r);
  p.late_corr = get_u64(&r);
  p.files_dropped = get_u64(&r);
  p.files_failed = get_u64(&r);
  if (r.off != CV_WALLEYE_REPORT_BYTES)
    return cv_err_set(err, CV_ERR_FORMAT, "%s: layout read %zu bytes", what, r.off);
  if (r.bad) return nonfinite_err(&r, what, err);
  *out = p;
  return CV_OK;
}
