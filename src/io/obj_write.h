/* Wavefront OBJ export of a cv_mesh (for inspecting generated or cleaned
 * cabins in other tools).  Writes <name>.obj and a sibling <name>.mtl with
 * one `newmtl` per material (`Kd` = albedo); faces are grouped by material
 * with `usemtl`.  Material flags (window, LCD) are carried only by the
 * material names ("window..." / "lcd..."), which are written unchanged. */
#ifndef CV_IO_OBJ_WRITE_H
#define CV_IO_OBJ_WRITE_H

#include "core/status.h"
#include "mesh/mesh.h"

/* Writes obj_path and the .mtl beside it (obj_path with its ".obj"
 * extension replaced, or ".mtl" appended).  Vertices use %.9g, so floats
 * round-trip exactly.  Both files appear only when complete.  Errors: those
 * of cv_mesh_validate (CV_ERR_EMPTY, CV_ERR_NONFINITE, CV_ERR_RANGE; the
 * message is prefixed with obj_path), CV_ERR_INVALID (a material name is
 * empty or contains whitespace, which OBJ cannot represent), CV_ERR_IO. */
int cv_obj_write(const char *obj_path, const cv_mesh *m, cv_err *err);

#endif
