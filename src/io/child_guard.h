/* Guarded child: runs a function in a forked child process under a
 * wall-clock limit and an address-space limit, so that a third-party
 * library that loops, allocates without end or crashes on hostile input
 * (assimp, OpenEXR's C++ library) costs the caller at most the limits and
 * one line of error instead of the process.
 *
 * The child writes its result to a pipe (cv_child_write); the parent
 * collects it, and everything the child prints (stdout and stderr, a
 * sanitizer report included) into a second buffer, kills the child when the
 * time limit passes and always reaps it (no zombie).  Bulk results can also
 * go through memory the caller mapped MAP_SHARED before the call.
 *
 * Limits:
 *  - time: the parent's wall-clock deadline (SIGKILL), and RLIMIT_CPU one
 *    second later as a back-stop (SIGXCPU);
 *  - memory: RLIMIT_AS set in the child to the address space the process
 *    already had at the fork plus memory_mb, so the limit means the same in
 *    a small test and in a big service process.  Not applied under
 *    AddressSanitizer, which reserves terabytes of address space for its
 *    shadow memory (cv_child_memory_limit_applies() says which).
 *
 * Call it from one thread at a time: a child forked meanwhile by another
 * thread would hold this call's pipe open and delay its end until that
 * child ends.  Only the calling thread exists in the child, so the function
 * must not wait for work of other threads (locks they held at the fork).
 *
 * The child ends with _exit, not exit: atexit handlers of the parent
 * (libFuzzer's "fuzz target exited" among them) must not run in it.  Under
 * AddressSanitizer LeakSanitizer checks the child before it ends when the
 * parent had one thread at the fork (not in the libFuzzer build,
 * -DCAVE_FUZZ=ON, where that check costs 75 ms a child and sees false
 * leaks; not after OpenMP or Embree started threads, whose locks the check
 * could wait for in the child). */
#ifndef CV_IO_CHILD_GUARD_H
#define CV_IO_CHILD_GUARD_H

#include <stddef.h>

#include "core/status.h"

/* 1 when this process has a single thread (/proc/self/status; 0 when it
 * cannot tell).  Only then is a forked child safe to run library code: a
 * lock another thread held at the fork (malloc's, Mesa's, TBB's, Open
 * MPI's) stays held in the child for ever. */
int cv_child_single_threaded(void);

/* A limit from the environment variable name: a non-negative number;
 * unset or empty: fallback; anything else (unparsable, negative, NaN/Inf):
 * NaN, which cv_child_env_check turns into an error. */
double cv_child_env_limit(const char *name, double fallback);
/* CV_OK when value (a limit from cv_child_env_limit) is not NaN, else err
 * "<name>: expected <what>, got '<its value>'" and CV_ERR_RANGE. */
int cv_child_env_check(const char *name, double value, const char *what, cv_err *err);

typedef struct cv_child_limits {
  double seconds;   /* wall-clock seconds (0 = none) */
  double memory_mb; /* MB of address space the child may add to the process's (0 = none) */
} cv_child_limits;

/* Runs in the child: does the work and writes the result to fd with
 * cv_child_write.  Returns CV_OK, or a cv_status (CV_ERR_NOMEM when it ran
 * out of memory: under a memory limit that is reported as the limit hit). */
typedef int (*cv_child_fn)(void *ctx, int fd);

/* How a child ended. */
typedef enum cv_child_outcome {
  CV_CHILD_DONE = 0, /* returned CV_OK: data holds what it wrote */
  CV_CHILD_TIMEOUT,  /* killed at the time limit (or SIGXCPU) */
  CV_CHILD_MEMORY,   /* the memory limit stopped it (CV_ERR_NOMEM returned, or an
                        uncaught std::bad_alloc) */
  CV_CHILD_SIGNAL,   /* killed by a signal: a crash */
  CV_CHILD_FAILED,   /* returned an error, or exited otherwise (a sanitizer report) */
  CV_CHILD_RECEIVE   /* the parent ran out of memory receiving the result */
} cv_child_outcome;

typedef struct cv_child_result {
  cv_child_outcome outcome;
  int status;         /* CV_CHILD_FAILED: the child's cv_status, or CV_ERR_BACKEND */
  int exit_code;      /* the child's exit code (-1 when a signal ended it) */
  int signal;         /* the signal that ended it (0: none) */
  int memory_limited; /* 1 when RLIMIT_AS was set */
  double seconds;     /* wall clock from fork to reaping */
  unsigned char *data; /* what the child wrote with cv_child_write (malloc'd; may be NULL) */
  size_t data_n;
  char *output;       /* what it printed (malloc'd; may be NULL) */
  size_t output_n;
} cv_child_result;

/* Runs fn(ctx, fd) in a child under lim (NULL: none) and fills *res (free
 * it with cv_child_result_free).  Returns CV_OK when the child ran, whatever
 * its outcome, or CV_ERR_IO when no child could be started (pipe or fork
 * failed; err says which). */
int cv_child_run(cv_child_fn fn, void *ctx, const cv_child_limits *lim, cv_child_result *res,
                 cv_err *err);

void cv_child_result_free(cv_child_result *res);

/* Writes all n bytes to fd (in the child).  Returns 0, or -1 on error. */
int cv_child_write(int fd, const void *buf, size_t n);

/* What the failure messages name. */
typedef struct cv_child_labels {
  const char *path;        /* the input file, first in the line */
  const char *what;        /* the work, e.g. "import (OFF)", "EXR decode (dwab)" */
  const char *library;     /* who crashed, e.g. "assimp", "OpenEXR" */
  const char *timeout_env; /* the variables that set the limits */
  const char *memory_env;
} cv_child_labels;

/* For a result other than CV_CHILD_DONE: sets err to one line naming the
 * file, the work, the reason and the limit hit, and returns its status:
 *   CV_ERR_RANGE    "P: W stopped after 1.0 s: time limit 1 s hit (ENV sets it)"
 *   CV_ERR_NOMEM    "P: W stopped: memory limit 256 MB hit (ENV sets it)"
 *   CV_ERR_BACKEND  "P: W crashed: signal SIGSEGV (Segmentation fault) in LIB"
 *                   "P: W failed: child exit status 1"
 *   the child's     "P: W failed: <its status text>"
 * For CV_CHILD_DONE returns CV_OK and leaves err alone. */
int cv_child_error(const cv_child_result *res, const cv_child_limits *lim,
                   const cv_child_labels *lab, cv_err *err);

/* Copies the child's output to stderr between two marker lines naming
 * whose it is ("the import of x.off"); nothing when it printed nothing. */
void cv_child_show_output(const cv_child_result *res, const char *whose);

/* "SIGSEGV", "SIGABRT", ...; "signal N" for one without a name here
 * (buf holds that). */
const char *cv_child_signal_name(int sig, char *buf, size_t n);

/* 0 in an AddressSanitizer build (the memory limit is not applied), else 1. */
int cv_child_memory_limit_applies(void);

#endif
