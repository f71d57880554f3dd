/* Parametric car-cabin generator: the service's built-in default scene.
 *
 * The cabin is a compact-car interior in metres (+Y up, the car looks along
 * -Z, +X is the driver's right; the driver sits on the LEFT, x < 0):
 *  - a closed shell (floor, firewall, windshield, roof, rear window, rear
 *    wall, two side walls) built from conforming structured grids, wound
 *    counter-clockwise seen from INSIDE.  Window openings (windshield, four
 *    side windows, rear window) are cells of those grids tagged with
 *    materials "window_*" (flag CV_MAT_WINDOW), so shell + windows is one
 *    watertight surface once coincident positions are identified (vertices
 *    are not shared across sharp creases, so the PRT bake never averages a
 *    floor sample into a wall vertex);
 *  - a dashboard across the width with an LCD panel ("lcd_panel",
 *    CV_MAT_LCD) set in its driver-facing face, two front seats (cushion,
 *    backrest, headrest), a rear bench (cushion, backrest), a centre
 *    console, and a steering wheel (torus rim, hub, three spokes, column) in
 *    front of the driver.  These closed objects are wound outward.
 *
 * One parameter, `tess`, scales every part's subdivision (grid cells of
 * 0.09 m / tess, the wheel rim 24 tess x 8 tess); the triangle count grows
 * about as tess^2 (default dimensions, measured by tests/mesh/test_cabin.c):
 *     tess 1:  10,264 triangles (6,316 vertices)
 *     tess 2:  38,188             tess 5: 223,640
 *     tess 3:  82,600             tess 6: 321,396
 *     tess 4: 146,604             tess 7: 438,384
 *                                 tess 8: 570,648 (293,264 vertices)
 * cv_cabin_tess_for_triangles(500000) = 8; generating it takes ~13 ms
 * (Release build, one core).
 * The output is a pure function of the parameters (bit-identical on
 * repeated calls). */
#ifndef CV_MESH_CABIN_H
#define CV_MESH_CABIN_H

#include <stddef.h>

#include "core/status.h"
#include "mesh/mesh.h"

typedef struct cv_cabin_params {
  double length; /* interior length along Z, metres (default 2.6, range [1.5, 5]) */
  double width;  /* interior width along X (default 1.45, range [1.0, 2.5]) */
  double height; /* floor to roof along Y (default 1.2, range [0.9, 2.0]) */
  int tess;      /* subdivision scale, 1..64 (default 1, ~10K triangles) */
} cv_cabin_params;

/* The LCD panel's frame: a w x h rectangle centred at `center` in the plane
 * spanned by the unit vectors u (panel width, towards +X) and v (panel
 * height, upwards); `normal` = u x v points out of the panel (towards the
 * occupants). */
typedef struct cv_cabin_lcd {
  float center[3], normal[3], u[3], v[3];
  float size[2]; /* width along u, height along v (metres) */
} cv_cabin_lcd;

/* Points that later modules need: the driver's eye, a default camera (at the
 * eye, looking ahead and slightly down) and the LCD frame.  The floor is at
 * y = 0, the roof at y = height, the cabin spans z in [-length/2, length/2]
 * and x in [-width/2, width/2]. */
typedef struct cv_cabin_info {
  float eye[3];                     /* driver's eye point */
  float cam_pos[3], cam_target[3], cam_up[3];
  float cam_fov_y_deg;              /* vertical field of view */
  cv_cabin_lcd lcd;
  size_t shell_tri_begin, shell_tri_end; /* shell + windows triangles [begin, end) */
} cv_cabin_info;

/* Fills p with the defaults (2.6 x 1.45 x 1.2 m, tess 1). */
void cv_cabin_default_params(cv_cabin_params *p);

/* Generates the cabin; *out is a new mesh owned by the caller
 * (cv_mesh_destroy).  Errors: CV_ERR_INVALID for NULL arguments,
 * CV_ERR_RANGE (err names the field) for a dimension or tess outside its
 * range, CV_ERR_NOMEM.  *out is NULL on error. */
int cv_cabin_generate(const cv_cabin_params *p, cv_mesh **out, cv_err *err);

/* As cv_cabin_generate, and also fills *info (may be NULL). */
int cv_cabin_generate_ex(const cv_cabin_params *p, cv_mesh **out, cv_cabin_info *info,
                         cv_err *err);

/* Vertex and triangle counts the generator would produce for p, without
 * building the mesh.  Same errors as cv_cabin_generate (except NOMEM). */
int cv_cabin_count(const cv_cabin_params *p, size_t *nv, size_t *nt, cv_err *err);

/* Smallest tess whose default-dimension cabin has at least `target`
 * triangles (1 for target <= ~10K; 64, the maximum, if none reaches it). */
int cv_cabin_tess_for_triangles(size_t target);

#endif
