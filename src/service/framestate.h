/* Fixed-layout messages of the render service: the frame state the master
 * broadcasts every frame, and the report each wall-eye rank sends back.
 *
 * Both are packed into byte buffers of a fixed size by PURE functions (no
 * MPI here: cluster/ moves the bytes).  Every field is written explicitly in
 * little-endian order, doubles as their IEEE-754 bit patterns, so the bytes
 * are the same on every host and a double survives bit for bit (-0.0 and
 * denormals included).  Each buffer opens with a magic number and a version;
 * unpack checks them, the length, the counts and that every double is
 * finite, so a corrupt or foreign buffer never reaches the renderer.
 *
 * Frame state layout (offsets in bytes; u32/i32/u64 little-endian, f64 =
 * IEEE-754 bits as u64):
 *      0 u32 magic CV_FRAME_STATE_MAGIC      4 u32 version CV_FRAME_STATE_VERSION
 *      8 u32 frame    12 u32 flags    16 f64 time    24 f64 dt
 *     32 f64 head[3]  56 f64 gaze[3]  80 f64 tracker_age
 *     88 drive: f64 t, yaw, pitch, roll; i32 n_maps; f64 weights[8];
 *        i32 is_sky; f64 turbidity, sun_elevation, sun_azimuth   (128 bytes)
 *    216 u64 light_key  224 i32 bands  228 f64 sh[192]
 *   1764 i32 has_sun  1768 f64 sun_dir[3]  1792 f64 sun_E[3]
 *   1816 f64 lwa  1824 f64 lwmax  1832 f64 adapt[6]
 *   1880 u64 lcd_key  1888 u32 lcd_rounds  1892 i32 has_eyes  1896 f64 eyes[2][3]
 *   1944 u64 lcd_dead  1952 u32 lcd_dead_floor                 = 1956 bytes
 */
#ifndef CV_SERVICE_FRAMESTATE_H
#define CV_SERVICE_FRAMESTATE_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"
#include "service/drive.h"

#define CV_FS_QUIT 1u      /* every rank leaves the frame loop after this frame */
#define CV_FS_WRITE 2u     /* write this frame's images */
#define CV_FS_NEW_LIGHT 4u /* lighting changed (light_key differs from the last frame) */
#define CV_FS_HOLD 8u      /* time held after the drive (--lcd-wait): the LCD converges */
#define CV_FS_PREVIEW 16u  /* send the desktop preview image of this frame (--present desktop) */
#define CV_FS_MEASURE 32u  /* adaptation priming before frame 0: render and report the
                              luminance statistics only (no present, write, LCD or
                              compensation); frame number CV_FRAME_MEASURE */
#define CV_FRAME_MEASURE 0xFFFFFFFFu

#define CV_FRAME_STATE_MAGIC 0x53465643u /* "CVFS" in little-endian bytes */
#define CV_FRAME_STATE_VERSION 3u
#define CV_FRAME_STATE_SH_MAX (3 * 64) /* bands <= 8 */

/* Packed size of a cv_drive_state: 4 f64, i32, CV_MAX_ENV_MAPS f64, i32, 3 f64. */
#define CV_DRIVE_STATE_BYTES (8 * 4 + 4 + 8 * CV_MAX_ENV_MAPS + 4 + 8 * 3)

#define CV_FRAME_STATE_BYTES                                                                \
  (4 + 4 + 4 + 4 + 8 * 2 + 8 * 3 + 8 * 3 + 8 + CV_DRIVE_STATE_BYTES + 8 + 4 +              \
   8 * CV_FRAME_STATE_SH_MAX + 4 + 8 * 3 + 8 * 3 + 8 * 2 + 8 * 6 + 8 + 4 + 4 + 8 * 6 + 8 + 4)

typedef struct cv_frame_state {
  uint32_t frame;            /* frame index */
  uint32_t flags;            /* CV_FS_QUIT 1, CV_FS_WRITE 2 (write this frame's images), CV_FS_NEW_LIGHT 4 */
  double time, dt;           /* seconds */
  double head[3], gaze[3];   /* tracked head pose, CAVE frame */
  double tracker_age;        /* seconds since the last tracker update */
  cv_drive_state drive;      /* car pose and lighting parameters */
  uint64_t light_key;        /* cv_drive_state_key of drive */
  int32_t bands;             /* SH bands of sh */
  double sh[3 * 64];         /* SH lighting (sun excluded), car frame */
  int32_t has_sun; double sun_dir[3], sun_E[3];
  double lwa, lwmax;         /* adaptation luminance and max luminance for Drago (cd/m2) */
  double adapt[6];           /* the Pattanaik state (a_cone, a_rod, b_cone, b_rod, time, initialised) */
  uint64_t lcd_key;          /* key of the LCD image being accumulated */
  uint32_t lcd_rounds;       /* rounds summed so far into the current LCD image */
  int32_t has_eyes;          /* 1: eyes[] from a calibrated tracker (docs/tracker.md: IPD,
                                roll); 0: from head, gaze and the CAVE's eye_separation */
  double eyes[2][3];         /* left, right eye, CAVE frame, metres */
  uint64_t lcd_dead;         /* bit g: gather-only rank g (0 = the first) declared dead; the
                                LCD contributors share its rounds (docs/dead-rank.md) */
  uint32_t lcd_dead_floor;   /* the dead gather ranks' rounds of lcd_key below this one are
                                all summed (not rendered again) */
} cv_frame_state;

/* Packs s into buf (exactly CV_FRAME_STATE_BYTES written).  All 192 sh
 * entries are sent whatever bands is (zero the unused ones).  Errors (buf
 * then undefined): CV_ERR_NONFINITE if any double is not finite,
 * CV_ERR_RANGE if bands is outside [0, 8], drive.n_maps outside
 * [0, CV_MAX_ENV_MAPS], or drive.is_sky / has_sun not 0 or 1;
 * CV_ERR_INVALID on NULL. */
int cv_frame_state_pack(const cv_frame_state *s, uint8_t buf[CV_FRAME_STATE_BYTES]);
/* Unpacks len bytes of buf into *out (written only on success).  Errors
 * (err: one line naming the field): CV_ERR_FORMAT (len != CV_FRAME_STATE_BYTES,
 * wrong magic or version, a count or flag out of range), CV_ERR_NONFINITE (a
 * double that is NaN or Inf), CV_ERR_INVALID on NULL. */
int cv_frame_state_unpack(const uint8_t *buf, size_t len, cv_frame_state *out, cv_err *err);

/* --- wall-eye report ---------------------------------------------------- */

/* Sent every frame by each wall-eye rank to the master: its foveal
 * statistics (merged in double precision into the adaptation luminance),
 * its stage times and its LCD contribution.  Layout: u32 magic, u32 version,
 * u32 frame, i32 rank, wall, eye, f64 sum_log, weight, max_l, u64 n_pixels,
 * n_invalid, f64 ms_lum, ms_depth, ms_shade, ms_read, ms_total, ms_lcd,
 * u64 lcd_rounds_done, state_hash = 128 bytes. */
typedef struct cv_walleye_report {
  uint32_t frame;
  int32_t rank, wall, eye;
  double sum_log, weight, max_l; /* foveal: sum of w ln L, sum of w, max L */
  uint64_t n_pixels, n_invalid;  /* pixels in the foveal region, non-finite ones skipped */
  double ms_lum, ms_depth, ms_shade, ms_read, ms_total, ms_lcd; /* stage times, ms */
  uint64_t lcd_rounds_done;
  uint64_t state_hash;       /* FNV-1a of the packed frame state this rank rendered with */
  uint32_t swap_frame;       /* the frame whose swap swap_t stamps (the previous one; 0xffffffff: none) */
  double swap_t;             /* monotonic seconds of this rank's clock when that swap returned */
  double ms_present;         /* that frame: present draw + glFinish, barrier wait, swap (ms) */
  double ms_barrier;         /* of which waiting in the swap-lock barrier (ms) */
  /* The frame path (issue 29), of that same previous frame of this rank: */
  uint64_t bytes_read;       /* bytes read back from the GL since the rank's previous report */
  uint64_t bytes_up;         /* bytes uploaded to the GL since the rank's previous report */
  double ms_cpu;             /* thread CPU ms of the frame's path outside GL calls (no relight, no waits) */
  double ms_gpu;             /* GPU ms of the frame's GL work (timer query); -1: none */
  double ms_corr_wait;       /* ms waited for the scattering correction */
  uint32_t corr_frame;       /* the frame whose correction was applied (0xffffffff: none) */
  uint64_t late_corr;        /* corrections that did not come in time, since the start */
  uint64_t files_dropped;    /* written frames whose files were dropped (writer queue full), since the start */
  uint64_t files_failed;     /* written frames whose files could not be written, since the start */
} cv_walleye_report;

#define CV_WALLEYE_REPORT_MAGIC 0x52455743u /* "CWER" */
#define CV_WALLEYE_REPORT_VERSION 4u
#define CV_WALLEYE_REPORT_BYTES (4 + 4 + 4 + 4 * 3 + 8 * 3 + 8 * 2 + 8 * 6 + 8 + 8 + 4 + 8 * 3 + 8 * 2 + 8 * 3 + 4 + 8 + 8 * 2)

/* Packs r into buf (CV_WALLEYE_REPORT_BYTES bytes).  Errors: CV_ERR_NONFINITE
 * if a double is not finite, CV_ERR_INVALID on NULL. */
int cv_walleye_report_pack(const cv_walleye_report *r, uint8_t *buf);
/* Unpacks; errors as cv_frame_state_unpack (CV_ERR_FORMAT, CV_ERR_NONFINITE,
 * CV_ERR_INVALID), *out written only on success. */
int cv_walleye_report_unpack(const uint8_t *buf, size_t len, cv_walleye_report *out,
                             cv_err *err);

#endif
