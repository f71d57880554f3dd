/* The console's controls: parsed from form fields (console.h). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "core/parse.h"
#include "service/console.h"

/* Field `name` as a finite number in [lo, hi] into *v; 0 absent, 1 read,
 * -1 bad (err set). */
static int field(const char *(*get)(void *, const char *), void *ctx, const char *name, double lo, double hi,
                 double *v, cv_err *err) {
  const char *s = get(ctx, name);
  if (!s || !*s) return 0;
  double d;
  if (cv_parse_double(s, &d) || !isfinite(d) || d < lo || d > hi) {
    cv_err_set(err, CV_ERR_RANGE, "%s: expected a number in %g..%g, got '%.40s'", name, lo, hi, s);
    return -1;
  }
  *v = d;
  return 1;
}

static int parse_head(const char *(*get)(void *, const char *), void *ctx, cv_console_ctl *out, cv_err *err) {
  static const char *pos[3] = {"x", "y", "z"}, *gz[3] = {"gx", "gy", "gz"};
  for (int a = 0; a < 3; a++) {
    const int r = field(get, ctx, pos[a], -100, 100, &out->v[a], err);
    if (r < 0) return err->status;
    if (r == 0) return cv_err_set(err, CV_ERR_CONFIG, "head: %s: expected the head position in metres (CAVE coordinates)", pos[a]);
  }
  int n = 0;
  for (int a = 0; a < 3; a++) {
    const int r = field(get, ctx, gz[a], -1e3, 1e3, &out->v[3 + a], err);
    if (r < 0) return err->status;
    n += r;
  }
  if (n != 0 && n != 3) return cv_err_set(err, CV_ERR_CONFIG, "head: gx, gy, gz: give all three or none");
  if (n == 3) {
    const double l = sqrt(out->v[3] * out->v[3] + out->v[4] * out->v[4] + out->v[5] * out->v[5]);
    if (!(l > 1e-9)) return cv_err_set(err, CV_ERR_RANGE, "head: gx, gy, gz: expected a gaze direction, got a zero vector");
    for (int a = 0; a < 3; a++) out->v[3 + a] /= l;
    out->mask = 1;
  }
  return CV_OK;
}

static int parse_sky(const char *(*get)(void *, const char *), void *ctx, cv_console_ctl *out, cv_err *err) {
  static const char *names[3] = {"elevation", "azimuth", "turbidity"};
  static const double lo[3] = {-90, -360, 2}, hi[3] = {90, 360, 10};
  for (int k = 0; k < 3; k++) {
    const int r = field(get, ctx, names[k], lo[k], hi[k], &out->v[k], err);
    if (r < 0) return err->status;
    if (r) out->mask |= 1u << k;
  }
  if (!out->mask) return cv_err_set(err, CV_ERR_CONFIG, "sky: expected elevation (deg), azimuth (deg) or turbidity (2..10)");
  return CV_OK;
}

int cv_console_parse_control(const char *(*get)(void *ctx, const char *name), void *ctx, cv_console_ctl *out,
                             cv_err *err) {
  memset(out, 0, sizeof *out);
  const char *a = get(ctx, "action");
  if (!a || !*a) return cv_err_set(err, CV_ERR_CONFIG, "action: expected pause, resume, quit, head, sky, yaw or drive");
  if (!strcmp(a, "pause")) out->kind = CV_CTL_PAUSE;
  else if (!strcmp(a, "resume")) out->kind = CV_CTL_RESUME;
  else if (!strcmp(a, "quit")) out->kind = CV_CTL_QUIT;
  else if (!strcmp(a, "drive")) out->kind = CV_CTL_DRIVE;
  else if (!strcmp(a, "head")) {
    out->kind = CV_CTL_HEAD;
    return parse_head(get, ctx, out, err);
  } else if (!strcmp(a, "sky")) {
    out->kind = CV_CTL_SKY;
    return parse_sky(get, ctx, out, err);
  } else if (!strcmp(a, "yaw")) {
    out->kind = CV_CTL_YAW;
    const int r = field(get, ctx, "yaw", -360, 360, &out->v[0], err);
    if (r < 0) return err->status;
    if (r == 0) return cv_err_set(err, CV_ERR_CONFIG, "yaw: expected the car's heading in degrees");
  } else {
    return cv_err_set(err, CV_ERR_CONFIG, "action: expected pause, resume, quit, head, sky, yaw or drive, got '%.40s'", a);
  }
  return CV_OK;
}

void cv_console_ctl_text(const cv_console_ctl *c, char *buf, size_t cap) {
  switch (c->kind) {
  case CV_CTL_PAUSE: snprintf(buf, cap, "pause"); break;
  case CV_CTL_RESUME: snprintf(buf, cap, "resume"); break;
  case CV_CTL_QUIT: snprintf(buf, cap, "quit"); break;
  case CV_CTL_DRIVE: snprintf(buf, cap, "drive"); break;
  case CV_CTL_YAW: snprintf(buf, cap, "yaw %g", c->v[0]); break;
  case CV_CTL_HEAD:
    if (c->mask) snprintf(buf, cap, "head %g %g %g gaze %.3g %.3g %.3g", c->v[0], c->v[1], c->v[2], c->v[3], c->v[4], c->v[5]);
    else snprintf(buf, cap, "head %g %g %g", c->v[0], c->v[1], c->v[2]);
    break;
  case CV_CTL_SKY: {
    int n = snprintf(buf, cap, "sky");
    static const char *names[3] = {"elevation", "azimuth", "turbidity"};
    for (int k = 0; k < 3; k++)
      if ((c->mask >> k & 1) && n >= 0 && (size_t)n < cap) n += snprintf(buf + n, cap - (size_t)n, " %s %g", names[k], c->v[k]);
    break;
  }
  default: snprintf(buf, cap, "?"); break;
  }
}
