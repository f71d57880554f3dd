/* Placing an imported model in the scene's frame (metres, +Y up, see
 * docs/conventions.md): file units to metres, Z-up to Y-up, then an optional
 * user transform.  The order is fixed:
 *
 *   p' = T + R * (s * U(up) * (unit_m * p))
 *
 * unit_m: metres per file unit; U(z): -90 degrees about X, (x, y, z) ->
 * (x, z, -y), so a Z-up model stands upright with its +Y pointing to -Z;
 * s: uniform scale; R = Rz * Ry * Rx (rotate about X first, then Y, then Z,
 * right-handed, degrees); T: translation in metres.
 *
 * unit_m = 0 and up = 0 mean "what the file says": the caller passes what
 * the file carries (glTF: metres and Y up by specification; FBX: its
 * UnitScaleFactor and UpAxis; COLLADA: assimp already converts) and when the
 * file says nothing, metres and Y up. */
#ifndef CV_MESH_PLACE_H
#define CV_MESH_PLACE_H

#include "core/status.h"
#include "mesh/mesh.h"

typedef struct cv_placement {
  double unit_m;        /* metres per file unit; 0 = from the file, else 1 */
  char up;              /* 'y', 'z'; 0 = from the file, else 'y' */
  double scale;         /* uniform scale after units and up (default 1) */
  double rotate_deg[3]; /* about X, then Y, then Z (default 0) */
  double translate[3];  /* metres, applied last (default 0) */
} cv_placement;

/* What the file itself says (0 where it says nothing) and where it was read. */
typedef struct cv_file_frame {
  double unit_m;      /* metres per file unit, 0 = unknown */
  char up;            /* 'y', 'z', 0 = unknown */
  const char *source; /* e.g. "glTF specification", "FBX UnitScaleFactor" (static), or NULL */
} cv_file_frame;

/* What was applied, for the report. */
typedef struct cv_placement_report {
  double unit_m;
  const char *unit_from; /* "option", "file", "default" */
  char up;
  const char *up_from;   /* "option", "file", "default" */
  float lo[3], hi[3];    /* bounding box after placement, metres */
  double size[3];        /* hi - lo */
  int implausible_car;   /* largest extent < 0.5 m or > 20 m */
} cv_placement_report;

/* Implausible-size limits for a car model, metres. */
#define CV_CAR_MIN_EXTENT_M 0.5
#define CV_CAR_MAX_EXTENT_M 20.0

/* Defaults: units and up from the file, scale 1, no rotation or translation. */
void cv_placement_default(cv_placement *p);
/* "mm", "cm", "m", "in", "ft" or a positive finite number (metres per unit)
 * into *unit_m.  CV_ERR_INVALID otherwise (err names the value and what is
 * expected; the caller prefixes the file and key). */
int cv_parse_units(const char *s, double *unit_m, cv_err *err);
/* The accepted values of `units`, for error messages and help. */
const char *cv_units_expected(void);
/* "y" or "z" (case-insensitive) into *up; CV_ERR_INVALID otherwise. */
int cv_parse_up(const char *s, char *up, cv_err *err);
/* Checks p (finite values, scale > 0, unit_m >= 0, up 0/'y'/'z'). */
int cv_placement_check(const cv_placement *p, cv_err *err);
/* Applies p to every vertex of m (ff may be NULL) and fills *r (may be
 * NULL).  CV_ERR_NONFINITE if a coordinate overflows. */
int cv_mesh_place(cv_mesh *m, const cv_placement *p, const cv_file_frame *ff,
                  cv_placement_report *r, cv_err *err);
/* R = Rz Ry Rx for angles in degrees about X, Y, Z (rotate about X first),
 * right-handed, row-major 3x3 (also the tracker's room-to-CAVE rotation). */
void cv_rotation_xyz_deg(const double deg[3], double R[9]);
/* Bounding box of m (metres) into r->lo/hi/size and the plausibility flag. */
void cv_placement_measure(const cv_mesh *m, cv_placement_report *r);

#endif
