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
  if (s->o.display_path[0] && cv_display_is_cave_config(s->o.display_path)) {
    /* a CAVE config stands in for a display description (docs/display-format.md):
     * its walls and "screens", --patches / --reflectance overriding */
    cv_cave dc;
    if ((st = cv_cave_load(s->o.display_path, &dc, err))) return st;
    st = cv_display_from_cave(&dc, s->o.patches, s->o.reflectance, &d, err);
    if (st) return cv_err_prefix(err, "%s", s->o.display_path);
  } else if (s->o.display_path[0]) {
    st = cv_display_load(s->o.display_path, &d, err);
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
