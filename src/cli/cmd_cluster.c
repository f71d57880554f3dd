/* `cave cluster hostfile|rankfile CONFIG`: writes the Open MPI rankfile (or
 * hostfile) that puts each rank of the render service on the right host of
 * a multi-host CAVE (view/deploy.h) and prints the rank -> role -> host ->
 * slot -> display -> GPU table for the operator to check.  The file is
 * written through a temporary and renamed, so it is whole or absent. */
#include <stdio.h>
#include <string.h>

#include "cli/cli.h"
#include "cli/cluster_check.h"
#include "core/outfile.h"
#include "view/cave.h"
#include "view/deploy.h"

static void help(FILE *f) {
  fprintf(f,
          "usage: cave cluster rankfile|hostfile <cave.json> [--gather N | --farm HOSTFILE]\n"
          "                    [--master-host H] [--cores C] [-o FILE]\n"
          "       cave cluster check <cave.json> [options]   the pre-flight on every host\n"
          "                    (cave cluster check --help)\n"
          "       cave cluster probe [options]   what this host offers (run by check)\n\n"
          "Maps the render service's ranks onto hosts for mpirun: rank 0 (the master) on\n"
          "--master-host (default: the first output's host, or localhost), rank 1 + i on the\n"
          "host of the CAVE config's outputs[i] (localhost when it names none), then the\n"
          "gather-only ranks (LCD path tracing).  Each host's ranks get slots 0, 1, 2, ...\n"
          "in rank order.\n\n"
          "  rankfile          'rank K=host slot=S' per rank (mpirun --rankfile FILE -np N);\n"
          "                    S is a logical core list (see --cores)\n"
          "  hostfile          'host slots=N' per host (N: the ranks that host runs)\n"
          "  --gather N        N gather ranks, round-robin over the CAVE's hosts (default 0)\n"
          "  --farm HOSTFILE   gather ranks on other machines: one per slot of HOSTFILE\n"
          "                    (lines 'host [slots=N]', '#' comments), each host's slots\n"
          "                    filled in order\n"
          "  --master-host H   the master's host\n"
          "  --cores C         cores per host: a host's n ranks share its C cores (ranges of\n"
          "                    C/n cores when n <= C, else core slot mod C); default: core =\n"
          "                    slot (the host needs a core per rank, or mpirun refuses the file)\n"
          "  -o FILE           write the file there (default: stdout); the table then goes to\n"
          "                    stdout, else to stderr\n\n"
          "The table ends with the rank count: pass it to mpirun -np and to\n"
          "cave run --check --ranks N.  cluster/launch.sh does both.\n\n"
          "examples:\n"
          "  cave cluster rankfile configs/caves/cave5-2hosts.json -o cave.rankfile\n"
          "  cave cluster rankfile configs/caves/cave5.json --gather 3 --cores $(nproc) -o rf\n"
          "  cave cluster rankfile configs/caves/cave5-2hosts.json --farm farm.txt --master-host cave1\n"
          "  cave cluster hostfile configs/caves/cave5-2hosts.json --gather 4\n"
          "  mpirun --rankfile cave.rankfile -np 11 cave run configs/caves/cave5-2hosts.json --scene s.prt\n\n"
          "Exit status: 0 written, 1 a file problem (config, farm, output), 2 a usage error.\n");
}

/* Prints every problem of the CAVE config (one line each); returns 1. */
static int config_problems(const char *path, char *buf, int n, const cv_err *err) {
  int listed = 0;
  for (char *save = NULL, *line = strtok_r(buf, "\n", &save); line; line = strtok_r(NULL, "\n", &save), listed++)
    fprintf(stderr, "cave cluster: %s\n", line);
  if (listed == 0) fprintf(stderr, "cave cluster: %s\n", err->msg);
  else if (listed < n) fprintf(stderr, "cave cluster: %s: %d further problems did not fit in the list\n", path, n - listed);
  return 1;
}

int cmd_cluster(int argc, char **argv) {
  if (argc > 1 && !strcmp(argv[1], "check")) return cmd_cluster_check(argc, argv);
  if (argc > 1 && !strcmp(argv[1], "probe")) return cmd_cluster_probe(argc, argv);
  const char *what = NULL, *cfg = NULL, *farm_path = NULL, *master = NULL, *out = NULL;
  int n_gather = 0, gather_given = 0, cores = 0;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      help(stdout);
      return 0;
    } else if (a[0] != '-' || !a[1]) {
      if (!what) what = a;
      else if (!cfg) cfg = a;
      else return cli_fail("cluster", 2, "unexpected argument '%s' (cave cluster --help)", a);
    } else if (!v) {
      return cli_fail("cluster", 2, "%s: expected a value (cave cluster --help)", a);
    } else if (!strcmp(a, "--gather")) {
      i++;
      if (cli_parse_int(v, 0, CV_DEPLOY_MAX_RANKS, &n_gather))
        return cli_fail("cluster", 2, "--gather: expected a rank count 0..%d, got '%s'", CV_DEPLOY_MAX_RANKS, v);
      gather_given = 1;
    } else if (!strcmp(a, "--cores")) {
      i++;
      if (cli_parse_int(v, 1, 1 << 20, &cores))
        return cli_fail("cluster", 2, "--cores: expected a core count >= 1, got '%s'", v);
    } else if (!strcmp(a, "--farm")) {
      farm_path = argv[++i];
    } else if (!strcmp(a, "--master-host")) {
      master = argv[++i];
    } else if (!strcmp(a, "-o")) {
      out = argv[++i];
    } else {
      return cli_fail("cluster", 2, "unknown option '%s' (cave cluster --help)", a);
    }
  }
  if (!what) return cli_fail("cluster", 2, "expected rankfile or hostfile, then a CAVE config (cave cluster --help)");
  const int rankfile = !strcmp(what, "rankfile");
  if (!rankfile && strcmp(what, "hostfile"))
    return cli_fail("cluster", 2, "'%s': expected rankfile or hostfile (cave cluster --help)", what);
  if (!cfg) return cli_fail("cluster", 2, "%s: expected a CAVE config (e.g. configs/caves/cave5.json)", what);
  if (farm_path && gather_given) return cli_fail("cluster", 2, "--gather and --farm: give one of them");
  if (out && !out[0]) return cli_fail("cluster", 2, "-o: expected a file name");
  if (master && !master[0]) return cli_fail("cluster", 2, "--master-host: expected a host name, got ''");

  static cv_cave cave; /* large: not on the stack */
  static char buf[8192];
  int n = 0;
  cv_err err;
  cv_err_clear(&err);
  buf[0] = 0;
  if (cv_cave_load_all(cfg, &cave, buf, sizeof buf, &n, &err)) return config_problems(cfg, buf, n, &err);
  cv_farm farm;
  memset(&farm, 0, sizeof farm);
  if (farm_path && cv_farm_load(farm_path, &farm, &err)) return cli_fail("cluster", 1, "--farm: %s", err.msg);
  /* --gather is a command-line value: too many ranks with it is a usage
   * error (2), said with the range this CAVE leaves for it. */
  if (!farm_path && (long)n_gather + 1 + cave.n_outputs > CV_DEPLOY_MAX_RANKS)
    return cli_fail("cluster", 2, "--gather: expected 0..%d for %s (1 master + %d wall-eye ranks, "
                    "at most %d ranks in all), got '%d'", CV_DEPLOY_MAX_RANKS - 1 - cave.n_outputs, cfg,
                    cave.n_outputs, CV_DEPLOY_MAX_RANKS, n_gather);
  cv_deploy_opts o = {master, n_gather, farm_path ? &farm : NULL, cores};
  cv_deploy d;
  int st = cv_deploy_plan(&cave, &o, &d, &err);
  cv_farm_free(&farm);
  if (st) return cli_fail("cluster", st == CV_ERR_INVALID ? 2 : 1, "%s", err.msg);

  int rc = 0;
  FILE *table = out ? stdout : stderr;
  if (out) {
    cv_outfile of;
    if (cv_outfile_open(&of, out, 1, &err)) {
      rc = cli_fail("cluster", 1, "-o: %s", err.msg);
    } else {
      st = rankfile ? cv_deploy_write_rankfile(&d, cfg, of.f) : cv_deploy_write_hostfile(&d, cfg, of.f);
      if (st) {
        cv_outfile_abort(&of);
        rc = cli_fail("cluster", 1, "-o: %s: write error", out);
      } else if (cv_outfile_commit(&of, &err)) {
        rc = cli_fail("cluster", 1, "-o: %s", err.msg);
      }
    }
  } else {
    st = rankfile ? cv_deploy_write_rankfile(&d, cfg, stdout) : cv_deploy_write_hostfile(&d, cfg, stdout);
    if (st || fflush(stdout)) rc = cli_fail("cluster", 1, "write error on standard output");
  }
  if (rc == 0) {
    if (out) fprintf(table, "cave cluster: %s %s\n", what, out);
    cv_deploy_write_table(&d, table);
  }
  cv_deploy_free(&d);
  return rc;
}
