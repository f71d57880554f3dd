/* `cave`: the CAVE predictive-rendering service's one program, with
 * git-style subcommands.  Each subcommand lives in its own cmd_*.c file and
 * answers --help. */
#include <stdio.h>
#include <string.h>

#include "cli/cli.h"

#ifndef CAVE_VERSION
#define CAVE_VERSION "0.1.0"
#endif

static const struct {
  const char *name;
  int (*fn)(int, char **);
  const char *summary;
} commands[] = {
    {"cabin", cmd_cabin, "write the built-in parametric car cabin as OBJ + MTL"},
    {"bake", cmd_bake, "precompute radiance transfer (PRT) for a scene"},
    {"materials", cmd_materials, "list a model's materials: triangles, area, tag, albedo"},
    {"shade", cmd_shade, "relight a baked scene on the CPU: per-vertex PLY or a view image"},
    {"reference", cmd_reference, "unbiased path-traced view of a scene, the judge of cave shade"},
    {"compensate", cmd_compensate, "cancel the light that screens scatter onto each other"},
    {"lcd", cmd_lcd, "what the driver sees on the LCD panel: BRDF final gather, progressive"},
    {"render", cmd_render, "render every wall-eye of a CAVE on the GPU with shared adaptation"},
    {"tonemap", cmd_tonemap, "Drago tone mapping of an HDR image (EXR or PNG out)"},
    {"tracker", cmd_tracker, "print DTrack head poses in CAVE coordinates (check a calibration)"},
    {"plot", cmd_plot, "PNG plots of a run from its metrics.jsonl: frame time, skew, latency, readability"},
    {"cluster", cmd_cluster, "write the Open MPI rankfile/hostfile of a multi-host CAVE"},
#ifdef CAVE_HAVE_CLUSTER
    {"run", cmd_run, "the CAVE render service under mpirun (master, wall-eyes, LCD gather)"},
#endif
};

static void usage(FILE *f) {
  fprintf(f,
          "usage: cave <command> [options]   (cave <command> --help for details)\n\n"
          "Predictive rendering of a car interior under HDR daylight for CAVE displays.\n\n"
          "commands:\n");
  for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
    fprintf(f, "  %-10s %s\n", commands[i].name, commands[i].summary);
  fprintf(f, "\n  help [command]  this text, or the command's help\n  version         print the version\n");
}

int main(int argc, char **argv) {
  if (argc < 2) {
    usage(stderr);
    return 2;
  }
  const char *cmd = argv[1];
  if (!strcmp(cmd, "help") && argc > 2) { /* cave help <command>: that command's help */
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
      if (!strcmp(argv[2], commands[i].name)) {
        static char help_opt[] = "--help";
        char *args[] = {argv[2], help_opt, NULL};
        return commands[i].fn(2, args);
      }
    fprintf(stderr, "cave help: '%s' is not a command (cave --help lists them)\n", argv[2]);
    return 2;
  }
  if (!strcmp(cmd, "help") || !strcmp(cmd, "--help") || !strcmp(cmd, "-h")) {
    usage(stdout);
    return 0;
  }
  if (!strcmp(cmd, "version") || !strcmp(cmd, "--version")) {
    printf("cave %s\n", CAVE_VERSION);
    return 0;
  }
  for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
    if (!strcmp(cmd, commands[i].name)) return commands[i].fn(argc - 1, argv + 1);
  fprintf(stderr, "cave: '%s' is not a command (cave --help lists them)\n", cmd);
  return 2;
}
