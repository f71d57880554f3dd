/* Tracker calibration: from DTrack bodies in the tracking room's frame to
 * the eyes in CAVE coordinates (metres, +Y up, the front wall towards -Z).
 * The tracker config (JSON, docs/tracker.md) says:
 *
 *   units        what one tracker unit is (DTrack sends mm: "mm"; as the
 *                scene config's mesh.units: mm, cm, m, in, ft or a number)
 *   room_to_cave the rigid transform from the tracking room to the CAVE:
 *                p_cave = R p_room + T, R = Rz Ry Rx of rotate_deg
 *   body_id      which DTrack body is the head (the glasses)
 *   forward, up  the glasses' viewing direction and up in the body's own
 *                frame (defaults (0, 0, -1) and (0, 1, 0)); right = forward x up
 *   eye_offset   body frame, metres: from the marker to the midpoint between
 *                the eyes
 *   ipd          interpupillary distance, metres: each eye ipd/2 along right
 *   udp          port, bind address, optional multicast group and interface
 *
 * With B the body's rotation (DTrack's matrix, body to room) and p its
 * position: M = R B (body to CAVE), centre = R (units p) + T + M eye_offset,
 * eye_left/right = centre -/+ (ipd/2) M right, gaze = M forward, up = M up;
 * the head's roll comes from the full matrix. */
#ifndef CV_SERVICE_TRACKER_CALIB_H
#define CV_SERVICE_TRACKER_CALIB_H

#include "service/tracker.h"

typedef struct cv_tracker_config {
  char source[256];  /* the config file, or "(defaults)" */
  double unit_m;     /* metres per tracker unit (default 0.001: DTrack's mm) */
  double room_rotate_deg[3];
  double room_R[9];  /* row-major, from room_rotate_deg */
  double room_T[3];  /* metres */
  int body_id;       /* default 1 */
  double forward[3]; /* body frame, unit (default 0, 0, -1) */
  double up[3];      /* body frame, unit, orthogonalised against forward (default 0, 1, 0) */
  double eye_offset[3]; /* body frame, metres (default 0) */
  double ipd;        /* metres (default 0.064) */
  int port;          /* default 5000 */
  char bind[64];     /* default "0.0.0.0" */
  char multicast[64]; /* "" = unicast */
  char iface[64];    /* multicast interface address, "" = any */
} cv_tracker_config;

/* A calibrated head: everything in CAVE coordinates (metres). */
typedef struct cv_tracked_head {
  double marker[3];        /* the body's origin */
  double center[3];        /* midpoint between the eyes */
  double eye[2][3];        /* left, right */
  double gaze[3], up[3], right[3]; /* unit, orthonormal */
  double yaw_deg;          /* gaze about +Y: 0 looks along -Z, > 0 towards +X */
  double pitch_deg;        /* > 0 looks up */
  double roll_deg;         /* about the gaze: > 0 the head tilts to its right */
  double quality;          /* DTrack's quality of the body */
} cv_tracked_head;

void cv_tracker_config_default(cv_tracker_config *c);
/* Parses a tracker config.  Unknown fields, wrong types and bad values are
 * errors naming "file: field: what" (CV_ERR_CONFIG; CV_ERR_IO unreadable). */
int cv_tracker_config_load(const char *path, cv_tracker_config *c, cv_err *err);
/* Same on JSON text; name stands for the file in messages. */
int cv_tracker_config_parse(const char *text, const char *name, cv_tracker_config *c, cv_err *err);

/* The head of body c->body_id in frame f.  CV_ERR_NOT_FOUND: no such body
 * or not tracked (quality <= 0); CV_ERR_RANGE: a degenerate rotation. */
int cv_tracker_head(const cv_tracker_config *c, const cv_dtrack_frame *f, cv_tracked_head *out);

/* Opens a receiver as the config says (unicast on bind:port, or multicast
 * group joined).  port_override >= 0 replaces c->port (0: ephemeral). */
int cv_tracker_open(const cv_tracker_config *c, int port_override, cv_dtrack_receiver **out,
                    cv_err *err);

#endif
