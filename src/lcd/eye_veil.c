/* The veil of a panel at the eye (eye_veil.h). */
#include "lcd/eye_veil.h"

#include <math.h>

#include "light/envmap.h"
#include "rt/rt.h"

typedef struct eye_ctx {
  const cv_lcd_gather *g;
  const cv_lcd_light *l;
  float eye[3];
} eye_ctx;

static double eye_luminance(void *ctx, const double dir[3]) {
  const eye_ctx *c = ctx;
  const float d[3] = {(float)dir[0], (float)dir[1], (float)dir[2]};
  float rgb[3];
  cv_lcd_eye_radiance(c->g, c->l, c->eye, d, rgb);
  return cv_luminance(rgb[0], rgb[1], rgb[2]);
}

int cv_lcd_panel_veil(const cv_lcd_gather *g, const cv_lcd_light *l, const float eye[3],
                      const cv_lcd_veil_params *vp, cv_lcd_figure *lv, double *sun_deg) {
  const cv_lcd_panel *pn = cv_lcd_gather_panel(g);
  double gaze[3], len = 0;
  for (int k = 0; k < 3; k++) {
    gaze[k] = (double)pn->center[k] - eye[k];
    len += gaze[k] * gaze[k];
  }
  len = sqrt(len);
  *sun_deg = -1;
  if (!(len > 0)) return CV_ERR_INVALID;
  for (int k = 0; k < 3; k++) gaze[k] /= len;
  eye_ctx c = {g, l, {eye[0], eye[1], eye[2]}};
  cv_lcd_point_source sun;
  int nsrc = 0;
  if (cv_lcd_sun_visible(g, l, eye)) {
    double sl = 0;
    for (int k = 0; k < 3; k++) sl += (double)l->sun_dir[k] * l->sun_dir[k];
    sl = sqrt(sl);
    double cosg = 0;
    for (int k = 0; k < 3; k++) {
      sun.dir[k] = l->sun_dir[k] / sl;
      cosg += sun.dir[k] * gaze[k];
    }
    sun.E = cv_luminance(l->sun_E[0], l->sun_E[1], l->sun_E[2]);
    *sun_deg = acos(cosg > 1 ? 1 : (cosg < -1 ? -1 : cosg)) * 180 / M_PI;
    nsrc = 1;
  }
  cv_rt_thread_init();
  return cv_lcd_veil(gaze, vp, eye_luminance, &c, &sun, nsrc, lv);
}
