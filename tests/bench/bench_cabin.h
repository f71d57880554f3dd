/* The 571K-triangle cabin (tess 8) that bench_render and bench_shadow
 * measure, baked cheaply (5 bands, 2 rays, 1 bounce: only the triangle and
 * vertex counts matter to them) and cached in $TMPDIR/cave_bench_render_t8.prt. */
#ifndef CV_BENCH_CABIN_H
#define CV_BENCH_CABIN_H

#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "core/status.h"
#include "mesh/cabin.h"
#include "prt/bake.h"
#include "prt/prt.h"

static inline double bench_now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/* The cached tess-8 transfer, baked and cached when missing; NULL on error
 * (printed). */
static inline cv_prt *bench_cabin_t8(void) {
  const char *tmp = getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp";
  char path[1024];
  snprintf(path, sizeof path, "%s/cave_bench_render_t8.prt", tmp);
  cv_prt *p = NULL;
  cv_err err;
  if (cv_prt_read(path, &p, NULL) == CV_OK && p->nt > 500000) return p;
  cv_prt_destroy(p);
  p = NULL;
  cv_cabin_params cp;
  cv_cabin_default_params(&cp);
  cp.tess = 8;
  cv_mesh *m;
  if (cv_cabin_generate(&cp, &m, &err)) {
    fprintf(stderr, "cabin: %s\n", err.msg);
    return NULL;
  }
  cv_bake_params bp = {.bands = 5, .rays = 2, .bounces = 1, .seed = 1,
                       .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  double t0 = bench_now_ms();
  if (cv_prt_bake(m, &bp, &p, NULL, &err)) {
    fprintf(stderr, "bake: %s\n", err.msg);
    cv_mesh_destroy(m);
    return NULL;
  }
  cv_mesh_destroy(m);
  fprintf(stderr, "baked %zu triangles in %.1f s (2 rays, 1 bounce), cached in %s\n", p->nt,
          (bench_now_ms() - t0) / 1e3, path);
  cv_prt_write(path, p, NULL);
  return p;
}

#endif
