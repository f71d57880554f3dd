/* The end of a wall-eye frame (issue 29), per eye, both ways `cave run`
 * can take it (--post, cluster/walleye.c), on the GL this process gets
 * (llvmpipe without a GPU), on the tess-1 cabin lit by a coloured SH light:
 *   cpu: cv_renderer_shade_stats with the display image read back (float),
 *        the luminance statistics as the renderer's default does them,
 *        cv_downsample_to_patches, cv_apply_patch_delta, cv_rec709_codes;
 *   gpu: cv_renderer_shade_gpu (statistics on the GPU), cv_renderer_patch_means,
 *        cv_renderer_post (equation 7 + codes in a shader).
 * Per size: the medians over --reps of wall ms and of the process's CPU ms
 * (every llvmpipe thread: the work the host pays for; glFinish after each
 * stage), the bytes read back and uploaded, the thread CPU ms outside GL,
 * and the error: the largest code difference between the two paths' images
 * (the CPU path's codes against the GPU's read back after the timing).
 *
 * usage: bench_frame_path [--sizes 240,360,720,1440] [--reps 7] [--patches 24] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_cabin.h"
#include "compensate/resample.h"
#include "render/renderer.h"
#include "tonemap/drago.h"
#include "tonemap/foveal.h"

#define MAXR 64
enum { S_SHADE, S_PATCH, S_POST, S_N };

static double cpu_ms(clockid_t c) {
  struct timespec ts;
  clock_gettime(c, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

static int cmp_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}
static double median(double *v, int n) {
  qsort(v, (size_t)n, sizeof *v, cmp_d);
  return v[n / 2];
}

typedef struct run_out {
  double wall[MAXR], proc[MAXR], stage[S_N][MAXR], outside[MAXR];
  uint64_t read, up;
} run_out;


/* One eye's frame end by path `gpu`; returns 0 or the failing status. */
static int one(cv_renderer *r, int gpu, const cv_render_view *v, const cv_drago_consts *dc, cv_image *disp,
               cv_image *lum, cv_image *out, uint8_t *codes, int P, const double *delta_d, const float *delta_f,
               double *patch, cv_rec709_lut *lut, double t[S_N], double *outside) {
  cv_err err;
  double p0, p1, p2, p3;
  double mx;
  uint64_t bad;
  *outside = 0;
  p0 = cpu_ms(CLOCK_PROCESS_CPUTIME_ID);
  int st = gpu ? cv_renderer_shade_gpu(r, v, dc, NULL, lum, &mx, &bad, NULL, &err)
               : cv_renderer_shade_stats(r, v, dc, 0, disp, NULL, lum, &mx, &bad, NULL, &err);
  p1 = cpu_ms(CLOCK_PROCESS_CPUTIME_ID);
  if (st) return fprintf(stderr, "shade: %s\n", err.msg), st;
  const double c1 = cpu_ms(CLOCK_THREAD_CPUTIME_ID);
  if (gpu) st = cv_renderer_patch_means(r, patch, &err);
  else cv_downsample_to_patches(disp, P, P, NULL, NULL, patch);
  if (!gpu) *outside += cpu_ms(CLOCK_THREAD_CPUTIME_ID) - c1;
  p2 = cpu_ms(CLOCK_PROCESS_CPUTIME_ID);
  const double c2 = cpu_ms(CLOCK_THREAD_CPUTIME_ID);
  if (gpu) {
    st = st ? st : cv_renderer_post(r, 0, 0, delta_f, &err);
  } else {
    cv_apply_patch_delta(disp, delta_d, P, P, NULL, NULL, out);
    cv_rec709_codes(lut, out->px, 3 * (size_t)out->w * out->h, codes);
    *outside += cpu_ms(CLOCK_THREAD_CPUTIME_ID) - c2;
  }
  cv_renderer_gpu_timer_begin(r); /* a no-op query: the GL queue drained */
  cv_renderer_gpu_timer_end(r);
  cv_renderer_gpu_timer_result(r);
  p3 = cpu_ms(CLOCK_PROCESS_CPUTIME_ID);
  if (st) return fprintf(stderr, "post: %s\n", err.msg), st;
  t[S_SHADE] = p1 - p0, t[S_PATCH] = p2 - p1, t[S_POST] = p3 - p2;
  return 0;
}

static int measure(cv_renderer *r, int gpu, int size, int P, int reps, run_out *o, uint8_t *codes_out) {
  double pa[3] = {-0.8, 0.4, -0.6}, pb[3] = {0.8, 0.4, -0.6}, pc[3] = {-0.8, 1.6, -0.6}, eye[3] = {0.0, 1.0, 0.3};
  cv_render_view v;
  memset(&v, 0, sizeof v);
  if (cv_offaxis_compute(pa, pb, pc, eye, 0.02, 20, &v.proj)) return 1;
  v.w = v.h = size, v.supersample = 1;
  cv_drago d;
  cv_drago_default(&d);
  d.lwa = 2, d.lwmax = 200;
  cv_drago_consts dc;
  cv_drago_prepare(&d, &dc);
  cv_image *disp, *lum, *out;
  cv_image_create(size, size, 3, &disp);
  cv_image_create(size, size, 3, &out);
  cv_image_create(128, 128, 1, &lum);
  uint8_t *codes = malloc(3 * (size_t)size * size);
  double *patch = malloc(3 * (size_t)P * P * sizeof *patch), *dd = malloc(3 * (size_t)P * P * sizeof *dd);
  float *df = malloc(3 * (size_t)P * P * sizeof *df);
  for (int i = 0; i < 3 * P * P; i++) dd[i] = df[i] = (float)(0.05 * sin(0.7 * i));
  cv_rec709_lut lut;
  cv_rec709_lut_init(&lut);
  cv_err err;
  int st = gpu ? cv_renderer_post_grid(r, P, P, NULL, NULL, size, size, &err) : 0;
  if (st) fprintf(stderr, "grid: %s\n", err.msg);
  uint64_t r0 = 0, u0 = 0, r1, u1;
  for (int k = -1; !st && k < reps; k++) { /* k = -1: warm-up (tables, targets) */
    if (k == 0) cv_renderer_io(r, &r0, &u0);
    double t[S_N] = {0}, outside = 0, w0 = bench_now_ms(), p0 = cpu_ms(CLOCK_PROCESS_CPUTIME_ID);
    st = one(r, gpu, &v, &dc, disp, lum, out, codes, P, dd, df, patch, &lut, t, &outside);
    if (k < 0) continue;
    o->wall[k] = bench_now_ms() - w0;
    o->proc[k] = cpu_ms(CLOCK_PROCESS_CPUTIME_ID) - p0;
    for (int s = 0; s < S_N; s++) o->stage[s][k] = t[s];
    o->outside[k] = outside;
  }
  cv_renderer_io(r, &r1, &u1);
  o->read = (r1 - r0) / (uint64_t)reps, o->up = (u1 - u0) / (uint64_t)reps;
  if (!st && gpu) st = cv_renderer_post_read(r, 0, codes_out, &err);
  else if (!st) memcpy(codes_out, codes, 3 * (size_t)size * size);
  cv_image_destroy(disp), cv_image_destroy(out), cv_image_destroy(lum);
  free(codes), free(patch), free(dd), free(df);
  return st;
}

int main(int argc, char **argv) {
  const char *sizes = "240,360,720,1440";
  int reps = 7, P = 24;
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--sizes") && i + 1 < argc) sizes = argv[++i];
    else if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--patches") && i + 1 < argc) P = atoi(argv[++i]);
    else {
      fprintf(stderr, "usage: bench_frame_path [--sizes 240,360,720,1440] [--reps 7] [--patches 24]\n");
      return strcmp(argv[i], "--help") ? 2 : 0;
    }
  }
  if (reps < 1 || reps > MAXR || P < 1 || P > 256) {
    fprintf(stderr, "bench_frame_path: --reps 1..%d, --patches 1..256\n", MAXR);
    return 2;
  }
  cv_cabin_params cp;
  cv_cabin_default_params(&cp);
  cp.tess = 1;
  cv_mesh *m;
  cv_err err;
  cv_prt *prt;
  cv_bake_params bp = {.bands = 3, .rays = 8, .bounces = 1, .seed = 1, .spread = CV_BAKE_DEFAULT_SPREAD, .quiet = 1};
  if (cv_cabin_generate(&cp, &m, &err) || cv_prt_bake(m, &bp, &prt, NULL, &err)) {
    fprintf(stderr, "scene: %s\n", err.msg);
    return 1;
  }
  cv_mesh_destroy(m);
  cv_render_opts o;
  cv_render_default_opts(&o);
  o.display_float = 1;
  o.timing = 0;
  cv_renderer *r;
  if (cv_renderer_create(prt, &o, &r, &err)) {
    fprintf(stderr, "renderer: %s\n", err.msg);
    return 1;
  }
  cv_lighting l;
  memset(&l, 0, sizeof l);
  l.bands = 3;
  for (int c = 0; c < 3; c++) l.sh[c] = (2.0 + c) * sqrt(4 * M_PI), l.sh[3 + c] = 1.0;
  if (cv_renderer_set_lighting(r, &l, NULL, NULL, &err)) {
    fprintf(stderr, "lighting: %s\n", err.msg);
    return 1;
  }
  printf("GL: %s; %d x %d patches; medians of %d; ms = process CPU ms (all threads), glFinish per stage\n",
         cv_renderer_gl_name(r), P, P, reps);
  printf("%6s %4s | %8s %8s | %8s %8s %8s | %10s %8s | %9s | %s\n", "size", "path", "wall ms", "CPU ms",
         "shade", "patches", "post", "read B", "up B", "CPU ms out", "codes vs cpu");
  char buf[256];
  snprintf(buf, sizeof buf, "%s", sizes);
  for (char *tok = strtok(buf, ","); tok; tok = strtok(NULL, ",")) {
    const int size = atoi(tok);
    if (size < P || size > 4096) continue;
    uint8_t *cc = malloc(3 * (size_t)size * size), *gc = malloc(3 * (size_t)size * size);
    run_out ro[2];
    memset(ro, 0, sizeof ro);
    int st = measure(r, 0, size, P, reps, &ro[0], cc) || measure(r, 1, size, P, reps, &ro[1], gc);
    int worst = 0;
    for (size_t i = 0; !st && i < 3 * (size_t)size * size; i++) {
      const int dlt = abs((int)cc[i] - (int)gc[i]);
      worst = dlt > worst ? dlt : worst;
    }
    for (int g = 0; !st && g < 2; g++) {
      run_out *q = &ro[g];
      printf("%4d^2 %4s | %8.2f %8.2f | %8.2f %8.2f %8.2f | %10llu %8llu | %9.3f | %d\n", size, g ? "gpu" : "cpu",
             median(q->wall, reps), median(q->proc, reps), median(q->stage[S_SHADE], reps),
             median(q->stage[S_PATCH], reps), median(q->stage[S_POST], reps), (unsigned long long)q->read,
             (unsigned long long)q->up, median(q->outside, reps), g ? worst : 0);
    }
    free(cc), free(gc);
    if (st) return 1;
  }
  cv_renderer_destroy(r);
  cv_prt_destroy(prt);
  return 0;
}
