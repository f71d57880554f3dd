/* `cave cabin`: writes the built-in parametric cabin as OBJ + MTL, so it can
 * be inspected in any modeller or fed back through the importer. */
#include <stdio.h>
#include <string.h>

#include "cli/cli.h"
#include "io/obj_write.h"
#include "mesh/cabin.h"

static void help(FILE *f) {
  fprintf(f,
          "usage: cave cabin [--tess N | --triangles N] [--length M] [--width M] [--height M]\n"
          "                  -o cabin.obj\n\n"
          "Writes the built-in car cabin (the default scene) as OBJ with a sibling .mtl.\n"
          "Window openings are materials named window_*, the dashboard display lcd_panel.\n\n"
          "  --tess N        subdivision scale 1..64 (default 1, about 10K triangles)\n"
          "  --triangles N   pick the smallest tess reaching N triangles (8 gives ~585K)\n"
          "  --length/--width/--height M   interior size in metres (2.6 / 1.45 / 1.2)\n"
          "  -o FILE         output OBJ path (required)\n"
          "\nexamples:\n"
          "  cave cabin -o cabin.obj\n"
          "  cave cabin --tess 2 --length 2.8 -o long.obj\n");
}

int cmd_cabin(int argc, char **argv) {
  cv_cabin_params p;
  cv_cabin_default_params(&p);
  const char *out = NULL;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    } else if (!strcmp(a, "-o") && v) {
      out = v;
      i++;
    } else if (!strcmp(a, "--tess") && v) {
      if (cli_parse_int(v, 1, 64, &p.tess)) return cli_fail("cabin", 2, "--tess: expected 1..64, got '%s'", v);
      i++;
    } else if (!strcmp(a, "--triangles") && v) {
      int n;
      if (cli_parse_int(v, 1, 100000000, &n)) return cli_fail("cabin", 2, "--triangles: expected a positive count, got '%s'", v);
      p.tess = cv_cabin_tess_for_triangles((size_t)n);
      i++;
    } else if ((!strcmp(a, "--length") || !strcmp(a, "--width") || !strcmp(a, "--height")) && v) {
      double d;
      if (cli_parse_double(v, &d)) return cli_fail("cabin", 2, "%s: expected metres, got '%s'", a, v);
      if (!strcmp(a, "--length")) p.length = d;
      else if (!strcmp(a, "--width")) p.width = d;
      else p.height = d;
      i++;
    } else {
      cli_print_usage(help);
      return cli_fail("cabin", 2, "unknown or incomplete option '%s'", a);
    }
  }
  if (!out) {
    cli_print_usage(help);
    return cli_fail("cabin", 2, "-o FILE.obj is required");
  }
  cv_mesh *m;
  cv_err err;
  cv_err_clear(&err);
  if (cv_cabin_generate(&p, &m, &err)) return cli_fail("cabin", 1, "%s", err.msg);
  int st = cv_obj_write(out, m, &err);
  if (!st)
    printf("wrote %s: %zu vertices, %zu triangles, %zu materials (tess %d)\n", out, m->nv, m->nt,
           m->nm, p.tess);
  cv_mesh_destroy(m);
  return st ? cli_fail("cabin", 1, "%s", err.msg) : 0;
}
