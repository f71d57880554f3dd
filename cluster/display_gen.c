/* The compensation display of a CAVE: the configured display file, checked
 * against the walls, or one generated from the walls (same corners and
 * order, reflectance and patch count from the options, patches graded
 * towards the seams, ideal projectors).  Every rank builds the same one, so
 * wall-eyes know their wall's patch grid without a message. */
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
    st = cv_display_load(s->o.display_path, &d, err);
    if (st) return st;
  } else {
    size_t cap = 1024 + (size_t)s->n_walls * 512, len = 0;
    char *json = malloc(cap);
    if (!json) return cv_err_set(err, CV_ERR_NOMEM, "display: out of memory");
    len += (size_t)snprintf(json + len, cap - len, "{\"surfaces\": [");
    for (int w = 0; w < s->n_walls; w++) {
      const cv_wall *W = &s->cave.walls[w];
      const double r = s->o.reflectance;
      len += (size_t)snprintf(
          json + len, cap - len,
          "%s{\"name\": \"%s\", \"corners\": [[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g],"
          "[%.17g,%.17g,%.17g]], \"patches\": [%d,%d], \"reflectance\": [%g,%g,%g], "
          "\"refine\": {\"seams\": \"auto\"}}",
          w ? ", " : "", W->name, W->pa[0], W->pa[1], W->pa[2], W->pb[0], W->pb[1], W->pb[2],
          W->pc[0], W->pc[1], W->pc[2], s->o.patches, s->o.patches, r, r, r);
    }
    snprintf(json + len, cap - len, "], \"projectors\": \"ideal\"}");
    st = cv_display_parse(json, "display generated from the CAVE walls", &d, err);
    free(json);
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
