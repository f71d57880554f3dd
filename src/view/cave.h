/* CAVE configuration: the projection walls (rectangles pa lower-left, pb
 * lower-right, pc upper-left, seen from inside, so (pb-pa) x (pc-pa) points
 * towards the viewer), their pixel resolution, the stereo and tone-mapping
 * settings of the wall-eye renderer, the default tracked pose and the mapping
 * of CAVE coordinates into the scene.  Loaded from JSON (configs/caves/).
 *
 * The module is independent of tonemap: the adaptation settings are plain
 * doubles the renderer copies into cv_adapt_params / cv_drago.
 *
 * JSON format (every field but "walls" optional, unknown fields are errors):
 *   { "description": "...",
 *     "walls": [ {"name": "front", "pa": [x,y,z], "pb": [..], "pc": [..],
 *                 "res": [w, h]}, ... ],               1..CV_CAVE_MAX_WALLS
 *     "eye_separation": 0.064, "supersample": 1, "foveal_deg": 10,
 *     "lum_res": 128, "drago_bias": 0.85, "drago_ldmax": 100,
 *     "t0_cone": 0.080, "t0_rod": 0.150, "tau_cone": 110, "tau_rod": 400,
 *     "head": [0, 1.2, 0], "gaze": [0, 0, -1], "scene_offset": [x, y, z],
 *     "near": 0.05, "far": 50, "rate": 60,
 *     "screens": {"reflectance": 0.8, "patches": 24},
 *     "outputs": [ {"wall": "front", "eye": "left", "host": "cave1", "display": ":0.1",
 *                   "geometry": [x, y, w, h] | "fullscreen": true,
 *                   "gpu": 0 | "auto" | "software", "stereo": "passive"}, ... ] }
 * Validation lists every problem with its field path, e.g. "walls[2].pc".
 *
 * Outputs (docs/cave-config.md): where each wall-eye is shown.  Every wall
 * is covered exactly once: by two "passive" outputs (eye "left" and
 * "right", one rank each) or by one output with both eyes in one window
 * ("quad": quad-buffered stereo; "side-by-side", "top-bottom": 3D
 * projectors).  Without "outputs" every wall-eye gets a passive output on
 * this host's $DISPLAY, tiled (geometry decided at run time from the
 * rendered size), GPU "auto".  Given outputs need "gpu"; windows on one
 * host and display must not overlap; a display naming a host ("node2:0")
 * belongs to that host.  Rank layout: rank 0 the master, rank 1 + i renders
 * outputs[i], ranks beyond are gather-only (cv_cave_rank_role). */
#ifndef CV_VIEW_CAVE_H
#define CV_VIEW_CAVE_H

#include <stddef.h>

#include "core/status.h"

#define CV_CAVE_MAX_WALLS 8
#define CV_CAVE_MAX_RES 16384
/* Corners count as rectangular when the angle between pb-pa and pc-pa is
 * within this many radians of 90 degrees (0.057 deg: 1.7 mm over 3 m). */
#define CV_CAVE_RIGHT_ANGLE_TOL 1e-3

typedef struct cv_wall {
  char name[32];            /* 1..31 characters, unique */
  double pa[3], pb[3], pc[3]; /* lower-left, lower-right, upper-left, metres */
  int res[2];               /* pixels w, h, each 1..16384 */
} cv_wall;

#define CV_CAVE_MAX_OUTPUTS (2 * CV_CAVE_MAX_WALLS)

/* GPU of an output: a hardware EGL device index >= 0 (counting hardware
 * devices only, in eglQueryDevicesEXT order), or one of these. */
#define CV_GPU_AUTO (-1)     /* the first hardware device, else the software one (said so) */
#define CV_GPU_SOFTWARE (-2) /* Mesa's software device (llvmpipe) */
#define CV_GPU_UNSET (-3)    /* not given (an error in explicit outputs) */

/* The --gpu option of every command: "auto", "software" or a hardware device
 * index 0..63.  Returns 0 and sets *gpu, or -1 (nothing set). */
int cv_gpu_parse(const char *s, int *gpu);

typedef enum cv_stereo_mode {
  CV_STEREO_PASSIVE = 0,  /* one eye per output (projector pairs with polarisation) */
  CV_STEREO_QUAD,         /* both eyes, quad-buffered window (needs a stereo GL config) */
  CV_STEREO_SIDE_BY_SIDE, /* both eyes, left half / right half */
  CV_STEREO_TOP_BOTTOM    /* both eyes, top half left eye / bottom half right eye */
} cv_stereo_mode;

/* "passive", "quad", "side-by-side", "top-bottom". */
const char *cv_stereo_mode_name(int mode);

typedef struct cv_output {
  int wall;           /* index into walls */
  int eyes;           /* bit 0 left eye, bit 1 right eye (3: both, packed stereo) */
  char host[64];      /* "" = any host (the one the rank runs on) */
  char display[64];   /* X display, e.g. ":0.1"; "" = $DISPLAY of the rank */
  int geometry[4];    /* x, y, w, h in pixels; w = 0: not given */
  int fullscreen;     /* 1: fullscreen (window manager hint, else the screen's size) */
  int gpu;            /* CV_GPU_* or a hardware device index */
  int stereo;         /* cv_stereo_mode */
} cv_output;

typedef struct cv_cave {
  int n_walls;
  cv_wall walls[CV_CAVE_MAX_WALLS];
  double eye_separation;   /* metres, default 0.064, in [0, 0.2] */
  int supersample;         /* 1 or 2, default 1 */
  double foveal_deg;       /* full cone angle, degrees, default 10, in (0, 180) */
  int lum_res;             /* luminance image size (adaptation statistics), default 128, 1..4096 */
  double drago_bias;       /* default 0.85, in (0, 1) */
  double drago_ldmax;      /* cd/m2, default 100, > 0 */
  double t0_cone, t0_rod;  /* Pattanaik neural time constants, s: 0.080, 0.150 */
  double tau_cone, tau_rod; /* Pattanaik bleaching time constants, s: 110, 400 */
  double head[3], gaze[3]; /* default tracked pose (CAVE coordinates); gaze unit */
  /* "tracking": the volume where a tracked head is plausible (m, CAVE
   * coordinates; default: the walls' bounding box grown by 0.5 m) and the
   * fastest plausible head (m/s, default 10; 0: no limit); issue 35 */
  double track_lo[3], track_hi[3];
  double max_head_speed;
  double scene_offset[3];  /* scene point = cave point + scene_offset */
  double near, far;        /* clip planes, metres, defaults 0.05, 50; 0 < near < far */
  double rate;             /* target frame rate of the wall clock, Hz, default 60, (0, 1000] */
  double screen_reflectance; /* screens' diffuse reflectance for compensation, default 0.8 */
  int screen_patches;      /* compensation patches per wall side, default 24, 1..256 */
  int n_outputs;
  int outputs_given;       /* 1: "outputs" was in the file; 0: the default layout */
  cv_output outputs[CV_CAVE_MAX_OUTPUTS];
} cv_cave;

/* Rank roles of the service for this CAVE (see the outputs above). */
enum { CV_ROLE_MASTER = 0, CV_ROLE_RENDER = 1, CV_ROLE_GATHER = 2 };
typedef struct cv_rank_role {
  int role;   /* CV_ROLE_* */
  int output; /* CV_ROLE_RENDER: index into outputs; else -1 */
} cv_rank_role;
/* The role of `rank` (0 <= rank).  Ranks needed: 1 + n_outputs. */
cv_rank_role cv_cave_rank_role(const cv_cave *c, int rank);
/* The rank that renders wall-eye (wall, eye), or -1. */
int cv_cave_walleye_rank(const cv_cave *c, int wall, int eye);

/* Fills c with the defaults and no walls (n_walls = 0). */
void cv_cave_defaults(cv_cave *c);

/* Reads and parses the JSON file at path into *out.  Errors: CV_ERR_IO
 * (cannot read), CV_ERR_FORMAT (not JSON), CV_ERR_CONFIG / CV_ERR_RANGE /
 * CV_ERR_NONFINITE (the first problem's code).  err->msg then holds every
 * problem on one line: "file: field: problem; field: problem; ..." (truncated
 * to fit with "... (N problems)").  *out is only written on success. */
int cv_cave_load(const char *path, cv_cave *out, cv_err *err);
/* As cv_cave_load, also writing every problem, one per line ("file: field:
 * what"), into buf (cap bytes, may be NULL) and their number into *n. */
int cv_cave_load_all(const char *path, cv_cave *out, char *buf, size_t cap, int *n, cv_err *err);

/* As cv_cave_load on a JSON string; name_for_errors prefixes messages. */
int cv_cave_parse(const char *json_text, const char *name_for_errors, cv_cave *out, cv_err *err);
/* As cv_cave_parse on a JSON tree already parsed (cJSON). */
struct cJSON;
int cv_cave_from_json(const struct cJSON *root, const char *name_for_errors, cv_cave *out,
                      cv_err *err);

/* CV_ERR_RANGE naming the wall when eye is on or behind any wall's plane
 * (signed distance along the wall normal <= 1e-6 m), CV_OK otherwise. */
/* --size N in cave render and cave run: every wall's res scaled so that its
 * longer side is n pixels, the other side keeping the wall's aspect
 * (rounded, at least 1).  n <= 0 leaves the config's res. */
void cv_cave_fit_res(cv_cave *c, int n);
int cv_cave_check_eye(const cv_cave *c, const double eye[3], cv_err *err);

#endif
