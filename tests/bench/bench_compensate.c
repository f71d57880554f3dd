/* Benchmark of the scattering compensation (speed against error).
 *
 *   bench_compensate [--sizes 16,32,64] [--reps N]
 *
 * For the two-sided wall (reflectance 0.475) and the 5-wall CAVE
 * (reflectance 0.8), each patch resolution, float and half storage, and each
 * solver (exact, the paper's Jacobi for H = 1..7 where rho < 0.5, bounded,
 * auto): solves per second (median of N timed solves, warm workspace, RGB
 * batched) and the displayed RMS / max error through the display physics,
 * on a white image with a black band at the corner (clipping) and a smooth
 * gradient image (no clipping).  Stereo is one solve on the pair's average
 * (cv_scatter_solve_stereo), so it costs one solve plus an average. */
#include <math.h>

#include "bench_util.h"
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "compensate/display.h"
#include "compensate/formfactor.h"
#include "compensate/solve.h"
#include "core/progress.h"

typedef struct {
  cv_scatter_solver s;
  int levels;
} run;


static char *display_json(int cave, int np) {
  char *s = malloc(4096);
  if (cave)
    snprintf(s, 4096,
             "{\"surfaces\": ["
             "{\"name\":\"front\",\"corners\":[[-1.5,0,-1.5],[1.5,0,-1.5],[-1.5,3,-1.5]],\"patches\":[%d,%d],\"reflectance\":[0.8,0.8,0.8]},"
             "{\"name\":\"left\",\"corners\":[[-1.5,0,1.5],[-1.5,0,-1.5],[-1.5,3,1.5]],\"patches\":[%d,%d],\"reflectance\":[0.8,0.8,0.8]},"
             "{\"name\":\"right\",\"corners\":[[1.5,0,-1.5],[1.5,0,1.5],[1.5,3,-1.5]],\"patches\":[%d,%d],\"reflectance\":[0.8,0.8,0.8]},"
             "{\"name\":\"floor\",\"corners\":[[-1.5,0,1.5],[1.5,0,1.5],[-1.5,0,-1.5]],\"patches\":[%d,%d],\"reflectance\":[0.8,0.8,0.8]},"
             "{\"name\":\"ceiling\",\"corners\":[[-1.5,3,-1.5],[1.5,3,-1.5],[-1.5,3,1.5]],\"patches\":[%d,%d],\"reflectance\":[0.8,0.8,0.8]}],"
             "\"projectors\":\"ideal\"}",
             np, np, np, np, np, np, np, np, np, np);
  else
    snprintf(s, 4096,
             "{\"surfaces\": ["
             "{\"name\":\"left\",\"corners\":[[-2.1213203435596424,0,0],[0,0,-2.1213203435596424],[-2.1213203435596424,2,0]],\"patches\":[%d,%d],\"reflectance\":[0.475,0.475,0.475]},"
             "{\"name\":\"right\",\"corners\":[[0,0,-2.1213203435596424],[2.1213203435596424,0,0],[0,2,-2.1213203435596424]],\"patches\":[%d,%d],\"reflectance\":[0.475,0.475,0.475]}],"
             "\"projectors\":\"ideal\"}",
             np, np, np, np);
  return s;
}

/* Wanted radiosity: band = white (M) except a black band on the second
 * surface's first 15% of columns (next to the corner); smooth = a gradient. */
static void targets(const cv_display *d, int band, float *T) {
  for (size_t i = 0; i < cv_display_patch_count(d); i++) {
    const cv_patch *p = cv_display_patch(d, i);
    const cv_display_surface *S = cv_display_surface_at(d, p->surface);
    double x = band ? ((p->surface == 1 && p->u < 0.15 * S->nu) ? 0.0 : 1.0)
                    : 0.3 + 0.5 * (double)p->v / S->nv;
    for (int c = 0; c < 3; c++) T[3 * i + c] = (float)(d->proj[i] * d->refl[3 * i + c] * x);
  }
}

static void errors(const cv_scatter_system *s, const float *I, const float *T, double *rms,
                   double *mx) {
  double *B = malloc(3 * s->n * sizeof(double));
  int it;
  cv_scatter_physics(s, I, B, 1e-9, &it);
  double e2 = 0, m = 0;
  for (size_t k = 0; k < 3 * s->n; k++) {
    double e = fabs(B[k] - T[k]);
    e2 += e * e;
    m = e > m ? e : m;
  }
  *rms = sqrt(e2 / (3.0 * s->n));
  *mx = m;
  free(B);
}

int main(int argc, char **argv) {
  int sizes[8] = {16, 32, 64}, nsizes = 3, reps = 7, storage_mask = 7;
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--sizes") && i + 1 < argc) {
      nsizes = 0;
      for (char *t = strtok(argv[++i], ","); t && nsizes < 8; t = strtok(NULL, ",")) sizes[nsizes++] = atoi(t);
    } else if (!strcmp(argv[i], "--storage") && i + 1 < argc) {
      storage_mask = 0;
      for (char *t = strtok(argv[++i], ","); t; t = strtok(NULL, ","))
        storage_mask |= !strcmp(t, "float") ? 1 : !strcmp(t, "half") ? 2 : !strcmp(t, "low-rank") ? 4 : 0;
    } else if (!strcmp(argv[i], "--reps") && i + 1 < argc) {
      reps = atoi(argv[++i]);
    } else {
      fprintf(stderr, "usage: bench_compensate [--sizes 16,32,64] [--storage float,half,low-rank] [--reps N]\n");
      return strcmp(argv[i], "--help") ? 2 : 0;
    }
  }
  printf("| display | patches/surface | storage | solver | image | solves/s | iterations | clipped patches | RMS error | max error |\n");
  printf("|---|---|---|---|---|---|---|---|---|---|\n");
  for (int cave = 0; cave < 2; cave++)
    for (int si = 0; si < nsizes; si++) {
      {
        /* The form factors are built dense before compression: 8 bytes a pair. */
        const double np2 = (double)sizes[si] * sizes[si];
        const double pairs = cave ? 5 * np2 * 4 * np2 : 2 * np2 * np2;
        if (pairs > 1.5e9) {
          printf("| %s | %d | - | - | - | skipped: %.1fG form factor pairs need %.0f GB before compression |  |  |  |  |\n",
                 cave ? "cave5" : "two-sided wall", sizes[si], pairs / 1e9, pairs * 8 / 1e9);
          continue;
        }
      }
      char *json = display_json(cave, sizes[si]);
      cv_display *d;
      cv_err err;
      if (cv_display_parse(json, cave ? "cave5" : "two-sided-wall", &d, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
      }
      free(json);
      cv_ff_params fp;
      cv_ff_params_default(&fp);
      fp.quiet = 1;
      cv_ffmatrix *F;
      cv_ff_report rep;
      if (cv_formfactors_build(d, &fp, &F, &rep, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
      }
      fprintf(stderr, "%s %d: %zu patches, %zu form factors, built in %.1f s\n", cave ? "cave5" : "two-wall",
              sizes[si], rep.n, rep.nnz, rep.seconds);
      cv_scatter_system sys;
      cv_display_scatter_system(d, F, &sys);
      size_t n = sys.n;
      float *T = malloc(3 * n * sizeof(float)), *I = malloc(3 * n * sizeof(float));
      for (int mode = 0; mode < 3; mode++) {
        if (!(storage_mask & (1 << mode))) continue;
        /* Large systems: only the compressed storage (the plain copies would
         * add several GB and minutes per table row). */
        const int large = rep.nnz > 100000000u;
        if (large && mode < 2) {
          printf("| %s | %d | %s | - | - | skipped: %.0fM form factors |  |  |  |  |\n",
                 cave ? "cave5" : "two-sided wall", sizes[si], mode ? "half" : "float", rep.nnz / 1e6);
          continue;
        }
        static const char *mode_name[] = {"float", "half", "low-rank"};
        static const unsigned mode_flags[] = {0, CV_SCATTER_WS_HALF, CV_SCATTER_WS_COMPRESS};
        const char *storage = mode_name[mode];
        cv_scatter_workspace *ws;
        double tb = cv_now_seconds();
        if (cv_scatter_workspace_create_ex(&sys, mode_flags[mode], &ws, &err)) {
          fprintf(stderr, "%s\n", err.msg);
          return 1;
        }
        cv_scatter_model model;
        cv_scatter_workspace_get_model(ws, &model);
        fprintf(stderr, "  %s: picked %s, %.1f MB of values (plain %.1f MB), workspace %.2f s",
                storage, model.storage, model.bytes / 1e6, model.source_bytes / 1e6,
                cv_now_seconds() - tb);
        if (model.compress_tried)
          fprintf(stderr, "; %zu blocks: %zu low-rank (mean rank %.1f, max %d), %zu dense; "
                  "max row error %.2e (%.2e of the row)", model.compress_info.n_blocks,
                  model.compress_info.n_lowrank, model.compress_info.mean_rank,
                  model.compress_info.max_rank, model.compress_info.n_dense,
                  model.compress_info.max_row_error, model.compress_info.max_rel_row_error);
        fprintf(stderr, "\n");
        if (mode == 2 && strcmp(model.storage, "block low-rank")) {
          printf("| %s | %d | low-rank | - | - | not picked: %.1f MB compressed against %.1f MB |  |  |  |  |\n",
                 cave ? "cave5" : "two-sided wall", sizes[si], model.compressed_bytes / 1e6,
                 model.source_bytes / 1e6);
          cv_scatter_workspace_destroy(ws);
          continue;
        }
        double rho = cv_scatter_workspace_rho(ws);
        run runs[10] = {{CV_SCATTER_EXACT, 0}, {CV_SCATTER_BOUNDED, 0}, {CV_SCATTER_AUTO, 0}};
        int nruns = 3;
        if (rho < 0.5)
          for (int h = 1; h <= 7; h++) runs[nruns++] = (run){CV_SCATTER_JACOBI, h};
        if (large && nruns > 5) nruns = 5; /* jacobi H = 1, 2 only */
        for (int r = 0; r < nruns; r++)
          for (int band = 1; band >= 0; band--) {
            if (runs[r].s == CV_SCATTER_JACOBI && band) continue; /* Jacobi does not clip-aware */
            targets(d, band, T);
            cv_scatter_opts o;
            cv_scatter_opts_default(&o);
            o.solver = runs[r].s;
            if (runs[r].levels) o.levels = runs[r].levels;
            cv_scatter_stats st;
            double t[64];
            int k, ok = 1;
            for (k = 0; k < reps && k < 64; k++) {
              double t0 = cv_now_seconds();
              if (cv_scatter_solve(ws, T, &o, I, &st, &err)) {
                ok = 0;
                break;
              }
              t[k] = cv_now_seconds() - t0;
            }
            char name[32];
            if (runs[r].levels) snprintf(name, sizeof name, "jacobi H=%d", runs[r].levels);
            else snprintf(name, sizeof name, "%s", cv_scatter_solver_name(runs[r].s));
            if (!ok) {
              printf("| %s | %d | %s | %s | %s | refused: %s |  |  |  |  |\n", cave ? "cave5" : "two-sided wall",
                     sizes[si], storage, name, band ? "band" : "smooth", err.msg);
              continue;
            }
            double rms, mx;
            errors(&sys, I, T, &rms, &mx);
            printf("| %s | %d | %s | %s | %s | %.0f | %d | %zu | %.5f | %.5f |\n",
                   cave ? "cave5" : "two-sided wall", sizes[si], storage, name,
                   band ? "band" : "smooth", 1.0 / bench_median(t, k), st.iterations, st.clipped_patches, rms, mx);
            fflush(stdout);
          }
        cv_scatter_workspace_destroy(ws);
      }
      free(T);
      free(I);
      cv_ffmatrix_destroy(F);
      cv_display_destroy(d);
    }
  return 0;
}
