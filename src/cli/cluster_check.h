/* The pre-flight of a multi-host CAVE (docs/deploy.md, "Pre-flight"):
 * `cave cluster check CONFIG` runs `cave cluster probe` on every host of the
 * rank layout through the remote shell and lists every problem, one line
 * each, naming the host and its outputs. */
#ifndef CV_CLI_CLUSTER_CHECK_H
#define CV_CLI_CLUSTER_CHECK_H

#include <stddef.h>
#include <stdint.h>

int cmd_cluster_probe(int argc, char **argv);
int cmd_cluster_check(int argc, char **argv);
/* FNV-1a 64 of a file's bytes (core/hash.h); -1 with why set when unreadable. */
int cv_file_hash(const char *path, uint64_t *h, char *why, size_t cap);

#endif
