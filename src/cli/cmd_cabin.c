/* `cave cabin`: writes the built-in parametric cabin as OBJ + MTL, so it can
 * be inspected in any modeller or fed back through the importer. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/cli.h"
#include "io/obj_write.h"
#include "io/scene_config.h"
#include "mesh/cabin.h"

/* The ranges mesh/cabin.c accepts (its check_params), named here so the
 * command line refuses a bad value with the option's name and exit 2. */
#define CABIN_LENGTH_MIN 1.5
#define CABIN_LENGTH_MAX 5.0
#define CABIN_WIDTH_MIN 1.0
#define CABIN_WIDTH_MAX 2.5
#define CABIN_HEIGHT_MIN 0.9
#define CABIN_HEIGHT_MAX 2.0

static void help(FILE *f) {
  fprintf(f,
          "usage: cave cabin [--tess N | --triangles N] [--length M] [--width M] [--height M]\n"
          "                  -o cabin.obj\n\n"
          "Writes the built-in car cabin as OBJ with a sibling .mtl (cabin.obj -> cabin.mtl);\n"
          "with the defaults it is the default scene's cabin ('cave bake default').\n"
          "Window openings are materials named window_*, the dashboard display lcd_panel.\n\n"
          "  --tess N        subdivision scale 1..64 (default %d, the default scene's, about\n"
          "                  38K triangles; 1 gives about 10K)\n"
          "  --triangles N   pick the smallest tess reaching N triangles (8 gives ~571K)\n"
          "  --length M      interior length in metres, %g..%g (default 2.6)\n"
          "  --width M       interior width in metres, %g..%g (default 1.45)\n"
          "  --height M      interior height in metres, %g..%g (default 1.2)\n"
          "  -o FILE.obj     output OBJ path (required; the .mtl goes beside it)\n"
          "\nexamples:\n"
          "  cave cabin -o cabin.obj\n"
          "  cave cabin --tess 1 --length 2.8 -o long.obj\n",
          CV_SCENE_DEFAULT_TESS, CABIN_LENGTH_MIN, CABIN_LENGTH_MAX, CABIN_WIDTH_MIN,
          CABIN_WIDTH_MAX, CABIN_HEIGHT_MIN, CABIN_HEIGHT_MAX);
}

int cmd_cabin(int argc, char **argv) {
  cv_cabin_params p;
  cv_cabin_default_params(&p);
  p.tess = CV_SCENE_DEFAULT_TESS; /* the default scene's cabin */
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
      const int len = !strcmp(a, "--length"), wid = !strcmp(a, "--width");
      const double lo = len ? CABIN_LENGTH_MIN : wid ? CABIN_WIDTH_MIN : CABIN_HEIGHT_MIN;
      const double hi = len ? CABIN_LENGTH_MAX : wid ? CABIN_WIDTH_MAX : CABIN_HEIGHT_MAX;
      double d;
      if (cli_parse_double(v, &d) || !(d >= lo && d <= hi))
        return cli_fail("cabin", 2, "%s: expected metres in %g..%g, got '%s'", a, lo, hi, v);
      if (len) p.length = d;
      else if (wid) p.width = d;
      else p.height = d;
      i++;
    } else {
      static const char *const value_opts[] = {"-o", "--tess", "--triangles", "--length",
                                               "--width", "--height", NULL};
      return cli_value_missing("cabin", help, a, value_opts);
    }
  }
  if (!out) {
    cli_print_usage(help);
    return cli_fail("cabin", 2, "-o FILE.obj is required");
  }
  /* Before any work: an .obj name (the .mtl is its sibling: x.mtl would
   * get the OBJ and x.mtl.mtl the materials), a writable folder, and no
   * folder in the way of either file. */
  if (!out[0]) return cli_fail("cabin", 2, "-o: expected a file name");
  if (!cli_has_ext(out, ".obj") || strlen(out) <= 4 || out[strlen(out) - 5] == '/')
    return cli_fail("cabin", 2, "-o: expected an .obj path, got '%s'", out);
  size_t n = strlen(out);
  char *mtl = malloc(n + 8);
  if (!mtl) return cli_fail("cabin", 1, "out of memory");
  memcpy(mtl, out, n + 1);
  if (strcmp(out + n - 4, ".obj") == 0) memcpy(mtl + n - 4, ".mtl", 5); /* as io/obj_write.c */
  else memcpy(mtl + n, ".mtl", 5);
  /* both files: a folder in the way of the .obj left the .mtl behind */
  int rc = cli_check_output("cabin", "-o", out);
  if (!rc) rc = cli_check_output("cabin", "-o", mtl);
  free(mtl);
  if (rc) return rc;
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
