/* Deployment of the render service on hosts: which host (and which cores)
 * each MPI rank of a CAVE runs on, for `cave cluster` to write an Open MPI
 * rankfile or hostfile.  Pure logic, no MPI: the rank layout is the
 * service's (cv_cave_rank_role): rank 0 the master, rank 1 + i renders
 * outputs[i] on that output's host ("" = this machine, written "localhost"),
 * further ranks are gather-only (LCD path tracing), spread round-robin over
 * the CAVE's hosts or filling the slots of a farm hostfile in order.
 *
 * Slots: each host's ranks are numbered 0, 1, 2, ... in rank order (the
 * "slot index").  The rankfile's `slot=` field is a list of logical cores
 * (mpirun(1), "Rankfiles"); without a core count it is the slot index (one
 * core per rank: the host needs at least as many cores as ranks, else mpirun
 * refuses the rankfile); with `cores` C per host, a host's n ranks share its
 * C cores: contiguous ranges of C / n cores when n <= C, else core
 * (index mod C). */
#ifndef CV_VIEW_DEPLOY_H
#define CV_VIEW_DEPLOY_H

#include <stdio.h>

#include "core/status.h"
#include "view/cave.h"

#define CV_DEPLOY_HOSTLEN 64
#define CV_DEPLOY_MAX_RANKS 100000 /* as cave run --ranks */

/* A farm hostfile: lines "host [slots=N]" (N >= 1, default 1), blank lines
 * and "#" comments (also after the entry) ignored. */
typedef struct cv_farm_host {
  char name[CV_DEPLOY_HOSTLEN];
  int slots;
} cv_farm_host;
typedef struct cv_farm {
  int n;
  cv_farm_host *hosts; /* owned; cv_farm_free */
  int total_slots;
} cv_farm;

/* Parses farm text; name_for_errors prefixes messages ("file:line: ...").
 * Errors: CV_ERR_FORMAT (a malformed line; err says what was expected),
 * CV_ERR_EMPTY (no host), CV_ERR_RANGE (more slots than CV_DEPLOY_MAX_RANKS),
 * CV_ERR_NOMEM.  *out is only written on success. */
int cv_farm_parse(const char *text, const char *name_for_errors, cv_farm *out, cv_err *err);
/* As cv_farm_parse on a file; CV_ERR_IO when it cannot be read. */
int cv_farm_load(const char *path, cv_farm *out, cv_err *err);
void cv_farm_free(cv_farm *f);

typedef struct cv_deploy_opts {
  const char *master_host; /* NULL or "": the first output's host, else "localhost" */
  int n_gather;            /* gather ranks over the CAVE's hosts (>= 0); ignored with farm */
  const cv_farm *farm;     /* non-NULL: one gather rank per farm slot */
  int cores;               /* cores per host for the slot= lists; 0: one core per slot index */
} cv_deploy_opts;

typedef struct cv_deploy_rank {
  int rank;
  int role;                     /* CV_ROLE_* */
  int output;                   /* CV_ROLE_RENDER: index into the CAVE's outputs; else -1 */
  char host[CV_DEPLOY_HOSTLEN]; /* never empty */
  int slot;                     /* index among this host's ranks, in rank order */
  char cores[32];               /* the rankfile's slot= list: "3" or "0-7" */
} cv_deploy_rank;

typedef struct cv_deploy_host {
  char name[CV_DEPLOY_HOSTLEN];
  int ranks; /* ranks mapped here (the hostfile's slots=) */
} cv_deploy_host;

typedef struct cv_deploy {
  int n_ranks;
  cv_deploy_rank *ranks; /* rank order; owned */
  int n_hosts;
  cv_deploy_host *hosts; /* master's host first, then in order of first use; owned */
  int n_render, n_gather;
  const cv_cave *cave;   /* borrowed, for the table */
} cv_deploy;

/* Maps every rank of the service for cave c onto hosts.  Errors:
 * CV_ERR_INVALID (negative n_gather, cores < 0, a bad master host name),
 * CV_ERR_CONFIG (an output's host name that a rankfile cannot hold),
 * CV_ERR_RANGE (more than CV_DEPLOY_MAX_RANKS ranks), CV_ERR_NOMEM.
 * c must outlive *out (the table reads its outputs). */
int cv_deploy_plan(const cv_cave *c, const cv_deploy_opts *o, cv_deploy *out, cv_err *err);
void cv_deploy_free(cv_deploy *d);

/* Formatting.  Each writes to f and returns CV_OK or CV_ERR_IO (write
 * error); `source` (may be NULL) is named in the header comment. */
/* "rank K=host slot=S" per rank, after "#" comment lines. */
int cv_deploy_write_rankfile(const cv_deploy *d, const char *source, FILE *f);
/* "host slots=N" per host, after "#" comment lines. */
int cv_deploy_write_hostfile(const cv_deploy *d, const char *source, FILE *f);
/* The operator's table: rank, role, host, slot (index and cores), display,
 * GPU, one rank a line, then the totals and the mpirun -np to use. */
int cv_deploy_write_table(const cv_deploy *d, FILE *f);

/* Text of a role: "master", "render front L", "render front L+R quad",
 * "gather".  buf of cap bytes; returns buf. */
const char *cv_deploy_role_text(const cv_deploy *d, int rank, char *buf, size_t cap);

#endif
