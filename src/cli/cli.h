/* Shared helpers of the `cave` command-line program: argument parsing and
 * loading a scene (config file or mesh file) into a cleaned mesh. */
#ifndef CV_CLI_CLI_H
#define CV_CLI_CLI_H

#include <stdio.h>

#include "core/outfile.h"
#include "io/scene_mesh.h"
#include "io/scene_config.h"
#include "mesh/mesh.h"
#include "mesh/place.h"

/* gnuplot's PNG under a temporary name (cli_plot_begin), checked and renamed
 * by cli_plot_end: gnuplot writing a PNG straight to its name left a
 * cut-short plot on a full disk that was reported as written (issue 35 (3)). */
typedef struct cli_plot {
  cv_outfile of;
  FILE *g; /* gnuplot's stdin: the script, with output p->of.tmp */
} cli_plot;
/* 1: gnuplot started, its script goes to p->g with output p->of.tmp; 0: no
 * gnuplot installed; -1: failed (err set). */
int cli_plot_begin(cli_plot *p, const char *png, cv_err *err);
/* Ends gnuplot; the plot gets its name only when gnuplot succeeded and the
 * PNG decodes whole.  1 when written, -1 (err set, nothing left) if not. */
int cli_plot_end(cli_plot *p, const char *png, cv_err *err);

/* Subcommands: each returns the process exit status. */
int cmd_cabin(int argc, char **argv);
int cmd_bake(int argc, char **argv);
int cmd_shade(int argc, char **argv);
int cmd_materials(int argc, char **argv);
int cmd_tracker(int argc, char **argv);
int cmd_reference(int argc, char **argv);
int cmd_compensate(int argc, char **argv);
int cmd_lcd(int argc, char **argv);
int cmd_render(int argc, char **argv);
int cmd_tonemap(int argc, char **argv);
int cmd_cluster(int argc, char **argv);
int cmd_plot(int argc, char **argv);
/* The MPI service; implemented in cluster/run.c (the only code with MPI). */
int cmd_run(int argc, char **argv);

/* Prints a command's usage lines (its help text up to the first blank line)
 * to stderr: before the one-line error of a missing or bad argument, so the
 * error stays the last line and the whole help is not repeated. */
void cli_print_usage(void (*help)(FILE *));
/* Prints "cave <cmd>: message" to stderr and returns 2 (usage) or 1. */
int cli_fail(const char *cmd, int code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* Strict number parsing: the whole string must be a finite number. */
int cli_parse_double(const char *s, double *out);
int cli_parse_int(const char *s, int lo, int hi, int *out);
/* "x,y,z" (n values) into out; 0 on success. */
int cli_parse_vec(const char *s, int n, double *out);

/* Checks before any work that the output path is a name (not empty: exit 2)
 * that is not a folder, and that its folder exists and is writable; prints
 * "cave <cmd>: <opt>: cannot write ..." and returns the exit status (2 for
 * an empty name, else 1) if not, else 0. */
int cli_check_output(const char *cmd, const char *opt, const char *path);
/* 1 when a and b name the same file: the same string, or both exist and are
 * one inode (a link or another spelling of the path). */
int cli_same_file(const char *a, const char *b);
/* --size WxH: two decimal integers in 1..max joined by 'x', nothing else
 * ("32x24junk", "32x24.9", "+32x24", " 32x24" are refused); 0 on success. */
int cli_parse_size(const char *s, int max, int *w, int *h);

/* A pinhole camera as given on the command line (--view, --look, --view-up)
 * with the strings to quote in an error. */
typedef struct cli_camera_arg {
  const double *eye, *look, *up;
  const char *eye_s, *look_s, *up_s;
} cli_camera_arg;
/* Checks before any work that the camera can be traced: --view and --look
 * within +-1e6 m, --look at least 1e-6 m from --view, --view-up non-zero and
 * not along the view.  Prints "cave <cmd>: <option>: expected ..., got '...'"
 * and returns 2, else 0. */
int cli_check_camera(const char *cmd, const cli_camera_arg *c);

/* An option `a` came last on the line, without the value it needs (or it is
 * no option at all): prints the usage (help non-NULL) and "option 'a' needs a
 * value" when a is one of value_opts (NULL-terminated) or a lighting option,
 * else "unknown option 'a'"; returns 2. */
int cli_value_missing(const char *cmd, void (*help)(FILE *), const char *a,
                      const char *const *value_opts);

/* --illuminance: lux in (0, 1e7] or "auto" (CV_ILLUMINANCE_AUTO); 0 on success. */
int cli_parse_illuminance(const char *s, double *lux);

/* The lighting options shared by shade, render and reference: --env FILE[,..],
 * --weights W,.., --scale S, --illuminance LUX|auto, --env-constant R,G,B,
 * --sky T,EL,AZ, --yaw/--pitch/--roll DEG; in the scene config's ranges
 * (radiance, scale and weights 0..1e9, yaw and azimuth -360..360, pitch
 * -90..90, roll -180..180, no empty name).  argv[*i] is the option.  Returns 0
 * when it is none of these, 1 when it was taken (with its value: *i advanced),
 * or minus the exit code (-1 or -2) after printing the error as `cave CMD: ...`.
 * --weights is only kept in *weights; cli_apply_weights checks it. */
int cli_parse_light(const char *cmd, int argc, char **argv, int *i, cv_light_spec *spec,
                    const char **weights);
/* Applies --weights (NULL: nothing to do) to spec's --env maps; 0 or exit
 * code 2 after printing the error. */
int cli_apply_weights(const char *cmd, cv_light_spec *spec, const char *weights);
#define CLI_ILLUMINANCE_HELP                                                                 \
  "  --illuminance LUX|auto  calibrate the env map(s): the horizontal illuminance of\n"     \
  "                  the upper hemisphere becomes LUX (pixels then in cd/m^2); auto:\n"     \
  "                  each blender-data map at its documented daylight level (forest\n"     \
  "                  10000 lx, ...: docs/scene-config.md); not with --scale\n"     \
  "  (DWA/B44 maps, blender-data's among them, are decoded in a child process\n"           \
  "   under limits: CAVE_EXR_TIMEOUT=S (default 120), CAVE_EXR_MEMORY_MB=M (default\n"     \
  "   1024 + twice the pixel bytes), CAVE_EXR_VERBOSE=1; docs/fuzzing.md)\n"

/* 1 if path ends with ext (case-insensitive, ext includes the dot). */
int cli_has_ext(const char *path, const char *ext);


/* The placement options shared by commands that load a mesh: --units U,
 * --up y|z, --model-scale S, --rotate X,Y,Z (degrees), --translate X,Y,Z (m). */
typedef struct cli_place_opts {
  cv_placement p;
  int given; /* bit per option seen */
} cli_place_opts;
#define CLI_PLACE_HELP                                                                     \
  "  --units U       file units: mm, cm, m, in, ft or metres per unit (default:\n"         \
  "                  what the file says - glTF metres, FBX UnitScaleFactor - else m)\n"    \
  "  --up y|z        the file's up axis (default: from the file, else y)\n"                \
  "  --model-scale S uniform scale after units (default 1)\n"                              \
  "  --rotate X,Y,Z  degrees about X, then Y, then Z, after units and up\n"                \
  "  --translate X,Y,Z  metres, applied last\n"
/* argv[*i] is a placement option: parses it (and its value, advancing *i)
 * and returns 1; 0 when it is not one; -1 on a bad value (*rc = 2, the
 * message printed). */
int cli_place_option(const char *cmd, char **argv, int argc, int *i, cli_place_opts *o, int *rc);
/* Copies the given options into c->place; returns 2 (message printed) when
 * they are given for the built-in cabin, else 0. */
int cli_place_apply(const char *cmd, const cli_place_opts *o, cv_scene_config *c);


#endif
