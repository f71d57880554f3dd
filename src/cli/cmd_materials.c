/* `cave materials`: lists a model's materials (index, triangles, area in
 * square metres, tag, albedo, name) as the scene will see them: after
 * placement (units, up, transform) and the scene config's overrides, before
 * geometry cleaning. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/cli.h"

static void help(FILE *f) {
  fprintf(f,
          "usage: cave materials <scene.json | mesh.obj|.ply|.gltf|.glb|.fbx|.dae|.ifc | default>\n"
          "                      [--units U] [--up y|z] [--model-scale S] [--rotate X,Y,Z]\n"
          "                      [--translate X,Y,Z]\n\n"
          "Lists every material of the model: index, triangle count, area (m^2, after\n"
          "units and transform), tag (window / lcd / none) and albedo, as the bake will\n"
          "see them before geometry cleaning.  With a scene config the overrides of its\n"
          "\"materials\" list (glob patterns) are applied first and a line per pattern says\n"
          "how many materials and triangles it matched.  'default' lists the built-in\n"
          "cabin of the default scene.\n\n" CLI_PLACE_HELP
          "\nexamples:\n"
          "  cave materials /usr/share/assimp/models/IFC/AC14-FZK-Haus.ifc\n"
          "  cave materials configs/scenes/default.json\n");
}

/* Triangle count and area per material. */
static int per_material(const cv_mesh *m, size_t **ntri, double **area) {
  *ntri = calloc(m->nm + 1, sizeof **ntri);
  *area = calloc(m->nm + 1, sizeof **area);
  if (!*ntri || !*area) return -1;
  for (size_t t = 0; t < m->nt; t++) {
    float n[3];
    cv_mesh_tri_normal(m, t, n);
    uint32_t k = m->tri_mat[t];
    (*ntri)[k]++;
    (*area)[k] += 0.5 * sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
  }
  return 0;
}

int cmd_materials(int argc, char **argv) {
  const char *in = NULL;
  cli_place_opts place = {.given = 0};
  cv_placement_default(&place.p);
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i];
    int pr, prc = 0;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    } else if ((pr = cli_place_option("materials", argv, argc, &i, &place, &prc)) != 0) {
      if (pr < 0) return prc;
    } else if (a[0] == '-' && a[1]) {
      cli_print_usage(help);
      return cli_fail("materials", 2, "unknown option '%s'", a);
    } else if (!in) {
      in = a;
    } else {
      return cli_fail("materials", 2, "more than one input ('%s' and '%s')", in, a);
    }
  }
  if (!in) {
    cli_print_usage(help);
    return cli_fail("materials", 2, "missing the model (a scene config or a mesh file)");
  }
  cv_scene_config cfg;
  cv_err err;
  cv_err_clear(&err);
  if (cli_has_ext(in, ".json")) {
    if (cv_scene_config_load(in, &cfg, &err)) return cli_fail("materials", 1, "%s", err.msg);
  } else if (!strcmp(in, "default")) {
    cv_scene_config_default(&cfg);
  } else {
    cv_scene_config_default(&cfg);
    cfg.mesh_is_cabin = 0;
    snprintf(cfg.mesh_path, sizeof cfg.mesh_path, "%s", in);
    snprintf(cfg.source, sizeof cfg.source, "%s", in);
  }
  int rc = cli_place_apply("materials", &place, &cfg);
  cv_mesh *m = NULL;
  size_t *ntri = NULL;
  double *area = NULL;
  if (rc) goto done;
  rc = 1;
  if (cv_scene_mesh_import(&cfg, stdout, &m, &err)) {
    rc = cli_fail("materials", 1, "%s", err.msg);
    goto done;
  }
  if (per_material(m, &ntri, &area)) {
    rc = cli_fail("materials", 1, "out of memory");
    goto done;
  }
  printf("%5s %9s %12s  %-10s %-17s %s\n", "index", "triangles", "area_m2", "tag", "albedo", "name");
  double total = 0;
  for (size_t k = 0; k < m->nm; k++) {
    const cv_material *mt = &m->mats[k];
    printf("%5zu %9zu %12.4f  %-10s %5.3f %5.3f %5.3f %s\n", k, ntri[k], area[k],
           cv_material_tag_name(mt->flags), (double)mt->albedo[0], (double)mt->albedo[1],
           (double)mt->albedo[2], mt->name);
    total += area[k];
  }
  printf("%zu materials, %zu triangles, %.4f m^2\n", m->nm, m->nt, total);
  rc = 0;
done:
  free(ntri);
  free(area);
  cv_mesh_destroy(m);
  cv_scene_config_free(&cfg);
  return rc;
}
