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
 *              "cr_min": 3, "age": 40, "pigment": 0.5 } } */
#ifndef CV_LCD_LCD_CONFIG_H
#define CV_LCD_LCD_CONFIG_H

#include <stdint.h>

#include "core/status.h"
#include "io/scene_config.h"

/* Panel white (cd/m^2) of `cave lcd` and `cave run` unless configured; black
 * is CV_LCD_BLACK_LEVEL of white unless configured. */
#define CV_LCD_WHITE_DEFAULT 500.0
#define CV_LCD_BLACK_LEVEL 0.002

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

#endif
