/* The disability-glare veil of one panel at the driver's eye, the same for
 * `cave lcd` and the service's LCD contributors (cluster/lcdwork.c): the eye
 * looks at the panel centre; what it sees is traced from the eye
 * (cv_lcd_eye_radiance: environment through the windows, the interior's PRT
 * radiance, nothing from the panel itself), plus the sun as a point source
 * when a ray from the eye towards it leaves through a window; the integral
 * is readability.h's cv_lcd_veil (CIE 146:2002).  Deterministic: a pure
 * function of (gather, light, eye, params).  No MPI, nothing printed. */
#ifndef CV_LCD_EYE_VEIL_H
#define CV_LCD_EYE_VEIL_H

#include "lcd/gather.h"
#include "lcd/readability.h"

/* *lv: the veil (cd/m^2, with its standard error); *sun_deg: the sun's glare
 * angle from the line of sight in degrees, -1 when there is no sun or it is
 * hidden.  Errors: CV_ERR_INVALID (the eye at the panel centre, bad params). */
int cv_lcd_panel_veil(const cv_lcd_gather *g, const cv_lcd_light *l, const float eye[3],
                      const cv_lcd_veil_params *vp, cv_lcd_figure *lv, double *sun_deg);

#endif
