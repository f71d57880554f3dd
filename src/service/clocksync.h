/* Clock offsets between ranks and head-pose prediction for the service's
 * real-time clock (issue 11).  Pure: the cluster moves the timestamps.
 *
 * Offset of a rank's clock to the master's, NTP style (REFERENCES.md
 * "Cluster"): the master sends at t0 (its clock), the rank stamps receipt t1
 * and reply t2 (its clock), the master receives at t3.  With equal delays
 * each way, offset = ((t1 - t0) + (t2 - t3)) / 2 exactly; whatever the
 * delays, the true offset lies within +- uncertainty = ((t3 - t0) - (t2 - t1)) / 2
 * of it (half the round trip spent on the wire).  The estimator keeps the
 * samples of the last `window` seconds and answers with the one of the
 * smallest round trip (the tightest bound); older samples age out, so the
 * estimate follows drift. */
#ifndef CV_SERVICE_CLOCKSYNC_H
#define CV_SERVICE_CLOCKSYNC_H

#include "core/status.h"

typedef struct cv_clock_sample {
  double t0, t1, t2, t3; /* seconds: master send, rank receive, rank send, master receive */
} cv_clock_sample;

/* offset (rank clock - master clock) and its bound.  CV_ERR_RANGE when the
 * sample is impossible (t3 < t0, t2 < t1, or a round trip shorter than the
 * rank's own hold time), CV_ERR_NONFINITE on NaN/Inf. */
int cv_clock_offset(const cv_clock_sample *s, double *offset, double *uncertainty);

#define CV_CLOCK_SAMPLES 64
typedef struct cv_clock_est {
  cv_clock_sample s[CV_CLOCK_SAMPLES];
  int n, next;
  double window; /* seconds of samples kept (default 10) */
  unsigned long rejected;
} cv_clock_est;

void cv_clock_est_init(cv_clock_est *e, double window_s);
/* Adds a sample (rejected and counted when cv_clock_offset refuses it). */
void cv_clock_est_add(cv_clock_est *e, const cv_clock_sample *s);
/* The estimate at master time `now` from the samples with t3 >= now -
 * window: 1 with *offset and *uncertainty set, 0 when there is none. */
int cv_clock_est_get(const cv_clock_est *e, double now, double *offset, double *uncertainty);

/* --- head prediction --------------------------------------------------- */

/* Constant-velocity prediction of a head pose: from two timed samples (p0
 * at t0, p1 at t1 > t0; gaze unit vectors g0, g1) to time t, extrapolating
 * at most `horizon` seconds beyond t1 (the rest is held: a tracker dropout
 * must not fling the head).  Position linearly, gaze by rotating g1 further
 * about g0 x g1 at the same angular rate.  With t1 <= t0 (one sample) the
 * newest pose is returned.  Returns the seconds actually extrapolated. */
double cv_head_predict(const double p0[3], const double g0[3], double t0, const double p1[3],
                       const double g1[3], double t1, double t, double horizon, double p[3],
                       double g[3]);

#endif
