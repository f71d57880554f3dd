/* Shared helpers of the `cave` program (see cli.h). */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "cli/cli.h"
#include "core/parse.h"
#include "io/mesh_import.h"
#include "mesh/cabin.h"
#include "mesh/clean.h"

int cli_fail(const char *cmd, int code, const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  fprintf(stderr, "cave %s: ", cmd);
  vfprintf(stderr, fmt, ap);
  fputc('\n', stderr);
  va_end(ap);
  return code;
}

int cli_parse_double(const char *s, double *out) { return cv_parse_double(s, out); }
int cli_parse_int(const char *s, int lo, int hi, int *out) { return cv_parse_int(s, lo, hi, out); }
int cli_parse_vec(const char *s, int n, double *out) { return cv_parse_vec(s, n, out); }

int cli_has_ext(const char *path, const char *ext) {
  size_t n = strlen(path), e = strlen(ext);
  return n >= e && strcasecmp(path + n - e, ext) == 0;
}

int cli_load_scene_mesh(const cv_scene_config *c, FILE *report, cv_mesh **out, cv_err *err) {
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
    st = cv_mesh_import(c->mesh_path, NULL, &m, err);
    if (st) return st;
    if (report)
      fprintf(report, "scene: %s: %zu vertices, %zu triangles, %zu materials\n", c->mesh_path,
              m->nv, m->nt, m->nm);
  }
  if ((st = cv_scene_apply_overrides(c, m, err))) goto fail;
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
