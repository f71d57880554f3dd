/* Scene configuration (JSON files in configs/scenes/): which mesh, material
 * overrides, geometry-cleaning thresholds, PRT parameters and lighting.
 * Every field is optional; unknown fields are errors naming their path, so a
 * typo never silently falls back to a default.  The format is documented in
 * docs/scene-config.md. */
#ifndef CV_IO_SCENE_CONFIG_H
#define CV_IO_SCENE_CONFIG_H

#include <stdint.h>

#include "core/status.h"
#include "mesh/mesh.h"
#include "mesh/place.h"

#define CV_PATH_MAX 1024
#define CV_MAX_ENV_MAPS 8

#define CV_ILLUMINANCE_AUTO (-1.0)

typedef enum { CV_LIGHT_NONE = 0, CV_LIGHT_ENV, CV_LIGHT_SKY, CV_LIGHT_CONSTANT } cv_light_kind;

/* Lighting description shared by the scene config and the command line. */
typedef struct cv_light_spec {
  cv_light_kind kind;
  char env[CV_MAX_ENV_MAPS][CV_PATH_MAX]; /* resolved paths */
  double weight[CV_MAX_ENV_MAPS];
  int n_env;
  double scale;                 /* radiance multiplier for env maps (default 1) */
  double illuminance;           /* env maps: lux of the upper hemisphere's horizontal
                                   illuminance (light/calibrate.h); 0 = not calibrated
                                   (scale applies), CV_ILLUMINANCE_AUTO = each
                                   blender-data map at its documented default */
  int absolute;                 /* env maps: the config declares the maps times scale in
                                   cd/m^2 ("absolute": true; docs/readability.md) */
  int extract_sun;              /* env maps: split a sun out when one is found (default 1) */
  double turbidity;             /* sky, 2..10 (default 3) */
  double sun_elevation_deg;     /* sky (default 35) */
  double sun_azimuth_deg;       /* sky, clockwise from -Z (ahead) seen from above (default 0) */
  double ground_albedo;         /* sky (default 0.2) */
  double constant[3];           /* constant environment radiance */
  double yaw_deg, pitch_deg, roll_deg; /* car orientation (cv_car_rotation) */
} cv_light_spec;

typedef struct cv_scene_material {
  char name[64]; /* a glob pattern (fnmatch) over material names */
  int has_albedo;
  float albedo[3];
  int has_tag;
  uint32_t flags; /* CV_MAT_WINDOW / CV_MAT_LCD / 0 */
} cv_scene_material;

typedef struct cv_scene_config {
  char source[CV_PATH_MAX]; /* the config file, or "(built-in)" */
  int mesh_is_cabin;        /* 1: parametric cabin, 0: mesh_path */
  char mesh_path[CV_PATH_MAX];
  cv_placement place;       /* mesh.units / up / transform (file meshes only) */
  double cabin_length, cabin_width, cabin_height; /* 0 = generator default */
  int cabin_tess;
  cv_scene_material *overrides;
  int n_overrides;
  int clean_enabled;
  double weld_tolerance, crease_angle_deg, crack_width, sliver_aspect; /* <0: default */
  int bands;                /* 0 = auto */
  int rays;                 /* 0 = auto */
  int bounces;
  uint32_t seed;
  double spread;            /* 0..1, fraction of each vertex's fan sampled */
  int window_sampling;      /* 1: MIS towards the windows in the direct pass */
  int tail;                 /* 1: geometric tail of the missing bounces (bake.h) */
  double error_budget;      /* relative, for auto */
  cv_light_spec light;      /* kind NONE when the config names no lighting */
} cv_scene_config;

/* The one default cabin subdivision of a scene (`cave bake default`, a
 * config without mesh.tess, configs/scenes/default.json): ~38K triangles. */
#define CV_SCENE_DEFAULT_TESS 2

/* Defaults: built-in cabin at tess CV_SCENE_DEFAULT_TESS, cleaning on, 8 bands, 1024 rays,
 * 2 bounces + tail, seed 1, budget 0.05, no lighting. */
void cv_scene_config_default(cv_scene_config *c);
/* Light defaults (no kind, scale 1, sun extraction on, sky T=3 ...). */
void cv_light_spec_default(cv_light_spec *l);
/* Parses a file.  Relative mesh and env-map paths are resolved against the
 * config's folder; a bare env-map name ("forest.exr") that is not there is
 * looked up in blender-data's studio-light folder.  err: "file: field: what
 * was expected".  Frees nothing of *c on error beyond what it allocated. */
int cv_scene_config_load(const char *path, cv_scene_config *c, cv_err *err);
/* Parses a "lighting" JSON object (a const cJSON *) into l (call
 * cv_light_spec_default first); used by the scene config and later by drive
 * files.  file names the source in errors; base_dir resolves relative maps. */
int cv_light_spec_parse_json(const void *json, const char *file, const char *base_dir,
                             cv_light_spec *l, cv_err *err);
/* Frees the override list. */
void cv_scene_config_free(cv_scene_config *c);
/* Resolves an env-map name: as given if it exists, else relative to base_dir
 * (may be NULL), else in CAVE_BLENDER_WORLD_DIR.  CV_ERR_NOT_FOUND otherwise. */
int cv_resolve_env_path(const char *name, const char *base_dir, char out[CV_PATH_MAX],
                        cv_err *err);
/* Applies the material overrides in order (a later entry wins); each name is
 * a glob pattern (fnmatch(3): *, ?, [..], backslash escapes; an exact name
 * matches itself) applied to EVERY matching material.  A pattern that
 * matches no material is an error (CV_ERR_CONFIG naming materials[i].name),
 * checked before anything is changed. */
int cv_scene_apply_overrides(const cv_scene_config *c, cv_mesh *m, cv_err *err);
/* What one override entry matched. */
typedef struct cv_override_count {
  size_t materials, triangles;
} cv_override_count;
/* As above; counts (c->n_overrides entries, may be NULL) gets what each matched. */
int cv_scene_apply_overrides_ex(const cv_scene_config *c, cv_mesh *m,
                                cv_override_count *counts, cv_err *err);

#endif
