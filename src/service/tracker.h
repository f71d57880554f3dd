/* Head tracking for the render service's master rank: a recorded head path
 * (text file) or live ART DTrack ASCII packets over UDP.
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
void cv_dtrack_receiver_close(cv_dtrack_receiver *r); /* accepts NULL */

#endif
