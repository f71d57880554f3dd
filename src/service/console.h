/* The live console's data (issue 33; docs/service.md "Live console",
 * docs/metrics.md "Prometheus"): what the master publishes once per frame,
 * what the HTTP threads read, and the controls they queue for the master.
 * No MPI and no HTTP here: cluster/master_http.c fills the state from the
 * master, src/http/ serves it.
 *
 * Threads.  The master is the only writer: cv_console_publish copies its
 * state and appends one per-frame sample, taking the lock only if it is free
 * (pthread_mutex_trylock): when an HTTP thread holds it, the state and the
 * samples wait in the master's own staging area and go in with the next
 * frame's publish.  So the frame loop never waits for a reader.  Readers
 * (cv_console_read) copy the state and the sample ring under the lock and
 * render outside it.  Images (the montages from the master's image thread,
 * the LCD heat map) have their own lock; their PNGs are encoded by the
 * reader that asks for them, once per image version.  Controls go the other
 * way through a bounded queue that the master empties at the start of a
 * frame (again with trylock). */
#ifndef CV_SERVICE_CONSOLE_H
#define CV_SERVICE_CONSOLE_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"

#define CV_CONSOLE_MAX_RANKS 256
#define CV_CONSOLE_PANELS 8
#define CV_CONSOLE_RING 600    /* per-frame samples kept (20 s at 30 fps) */
#define CV_CONSOLE_BUCKETS 12  /* cave_frame_seconds buckets, +Inf included */
#define CV_CONSOLE_QUEUE 16    /* controls waiting for the master */

/* The upper bounds (s) of cave_frame_seconds's buckets; the last is +Inf. */
extern const double cv_console_buckets[CV_CONSOLE_BUCKETS];

enum { CV_ROLE_NAME_MASTER = 0, CV_ROLE_NAME_WALLEYE = 1, CV_ROLE_NAME_GATHER = 2 };

typedef struct cv_console_rank {
  int rank;
  int role;            /* CV_ROLE_NAME_* */
  char host[64];
  char view[48];       /* wall-eye: "front L", "front L+R"; else "" */
  char gpu[96];        /* GL_RENDERER of a render rank; "" for others */
  double fps;          /* render ranks: reports a second over the last seconds; gather: 0 */
  uint64_t late;       /* frames whose report missed the deadline */
  int dead;            /* declared dead (docs/dead-rank.md) */
  char error[160];     /* the last problem seen, "" none */
} cv_console_rank;

/* One frame, as the plots show it.  NaN: not measured that frame. */
typedef struct cv_console_sample {
  uint32_t frame;
  double t;                          /* seconds since the run's first frame (wall) */
  double frame_s, master_s;          /* frame time, the master's own work (s) */
  double skew_s, mtp_s;              /* swap skew, motion-to-photon (s) */
  double cr[CV_CONSOLE_PANELS];      /* each panel's mean contrast ratio */
} cv_console_sample;

typedef struct cv_console_state {
  char master_host[64];
  char url[160];         /* where the console is: http://ADDR:PORT/ */
  char clock[8];         /* wall or sim */
  int files;             /* --present files: montage images on disk too */
  int images;            /* the montages reach the console (the viewer simulation ran) */
  int lcd;               /* the LCD final gather runs */
  int compensation;      /* the scattering compensation runs */
  int paused, quitting;
  uint32_t frame;        /* the last frame finished */
  uint64_t frames_total;
  double run_seconds;    /* since the first frame */
  double drive_time_s;   /* the drive's clock (stands still while paused) */
  double frame_sum_s;    /* sum of every frame's time (the histogram's _sum) */
  uint64_t frame_hist[CV_CONSOLE_BUCKETS]; /* frames with time <= bucket (cumulative) */
  double master_s_p99;   /* p99 of the master's work over the ring (s) */
  uint64_t late_reports_total, late_walleyes_total, state_mismatch_total;
  uint64_t files_dropped_total, files_failed_total, montages_total;
  /* lighting and head */
  double lwa, lwmax;     /* adaptation luminance, Drago's Lwmax (cd/m2) */
  char head_source[24];  /* fixed, path, dtrack, dtrack-calibrated, desktop, console */
  double head[3], gaze[3];
  int sky;               /* a sky drive (else maps) */
  double yaw_deg, pitch_deg, roll_deg, turbidity, sun_elevation_deg, sun_azimuth_deg;
  int n_maps;
  double weights[8];
  int override_sky, override_yaw; /* the console's sky / heading hold the drive's */
  /* LCD */
  uint32_t lcd_rounds, lcd_budget;
  int n_panels;
  char panel_name[CV_CONSOLE_PANELS][32];
  double cr[CV_CONSOLE_PANELS];   /* NaN before the first estimate */
  double cr_min;
  char verdict[16];      /* READABLE, UNREADABLE, uncalibrated, "" none yet */
  double viewer_rms, viewer_rms_unc; /* NaN before the first viewer simulation */
  /* sync */
  double skew_us, mtp_ms; /* the last frame's, NaN unmeasured */
  /* controls */
  uint64_t controls_applied, controls_rejected;
  char last_control[160];
  /* ranks */
  int n_ranks;
  cv_console_rank ranks[CV_CONSOLE_MAX_RANKS];
} cv_console_state;

/* A control from the console (applied by the master at its next frame). */
enum {
  CV_CTL_PAUSE = 1,  /* the drive's clock stands still (frames go on) */
  CV_CTL_RESUME,
  CV_CTL_QUIT,       /* as SIGTERM: the frame ends, every rank quits, the summary */
  CV_CTL_HEAD,       /* a head pose, as a tracker sample: v[0..2] position (m), v[3..5] gaze */
  CV_CTL_SKY,        /* sun elevation, azimuth (deg), turbidity: v[0..2]; mask bits 1, 2, 4 */
  CV_CTL_YAW,        /* the car's heading (deg): v[0] */
  CV_CTL_DRIVE       /* back to the drive's own sky and heading */
};

typedef struct cv_console_ctl {
  int kind;
  unsigned mask;  /* CV_CTL_SKY: which of v[0..2] were given; CV_CTL_HEAD: 1 when a gaze was */
  double v[6];
} cv_console_ctl;

typedef struct cv_console cv_console;

int cv_console_create(cv_console **out);
void cv_console_destroy(cv_console *c); /* accepts NULL */

/* The master's publish: the state (copied) and, when s is not NULL, one
 * sample appended.  Never waits: see the top of this file.  Returns 1 when
 * it reached the readers now, 0 when staged for the next publish. */
int cv_console_publish(cv_console *c, const cv_console_state *st, const cv_console_sample *s);
/* The readers' copy: the state, the newest samples (at most cap, oldest
 * first) into ring and their count into *n, and the version (counts
 * publishes that reached the readers).  ring may be NULL with cap 0. */
void cv_console_read(cv_console *c, cv_console_state *st, cv_console_sample *ring, size_t cap, size_t *n,
                     uint64_t *version);
uint64_t cv_console_version(cv_console *c);

/* Images the page shows: 8-bit RGB, row 0 at the top. */
enum { CV_IMG_PROJECTOR = 0, CV_IMG_UNCOMPENSATED, CV_IMG_VIEWER, CV_IMG_HEATMAP, CV_IMG_COUNT };
extern const char *const cv_console_image_names[CV_IMG_COUNT]; /* projector, uncompensated, viewer, heatmap */
/* Copies an image in (the producer's thread).  blocking 0: gives up (returns
 * 1) when a reader holds the images' lock, for callers on the frame's path.
 * Returns 0 when stored, -1 out of memory. */
int cv_console_set_image(cv_console *c, int which, uint32_t frame, int w, int h, const uint8_t *rgb,
                         int blocking);
/* The image as a PNG (malloc'd, the caller frees it), encoded on the
 * caller's thread once per image version.  CV_ERR_NOT_FOUND when there is
 * none yet. */
int cv_console_image_png(cv_console *c, int which, uint8_t **png, size_t *n, uint32_t *frame, cv_err *err);

/* Controls.  push: 0 queued, -1 the queue is full.  take (the master): 1
 * when one was taken into *out, 0 when none (or a reader held the lock). */
int cv_console_push(cv_console *c, const cv_console_ctl *ctl);
int cv_console_take(cv_console *c, cv_console_ctl *out);

/* Parses a control from its form fields (application/x-www-form-urlencoded
 * pairs or the query string): "action" = pause, resume, quit, head (x, y, z
 * in metres, optional gx, gy, gz), sky (any of elevation, azimuth in
 * degrees, turbidity 2..10), yaw (deg), drive.  get(name) returns a field's
 * value or NULL.  CV_OK, or CV_ERR_CONFIG / CV_ERR_RANGE with a message
 * naming the field and what was expected. */
int cv_console_parse_control(const char *(*get)(void *ctx, const char *name), void *ctx, cv_console_ctl *out,
                             cv_err *err);
/* "pause", "head 0.1 1.6 0.2", ... for the page and the logs. */
void cv_console_ctl_text(const cv_console_ctl *ctl, char *buf, size_t cap);

/* Rendering (pure functions of a copy).  *out malloc'd, the caller frees.
 * prometheus: the text exposition format 0.0.4 (docs/metrics.md);
 * json: {"state": {...}, "samples": [...]}, samples newer than frame
 * `since` only (since < 0: all).  CV_ERR_NOMEM. */
int cv_console_prometheus(const cv_console_state *st, char **out, size_t *len);
int cv_console_json(const cv_console_state *st, const cv_console_sample *ring, size_t n, int64_t since,
                    char **out, size_t *len);

/* Frame-time histogram: adds one frame of `seconds` to st (count, sum and
 * the cumulative buckets). */
void cv_console_hist_add(cv_console_state *st, double seconds);

#endif
