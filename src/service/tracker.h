/* Head tracking for the render service's master rank: a recorded head path
 * (text file), live ART DTrack ASCII packets over UDP, or a head steered
 * from a desktop's keyboard and mouse (cv_head_nav, for the desktop
 * preview without a CAVE).
 *
 * Poses are in CAVE coordinates (metres, right-handed, +Y up, the front
 * wall towards -Z).  The DTrack receiver is non-blocking so the master can
 * poll it once per frame: a silent tracker holds the last pose, a malformed
 * packet is counted and dropped, and neither ever stalls a frame.
 *
 * DTrack ASCII (REFERENCES.md "Cluster"; one UDP datagram per frame, lines
 * separated by CR/LF):
 *   fr <n>                               frame counter
 *   ts <t>                               timestamp, seconds
 *   6d <n> [id qu][x y z eta theta phi][b0 b1 ... b8] ... (n bodies)
 * positions in mm, angles in degrees, rotation matrix b column-wise
 * (R[row][col] = b[col*3 + row]).  Other line types (3d, 6df, 6df2, gl,
 * 6dcal, ...) are skipped. */
#ifndef CV_SERVICE_TRACKER_H
#define CV_SERVICE_TRACKER_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"

typedef struct cv_head_pose {
  double pos[3];  /* metres, CAVE frame */
  double gaze[3]; /* unit */
  double t;       /* seconds (path time, or receive time for DTrack) */
  int valid;      /* 0: no pose yet */
} cv_head_pose;

/* --- recorded path ------------------------------------------------------ */

/* Recorded path: text lines "t x y z gx gy gz" (seconds, metres in CAVE
 * coordinates; '#' starts a comment, blank lines are skipped); t strictly
 * increasing; the gaze need not be unit (it is normalised) but not zero. */
typedef struct cv_head_path cv_head_path; /* opaque, immutable once loaded */

/* Loads a path file.  *out owned by the caller (cv_head_path_destroy).
 * Errors (err: "file:line: what"): CV_ERR_IO (unreadable), CV_ERR_FORMAT
 * (not 7 numbers, trailing text), CV_ERR_NONFINITE, CV_ERR_RANGE (t not
 * strictly increasing, zero gaze), CV_ERR_EMPTY (no samples), CV_ERR_NOMEM. */
int cv_head_path_load(const char *path, cv_head_path **out, cv_err *err);
/* Same on text in memory; name stands for the file in the messages. */
int cv_head_path_parse(const char *text, const char *name, cv_head_path **out, cv_err *err);
void cv_head_path_destroy(cv_head_path *p); /* accepts NULL */
int cv_head_path_count(const cv_head_path *p);
double cv_head_path_duration(const cv_head_path *p); /* last t - first t */

/* Pose at time t: linear interpolation of the position, normalised linear
 * interpolation of the gaze (falls back to the nearer sample's gaze when the
 * two are opposite).  loop: t wraps into [t_first, t_last); otherwise the
 * ends are held.  out->t = t, out->valid = 1.  A non-finite t is taken as
 * the first sample's time. */
void cv_head_path_eval(const cv_head_path *p, double t, int loop, cv_head_pose *out);

/* --- DTrack ASCII ------------------------------------------------------- */

#define CV_DTRACK_MAX_BODIES 16
#define CV_DTRACK_MAX_DRAIN 1024

typedef struct cv_dtrack_frame {
  uint32_t frame;
  double ts;
  int has_ts;
  int n_bodies;
  struct {
    int id;
    double quality;
    double pos_mm[3];
    double euler_deg[3];
    double rot[9]; /* column-wise as sent: R[row][col] = rot[col*3 + row] */
  } body[16];
} cv_dtrack_frame;

/* Parses one datagram of len bytes (need not be NUL-terminated).  Errors
 * (err: "dtrack: line N: what"), *out undefined: CV_ERR_FORMAT (truncated or
 * unbalanced brackets, body count not matching the blocks, non-numbers,
 * trailing text, more than 16 bodies, no fr/6d line at all), CV_ERR_NONFINITE
 * (NaN/Inf anywhere), CV_ERR_RANGE (rotation not orthonormal with det +1
 * within 1e-3 per entry of R^T R - I; checked for bodies with quality > 0,
 * since untracked bodies may carry a zero matrix).  Unknown line types
 * (any token of letters and digits) are skipped; a packet must hold an fr or
 * a 6d line. */
int cv_dtrack_parse(const char *buf, size_t len, cv_dtrack_frame *out, cv_err *err);

/* Head pose of body body_id: pos in metres, gaze = R * forward_local
 * normalised (forward_local NULL: (0, 0, -1)).  out->t = f->ts (0 without
 * ts), valid = 1.  Errors: CV_ERR_NOT_FOUND (no such body, or its quality
 * <= 0: DTrack's "not tracked"), CV_ERR_INVALID (zero forward). */
int cv_dtrack_head_pose(const cv_dtrack_frame *f, int body_id, const double forward_local[3],
                        cv_head_pose *out);

/* UDP receiver: non-blocking, bound to host (NULL: "127.0.0.1", an IPv4
 * address) and port (0: an ephemeral port, see cv_dtrack_receiver_port);
 * poll returns the newest valid pose received since the last poll; counts
 * packets, malformed ones (dropped) and packets without the body, and keeps
 * the last pose and its receive time. */
typedef struct cv_dtrack_receiver cv_dtrack_receiver;
typedef struct cv_tracker_stats {
  uint64_t packets;   /* datagrams received */
  uint64_t malformed; /* rejected by cv_dtrack_parse, dropped */
  uint64_t no_body;   /* well-formed but without a tracked body_id */
  double last_rx_time; /* `now` of the poll that got the last pose; -1: none */
} cv_tracker_stats;

/* Opens the socket.  *out owned by the caller (cv_dtrack_receiver_close).
 * Errors (err names host:port): CV_ERR_INVALID (bad host or port),
 * CV_ERR_IO (socket/bind failed, e.g. port in use), CV_ERR_NOMEM. */
int cv_dtrack_receiver_open(const char *host, int port, int body_id, cv_dtrack_receiver **out,
                            cv_err *err);
/* Bound port (useful after opening port 0). */
int cv_dtrack_receiver_port(const cv_dtrack_receiver *r);
/* Drains the pending datagrams without blocking (at most
 * CV_DTRACK_MAX_DRAIN per call, so a flood cannot stall a frame; the rest
 * wait for the next poll).  Returns 1 when a new
 * pose arrived (pose_out = the newest, t = now), 0 when none (pose_out = the
 * last pose, valid 0 if there never was one: a silent tracker holds the last
 * pose), CV_ERR_IO on a socket error.  now is the caller's clock (seconds,
 * finite: it becomes the pose's t and last_rx_time).
 * pose_out and stats may be NULL; stats receives the running totals. */
int cv_dtrack_receiver_poll(cv_dtrack_receiver *r, double now, cv_head_pose *pose_out,
                            cv_tracker_stats *stats);
/* As cv_dtrack_receiver_poll, and frame_out (may be NULL) gets the whole
 * frame the pose came from (all bodies, the rotation matrix; n_bodies 0
 * before the first), for calibrated poses (tracker_calib.h). */
int cv_dtrack_receiver_poll_frame(cv_dtrack_receiver *r, double now, cv_head_pose *pose_out,
                                  cv_dtrack_frame *frame_out, cv_tracker_stats *stats);
/* Multicast: joins group (an IPv4 multicast address) on the interface with
 * address iface (NULL: any) so that the socket (opened on "0.0.0.0" and
 * the group's port) receives it.  CV_ERR_INVALID, CV_ERR_IO. */
int cv_dtrack_receiver_join(cv_dtrack_receiver *r, const char *group, const char *iface,
                            cv_err *err);
void cv_dtrack_receiver_close(cv_dtrack_receiver *r); /* accepts NULL */

/* --- keyboard and mouse (desktop preview) --------------------------------- */

/* Input gathered since the last apply: key presses counted per axis of the
 * head's own floor frame and the mouse drag in pixels. */
typedef struct cv_head_nav_input {
  int right;      /* presses: > 0 right, < 0 left (perpendicular to the gaze, floor plane) */
  int forward;    /* presses: > 0 forward, < 0 back (the gaze projected on the floor) */
  int up;         /* presses: > 0 up, < 0 down (+Y) */
  double drag_x;  /* left-button drag, pixels: > 0 turns the gaze right */
  double drag_y;  /* pixels: > 0 (downwards on the screen) turns the gaze down */
  int reset;      /* back to the home pose (applied before the rest) */
} cv_head_nav_input;

/* A head moved by key steps in the CAVE's floor plane (XZ, relative to
 * where the gaze points), up and down along +Y, and turned by mouse drags
 * (yaw about +Y, pitch within +-85 degrees), kept inside a box.  Plain
 * data, owned by the caller; the pose's t is the caller's clock at the
 * input that last changed it (a sample time, as DTrack's receive time). */
typedef struct cv_head_nav {
  double home_pos[3], home_gaze[3]; /* reset pose (gaze unit) */
  double lo[3], hi[3];              /* the head stays within [lo, hi] */
  double step;                      /* metres per key press */
  double deg_per_px;                /* degrees of turn per pixel of drag */
  double yaw, pitch;                /* radians; yaw 0 looks along -Z, > 0 towards +X */
  cv_head_pose pose;                /* current pose */
  uint64_t inputs;                  /* applies that changed the pose */
} cv_head_nav;

/* Starts at pos/gaze (the home pose), sampled at time `now`.  Errors:
 * CV_ERR_INVALID (zero or non-finite gaze, a non-finite or empty box, pos
 * outside it, step or deg_per_px not > 0 and finite). */
int cv_head_nav_init(cv_head_nav *n, const double pos[3], const double gaze[3], const double lo[3],
                     const double hi[3], double step, double deg_per_px, double now, cv_err *err);
/* Applies one batch of input at time now: reset first, then the turn,
 * then the steps along the turned gaze's floor axes (the position clamped
 * to the box).  Returns 1 when the pose changed (pose.t = now, inputs
 * counted), 0 when not (an empty batch, or a step into the box's side). */
int cv_head_nav_apply(cv_head_nav *n, const cv_head_nav_input *in, double now);

#endif
