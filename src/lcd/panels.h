/* The LCD panels of a scene (lcd_config.h's lcd.panels) as `cave lcd` and the
 * service render them: one model, so both give the same numbers.
 *
 * Layout: the panels' texel grids are stacked top to bottom into one
 * buffer of W = the widest panel x H = the sum of their heights (panel i at
 * rows y0[i] .. y0[i] + h[i] - 1, columns 0 .. w[i] - 1; texels right of a
 * narrower panel stay 0).  A round renders every panel (each with its own
 * gather, BRDF and sequences) and stacks them, so one round (one message,
 * one allreduce slot) carries all panels and the service's aggregation is
 * the single-panel one; the readability of panel i comes from its rows
 * (cv_lcd_accum_crop).  Each panel's texels equal those of the panel
 * rendered alone, bit for bit.
 *
 * Veils: panel i's veil (the eye looking at its centre) is stored in the
 * buffer's veil slot i (accum.h).  No MPI, nothing printed. */
#ifndef CV_LCD_PANELS_H
#define CV_LCD_PANELS_H

#include "core/image.h"
#include "lcd/accum.h"
#include "lcd/brdf.h"
#include "lcd/gather.h"
#include "lcd/lcd_config.h"
#include "lcd/readability.h"
#include "mesh/mesh.h"

typedef struct cv_lcd_layout {
  int n;                            /* panels */
  int W, H;                         /* the stacked buffer */
  cv_lcd_panel rect[CV_LCD_MAX_PANELS];
  int w[CV_LCD_MAX_PANELS], h[CV_LCD_MAX_PANELS], y0[CV_LCD_MAX_PANELS];
} cv_lcd_layout;

/* Panel rectangles and texel sizes of c's panels (cv_lcd_config_panels must
 * have run): a panel with corners takes them, the others the mesh's
 * triangles tagged lcd; a height of 0 follows the panel's aspect (square
 * texels).  Errors (CV_ERR_CONFIG, naming c->source and the key): a corner
 * outside the scene (the mesh's bounding box grown by 1 cm), no lcd
 * triangles for a panel without corners, the stacked buffer over 16384
 * texels high. */
int cv_lcd_layout_make(const cv_lcd_config *c, const cv_mesh *m, cv_lcd_layout *out, cv_err *err);

/* The panels' emitted content (their content images at their white and
 * black, each with its own aspect), stacked like the buffer: W x H x 3.
 * Errors name the file. */
int cv_lcd_layout_content(const cv_lcd_config *c, const cv_lcd_layout *L, cv_image **out,
                          cv_err *err);

/* Panel i's part of a stacked buffer: a w[i] x h[i] buffer with the same
 * counters, its veil in slot 0.  *out owned by the caller.  Errors:
 * CV_ERR_INVALID (sizes), CV_ERR_NOMEM. */
int cv_lcd_layout_crop(const cv_lcd_layout *L, const cv_lcd_accum *stacked, int i,
                       cv_lcd_accum **out);

/* The gathers of every panel. */
typedef struct cv_lcd_panels {
  cv_lcd_layout L;
  cv_brdf *brdf[CV_LCD_MAX_PANELS];        /* owned */
  cv_lcd_gather *g[CV_LCD_MAX_PANELS];     /* owned */
} cv_lcd_panels;

/* Loads each panel's BRDF and builds its gather (rt borrowed, must outlive
 * *out).  Errors name the file. */
int cv_lcd_panels_create(const cv_lcd_config *c, const cv_lcd_layout *L, const cv_rt *rt,
                         const cv_mesh *m, cv_lcd_panels **out, cv_err *err);
void cv_lcd_panels_destroy(cv_lcd_panels *ps);

/* The sample clamp of every panel: c->clamp when > 0, else the largest of
 * the panels' automatic clamps (cv_lcd_default_clamp): one unit for the
 * stacked buffer. */
double cv_lcd_panels_clamp(const cv_lcd_panels *ps, const cv_lcd_light *l, double config_clamp);

/* Fingerprint of the panels' setups (cv_lcd_setup_hash of each, combined). */
uint64_t cv_lcd_panels_setup_hash(const cv_lcd_panels *ps, const cv_lcd_params *p, double clamp,
                                  double tolerance, uint64_t scene_hash);

/* Round `round` of every panel, ADDED to the stacked buffer acc (W x H):
 * panel i with p's settings at its own size.  Errors as
 * cv_lcd_render_round, CV_ERR_NOMEM. */
int cv_lcd_panels_round(const cv_lcd_panels *ps, const cv_lcd_light *l, const cv_lcd_params *p,
                        uint32_t round, cv_lcd_accum *acc);

/* The veil of every panel at the eye (eye_veil.h): lv[i], sun_deg[i]. */
int cv_lcd_panels_veils(const cv_lcd_panels *ps, const cv_lcd_light *l, const float eye[3],
                        const cv_lcd_veil_params *vp, cv_lcd_figure *lv, double *sun_deg);

#endif
