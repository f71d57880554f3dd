/* Implausible head poses (see posegate.h). */
#include "service/posegate.h"

#include <math.h>
#include <string.h>

void cv_pose_gate_init(cv_pose_gate *g, const double lo[3], const double hi[3], double max_speed) {
  memset(g, 0, sizeof *g);
  memcpy(g->lo, lo, sizeof g->lo);
  memcpy(g->hi, hi, sizeof g->hi);
  g->max_speed = max_speed;
}

int cv_pose_gate_check(cv_pose_gate *g, const double pos[3], double t, double *speed) {
  double v = 0;
  for (int k = 0; k < 3; k++)
    if (!(pos[k] >= g->lo[k] && pos[k] <= g->hi[k])) {
      g->outside++;
      if (speed) *speed = 0;
      return CV_POSE_OUTSIDE;
    }
  if (g->have_last) {
    const double dx = pos[0] - g->last[0], dy = pos[1] - g->last[1], dz = pos[2] - g->last[2];
    const double d = sqrt(dx * dx + dy * dy + dz * dz), dt = t - g->last_t;
    v = dt > 0 ? d / dt : (d > 0 ? INFINITY : 0);
  }
  if (speed) *speed = v;
  if (g->max_speed > 0 && v > g->max_speed) {
    g->too_fast++;
    return CV_POSE_TOO_FAST;
  }
  memcpy(g->last, pos, sizeof g->last);
  g->last_t = t;
  g->have_last = 1;
  return CV_POSE_OK;
}
