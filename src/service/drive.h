/* Scripted drives (JSON files in configs/drives/): how the car turns and how the
 * lighting changes over time, for the render service's master rank.
 *
 * A drive is a list of keyframes of the car's attitude (yaw, pitch, roll in
 * degrees, the cv_car_rotation convention of light/envmap.h) and of either
 * the blend weights of a list of environment maps or the parameters of a
 * Preetham sky.  Between keyframes every value is interpolated linearly (yaw,
 * pitch and roll along the shorter arc); past the end the drive loops or
 * holds its last keyframe.
 *
 * File format (JSON object; unknown fields are errors, every problem is
 * listed as "file: field.path: what was expected"):
 *
 *   {
 *     "description": "...",          optional string
 *     "loop": true,                  optional (default false: hold the ends)
 *     "maps": ["sunrise.exr", ...],  1..CV_MAX_ENV_MAPS env maps, resolved as
 *                                    scene configs do (cv_resolve_env_path:
 *                                    as given, next to the drive file, then
 *                                    blender-data's CAVE_BLENDER_WORLD_DIR)
 *     "sky": true,                   instead of "maps": a Preetham sky
 *     "scale": 1.0,                  optional radiance multiplier for maps, > 0
 *     "illuminance": 10000,          optional instead of scale: every map scaled
 *                                    to this horizontal illuminance (lux) of its
 *                                    upper hemisphere, or "auto": each
 *                                    blender-data map at its documented level
 *                                    (light/calibrate.h, docs/drive-format.md)
 *     "ground_albedo": 0.2,          optional, sky only, [0, 1]
 *     "keyframes": [                 1..CV_DRIVE_MAX_KEYS objects
 *       {"t": 0,                     seconds; first t = 0, strictly increasing
 *        "yaw": 0, "pitch": 0, "roll": 0,        degrees, finite
 *        "weights": [1, 0, 0],       maps: one per map, >= 0, sum > 0
 *                                    (normalised to sum 1 on load)
 *        "turbidity": 3,             sky: [2, 10]
 *        "sun_elevation": 35,        sky: [-90, 90] degrees
 *        "sun_azimuth": 0}           sky: degrees, clockwise from -Z seen
 *     ]                                   from above (as cv_light_spec)
 *   }
 *
 * A field missing from a keyframe keeps the previous keyframe's value; the
 * first keyframe's defaults are yaw = pitch = roll = 0, weights all on the
 * first map, turbidity 3, sun elevation 35, sun azimuth 0.  Exactly one of
 * "maps" and "sky": true must be given; map keyframes may not carry sky
 * fields and sky keyframes may not carry weights.  The duration is the last
 * keyframe's t (0 for a single keyframe: a constant drive).  With "loop",
 * the value at t = duration equals the first keyframe's only if the file
 * makes it so (yaw 360 and 0 are the same attitude). */
#ifndef CV_SERVICE_DRIVE_H
#define CV_SERVICE_DRIVE_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"
#include "io/scene_config.h"

#define CV_DRIVE_MAX_KEYS 1024

/* The drive's value at one time (also one field of the broadcast frame
 * state, service/framestate.h).  For a map drive weights[0..n_maps) sum to 1
 * and the sky fields are 0; for a sky drive n_maps is 0. */
typedef struct cv_drive_state {
  double t, yaw_deg, pitch_deg, roll_deg;
  int n_maps;
  double weights[CV_MAX_ENV_MAPS];
  int is_sky;
  double turbidity, sun_elevation_deg, sun_azimuth_deg;
} cv_drive_state;

typedef struct cv_drive cv_drive; /* opaque, immutable once loaded */

/* Loads a drive file; relative map names resolve against the file's folder.
 * *out owned by the caller (cv_drive_destroy).  Errors (err: the first
 * problem as "file: field: what", with "[+N more problems]" when there are
 * several): CV_ERR_IO (unreadable), CV_ERR_CONFIG (syntax, unknown or missing
 * field, wrong type), CV_ERR_RANGE, CV_ERR_NONFINITE, CV_ERR_NOT_FOUND (a map
 * that does not exist), CV_ERR_NOMEM. */
int cv_drive_load(const char *path, cv_drive **out, cv_err *err);
/* As cv_drive_load on JSON text in memory; name stands for the file in the
 * messages; base_dir (may be NULL) resolves relative map names. */
int cv_drive_parse(const char *json, const char *name, const char *base_dir, cv_drive **out,
                   cv_err *err);
/* Lists every problem of a drive file, one "file: field: what" line each,
 * into buf (NUL-terminated, truncated to n bytes; buf may be NULL when n is
 * 0) and their count into *n_problems (may be NULL).  Returns CV_OK when the
 * file is valid, else the status of the first problem. */
int cv_drive_validate_all(const char *path, char *buf, size_t n, int *n_problems);
/* Same on JSON text (name and base_dir as cv_drive_parse). */
int cv_drive_validate_text(const char *json, const char *name, const char *base_dir, char *buf,
                           size_t n, int *n_problems);
void cv_drive_destroy(cv_drive *d); /* accepts NULL */

/* Accessors (d non-NULL). */
double cv_drive_duration(const cv_drive *d); /* last keyframe's t, seconds */
int cv_drive_n_maps(const cv_drive *d);      /* 0 for a sky drive */
/* Resolved path of map i (0 <= i < n_maps), owned by d; NULL out of range. */
const char *cv_drive_map_path(const cv_drive *d, int i);
int cv_drive_is_sky(const cv_drive *d);
int cv_drive_loops(const cv_drive *d);
int cv_drive_n_keys(const cv_drive *d);
const char *cv_drive_description(const cv_drive *d); /* "" when none; owned by d */

/* The drive at time t (seconds): linear interpolation between the two
 * keyframes around t, weights renormalised to sum 1; an angle goes from a to
 * a + delta with delta = b - a wrapped to [-180, 180) (the shorter arc), so a
 * drive 0 -> 90 -> ... -> 360 yields 0..360 while 350 -> 10 passes 0.  Looping
 * drives use t mod duration (t = duration gives the first keyframe); others
 * hold the first keyframe before 0 and the last after the end.  out->t is
 * the time asked for (not wrapped); a non-finite t is taken as 0, out->t
 * included.  Every double of *out is finite. */
void cv_drive_eval(const cv_drive *d, double t, cv_drive_state *out);

/* Lighting description for state s: kind CV_LIGHT_ENV with the maps whose
 * weight is > 0 (zero-weight maps dropped, weights as in s) and the drive's
 * scale, or CV_LIGHT_SKY with s's sky parameters and the drive's ground
 * albedo; yaw/pitch/roll from s; extract_sun 1.  Everything else as
 * cv_light_spec_default. */
void cv_drive_to_light_spec(const cv_drive *d, const cv_drive_state *s, cv_light_spec *out);

/* 64-bit hash of s quantised for lighting caches: yaw/pitch/roll rounded to
 * multiples of yaw_step_deg (wrapped so that 0 and 360 agree), weights to
 * multiples of weight_step, turbidity to 0.1 and the sun angles to 0.5 deg.
 * s->t is ignored.  Equal keys mean the same lighting up to the
 * quantisation (different keys may still be close: a value near a rounding
 * boundary).  Steps <= 0 or non-finite fall back to 1 deg and 1e-3. */
uint64_t cv_drive_state_key(const cv_drive_state *s, double yaw_step_deg, double weight_step);

#endif
