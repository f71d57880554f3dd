/* The scene's mesh from its config (cv_scene_config): the parametric cabin
 * or an imported, placed model, the config's material overrides, then the
 * geometry cleaning.  Used by cave bake, lcd, reference and materials; the
 * report lines (when `report` is non-NULL) are what those commands print. */
#ifndef CV_IO_SCENE_MESH_H
#define CV_IO_SCENE_MESH_H

#include <stdint.h>
#include <stdio.h>

#include "core/status.h"
#include "io/scene_config.h"
#include "mesh/mesh.h"
#include "mesh/place.h"

/* Prints the placement (units, up, where they came from) and the bounding box
 * in metres, with a warning when the size is implausible for a car. */
void cv_placement_print(FILE *f, const cv_placement_report *r, const char *file_says);

/* "window", "lcd", "window+lcd" or "none" for CV_MAT_* flags. */
const char *cv_material_tag_name(uint32_t flags);

/* The scene's mesh before cleaning: the cabin or the imported, placed file,
 * with the config's material overrides (a line per pattern to `report`). */
int cv_scene_mesh_import(const cv_scene_config *c, FILE *report, cv_mesh **out, cv_err *err);

/* Builds the scene's mesh from the config: the parametric cabin or an
 * imported file, material overrides, then geometry cleaning (report printed
 * to `report` when non-NULL).  *out owned by the caller. */
int cv_scene_mesh_load(const cv_scene_config *c, FILE *report, cv_mesh **out, cv_err *err);

#endif
