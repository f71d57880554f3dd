/* Is the light behind a readability figure absolute, and how much of it is
 * there at the driver's eye?  (docs/readability.md, "Absolute light or no
 * verdict".)  The contrast ratio adds the panel's own luminances (cd/m^2)
 * to the reflection and the veil, so it means something only when the
 * lighting is in cd/m^2: a figure from a map in its own relative units is
 * "uncalibrated" and gets no READABLE / UNREADABLE verdict.
 *
 *   absolute:  --illuminance LUX (or "illuminance" in a scene or drive
 *              config), "absolute": true in a config (the maps times scale
 *              are declared cd/m^2), the Preetham sky, a constant
 *              environment (its value is taken as cd/m^2);
 *   assumed:   --illuminance auto / "illuminance": "auto": a blender-data
 *              map at its documented level (light/calibrate.c), printed as
 *              an assumption;
 *   relative:  an env map with only a scale (or none): uncalibrated.
 *
 * Illuminances at the eye are traced from the eye (cv_lcd_eye_radiance:
 * the environment through the windows, the interior's PRT radiance, black
 * towards a panel) plus the sun when the eye sees it.  Pure computation, no
 * MPI, nothing printed. */
#ifndef CV_LCD_LIGHT_LEVEL_H
#define CV_LCD_LIGHT_LEVEL_H

#include <stddef.h>

#include "io/scene_config.h"
#include "lcd/gather.h"
#include "lcd/readability.h"

typedef struct cv_lcd_calib {
  int absolute;     /* 1: luminances in cd/m^2 (given, declared or assumed) */
  int assumed;      /* 1: absolute by assumption (illuminance auto) */
  char source[640]; /* what makes it absolute, or why it is not (one line) */
} cv_lcd_calib;

/* The calibration of `spec`; origin names where the lighting came from
 * ("command line", "scene config x.json", "drive d.json"). */
void cv_lcd_calibration(const cv_light_spec *spec, const char *origin, cv_lcd_calib *out);

/* Illuminances (lx when the light is absolute, else in the map's units). */
typedef struct cv_lcd_illum {
  double outdoor_h; /* horizontal illuminance of the whole lighting (upper hemisphere of the
                       car frame, sun included, nothing in the way) */
  double eye_h;     /* at the eye on a horizontal plane facing up, the car around it */
  double eye_v;     /* at the eye on a vertical plane facing straight ahead (-Z) */
  double eye_h_se, eye_v_se; /* standard errors of the traced integrals */
} cv_lcd_illum;

/* outdoor_h of light l: its environment table's upper hemisphere plus the
 * sun's Y irradiance times its elevation's sine.  >= 0. */
double cv_lcd_outdoor_illuminance(const cv_lcd_light *l);

/* All three at `eye` (car frame): 128 x 128 stratified cosine-weighted rays
 * per plane (deterministic jitter), plus the sun when the eye sees it.  g is
 * any panel's gather of the scene (for its tracer).  Thread-safe. */
void cv_lcd_illuminance(const cv_lcd_gather *g, const cv_lcd_light *l, const float eye[3],
                        cv_lcd_illum *out);

/* --- the verdict ------------------------------------------------------------ */

typedef enum {
  CV_LCD_UNCALIBRATED = 0, /* no verdict: the light is not absolute */
  CV_LCD_READABLE,
  CV_LCD_UNREADABLE
} cv_lcd_verdict_kind;

/* READABLE when the light is absolute and the panel meets all three: mean
 * CR >= cr_min, area share >= p->area_min, VL >= p->vl_min; UNREADABLE when
 * absolute and one fails (why: the first that fails, e.g. "CR 2.1 < 3");
 * UNCALIBRATED otherwise (why: "uncalibrated light").  why may be NULL. */
cv_lcd_verdict_kind cv_lcd_verdict(const cv_lcd_readability *rd, const cv_lcd_read_params *p,
                                   int absolute, char *why, size_t why_n);

/* "READABLE", "UNREADABLE", "uncalibrated". */
const char *cv_lcd_verdict_name(cv_lcd_verdict_kind v);

#endif
