/* The compensation display of a CAVE configuration (issue 11: one
 * description of the CAVE serves rendering and compensation): the CAVE's
 * walls as plane surfaces with the same corners, names and order, the
 * config's "screens" reflectance and patches per side (or the caller's),
 * patches graded towards the seams, ideal projectors, the viewer at the
 * CAVE's default head (every patch must face it). */
#include <stdio.h>
#include <stdlib.h>

#include <cjson/cJSON.h>

#include "compensate/display.h"
#include "view/cave.h"

int cv_display_from_cave(const cv_cave *c, int patches, double reflectance, cv_display **out, cv_err *err) {
  *out = NULL;
  if (patches <= 0) patches = c->screen_patches;
  if (reflectance < 0) reflectance = c->screen_reflectance;
  size_t cap = 1024 + (size_t)c->n_walls * 512, len = 0;
  char *json = malloc(cap);
  if (!json) return cv_err_set(err, CV_ERR_NOMEM, "display: out of memory");
  len += (size_t)snprintf(json + len, cap - len, "{\"surfaces\": [");
  for (int w = 0; w < c->n_walls; w++) {
    const cv_wall *W = &c->walls[w];
    const double r = reflectance;
    len += (size_t)snprintf(json + len, cap - len,
                            "%s{\"name\": \"%s\", \"corners\": [[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g],"
                            "[%.17g,%.17g,%.17g]], \"patches\": [%d,%d], \"reflectance\": [%.17g,%.17g,%.17g], "
                            "\"refine\": {\"seams\": \"auto\"}}",
                            w ? ", " : "", W->name, W->pa[0], W->pa[1], W->pa[2], W->pb[0], W->pb[1], W->pb[2],
                            W->pc[0], W->pc[1], W->pc[2], patches, patches, r, r, r);
  }
  snprintf(json + len, cap - len, "], \"viewer\": [%.17g,%.17g,%.17g], \"projectors\": \"ideal\"}", c->head[0],
           c->head[1], c->head[2]);
  int st = cv_display_parse(json, "display generated from the CAVE walls", out, err);
  free(json);
  return st;
}

/* A CAVE config rather than a display description: a top-level "walls"
 * and no "surfaces". */
static int is_cave_tree(const cJSON *root) {
  return cJSON_IsObject(root) && cJSON_GetObjectItemCaseSensitive(root, "walls") &&
         !cJSON_GetObjectItemCaseSensitive(root, "surfaces");
}

int cv_display_load_any(const char *path, int patches, double reflectance, cv_display **out,
                        int *is_cave, cv_err *err) {
  *out = NULL;
  if (is_cave) *is_cave = 0;
  cJSON *root = NULL;
  int st = cv_display_read_json(path, &root, err);
  if (st) return st;
  if (!is_cave_tree(root)) {
    st = cv_display_from_json(root, path, out, err);
    cJSON_Delete(root);
    return st;
  }
  if (is_cave) *is_cave = 1;
  cv_cave cave;
  st = cv_cave_from_json(root, path, &cave, err);
  cJSON_Delete(root);
  if (st) return st;
  st = cv_display_from_cave(&cave, patches, reflectance, out, err);
  return st ? cv_err_prefix(err, "%s", path) : CV_OK;
}
