/* The cluster render service (`mpirun -np N cave run ...`): options, the
 * rank layout and the three roles (issue 6; ../shared/DESIGN.md "The system
 * in one picture").
 *   rank 0            master: scene state, tracker, adaptation, LCD sums,
 *                     compensation solve, metrics;
 *   ranks 1 .. R      render ranks: rank 1 + i shows outputs[i] of the CAVE
 *                     config (one eye of a wall, or both eyes in one window;
 *                     without outputs rank 1 + 2w + e is wall w, eye e); an
 *                     idle thread does LCD rounds;
 *   ranks > R         gather-only: LCD final-gather rounds.
 * No MPI here: roles talk through comm.h. */
#ifndef CV_CLUSTER_SERVICE_H
#define CV_CLUSTER_SERVICE_H

#include <signal.h>
#include <stdint.h>

#include "core/status.h"
#include "io/scene_config.h"
#include "lcd/lcd_config.h"
#include "lcd/panels.h"
#include "prt/prt.h"
#include "service/drive.h"
#include "service/framestate.h"
#include "service/tracker.h"
#include "view/cave.h"

#define CV_PATHLEN 1024

/* --swap-sync: how the swap lock releases the render ranks.
 *   barrier    MPI_Ibarrier among the render ranks, swap on release;
 *   scheduled  each rank tells the master it is ready; when all are (or the
 *              timeout passed) the master sends every rank one swap time,
 *              converted to that rank's clock with its measured offset, a
 *              margin ahead; each sleeps to it (clock_nanosleep, absolute)
 *              and swaps.  Oversubscribed hosts release a barrier one
 *              scheduler slice per rank apart; a shared deadline does not
 *              depend on who runs when. */
enum { CV_SWAP_SCHEDULED = 0, CV_SWAP_BARRIER = 1 };

/* --present: what the render ranks do with a frame (bits). */
#define CV_PRESENT_FILES 1u  /* EXR + PNG files on the frames the master marks */
#define CV_PRESENT_WINDOW 2u /* a window per output (X11, EGL), swap-locked */
#define CV_PRESENT_DESKTOP 4u /* one preview window on the master's desktop (docs/desktop.md) */

typedef struct cv_run_opts {
  char cave_path[CV_PATHLEN];
  char scene_path[CV_PATHLEN];   /* baked .prt */
  char drive_path[CV_PATHLEN];   /* "" = built-in: the drive configs/drives/default.json */
  char head_path[CV_PATHLEN];    /* recorded head path; "" = the CAVE's default pose */
  char out_dir[CV_PATHLEN];
  char display_path[CV_PATHLEN]; /* compensation display; "" = generated from the walls */
  char metrics_path[CV_PATHLEN]; /* "" = <out>/metrics.jsonl */
  int metrics_every;             /* write every K-th frame's metrics line (default 1) */
  double metrics_max_mb;         /* rotate the metrics file past this size, MB (default 512; 0 = never) */
  int metrics_keep;              /* rotated files kept: metrics.1.jsonl .. metrics.N.jsonl (default 4) */
  char lcd_content[CV_PATHLEN];  /* "" = the scene config's (built-in test pattern) */
  char scene_config[CV_PATHLEN]; /* scene config whose "lcd" block sets the LCD model; "" = defaults */
  int dtrack_port;               /* > 0: live DTrack on this UDP port */
  char dtrack_host[64];          /* bind address, default 127.0.0.1 */
  int dtrack_body;               /* body id of the head, default 1 */
  char tracker_path[CV_PATHLEN]; /* tracker config (docs/tracker.md); "" = none */
  int frames;                    /* frames to render (0 = until SIGINT/SIGTERM) */
  double dt;                     /* simulated seconds per frame (default 1/30) */
  double max_fps;                /* > 0: frames paced to at most this rate (default 0: free) */
  int size;                      /* > 0: pixels per wall-eye side, overrides the config */
  int write_every;               /* write images every k-th frame (default 10; 0 = last only) */
  double timeout_ms;             /* wait for late contributions at most this long (default 2000) */
  double startup_timeout_s;      /* ranks must be ready within this (default 300) */
  double gather_timeout_s;       /* a rank silent this long is dead (default 10; docs/dead-rank.md) */
  int barrier;                   /* per-frame MPI barrier (swap lock) */
  unsigned present;              /* CV_PRESENT_* bits (default files; 0 = none) */
  int desktop_view;              /* --desktop-view: -1 the cross of all walls (default), else a wall index */
  double desktop_fps;            /* --desktop-fps: at most this many previews a second (default 30; 0 every frame) */
  int gpu;                       /* CV_GPU_UNSET: each output's; else it overrides all (--gpu) */
  int clock;                     /* 0 sim (fixed dt), 1 wall (real time); -1: wall with windows */
  int swap_lock;                 /* render ranks meet at a barrier before each swap (on with
                                    windows or --barrier) */
  int swap_sync;                 /* CV_SWAP_SCHEDULED (default) or CV_SWAP_BARRIER */
  double swap_margin_ms;         /* scheduled swaps: GO sent this far ahead (default 3) */
  int predict;                   /* 1: head predicted to the expected scan-out (wall clock) */
  double predict_horizon;        /* at most this far ahead of the newest pose, s (default 0.1) */
  int compensate;                /* 1: scattering compensation (default) */
  int patches;                   /* patches per wall side for the generated display (default 24) */
  double reflectance;            /* screens of the generated display (default 0.8) */
  double compensation_ms;        /* time slot of the solve per frame (default 20) */
  int compensation_lag;          /* --compensation-lag: 1 (default): frame N applies frame N-1's
                                    correction, solved by the master's solver thread while N
                                    renders; 0: frame N's own, solved on the frame's path */
  int post;                      /* --post: CV_POST_AUTO (default), CV_POST_GPU, CV_POST_CPU */
  int lcd;                       /* 1: LCD final gather (default) */
  int lcd_w, lcd_h, lcd_spp;     /* after set-up: the stacked panels' buffer (panels.h) and
                                    samples per round; options: 0 = the scene config's */
  int lcd_budget;                /* rounds per key before a texel is final (default 64) */
  double lcd_tolerance;          /* camera-key quantisation, metres (0 = the config's, 0.005) */
  double lcd_luminance;          /* panel white, cd/m2 (< 0 = the config's, 500) */
  int lcd_idle;                  /* 1: wall-eye idle threads contribute rounds (default 1) */
  int lcd_wait;                  /* 1: after the frames, wait until the LCD budget is summed */
  int share_lighting;            /* --share-lighting: CV_SHARE_HOST (default) or CV_SHARE_OFF
                                    (cluster/lightshare.h) */
  int half_transfer;             /* --transfer: -1 auto (default), 0 float, 1 half (renderer.h) */
  int http_off;                  /* --http off: no console */
  char http_addr[64];            /* --http ADDR:PORT: the console's address (default 127.0.0.1) */
  int http_port;                 /* its port (default 8033; 0: any free port, in the ready line) */
  char http_token_path[CV_PATHLEN]; /* --http-token FILE: every request needs the token */
  uint32_t seed;
  int seed_set;                  /* --seed given: it also sets the LCD sequences' seed */
  int quiet;
} cv_run_opts;

/* --post: where a wall-eye's frame ends (patch means, equation 7, the 8-bit
 * codes): on the GPU (render_post.c; the frame never leaves the GL), on the
 * CPU (the image read back), or auto: the GPU where the GL can (fp64). */
enum { CV_POST_AUTO = 0, CV_POST_GPU = 1, CV_POST_CPU = 2 };

void cv_run_opts_default(cv_run_opts *o);

/* What every rank knows after set-up (identical on all ranks). */
typedef struct cv_service {
  cv_run_opts o;
  int rank, size;
  int n_walls, n_walleyes, n_gather;
  int n_render;        /* render ranks 1..n_render (one per output; n_walleyes views) */
  int n_contributors;  /* LCD: wall-eye idle threads (if on) + gather ranks */
  int lcd_members, lcd_me; /* LCD allreduce group (master + gather ranks): size, this rank (-1) */
  cv_cave cave;
  cv_lcd_config lcd;        /* the LCD model: the scene config's lcd block + options (run.c) */
  cv_lcd_layout lcd_layout; /* its panels, stacked (o.lcd_w x o.lcd_h) */
  cv_drive *drive;
  volatile sig_atomic_t *stop; /* set by SIGINT / SIGTERM */
} cv_service;

/* Contributor index of a rank for LCD rounds (round = index + k * count), or
 * -1 when the rank does not contribute. */
int cv_service_contributor(const cv_service *s, int rank);

/* Quantises a drive state the way the lighting key does (yaw/pitch/roll to
 * 1 degree, weights to 1%, sky angles to 0.5 degree, turbidity to 0.1), so
 * that every rank that sees the same key builds bit-identical lighting. */
void cv_service_quantise_drive(cv_drive_state *s);
uint64_t cv_service_light_key(const cv_drive_state *quantised);

/* `cave run`'s entry point (the cli's command table calls it). */
int cmd_run(int argc, char **argv);

int cv_master_run(cv_service *s);
int cv_walleye_run(cv_service *s);
int cv_gather_run(cv_service *s);

#endif
