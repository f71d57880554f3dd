/* LCD panel settings: panel resolution, samples per round, BRDF, content
 * image and its luminance, camera-key tolerance.  Read from the "lcd" object
 * of a JSON file (`cave lcd --lcd-config FILE`), with the same rules as the
 * scene config (docs/scene-config.md): every field optional, unknown fields
 * and wrong types are errors naming the file and the field.  Proposed as the
 * scene config's "lcd" block:
 *
 *   { "lcd": { "resolution": [400, 300], "spp": 40, "rounds": 1,
 *              "brdf": "builtin:antiglare", "content": "dash.png",
 *              "content_luminance": 250, "eye_tolerance": 0.005,
 *              "brdf_fraction": 0.9, "seed": 1, "env_width": 1024,
 *              "sun_samples": 16, "clamp": 0 } } */
#ifndef CV_LCD_LCD_CONFIG_H
#define CV_LCD_LCD_CONFIG_H

#include <stdint.h>

#include "core/status.h"
#include "io/scene_config.h"

typedef struct cv_lcd_config {
  int width, height;          /* panel texels (400 x 300) */
  int spp;                    /* samples per texel per round (40) */
  int rounds;                 /* rounds `cave lcd` renders (1) */
  char brdf[CV_PATH_MAX];     /* table or MERL file, or "builtin:antiglare" (default) */
  char content[CV_PATH_MAX];  /* image shown on the panel (.png/.exr); "" = built-in pattern */
  double content_luminance;   /* cd/m^2 of content white (250) */
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

#endif
