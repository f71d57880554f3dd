/* The compensation display of a CAVE: the configured display file, checked
 * against the walls, or the one the CAVE config describes
 * (cv_display_from_cave: its "screens", --patches / --reflectance
 * overriding).  Every rank builds the same one, so
 * wall-eyes know their wall's patch grid without a message. */
#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "compensate/display.h"
#include "service.h"
#include "service_internal.h"

int cv_service_display(const cv_service *s, cv_display **out, cv_err *err) {
  *out = NULL;
  cv_display *d = NULL;
  int st;
  if (s->o.display_path[0]) {
    /* a display description, or a CAVE config standing in for one
     * (docs/display-format.md): its walls and "screens", --patches /
     * --reflectance overriding */
    st = cv_display_load_any(s->o.display_path, s->o.patches, s->o.reflectance, &d, NULL, err);
    if (st) return st;
  } else {
    st = cv_display_from_cave(&s->cave, s->o.patches, s->o.reflectance, &d, err);
    if (st) return st;
  }
  if ((int)cv_display_surface_count(d) != s->n_walls) {
    int n = (int)cv_display_surface_count(d);
    cv_display_destroy(d);
    return cv_err_set(err, CV_ERR_CONFIG, "%s: %d surfaces for %d walls of %s", s->o.display_path,
                      n, s->n_walls, s->o.cave_path);
  }
  for (int w = 0; w < s->n_walls; w++)
    if (strcmp(cv_display_surface_at(d, (size_t)w)->name, s->cave.walls[w].name)) {
      cv_err_set(err, CV_ERR_CONFIG, "%s: surfaces[%d] is '%s', expected the wall '%s' (same order)",
                 s->o.display_path, w, cv_display_surface_at(d, (size_t)w)->name,
                 s->cave.walls[w].name);
      cv_display_destroy(d);
      return CV_ERR_CONFIG;
    }
  *out = d;
  return CV_OK;
}
