/* The master's state and the parts of its frame loop that live in their own
 * files (internal to cluster/):
 *   master.c         set-up, the frame loop as named phases
 *   master_metrics.c the metrics lines (ready, frame, summary)
 *   master_sync.c    clock probes of the render ranks, swap skew, tracker
 *                    age and motion-to-photon latency, head prediction,
 *                    stop requests from windows
 *   master_lcd.c     LCD rounds summed in fixed point, the LCD image
 *   master_images.c  montages of written frames and the viewer simulation
 *   master_desktop.c the desktop preview window: preview images shown,
 *                    keyboard and mouse as the head tracker */
#ifndef CV_CLUSTER_MASTER_INTERNAL_H
#define CV_CLUSTER_MASTER_INTERNAL_H

#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <sys/types.h>

#include "compensate/formfactor.h"
#include "compensate/solve.h"
#include "lcd/readability.h"
#include "render/desktop.h"
#include "service/clocksync.h"
#include "service/metrics.h"
#include "service/posegate.h"
#include "service/tracker_calib.h"
#include "lightshare.h"
#include "service_internal.h"
#include "tonemap/adapt.h"
#include "tonemap/drago.h"
#include "tonemap/foveal.h"

typedef struct wall_in {
  int got;                /* eyes that reported this frame */
  double *r;              /* 3 np: sum over eyes of the patch images */
} wall_in;

#define POSE_RING 256

/* What the master used for a frame: the pose's sample time (its clock), the
 * time the pose was predicted to, the pose itself. */
typedef struct pose_rec {
  uint32_t frame;
  int valid;
  double t_sample;        /* when the tracker sample was taken / received (s) */
  double t_target;        /* the scan-out time it was predicted to (s) */
  double pos[3];
} pose_rec;

typedef struct master {
  cv_service *s;
  int bands;
  double lcd_aspect; /* LCD panel width / height (metres), 0 when the scene has none */
  int wall_clock;         /* 1: --clock wall */
  double t_start;         /* master clock at the first frame */
  cv_head_path *path;
  cv_dtrack_receiver *dtr;
  int has_tcal;            /* --tracker: calibrated eyes */
  cv_tracker_config tcal;
  double eye_rel[2][3];    /* newest calibrated eyes minus their midpoint (IPD, roll) */
  int have_eyes;
  cv_head_pose pose;      /* newest tracker sample */
  double pose_time;       /* its sample time (master clock) */
  cv_head_pose prev_pose; /* the one before (prediction) */
  double prev_pose_time;
  double latency_est;     /* expected pose -> scan-out (s), running average */
  pose_rec poses[POSE_RING];
  cv_tracker_stats trk;
  cv_adapt_params ap;
  cv_adapt_feed adf;      /* the adaptation (tonemap/adapt.h: the policy cave render shares) */
  cv_lumstats stats;      /* previous frame's merged foveal statistics */
  int have_stats;
  double lwmax;
  uint64_t light_key;
  int have_light;
  cv_lighting lighting;
  cv_lightmix *mix;       /* map drives: per-frame lighting from preprocessed maps */
  /* compensation */
  cv_display *disp;
  cv_ffmatrix *F;
  cv_scatter_system sys;
  cv_scatter_workspace *ws;
  float *T, *I;
  double *r;              /* 3n: current patch images (eyes averaged) */
  wall_in *walls;
  cv_scatter_stats cst;
  int comp_ok;
  uint32_t comp_pending;  /* --compensation-lag 1: the frame whose patch images wait for
                             their solve (0xffffffff: none; master_comp.c) */
  double comp_t_in;       /* when they came in */
  double comp_delay_ms;   /* CAVE_TEST_SOLVE_DELAY_MS */
  float *comp_hold;       /* its deltas held back, of frame comp_hold_frame, until comp_hold_due */
  uint32_t comp_hold_frame;
  double comp_hold_due;   /* service time (0: nothing held) */
  uint32_t comp_frame;    /* the frame of the last solve finished (0xffffffff: none) */
  double comp_lag_ms;     /* its time from the patch images in to the corrections out */
  uint64_t comp_solves;   /* solves finished */
  /* the wall-eyes' frame path (issue 29): one sample per report, frames >= 2 */
  double *path_read, *path_cpu, *path_gpu, *path_wait;
  size_t path_n, path_cap;
  uint64_t *late_corr;    /* per render rank: its count */
  uint64_t *files_dropped, *files_failed; /* per render rank: its counts of written frames */
  /* LCD */
  cv_mailbox *lcd_mb;
  struct cv_lcd_reduce *lcd_red; /* allreduce with the gather ranks (NULL: none) */
  uint64_t lcd_key;
  int32_t lcd_eye_q[3];
  cv_lcd_progress prog;
  uint8_t *seen;          /* budget flags: round already summed */
  uint32_t lcd_key_frame; /* frame the current key started */
  /* the newest estimate of an earlier key (rounds that finished after the
   * head or the lighting moved on: each round is a snapshot) */
  struct {
    cv_lcd_progress prog;
    uint64_t key;
    uint32_t frame, rounds;
    uint8_t *seen;
  } mot;
  uint32_t lcd_rounds;
  uint64_t lcd_rejected, lcd_late;
  double lcd_last_send;
  uint32_t lcd_sent_rounds;
  cv_image *lcd_content;
  /* readability of the last LCD estimate (master_lcd.c, docs/readability.md) */
  struct {
    int valid;
    uint64_t key;         /* camera/lighting key of the estimate */
    uint32_t rounds;      /* rounds it holds */
    uint32_t frame;       /* frame whose head and lighting it is of */
    double t;             /* service time it was computed */
    double cr_min;
    int veil;             /* the rounds carried the veil (always, but from older ranks) */
    struct {              /* per panel (s->lcd.panels) */
      cv_lcd_figure L_r, L_v, cr, area, vl;
      double L_a;
    } p[CV_LCD_MAX_PANELS];
    int have_light;       /* the rounds carried the light level (lcdwork.c) */
    double light[3];      /* outdoor horizontal, eye horizontal, eye vertical illuminance */
  } lread;
  const char *lcd_verdict; /* the first panel's verdict of lread (master_lcd.c; NULL before) */
  /* the readability over the drive's frames, as their metrics lines had it
   * (master_lcd.c: lcd_drive_tally, the summary's lcd_drive) */
  struct {
    uint32_t frames, with_figure, fresh; /* drive frames; with a figure; at most 2 frames old */
    double time;                         /* drive time the frames stand for (s) */
    struct {
      double cr_min, cr_min_t;           /* lowest mean CR, the time of its frame */
      uint32_t cr_min_frame, cr_min_of;  /* that frame, the frame its figure is of */
      uint32_t below;                    /* frames below cr_min */
      double below_s;                    /* their time (s) */
    } p[CV_LCD_MAX_PANELS];
  } ldrive;
  /* render ranks (index i = rank - 1) and wall-eyes (k = 2 wall + eye) */
  cv_mailbox **rep_mb;
  uint64_t late_reports;
  uint64_t sent_hash;     /* FNV-1a of this frame's packed state */
  int state_mismatch;     /* reports of this frame rendered with other bytes */
  uint64_t state_mismatch_total;
  cv_walleye_report *reps; /* per wall-eye, this frame */
  /* shared lighting (lightshare.h): per render rank its last lighting step
   * and whether it came for the frame being written */
  cv_mailbox *light_mb;
  cv_light_msg *light;
  uint8_t *light_have;
  int *got;               /* per wall-eye */
  /* synchronisation (master_sync.c) */
  cv_mailbox *pong_mb, *stop_mb, *ready_mb;
  uint8_t *swap_ready;    /* per render rank: ready for this frame's swap */
  double release_ms;      /* the last frame: waiting for the ranks to be ready */
  int release_late;       /* ranks not ready by the deadline */
  cv_clock_est *clk;      /* per render rank */
  double *last_ping;      /* per render rank: when the last probe went out */
  double offset_unc_max;  /* largest offset uncertainty of the last frame (s) */
  double skew_us;         /* the last frame's swap skew; NAN when not measured */
  double mtp_ms, age_ms, pred_err_mm, held_err_mm; /* the last frame's; NAN unmeasured */
  double *skew_hist, *mtp_hist, *age_hist, *pred_hist, *held_hist;
  size_t n_skew, n_lat, n_pred;
  int stop_code;          /* CV_WIN_* of the first stop request, MASTER_STOP_DEAD; 0 none */
  char stop_reason[300];
  /* heartbeat watch (master_health.c) */
  cv_mailbox *alive_mb;   /* gather ranks' heartbeats */
  double *alive_t;        /* per rank: when last heard of */
  double *owed_t;         /* per render rank: first state sent since its last report; 0 none */
  uint8_t *dead;          /* per rank: declared dead */
  char (*rank_host)[64];  /* per rank: its host, from its ready line ("" unknown) */
  int ndead, health_armed, lcd_red_abandoned;
  uint64_t lcd_gather_p2p; /* gather ranks' rounds summed point-to-point */
  uint64_t lcd_shared, lcd_dup; /* a dead gather rank's rounds summed from others; rounds come again */
  /* montages of the left eye (written frames) and the viewer simulation */
  cv_mailbox **img_mb;
  cv_image **mont, **mont_unc; /* per wall: display-linear compensated / uncompensated */
  uint32_t mont_frame;
  int mont_have;
  uint64_t montages;
  /* the image thread (master_images.c) writes the montages and runs the
   * viewer simulation; it sets montages, viewer_*, have_viewer under img_mu */
  double viewer_rms, viewer_rms_unc, viewer_ms; /* last viewer simulation (display-linear) */
  struct cv_filewriter *fw;
  pthread_mutex_t img_mu;
  int img_mu_on;
  uint64_t mont_flushed;  /* written frames handed to the image thread (the master's count) */
  int have_viewer;
  cv_rec709_lut lut;
  /* the desktop preview (--present desktop) */
  cv_desktop *desk;
  int desk_source;        /* 1: its keyboard and mouse are the head tracker */
  cv_head_nav nav;
  cv_mailbox **prev_mb;   /* per wall; NULL for walls the preview does not show */
  int desk_walls;         /* walls shown */
  int cell_x[CV_CAVE_MAX_WALLS], cell_y[CV_CAVE_MAX_WALLS];
  uint8_t *desk_rgb;      /* the composed image, desk_w x desk_h x 3 */
  int desk_w, desk_h;
  uint32_t desk_frame;    /* the preview frame being assembled */
  int desk_got;           /* its walls in */
  uint8_t desk_have[CV_CAVE_MAX_WALLS];
  double desk_last_mark;  /* when the last preview frame was marked */
  double desk_polled;     /* when its events were last taken */
  int desk_marked;        /* the current frame is a preview frame */
  uint64_t desk_marks, desk_shown; /* preview frames marked, shown */
  double desk_show_ms;    /* the last compose + XPutImage */
  int desk_pic_w, desk_pic_h; /* the walls' picture (cross or one wall) at (0, 0) */
  int desk_gaze_n;        /* the view along the gaze: n x n right of the picture */
  int desk_band;          /* the readout band's height, below both */
  int desk_label;         /* label scale (view/montage.h) */
  int desk_win_k;         /* the window's pixels per composed pixel */
  struct {
    uint32_t frame;
    double head[3], gaze[3];
  } desk_pose[8];         /* the head and gaze of the last preview frames (ring by frame) */
  double desk_fps, desk_fps_t0; /* frames per second over the last second or more */
  size_t desk_fps_n0;
  /* the live console (master_http.c) */
  struct cv_console *con;
  struct cv_http *http;
  struct cv_console_state *con_st; /* the state being built (large: heap) */
  uint64_t *con_reports;  /* per render rank: frames it reported */
  uint64_t *con_rep0;     /* at con_fps_t */
  double con_fps_t, con_p99_t, con_heat_t;
  int paused, head_console;
  double raw_prev, held_s; /* the drive clock: raw time at the last frame, time held by pauses */
  int ovr_sky, ovr_yaw;
  unsigned sky_mask;
  double sky[3], yaw;
  double *con_ms;          /* per frame: the console's work on the master thread (controls, publish) */
  size_t con_n;
  double con_ms_frame;     /* this frame's so far */
  /* metrics */
  FILE *mf;
  char metrics_path[4200];  /* where mf writes */
  off_t metrics_good;       /* bytes of whole lines in it */
  uint32_t metrics_rotations; /* files rotated (--metrics-max-mb) */
  char metrics_err[400];    /* why a line could not be written ("" none: master_out.c) */
  int files_stop_said;      /* the stop for failed frame files was made */
  uint64_t prt_hash;        /* content hash of the .prt the master loaded (cv_prt_meta.file_hash) */
  char prt_bad[300];        /* ranks whose .prt hash differs ("3, 7"), prt_nbad of them */
  int prt_nbad;
  uint64_t prt_bad_hash;    /* the first of theirs */
  double stalled_s;         /* the master's own stalls (SIGSTOP, starved) in report waits, seconds */
  uint32_t stalls;          /* and their count */
  double stall_last;        /* master_stall_check's previous call */
  cv_pose_gate gate;        /* implausible DTrack poses held (service/posegate.h) */
  int gate_on;
  double gate_warn_t;       /* the last warning about them (one per 5 s) */
  uint64_t gate_warned;     /* held samples already said */
  cv_metrics_line *ml;
  double *frame_ms, *overhead_ms;
  double *overhead_cpu_ms; /* the master thread's CPU time in overhead_ms's intervals */
  double run_cpu0_ms;      /* its CPU time when the frames started */
  double *frame_t;        /* cap: service time each frame started */
  double *frame_sim_t;    /* cap: each frame's drive time (s; frame_clock) */
  size_t cap;             /* entries of the per-frame histories */
  size_t nframes_done;
} master;

/* master_sync.c */
int master_sync_setup(master *m, cv_err *err);
void master_sync_free(master *m);
/* Initial clock probes: `rounds` to every render rank, waiting for each. */
void master_sync_initial(master *m, int rounds);
/* Sends due probes (one per rank every 0.25 s) and takes the answers. */
void master_sync_poll(master *m);
/* Scheduled swap lock: waits (at most the timeout) until every render rank
 * finished frame f, then sends each its swap time, margin ahead, in its
 * own clock.  No-op unless --swap-sync scheduled with the swap lock on. */
void master_release_swaps(master *m, uint32_t f);
/* Takes stop requests; 1 when the service must stop (reason in m). */
int master_stop_poll(master *m);
/* Records the pose used for frame f (sample time, target time). */
void master_pose_record(master *m, uint32_t f, double t_sample, double t_target, const double pos[3]);
/* From this frame's reports: the previous frame's swap skew, tracker age,
 * motion-to-photon estimate and prediction error. */
void master_swap_stats(master *m, uint32_t f);
/* The head for a frame: newest sample, predicted to the expected scan-out
 * on the wall clock.  *t_sample gets the sample time, *t_target the target. */
void master_head(master *m, double now, double frame_time, double head[3], double gaze[3],
                 double *t_sample, double *t_target);
void master_sync_metrics(master *m, cv_metrics_line *ml);
void master_sync_summary(master *m, cv_metrics_line *ml);
/* "<stem>_p50", "_p99", "_max" of v[0..n) into the line (nothing when n = 0). */

/* master_lcd.c */
void lcd_drain(master *m);
/* The current LCD key becomes `key` at frame `frame`: the image of the old
 * key becomes the earlier-key estimate (when it has rounds), and that
 * estimate's rounds start the new image when they are of the new key. */
void lcd_key_change(master *m, uint64_t key, uint32_t frame);
void lcd_publish(master *m, int force);
void lcd_write(master *m, const char *stem);
/* At quit: the last allreduce epoch (bounded wait), before lcd_write. */
void lcd_reduce_finish(master *m);
/* The allreduce's totals as object `name` (nothing without gather ranks). */
void lcd_reduce_metrics(master *m, cv_metrics_line *ml, const char *name);
/* Recomputes the readability figures when the estimate gained rounds. */
void lcd_readability_update(master *m);
/* The ready line's lcd_panels: where the LCD panels come from (the scene
 * config, the lcd block baked with the .prt, or the defaults when the .prt
 * has none; master_lcd.c). */
void lcd_ready_metrics(master *m, cv_metrics_line *ml);
/* The readability object `name` of a metrics line (last valid estimate,
 * its key and age), nothing before the first estimate. */
void lcd_readability_metrics(master *m, cv_metrics_line *ml, const char *name);
/* After a frame's line: counts the figures it carried into m->ldrive (held
 * frames after the drive are left out; dt_s: the time the frame stands for). */
void lcd_drive_tally(master *m, uint32_t frame, double t, double dt_s, int held);
/* The summary's object `name`: per panel the lowest mean CR over the drive's
 * frames, its frame and time, the frames and the share of drive time below
 * cr_min; the frames with a figure and with one at most 2 frames old. */
void lcd_drive_summary(master *m, cv_metrics_line *ml, const char *name);

/* Panel 0's verdict text of the last estimate ("" before the first). */

/* The live console (master_http.c, docs/service.md "Live console"): the
 * server started in the set-up (a port in use fails it), the ranks' rows
 * from their ready lines, the controls taken at the start of a frame and
 * applied through the master's own state (pause holds the drive's clock,
 * quit stops as SIGTERM does, a head pose is a tracker sample, sky and yaw
 * hold those values of the drive), one publish after each frame's metrics
 * line, the montages from the image thread and the LCD heat map. */
int master_http_setup(master *m, cv_err *err);
void master_http_free(master *m);
void master_http_ready(master *m, char *const *lines);
void master_http_controls(master *m);
void master_http_publish(master *m, const cv_frame_state *fs, double frame_s, double master_s);
void master_http_montage(master *m, int which, uint32_t frame, cv_image *const *walls);
void master_http_heatmap(master *m, const cv_lcd_readability *rd, uint32_t frame);
void master_http_metrics(master *m, cv_metrics_line *ml);
void master_http_summary(master *m, cv_metrics_line *ml);
/* frame_clock's drive time with the console's pause: raw minus the time held. */
double master_http_drive_time(master *m, double raw);
/* The console's sky and heading over the drive's (frame_lighting). */
void master_http_drive(master *m, cv_drive_state *d);

/* master_desktop.c */
/* Opens the preview window (a no-op without --present desktop) sized for
 * the cross or the wall, the keyboard-and-mouse head (when neither
 * --head-path nor --dtrack is given) and the preview mailboxes.  Errors:
 * the window's (CV_ERR_BACKEND naming the X display), CV_ERR_NOMEM. */
int master_desktop_setup(master *m, cv_err *err);
void master_desktop_free(master *m);
/* 1 when frame f is a preview frame (--desktop-fps allows one now). */
int master_desktop_mark(master *m, uint32_t f, const double head[3], const double gaze[3]);
/* Takes preview images; shows a frame once all its walls are in. */
void master_desktop_drain(master *m);
/* Takes the window's events: input steers the head (m->pose, a tracker
 * sample at time now, the master's clock); Escape, close or a lost
 * connection become a stop request. */
void master_desktop_poll(master *m, double now);
void master_desktop_metrics(master *m, cv_metrics_line *ml);
void master_desktop_summary(master *m, cv_metrics_line *ml);

/* master_images.c */
int master_images_setup(master *m, cv_err *err);
void master_images_free(master *m);
void montage_drain(master *m);
void montage_flush(master *m);

/* The out folder (master_out.c): the metrics file opened, each line
 * written whole or not at all (a failed write is cut back to the last whole
 * line and stops the run, MASTER_STOP_OUT, as does a metrics file deleted
 * under the run); a rank's failed frame files stop the run; the last line
 * says where the metrics are and whether they are complete. */
int master_out_open(master *m, cv_err *err);
void master_metrics_put(master *m);

/* The master's metrics lines (master_metrics.c).  frame_times: the
 * service times (s) and the master thread's CPU times (ms) of a frame's
 * phases. */
typedef struct frame_times {
  double tf0, t_sent, t_wait, tc0, tc1, tf1;
  double cf0, c_sent, c_wait, cc0, cc1, cf1; /* the master thread's CPU time there (ms) */
} frame_times;
/* This thread's CPU time (ms). */
double master_thread_cpu_ms(void);
/* Frame f's drive time (s), NAN past the history. */
static inline double master_frame_time(const master *m, uint32_t f) {
  return f < m->cap && m->frame_sim_t ? m->frame_sim_t[f] : (double)NAN;
}
void master_metrics_ready(master *m, const char *host, const char *const *lines);
void master_metrics_frame(master *m, uint32_t f, const cv_frame_state *fs, const cv_lumstats *acc, int late,
                          const frame_times *t, double overhead, double overhead_cpu);
void master_metrics_summary(master *m, uint32_t f, double run_t0);
void master_out_files_failed(master *m, int rank, uint64_t failed, const char *first);
void master_out_final_line(master *m);
/* A ready message (flag, 8-byte .prt hash, text) of rank `from`: its hash
 * compared with the master's (issue 35, defect 5).  After all are in,
 * master_prt_mismatch gives 1 and why when some rank loaded another file. */
void master_prt_check(master *m, int from, const uint8_t *data, long len);
int master_prt_mismatch(master *m, char *why, size_t cap);
/* The master's own stall (issue 35, defect 9): the time since
 * m->stall_last (the previous call in a wait loop; the loop sets it when it
 * starts) when 0.5 s or more, else 0.  A stall is counted
 * (stalls, stalled_s), moves the heartbeat watch's times by the gap and,
 * from 1 s, is said on stderr; the caller moves its deadline by the gap. */
double master_stall_check(master *m);

/* Heartbeat watch (master_health.c, docs/dead-rank.md). */
/* stop_code: a wall-eye died; a wall-eye was signalled alone (walleye.c
 * watch_signal); the out folder or the metrics could not be written
 * (master_out.c): each gives exit status 1.  The console's quit
 * (master_http.c) ends the run as SIGTERM would. */
enum {
  MASTER_STOP_DEAD = 100,
  MASTER_STOP_SIGNAL = 101,
  MASTER_STOP_OUT = 102,
  MASTER_STOP_CONSOLE = 103
};
/* The scattering compensation (master_comp.c): set-up (form factors,
 * solver, the thread with lag 1), the frame's solve (on the path, lag 0)
 * or its hand-over to the thread (lag 1), the thread's finished solves
 * sent (call while waiting), metrics. */
int master_comp_setup(master *m, cv_err *err);
void master_comp_free(master *m);
void master_comp_frame(master *m, uint32_t frame);
void master_comp_poll(master *m);
void master_comp_metrics(master *m, cv_metrics_line *ml, double frame_ms);
/* The frame path's samples of a report (master_comp.c) and their summary. */
void master_path_sample(master *m, int from, const cv_walleye_report *r);
void master_path_summary(master *m, cv_metrics_line *ml);

int master_health_setup(master *m);
void master_health_free(master *m);
/* Starts the watch (every rank counts as heard of now). */
void master_health_arm(master *m);
void master_health_seen(master *m, int rank);
/* Keeps rank's host from its ready line ("rank K on HOST: ..."), for the
 * messages naming a dead rank. */
void master_health_host(master *m, int rank, const char *ready_line);
/* A frame state went out: the wall-eyes owe a report. */
void master_health_sent(master *m);
/* Takes heartbeats; declares ranks silent for --gather-timeout dead. */
void master_health_poll(master *m);
/* The frame state's lcd_dead: bit g for gather-only rank g declared dead. */
uint64_t master_health_lcd_dead(const master *m);
/* The frame state's lcd_dead_floor: the lowest round of the current key
 * that a dead gather rank owned and the master has not summed (0: none dead). */
uint32_t master_health_lcd_floor(const master *m);
/* "dead_ranks": [ranks] */
void master_health_metrics(master *m, cv_metrics_line *ml);

#endif
