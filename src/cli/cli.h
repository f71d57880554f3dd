/* Shared helpers of the `cave` command-line program: argument parsing and
 * loading a scene (config file or mesh file) into a cleaned mesh. */
#ifndef CV_CLI_CLI_H
#define CV_CLI_CLI_H

#include <stdio.h>

#include "io/scene_config.h"
#include "mesh/mesh.h"

/* Subcommands: each returns the process exit status. */
int cmd_cabin(int argc, char **argv);
int cmd_bake(int argc, char **argv);
int cmd_shade(int argc, char **argv);
int cmd_reference(int argc, char **argv);
int cmd_compensate(int argc, char **argv);
int cmd_lcd(int argc, char **argv);
int cmd_render(int argc, char **argv);
int cmd_tonemap(int argc, char **argv);
int cmd_cluster(int argc, char **argv);
/* The MPI service; implemented in cluster/run.c (the only code with MPI). */
int cmd_run(int argc, char **argv);

/* Prints "cave <cmd>: message" to stderr and returns 2 (usage) or 1. */
int cli_fail(const char *cmd, int code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* Strict number parsing: the whole string must be a finite number. */
int cli_parse_double(const char *s, double *out);
int cli_parse_int(const char *s, int lo, int hi, int *out);
/* "x,y,z" (n values) into out; 0 on success. */
int cli_parse_vec(const char *s, int n, double *out);

/* 1 if path ends with ext (case-insensitive, ext includes the dot). */
int cli_has_ext(const char *path, const char *ext);

/* Builds the scene's mesh from the config: the parametric cabin or an
 * imported file, material overrides, then geometry cleaning (report printed
 * to `report` when non-NULL).  *out owned by the caller. */
int cli_load_scene_mesh(const cv_scene_config *c, FILE *report, cv_mesh **out, cv_err *err);

#endif
