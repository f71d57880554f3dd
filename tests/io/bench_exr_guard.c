/* What the guard costs: the first read of an EXR in a fresh process, its
 * C++ fallback (DWA/B44) decoded in this process or in a guarded child
 * (src/io/exr_imf.c).  Prints one line: mode, file, milliseconds.
 *
 *   bench_exr_guard in|guarded FILE.exr [RESIDENT_MB]
 *
 * RESIDENT_MB (default 0): memory allocated and touched first, as a service
 * process holding its scene would have (fork copies page tables, so the
 * guard costs more in a bigger process).  CPU time (user + system, this
 * process and its children) is printed too: on a loaded machine it says
 * more than the wall clock.  Not a ctest: docs/fuzzing.md has
 * the loop that alternates the two modes. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include "core/image.h"
#include "core/status.h"
#include "io/exr.h"

static double now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return 1e3 * (double)ts.tv_sec + 1e-6 * (double)ts.tv_nsec;
}

/* CPU milliseconds (user + system) of this process and its reaped children. */
static double cpu_ms(void) {
  double ms = 0;
  struct rusage ru;
  int who[2] = {RUSAGE_SELF, RUSAGE_CHILDREN};
  for (int i = 0; i < 2; i++)
    if (getrusage(who[i], &ru) == 0)
      ms += 1e3 * (double)(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
            1e-3 * (double)(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
  return ms;
}

int main(int argc, char **argv) {
  if (argc < 3 || (strcmp(argv[1], "in") && strcmp(argv[1], "guarded"))) {
    fprintf(stderr, "usage: %s in|guarded FILE.exr [RESIDENT_MB]\n", argv[0]);
    return 2;
  }
  size_t resident = argc > 3 ? (size_t)strtoul(argv[3], NULL, 10) << 20 : 0;
  char *hold = resident ? malloc(resident) : NULL;
  if (resident && !hold) {
    fprintf(stderr, "bench_exr_guard: cannot allocate %s MB\n", argv[3]);
    return 1;
  }
  if (hold) memset(hold, 1, resident);
  cv_exr_guard g;
  cv_exr_guard_default(&g);
  g.in_process = strcmp(argv[1], "in") == 0;
  cv_image *img = NULL;
  cv_exr_read_info info;
  cv_err err;
  double t0 = now_ms(), c0 = cpu_ms();
  int st = cv_exr_read_with(argv[2], &g, &img, &info, &err);
  double ms = now_ms() - t0, cpu = cpu_ms() - c0;
  if (st != CV_OK) {
    fprintf(stderr, "bench_exr_guard: %s\n", err.msg);
    return 1;
  }
  printf("%s %s %s %dx%d resident %zu MB: %.2f ms wall, %.2f ms CPU\n", argv[1], argv[2],
         info.compression_name, img->w, img->h, resident >> 20, ms, cpu);
  cv_image_destroy(img);
  free(hold);
  return 0;
}
