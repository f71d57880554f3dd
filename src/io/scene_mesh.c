/* The scene's mesh from its config (scene_mesh.h). */
#include "io/scene_mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "io/mesh_import.h"
#include "mesh/cabin.h"
#include "mesh/clean.h"

void cv_placement_print(FILE *f, const cv_placement_report *r, const char *file_says) {
  fprintf(f, "scene: units %g m (%s%s%s), up %c (%s)\n", r->unit_m, r->unit_from,
          file_says && !strcmp(r->unit_from, "file") ? ": " : "",
          file_says && !strcmp(r->unit_from, "file") ? file_says : "", r->up, r->up_from);
  fprintf(f, "scene: bounding box %.3f x %.3f x %.3f m (x %.3f..%.3f, y %.3f..%.3f, z %.3f..%.3f)\n",
          r->size[0], r->size[1], r->size[2], (double)r->lo[0], (double)r->hi[0],
          (double)r->lo[1], (double)r->hi[1], (double)r->lo[2], (double)r->hi[2]);
  if (r->implausible_car)
    fprintf(f, "warning: a car is %g..%g m long, this model's largest extent is %.3g m: check "
               "\"units\" and \"up\"\n", CV_CAR_MIN_EXTENT_M, CV_CAR_MAX_EXTENT_M,
            fmax(r->size[0], fmax(r->size[1], r->size[2])));
}

const char *cv_material_tag_name(uint32_t flags) {
  switch (flags & (CV_MAT_WINDOW | CV_MAT_LCD)) {
  case CV_MAT_WINDOW: return "window";
  case CV_MAT_LCD: return "lcd";
  case CV_MAT_WINDOW | CV_MAT_LCD: return "window+lcd";
  default: return "none";
  }
}

/* The config's material overrides, with what each pattern matched. */
static int apply_overrides(const cv_scene_config *c, cv_mesh *m, FILE *report, cv_err *err) {
  if (c->n_overrides == 0) return CV_OK;
  cv_override_count *n = calloc((size_t)c->n_overrides, sizeof *n);
  if (!n) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  int st = cv_scene_apply_overrides_ex(c, m, n, err);
  for (int i = 0; !st && report && i < c->n_overrides; i++) {
    const cv_scene_material *ov = &c->overrides[i];
    fprintf(report, "materials[%d] '%s': %zu material%s, %zu triangles", i, ov->name,
            n[i].materials, n[i].materials == 1 ? "" : "s", n[i].triangles);
    if (ov->has_tag) fprintf(report, ", tag %s", cv_material_tag_name(ov->flags));
    if (ov->has_albedo)
      fprintf(report, ", albedo %.3g %.3g %.3g", (double)ov->albedo[0], (double)ov->albedo[1],
              (double)ov->albedo[2]);
    fputc('\n', report);
  }
  free(n);
  return st;
}

int cv_scene_mesh_import(const cv_scene_config *c, FILE *report, cv_mesh **out, cv_err *err) {
  *out = NULL;
  cv_mesh *m = NULL;
  int st;
  if (c->mesh_is_cabin) {
    cv_cabin_params cp;
    cv_cabin_default_params(&cp);
    cp.tess = c->cabin_tess;
    if (c->cabin_length > 0) cp.length = c->cabin_length;
    if (c->cabin_width > 0) cp.width = c->cabin_width;
    if (c->cabin_height > 0) cp.height = c->cabin_height;
    st = cv_cabin_generate(&cp, &m, err);
    if (st) return cv_err_prefix(err, "%s: mesh", c->source);
    if (report)
      fprintf(report, "scene: built-in cabin, tess %d: %zu vertices, %zu triangles\n", cp.tess,
              m->nv, m->nt);
  } else {
    cv_import_stats is;
    st = cv_mesh_import_ex(c->mesh_path, NULL, &m, &is, err);
    if (st) return st;
    if (report)
      fprintf(report, "scene: %s: %zu vertices, %zu triangles, %zu materials\n", c->mesh_path,
              m->nv, m->nt, m->nm);
    if (report && is.textures_averaged)
      fprintf(report, "scene: %zu textured materials use their texture's mean albedo\n",
              is.textures_averaged);
    if (report && is.textures_embedded)
      fprintf(report, "scene: %zu embedded textures written to the texture cache\n",
              is.textures_embedded);
    if (report && is.textures_unread)
      fprintf(report, "warning: %zu material textures not read (their colour is used alone); "
              "first: %s\n", is.textures_unread, is.texture_error);
    cv_placement_report pr;
    if ((st = cv_mesh_place(m, &c->place, &is.frame, &pr, err))) {
      cv_err_prefix(err, "%s", c->mesh_path);
      goto fail;
    }
    if (report) cv_placement_print(report, &pr, is.frame.source);
  }
  if ((st = apply_overrides(c, m, report, err))) goto fail;
  *out = m;
  return CV_OK;
fail:
  cv_mesh_destroy(m);
  return st;
}

int cv_scene_mesh_load(const cv_scene_config *c, FILE *report, cv_mesh **out, cv_err *err) {
  cv_mesh *m = NULL;
  int st = cv_scene_mesh_import(c, report, &m, err);
  if (st) return st;
  if (c->clean_enabled) {
    cv_clean_params cp;
    cv_clean_default_params(&cp);
    if (c->weld_tolerance >= 0) cp.weld_tol_rel = c->weld_tolerance;
    if (c->crease_angle_deg >= 0) cp.crease_deg = c->crease_angle_deg;
    if (c->crack_width >= 0) cp.crack_width_rel = c->crack_width;
    if (c->sliver_aspect >= 0) cp.sliver_aspect = c->sliver_aspect;
    cv_clean_report rep;
    if ((st = cv_mesh_clean(m, &cp, &rep, err))) {
      cv_err_prefix(err, "%s", c->mesh_is_cabin ? "built-in cabin" : c->mesh_path);
      goto fail;
    }
    if (report) cv_clean_report_print(report, &rep);
  }
  if ((st = cv_mesh_validate(m, err))) {
    cv_err_prefix(err, "%s%s", c->mesh_is_cabin ? "built-in cabin" : c->mesh_path,
                  c->clean_enabled ? " after cleaning" : "");
    goto fail;
  }
  size_t windows = 0;
  for (size_t t = 0; t < m->nt; t++) windows += (m->mats[m->tri_mat[t]].flags & CV_MAT_WINDOW) != 0;
  if (report && windows == 0)
    fprintf(report,
            "warning: the scene has no window triangles (materials named window*): every ray "
            "that escapes reaches the environment\n");
  *out = m;
  return CV_OK;
fail:
  cv_mesh_destroy(m);
  return st;
}
