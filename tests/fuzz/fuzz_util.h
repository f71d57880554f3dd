/* Shared helpers of the fuzz harnesses (tests/fuzz/fuzz_*.c): each harness
 * defines LLVMFuzzerTestOneInput, the entry point libFuzzer calls and the
 * replay program (replay_main.c) calls for every file of a corpus.  Inputs
 * that a reader takes as a path are written to a per-process file first. */
#ifndef CV_FUZZ_UTIL_H
#define CV_FUZZ_UTIL_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* data as a NUL-terminated string (embedded NULs end it early, as they
 * would for a reader of text); caller frees. */
static inline char *fuzz_text(const uint8_t *data, size_t size) {
  char *t = malloc(size + 1);
  if (!t) abort();
  memcpy(t, data, size);
  t[size] = '\0';
  return t;
}

/* Writes data to $TMPDIR/cave_fuzz_<pid><ext> (the same file on every call)
 * and returns its path. */
static inline const char *fuzz_file(const uint8_t *data, size_t size, const char *ext) {
  static char path[512];
  const char *dir = getenv("TMPDIR");
  snprintf(path, sizeof path, "%s/cave_fuzz_%ld%s", dir && *dir ? dir : "/tmp", (long)getpid(), ext);
  FILE *f = fopen(path, "wb");
  if (!f) abort();
  if (size && fwrite(data, 1, size, f) != size) abort();
  fclose(f);
  return path;
}

#endif
