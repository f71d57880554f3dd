/* Implausible tracked head poses held (issue 35, defect 8): a DTrack sample
 * outside the tracking volume (a box in CAVE coordinates) or one that moved
 * faster than a head can from the last accepted pose is not taken; the
 * caller keeps the last good pose and counts the sample.  The speed is
 * measured from the last accepted pose, so after a real jump (the target
 * re-acquired elsewhere) the pose is taken again once the elapsed time makes
 * the jump plausible (1 m at 10 m/s: after 0.1 s). */
#ifndef CV_SERVICE_POSEGATE_H
#define CV_SERVICE_POSEGATE_H

#include <stdint.h>

typedef struct cv_pose_gate {
  double lo[3], hi[3];  /* the tracking volume (m, CAVE coordinates) */
  double max_speed;     /* m/s; <= 0: no limit */
  int have_last;
  double last[3], last_t; /* the last accepted pose and its time (s) */
  uint64_t outside, too_fast; /* samples held, by reason */
} cv_pose_gate;

enum { CV_POSE_OK = 0, CV_POSE_OUTSIDE = 1, CV_POSE_TOO_FAST = 2 };

void cv_pose_gate_init(cv_pose_gate *g, const double lo[3], const double hi[3], double max_speed);
/* CV_POSE_OK (taken: the new last pose) or why it is held (counted);
 * *speed gets the speed from the last accepted pose (m/s, 0 for the first). */
int cv_pose_gate_check(cv_pose_gate *g, const double pos[3], double t, double *speed);

#endif
