/* Clock offsets (NTP style) and constant-velocity head prediction (see
 * clocksync.h). */
#include "service/clocksync.h"

#include <math.h>
#include <string.h>

int cv_clock_offset(const cv_clock_sample *s, double *offset, double *uncertainty) {
  if (!isfinite(s->t0) || !isfinite(s->t1) || !isfinite(s->t2) || !isfinite(s->t3)) return CV_ERR_NONFINITE;
  const double rtt = s->t3 - s->t0, hold = s->t2 - s->t1;
  if (rtt < 0 || hold < 0 || hold > rtt) return CV_ERR_RANGE;
  *offset = 0.5 * ((s->t1 - s->t0) + (s->t2 - s->t3));
  *uncertainty = 0.5 * (rtt - hold);
  return CV_OK;
}

void cv_clock_est_init(cv_clock_est *e, double window_s) {
  memset(e, 0, sizeof *e);
  e->window = window_s > 0 ? window_s : 10.0;
}

void cv_clock_est_add(cv_clock_est *e, const cv_clock_sample *s) {
  double o, u;
  if (cv_clock_offset(s, &o, &u)) {
    e->rejected++;
    return;
  }
  e->s[e->next] = *s;
  e->next = (e->next + 1) % CV_CLOCK_SAMPLES;
  if (e->n < CV_CLOCK_SAMPLES) e->n++;
}

int cv_clock_est_get(const cv_clock_est *e, double now, double *offset, double *uncertainty) {
  int found = 0;
  double best_u = INFINITY;
  for (int i = 0; i < e->n; i++) {
    const cv_clock_sample *s = &e->s[i];
    if (s->t3 < now - e->window) continue;
    double o, u;
    if (cv_clock_offset(s, &o, &u) == CV_OK && u < best_u) {
      best_u = u;
      *offset = o;
      *uncertainty = u;
      found = 1;
    }
  }
  return found;
}

static double dot(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Rotates v about the unit axis k by angle a (Rodrigues). */
static void rotate(const double v[3], const double k[3], double a, double out[3]) {
  const double c = cos(a), s = sin(a), kd = dot(k, v);
  const double kx[3] = {k[1] * v[2] - k[2] * v[1], k[2] * v[0] - k[0] * v[2], k[0] * v[1] - k[1] * v[0]};
  for (int i = 0; i < 3; i++) out[i] = v[i] * c + kx[i] * s + k[i] * kd * (1 - c);
}

double cv_head_predict(const double p0[3], const double g0[3], double t0, const double p1[3],
                       const double g1[3], double t1, double t, double horizon, double p[3],
                       double g[3]) {
  memcpy(p, p1, 3 * sizeof *p);
  memcpy(g, g1, 3 * sizeof *g);
  const double span = t1 - t0;
  if (!(span > 1e-6) || !isfinite(t)) return 0;
  double dt = t - t1;
  if (dt > horizon) dt = horizon;
  if (!(dt > 0)) return 0;
  const double f = dt / span;
  for (int i = 0; i < 3; i++) p[i] = p1[i] + (p1[i] - p0[i]) * f;
  double axis[3] = {g0[1] * g1[2] - g0[2] * g1[1], g0[2] * g1[0] - g0[0] * g1[2], g0[0] * g1[1] - g0[1] * g1[0]};
  const double sn = sqrt(dot(axis, axis)), cs = dot(g0, g1);
  if (sn > 1e-12) {
    for (int i = 0; i < 3; i++) axis[i] /= sn;
    rotate(g1, axis, atan2(sn, cs) * f, g);
    const double l = sqrt(dot(g, g));
    for (int i = 0; i < 3; i++) g[i] /= l;
  }
  return dt;
}
