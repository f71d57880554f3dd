/* Benchmark of the scattering compensation (speed against error).
 *
 *   bench_compensate [--sizes 16,32,64] [--storage float,half,low-rank,direct]
 *                    [--display wall|cave|both] [--eta E] [--no-check] [--reps N]
 *
 * "direct" builds the compressed K from the display without the dense
 * matrix (hmatrix.h cv_hmatrix_build_direct) and prints, on stderr and in a
 * second table, its build time, peak memory and the machine's load, and
 * where the dense build fits too (at most 4e8 pairs), the true per-row error
 * against it (rows sampled when there are more than 4096; --no-check skips
 * it).
 *
 * For the two-sided wall (reflectance 0.475) and the 5-wall CAVE
 * (reflectance 0.8), each patch resolution, float and half storage, and each
 * solver (exact, the paper's Jacobi for H = 1..7 where rho < 0.5, bounded,
 * auto): solves per second (median of N timed solves, warm workspace, RGB
 * batched) and the displayed RMS / max error through the display physics,
 * (in parentheses: 2 / the median CPU seconds of a solve, what two otherwise
 * idle cores would give if the solve scaled perfectly; the machine is shared)
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
#include "compensate/hmatrix.h"
#include "compensate/solve.h"
#include "core/progress.h"

#include <sys/resource.h>

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


static double cpu_seconds(void) {
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_utime.tv_sec + ru.ru_stime.tv_sec + 1e-6 * (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

static double peak_rss_gb(void) {
  struct rusage ru;
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_maxrss / 1048576.0; /* kB on Linux */
}

/* Error table row of the direct build: true per-row error against the dense
 * build without sparsification (rows sampled with a stride). */
static void direct_error(const cv_display *d, const cv_hmatrix *h, double *worst, double *mean,
                         double *est_worst, double *short_by, size_t *rows) {
  cv_ff_params fp;
  cv_ff_params_default(&fp);
  fp.quiet = 1;
  fp.drop_budget = 0;
  cv_ffmatrix *F;
  cv_err err;
  *worst = *mean = *est_worst = *short_by = -1;
  *rows = 0;
  if (cv_formfactors_build(d, &fp, &F, NULL, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return;
  }
  const size_t n = F->n, stride = n > 4096 ? (n + 4095) / 4096 : 1;
  const double *est = cv_hmatrix_row_error(h);
  double *row = malloc(n * sizeof *row), *dense = calloc(n, sizeof *dense);
  double w = 0, sum = 0, ew = 0, sb = 0;
  size_t cnt = 0;
  for (size_t i = 0; i < n; i += stride) {
    cv_hmatrix_row_values(h, i, row);
    double rs = 0, e = 0;
    for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) {
      dense[F->col[k]] = F->val[k];
      rs += F->val[k];
    }
    for (size_t j = 0; j < n; j++) e += fabs(row[j] - dense[j]);
    for (size_t k = F->row_off[i]; k < F->row_off[i + 1]; k++) dense[F->col[k]] = 0;
    if (!(rs > 0)) continue;
    w = fmax(w, e / rs);
    ew = fmax(ew, est[i] / rs);
    sb = fmax(sb, (e - est[i]) / rs);
    sum += e / rs;
    cnt++;
  }
  *worst = w;
  *mean = cnt ? sum / (double)cnt : 0;
  *est_worst = ew;
  *short_by = sb;
  *rows = cnt;
  free(row);
  free(dense);
  cv_ffmatrix_destroy(F);
}

/* The direct path: build, memory, time, error, then solves with K~. */
static double direct_eta = 1.0;
static int direct_check = 1;

static int bench_direct(int cave, int np, int reps, char *err_table, size_t err_cap) {
  char *json = display_json(cave, np);
  cv_display *d;
  cv_err err;
  if (cv_display_parse(json, cave ? "cave5" : "two-sided-wall", &d, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    free(json);
    return 1;
  }
  free(json);
  const char *dname = cave ? "cave5" : "two-sided wall";
  double load[3] = {0, 0, 0};
  cv_hmatrix_direct_params hp;
  cv_hmatrix_direct_params_default(&hp);
  hp.quiet = 1;
  hp.eta = direct_eta;
  cv_hmatrix *h;
  cv_hmatrix_info info;
  const double t0 = cv_now_seconds(), c0 = cpu_seconds();
  if (cv_hmatrix_build_direct(d, NULL, &hp, &h, &info, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  const double secs = cv_now_seconds() - t0, cpu = cpu_seconds() - c0, rss = peak_rss_gb();
  getloadavg(load, 3);
  fprintf(stderr, "%s %d direct: %zu patches, %.2fG pairs, built in %.1f s (%.1f CPU s, load %.2f), peak RSS %.2f GB, "
          "%zu blocks (%zu low-rank, mean rank %.1f, max %d; %zu dense), %.1f MB (dense float %.0f MB)\n",
          dname, np, cv_display_patch_count(d), info.source_nnz / 1e9, secs, cpu, load[0], rss,
          info.n_blocks, info.n_lowrank, info.mean_rank, info.max_rank, info.n_dense,
          4e-6 * info.stored_values, 4e-6 * info.source_nnz);
  double worst = -1, mean = -1, ew = -1, sb = -1;
  size_t rows = 0;
  if (direct_check && info.source_nnz <= 400000000u)
    direct_error(d, h, &worst, &mean, &ew, &sb, &rows);
  char line[512];
  if (worst >= 0)
    snprintf(line, sizeof line, "| %s | %d | %.3g | %.1f | %.1f | %.2f | %.2f | %.0f | %.1f | %zu | %.2e | %.2e | %.2e | %.2e |\n",
             dname, np, info.source_nnz / 1e9, secs, cpu, load[0], rss, 4e-6 * info.stored_values,
             info.mean_rank, rows, worst, mean, ew, sb);
  else
    snprintf(line, sizeof line, "| %s | %d | %.3g | %.1f | %.1f | %.2f | %.2f | %.0f | %.1f | - | not checked | | | |\n",
             dname, np, info.source_nnz / 1e9, secs, cpu, load[0], rss, 4e-6 * info.stored_values,
             info.mean_rank);
  strncat(err_table, line, err_cap - strlen(err_table) - 1);
  cv_scatter_system sys;
  cv_display_scatter_system(d, NULL, &sys);
  sys.H = h;
  cv_scatter_workspace *ws;
  if (cv_scatter_workspace_create_ex(&sys, 0, &ws, &err)) {
    fprintf(stderr, "%s\n", err.msg);
    return 1;
  }
  const size_t n = sys.n;
  float *T = malloc(3 * n * sizeof(float)), *I = malloc(3 * n * sizeof(float));
  const cv_scatter_solver solvers[2] = {CV_SCATTER_EXACT, CV_SCATTER_AUTO};
  for (int r = 0; r < 2; r++)
    for (int band = 1; band >= 0; band--) {
      targets(d, band, T);
      cv_scatter_opts o;
      cv_scatter_opts_default(&o);
      o.solver = solvers[r];
      cv_scatter_stats st;
      double t[64];
      int k, ok = 1;
      double tc[64];
      for (k = 0; k < reps && k < 64; k++) {
        double ts = cv_now_seconds(), cs = cpu_seconds();
        if (cv_scatter_solve(ws, T, &o, I, &st, &err)) {
          ok = 0;
          break;
        }
        t[k] = cv_now_seconds() - ts;
        tc[k] = cpu_seconds() - cs;
      }
      if (!ok) {
        fprintf(stderr, "%s\n", err.msg);
        continue;
      }
      double rms, mx;
      errors(&sys, I, T, &rms, &mx); /* judged with K~ (no dense K here) */
      char sname[40];
      if (o.solver == CV_SCATTER_AUTO)
        snprintf(sname, sizeof sname, "auto (%s)", cv_scatter_solver_name(st.solver));
      else
        snprintf(sname, sizeof sname, "%s", cv_scatter_solver_name(o.solver));
      printf("| %s | %d | direct (%.1f) | %s | %s | %.0f (%.0f) | %d | %zu | %.5f | %.5f |\n", dname, np,
             4e-6 * info.stored_values, sname,
             band ? "band" : "smooth", 1.0 / bench_median(t, k), 2.0 / bench_median(tc, k), st.iterations,
             st.clipped_patches, rms, mx);
      fflush(stdout);
    }
  free(T);
  free(I);
  cv_scatter_workspace_destroy(ws);
  cv_hmatrix_destroy(h);
  cv_display_destroy(d);
  return 0;
}

int main(int argc, char **argv) {
  int sizes[8] = {16, 32, 64}, nsizes = 3, reps = 7, storage_mask = 7, cave_lo = 0, cave_hi = 2;
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--sizes") && i + 1 < argc) {
      nsizes = 0;
      for (char *t = strtok(argv[++i], ","); t && nsizes < 8; t = strtok(NULL, ",")) sizes[nsizes++] = atoi(t);
    } else if (!strcmp(argv[i], "--storage") && i + 1 < argc) {
      storage_mask = 0;
      for (char *t = strtok(argv[++i], ","); t; t = strtok(NULL, ","))
        storage_mask |= !strcmp(t, "float") ? 1 : !strcmp(t, "half") ? 2 : !strcmp(t, "low-rank") ? 4 : !strcmp(t, "direct") ? 8 : 0;
    } else if (!strcmp(argv[i], "--display") && i + 1 < argc) {
      i++;
      cave_lo = !strcmp(argv[i], "cave") ? 1 : 0;
      cave_hi = !strcmp(argv[i], "wall") ? 1 : 2;
    } else if (!strcmp(argv[i], "--no-check")) {
      direct_check = 0;
    } else if (!strcmp(argv[i], "--eta") && i + 1 < argc) {
      direct_eta = atof(argv[++i]);
    } else if (!strcmp(argv[i], "--reps") && i + 1 < argc) {
      reps = atoi(argv[++i]);
    } else {
      fprintf(stderr, "usage: bench_compensate [--sizes 16,32,64] [--storage float,half,low-rank,direct] [--display wall|cave|both] [--eta E] [--no-check] [--reps N]\n");
      return strcmp(argv[i], "--help") ? 2 : 0;
    }
  }
  printf("| display | patches/surface | storage | solver | image | solves/s | iterations | clipped patches | RMS error | max error |\n");
  printf("|---|---|---|---|---|---|---|---|---|---|\n");
  static char err_table[8192];
  if (storage_mask & 8)
    snprintf(err_table, sizeof err_table,
             "| display | patches/surface | pairs (G) | build s | build CPU s | load | peak RSS GB | MB stored | mean rank | rows checked | max row error | mean row error | max estimate | estimate short by |\n"
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (int cave = cave_lo; cave < cave_hi; cave++)
    for (int si = 0; si < nsizes; si++) {
      if (storage_mask & 8) {
        if (bench_direct(cave, sizes[si], reps, err_table, sizeof err_table)) return 1;
        if (!(storage_mask & 7)) continue;
      }
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
            double tc[64];
            for (k = 0; k < reps && k < 64; k++) {
              double t0 = cv_now_seconds(), c0 = cpu_seconds();
              if (cv_scatter_solve(ws, T, &o, I, &st, &err)) {
                ok = 0;
                break;
              }
              t[k] = cv_now_seconds() - t0;
              tc[k] = cpu_seconds() - c0;
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
            printf("| %s | %d | %s | %s | %s | %.0f (%.0f) | %d | %zu | %.5f | %.5f |\n",
                   cave ? "cave5" : "two-sided wall", sizes[si], storage, name,
                   band ? "band" : "smooth", 1.0 / bench_median(t, k), 2.0 / bench_median(tc, k),
                   st.iterations, st.clipped_patches, rms, mx);
            fflush(stdout);
          }
        cv_scatter_workspace_destroy(ws);
      }
      free(T);
      free(I);
      cv_ffmatrix_destroy(F);
      cv_display_destroy(d);
    }
  if (storage_mask & 8) printf("\nDirect build against the dense build (row errors relative to the row's sum):\n\n%s", err_table);
  return 0;
}
