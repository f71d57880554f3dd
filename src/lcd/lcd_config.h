/* LCD panel settings: panel resolution, samples per round, BRDF, content
 * image, its white and black luminance, camera-key tolerance, readability
 * requirement and observer.  Read from the "lcd" object of the scene config
 * (cv_lcd_config_load_scene: `cave lcd scene.json`) or of a JSON file of its
 * own (`cave lcd --lcd-config FILE`), with the same rules as the scene
 * config (docs/scene-config.md): every field optional, unknown fields and
 * wrong types are errors naming the file and the field:
 *
 *   { "lcd": { "resolution": [400, 240], "spp": 40, "rounds": 1,
 *              "brdf": "builtin:antiglare", "content": "dash.png",
 *              "content_luminance": 500, "black_luminance": 1,
 *              "eye_tolerance": 0.005, "brdf_fraction": 0.9, "seed": 1,
 *              "env_width": 1024, "sun_samples": 16, "clamp": 0,
 *              "cr_min": 3, "age": 40, "pigment": 0.5,
 *              "panels": [ { "name": "centre" },
 *                          { "name": "cluster", "corners": [[x,y,z], [x,y,z], [x,y,z]],
 *                            "brdf": "...", "content": "nav.png", "resolution": [400, 240],
 *                            "content_luminance": 400, "black_luminance": 0.5 } ] } }
 *
 * Panels: without "panels" the block describes one panel, "lcd", on the
 * mesh's triangles tagged lcd.  A panel entry takes its rectangle from
 * "corners" (lower-left, lower-right, upper-left as the driver sees it, car
 * frame, metres; like a CAVE wall's pa, pb, pc) or, in at most one entry,
 * from the mesh's lcd triangles; brdf, content, content_luminance,
 * black_luminance and resolution it does not set are the block's. */
#ifndef CV_LCD_LCD_CONFIG_H
#define CV_LCD_LCD_CONFIG_H

#include <stdint.h>
#include <stddef.h>

#include "core/status.h"
#include "io/scene_config.h"

/* Panel white (cd/m^2) of `cave lcd` and `cave run` unless configured; black
 * is CV_LCD_BLACK_LEVEL of white unless configured. */
#define CV_LCD_WHITE_DEFAULT 500.0
#define CV_LCD_BLACK_LEVEL 0.002

#define CV_LCD_MAX_PANELS 4
#define CV_LCD_NAME_MAX 32

/* One panel (after cv_lcd_config_panels: every field resolved). */
typedef struct cv_lcd_panel_config {
  char name[CV_LCD_NAME_MAX]; /* [A-Za-z0-9_-]+, unique in the block */
  int has_corners;            /* 0: the mesh's triangles tagged lcd */
  double corners[3][3];       /* lower-left, lower-right, upper-left (m, car frame) */
  int width, height;          /* texels; 0: the block's (height 0: from the panel's aspect) */
  char brdf[CV_PATH_MAX];     /* "": the block's */
  char content[CV_PATH_MAX];  /* the block's unless content_set */
  int content_set;
  double content_luminance;   /* < 0: the block's */
  double black_luminance;     /* < 0: the block's (-2: unset) */
} cv_lcd_panel_config;

typedef struct cv_lcd_config {
  int width, height;          /* panel texels (400 x 0: height from the panel's aspect) */
  int spp;                    /* samples per texel per round (40) */
  int rounds;                 /* rounds `cave lcd` renders (1) */
  char brdf[CV_PATH_MAX];     /* table or MERL file, or "builtin:antiglare" (default) */
  char content[CV_PATH_MAX];  /* image shown on the panel (.png/.exr); "" = built-in pattern */
  double content_luminance;   /* cd/m^2 of content white (CV_LCD_WHITE_DEFAULT) */
  double black_luminance;     /* cd/m^2 of content black; < 0: CV_LCD_BLACK_LEVEL x white (-1) */
  double cr_min;              /* required contrast ratio (3, ISO 15008) */
  double age;                 /* driver's age, years, for the disability glare (40) */
  double pigment;             /* eye pigmentation 0..1 (0.5) */
  double eye_tolerance;       /* metres: eye positions in one cell share a key (0.005) */
  double brdf_fraction;       /* share of samples drawn from the BRDF table (0.9; 1 = BRDF
                                 sampling, 0 = cosine sampling) */
  uint32_t seed;              /* sequence seed (1) */
  int env_width;              /* car-frame background table width (1024; height = width/2) */
  int sun_samples;            /* fan points per vertex for the sun's direct light in the
                                 PRT radiance (16) */
  double clamp;               /* per-sample radiance clamp; 0 = automatic (default) */
  int n_panels;               /* 0: one panel "lcd" from the block's own fields */
  cv_lcd_panel_config panels[CV_LCD_MAX_PANELS];
  char source[CV_PATH_MAX];   /* the file the panels came from ("" = defaults), for errors */
} cv_lcd_config;

void cv_lcd_config_default(cv_lcd_config *c);
/* Parses `path`; relative brdf/content paths resolve against its folder.
 * Errors (err: "file: lcd.field: what was expected"): CV_ERR_IO,
 * CV_ERR_CONFIG, CV_ERR_NOMEM. */
int cv_lcd_config_load(const char *path, cv_lcd_config *c, cv_err *err);
/* The same for the "lcd" block of a scene config: other top-level fields are
 * the scene config's (cv_scene_config_load checks them); no block: c is
 * left as it is. */
int cv_lcd_config_load_scene(const char *path, cv_lcd_config *c, cv_err *err);
/* The black luminance in effect (black_luminance, or the default level). */
double cv_lcd_config_black(const cv_lcd_config *c);
/* Resolves the panels after every override of the block's fields (command
 * line options): with no "panels" one panel "lcd" from the block's
 * fields; each panel's unset brdf, content, white, black and resolution
 * become the block's.  Errors (CV_ERR_CONFIG, naming the file and
 * lcd.panels[i].field): black above white. */
int cv_lcd_config_panels(cv_lcd_config *c, cv_err *err);

/* What a command-line option set in the block (cv_lcd_config_override). */
enum {
  CV_LCD_SET_SIZE = 1,    /* width, height */
  CV_LCD_SET_BRDF = 2,    /* brdf */
  CV_LCD_SET_CONTENT = 4, /* content */
  CV_LCD_SET_WHITE = 8,   /* content_luminance */
  CV_LCD_SET_BLACK = 16   /* black_luminance */
};
/* One rule for `cave lcd` and `cave run` (docs/scene-config.md): an option
 * sets the block's value AND every panel's, so a panel's own value of that
 * field is dropped (the panel then takes the block's).  what: CV_LCD_SET_*
 * bits.  Call after the options set the block, before
 * cv_lcd_config_panels. */
void cv_lcd_config_override(cv_lcd_config *c, unsigned what);

/* --- the lcd block baked with a scene (lcd_sidecar.c) -----------------------
 * `cave bake scene.json -o scene.prt` writes the scene config's "lcd" block
 * next to the .prt, as <scene.prt>.lcd.json:
 *   { "prt_input_hash": "<16 hex digits: the .prt's input hash>",
 *     "scene_config": "<absolute path of the scene config>",
 *     "lcd": { ...the block, brdf and content paths made absolute... } }
 * so that `cave lcd scene.prt` and `cave run --scene scene.prt` use the
 * scene's panels without the scene config. */

/* <prt>.lcd.json into out (n bytes). */
void cv_lcd_sidecar_path(const char *prt, char *out, size_t n);
/* Writes the sidecar of prt_path from scene_json's "lcd" block (*written
 * 1), or, when the config has none (scene_json NULL: a mesh file or the
 * built-in scene), removes a sidecar left by an earlier bake (*written 0,
 * *removed 1 when there was one).  Errors name the file: CV_ERR_IO,
 * CV_ERR_CONFIG, CV_ERR_NOMEM. */
int cv_lcd_sidecar_write(const char *scene_json, const char *prt_path, uint64_t prt_hash,
                         int *written, int *removed, cv_err *err);
/* Loads the sidecar of prt_path into c (as cv_lcd_config_load_scene; c's
 * source becomes the sidecar's path) when there is one (*found 1).  A
 * sidecar of another bake (its prt_input_hash is not prt_hash) is an error
 * naming both hashes, never used silently.  *scene_config (may be NULL,
 * n bytes) gets the scene config it was baked from. */
int cv_lcd_sidecar_load(const char *prt_path, uint64_t prt_hash, cv_lcd_config *c, int *found,
                        char *scene_config, size_t n, cv_err *err);

/* The ranges every reader of the settings checks, the same in the config
 * and on the command line. */
#define CV_LCD_TOLERANCE_MIN 1e-5 /* metres (lcd.eye_tolerance, --lcd-tolerance) */
#define CV_LCD_TOLERANCE_MAX 1.0
#define CV_LCD_LUMINANCE_MAX 1e6  /* cd/m^2 (white, black, adaptation) */
#define CV_LCD_CR_MAX 1000.0      /* lcd.cr_min, --cr-min */

#endif
