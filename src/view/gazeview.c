/* The view along the gaze: see gazeview.h. */
#include "view/gazeview.h"

#include <math.h>
#include <string.h>

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void cross3(const double *a, const double *b, double *o) {
  o[0] = a[1] * b[2] - a[2] * b[1];
  o[1] = a[2] * b[0] - a[0] * b[2];
  o[2] = a[0] * b[1] - a[1] * b[0];
}

static int norm3(double *v) {
  const double l = sqrt(dot3(v, v));
  if (!(l > 1e-12)) return -1;
  for (int k = 0; k < 3; k++) v[k] /= l;
  return 0;
}

/* The camera basis of a gaze: forward, right, up (up near +Y). */
static int basis(const double gaze[3], double f[3], double r[3], double u[3]) {
  memcpy(f, gaze, 3 * sizeof *f);
  if (norm3(f)) return -1;
  const double wy[3] = {0, 1, 0}, wz[3] = {0, 0, -1};
  cross3(f, wy, r);
  if (norm3(r)) { /* looking straight up or down */
    cross3(f, wz, r);
    if (norm3(r)) return -1;
  }
  cross3(r, f, u);
  return 0;
}

/* The wall a ray hits first: its index and image coordinates (s, q in
 * [0, 1): along pb - pa and pc - pa); -1 when none. */
static int hit(const cv_cave *cave, const uint8_t *shown, const double *o, const double *d, double *s, double *q) {
  int best = -1;
  double bt = INFINITY;
  for (int w = 0; w < cave->n_walls; w++) {
    if (shown && !shown[w]) continue;
    const cv_wall *W = &cave->walls[w];
    double eu[3], ev[3], n[3], po[3];
    for (int k = 0; k < 3; k++) eu[k] = W->pb[k] - W->pa[k], ev[k] = W->pc[k] - W->pa[k], po[k] = W->pa[k] - o[k];
    cross3(eu, ev, n);
    const double dn = dot3(d, n);
    if (fabs(dn) < 1e-15) continue;
    const double t = dot3(po, n) / dn;
    if (!(t > 0) || t >= bt) continue;
    double rel[3];
    for (int k = 0; k < 3; k++) rel[k] = o[k] + t * d[k] - W->pa[k];
    const double ss = dot3(rel, eu) / dot3(eu, eu), qq = dot3(rel, ev) / dot3(ev, ev);
    if (ss < 0 || ss >= 1 || qq < 0 || qq >= 1) continue;
    best = w, bt = t, *s = ss, *q = qq;
  }
  return best;
}

long cv_gaze_view(const cv_cave *cave, const uint8_t *src, int src_w, const int *cell_x, const int *cell_y,
                  const int *ws, const int *hs, const uint8_t *shown, const double head[3], const double gaze[3],
                  double fov_deg, uint8_t *out, int n) {
  memset(out, 0, 3 * (size_t)n * n);
  double f[3], r[3], u[3];
  if (n < 1 || basis(gaze, f, r, u)) return 0;
  const double th = tan(0.5 * fov_deg * M_PI / 180.0);
  long hits = 0;
  for (int y = 0; y < n; y++)
    for (int x = 0; x < n; x++) {
      const double a = (2.0 * (x + 0.5) / n - 1.0) * th, b = (1.0 - 2.0 * (y + 0.5) / n) * th;
      double d[3], s, q;
      for (int k = 0; k < 3; k++) d[k] = f[k] + a * r[k] + b * u[k];
      const int w = hit(cave, shown, head, d, &s, &q);
      if (w < 0) continue;
      int px = (int)(s * ws[w]), py = (int)((1.0 - q) * hs[w]);
      if (px >= ws[w]) px = ws[w] - 1;
      if (py >= hs[w]) py = hs[w] - 1;
      if (py < 0) py = 0;
      memcpy(out + 3 * ((size_t)y * n + x), src + 3 * ((size_t)(cell_y[w] + py) * src_w + cell_x[w] + px), 3);
      hits++;
    }
  return hits;
}
