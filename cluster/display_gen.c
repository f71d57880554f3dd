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

/* A CAVE config (top-level "walls", no "surfaces") rather than a display
 * description, decided by the keys as `cave compensate --display` does
 * (cmd_compensate.c), so that each loader reports its own problems;
 * anything unreadable goes to the display loader, which says why. */
static int is_cave_config(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) return 0;
  char *text = NULL;
  long n = -1;
  if (!fseek(f, 0, SEEK_END) && (n = ftell(f)) >= 0 && n < (64L << 20) && !fseek(f, 0, SEEK_SET) &&
      (text = malloc((size_t)n + 1)) && fread(text, 1, (size_t)n, f) == (size_t)n)
    text[n] = 0;
  else
    n = -1;
  fclose(f);
  int cave = 0;
  if (n >= 0) {
    cJSON *root = cJSON_Parse(text);
    cave = cJSON_IsObject(root) && cJSON_GetObjectItemCaseSensitive(root, "walls") &&
           !cJSON_GetObjectItemCaseSensitive(root, "surfaces");
    cJSON_Delete(root);
  }
  free(text);
  return cave;
}

int cv_service_display(const cv_service *s, cv_display **out, cv_err *err) {
  *out = NULL;
  cv_display *d = NULL;
  int st;
  if (s->o.display_path[0] && is_cave_config(s->o.display_path)) {
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
