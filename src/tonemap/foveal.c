/* Foveal adaptation statistics (see foveal.h).  Per pixel: centre point on
 * the wall rectangle, direction from the eye, cone test against cos(half
 * angle), and the pixel's solid angle area*|cos|/dist^2.  Only pixels in the
 * cone take a logarithm, so a 128x128 wall costs little more than the
 * direction test. */
#include "tonemap/foveal.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>

#include "core/overlaps.h"
#include "core/status.h"

#include "core/vec3d.h"


/* Unit gaze into g; 0 when degenerate. */
static int unit_gaze(const double gaze[3], double g[3]) {
  if (!finite3(gaze)) return 0;
  double l = sqrt(dot3(gaze, gaze));
  if (!(l > 1e-12)) return 0;
  for (int k = 0; k < 3; k++) g[k] = gaze[k] / l;
  return 1;
}

void cv_foveal_accumulate(const float *lum, int w, int h, const double pa[3], const double pb[3],
                          const double pc[3], const double eye[3], const double gaze[3],
                          double half_angle_rad, cv_lumstats *acc) {
  double g[3];
  if (!lum || !acc || w <= 0 || h <= 0 || !pa || !pb || !pc || !eye || !gaze) return;
  if (!finite3(pa) || !finite3(pb) || !finite3(pc) || !finite3(eye) || !unit_gaze(gaze, g))
    return;
  if (!(half_angle_rad >= 0.0) || !isfinite(half_angle_rad)) return;
  /* Walls the cone misses hold no pixel centre inside it: skip them whole. */
  if (!cv_foveal_touches(pa, pb, pc, eye, gaze, half_angle_rad)) return;
  /* Half angles beyond 90 degrees (not a fovea, but allowed) need the
   * unsquared test below. */
  const double cos_half = half_angle_rad >= 3.14159265358979323846 ? -1.0 : cos(half_angle_rad);
  double du[3], dv[3], n[3];
  for (int k = 0; k < 3; k++) {
    du[k] = (pb[k] - pa[k]) / w; /* one pixel to the right */
    dv[k] = (pa[k] - pc[k]) / h; /* one pixel down (row 0 is next to pc) */
  }
  cross3(du, dv, n);
  const double area = sqrt(dot3(n, n)); /* pixel area, m^2 */
  if (!(area > 0.0)) return;
  for (int k = 0; k < 3; k++) n[k] /= area;
  /* Centre of pixel (0, 0) relative to the eye. */
  double o[3];
  for (int k = 0; k < 3; k++) o[k] = pc[k] + 0.5 * du[k] + 0.5 * dv[k] - eye[k];
  /* Per pixel: v = o + x du + y dv; the dot products are affine in x, y. */
  const double gu = dot3(g, du), gv = dot3(g, dv), go = dot3(g, o);
  const double nu = dot3(n, du), nv = dot3(n, dv), no = dot3(n, o);

  double sum_log = 0.0, weight = 0.0, max_l = acc->max_l;
  uint64_t n_pix = 0, n_bad = 0;
  for (int y = 0; y < h; y++) {
    double ry[3];
    for (int k = 0; k < 3; k++) ry[k] = o[k] + y * dv[k];
    const double gy = go + y * gv, ny = no + y * nv;
    const float *row = lum + (size_t)y * (size_t)w;
    for (int x = 0; x < w; x++) {
      const double vg = gy + x * gu;
      if (!(vg > 0.0) && cos_half >= 0.0) continue; /* behind the gaze plane */
      const double vx = ry[0] + x * du[0], vy = ry[1] + x * du[1], vz = ry[2] + x * du[2];
      const double d2 = vx * vx + vy * vy + vz * vz;
      /* cos(angle) >= cos_half  <=>  vg >= cos_half*|v| (vg > 0 here). */
      if (cos_half >= 0.0 ? vg * vg < cos_half * cos_half * d2 : vg < cos_half * sqrt(d2))
        continue;
      const float l = row[x];
      if (!(l >= 0.0f) || isinf(l)) {
        n_bad++;
        continue;
      }
      const double vn = fabs(ny + x * nu);
      const double wgt = area * vn / (d2 * sqrt(d2)); /* area*cos/dist^2 */
      sum_log += wgt * log((double)l + CV_LUM_EPS);
      weight += wgt;
      if (l > max_l) max_l = l;
      n_pix++;
    }
  }
  acc->sum_log += sum_log;
  acc->weight += weight;
  acc->max_l = max_l;
  acc->n_pixels += n_pix;
  acc->n_invalid += n_bad;
}

void cv_lumstats_image(const cv_image *img, cv_lumstats *acc) {
  if (!img || !acc || !img->px || img->w <= 0 || img->h <= 0 || img->c == 2 || img->c < 1)
    return;
  const int c = img->c;
  const size_t np = (size_t)img->w * (size_t)img->h;
  double s = 0.0, mx = acc->max_l;
  uint64_t n = 0, bad = 0;
  for (size_t i = 0; i < np; i++) {
    const float *p = img->px + i * (size_t)c;
    double y;
    if (c == 1) {
      if (!(p[0] >= 0.0f) || isinf(p[0])) {
        bad++;
        continue;
      }
      y = p[0];
    } else {
      if (!(p[0] >= 0.0f) || !(p[1] >= 0.0f) || !(p[2] >= 0.0f) || isinf(p[0]) || isinf(p[1]) ||
          isinf(p[2])) {
        bad++;
        continue;
      }
      y = 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
    }
    s += log(y + CV_LUM_EPS);
    if (y > mx) mx = y;
    n++;
  }
  acc->sum_log += s;
  acc->weight += (double)n;
  acc->max_l = mx;
  acc->n_pixels += n;
  acc->n_invalid += bad;
}

int cv_lum_downsample(const cv_image *src, cv_image *lum, double *max_y, uint64_t *n_invalid) {
  if (!src || !lum || !src->px || !lum->px || src->c < 3 || lum->c != 1 || src->w < 1 ||
      src->h < 1 || lum->w < 1 || lum->h < 1)
    return CV_ERR_INVALID;
  const int W = src->w, H = src->h, c = src->c;
  /* each luminance pixel's footprint: the source pixels (cells of edges
   * 0, 1, .., W in pixel units) under its 1/lum->w of the width, and so on */
  cv_overlaps fx = {0}, fy = {0};
  float *y = malloc((size_t)W * H * sizeof *y);
  double *ex = malloc(((size_t)(W > H ? W : H) + 1) * sizeof *ex);
  int st = !y || !ex ? -1 : 0;
  if (!st) {
    for (int k = 0; k <= (W > H ? W : H); k++) ex[k] = k;
    st = cv_overlaps_make(ex, W, lum->w, W, 0, &fx);
  }
  if (!st) st = cv_overlaps_make(ex, H, lum->h, H, 0, &fy);
  free(ex);
  if (st) {
    free(y), cv_overlaps_free(&fx), cv_overlaps_free(&fy);
    return CV_ERR_NOMEM;
  }
  /* Y of every source pixel once (NaN for an invalid one), and the max */
  double mx = 0;
  uint64_t bad = 0;
  for (size_t i = 0; i < (size_t)W * H; i++) {
    const float *p = src->px + i * (size_t)c;
    if (!(p[0] >= 0.0f) || !(p[1] >= 0.0f) || !(p[2] >= 0.0f) || isinf(p[0]) || isinf(p[1]) ||
        isinf(p[2])) {
      y[i] = NAN;
      bad++;
      continue;
    }
    const double v = 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
    y[i] = (float)v;
    if (v > mx) mx = v;
  }
  for (int j = 0; j < lum->h; j++)
    for (int i = 0; i < lum->w; i++) {
      double sw = 0, s = 0;
      for (int a = fy.first[j]; a < fy.first[j + 1]; a++) {
        const float *row = y + (size_t)fy.cell[a] * W;
        for (int b = fx.first[i]; b < fx.first[i + 1]; b++) {
          const float v = row[fx.cell[b]];
          if (isnan(v)) continue;
          const double w = fy.len[a] * fx.len[b];
          sw += w, s += w * v;
        }
      }
      lum->px[(size_t)j * lum->w + i] = sw > 0 ? (float)(s / sw) : NAN;
    }
  free(y), cv_overlaps_free(&fx), cv_overlaps_free(&fy);
  if (max_y) *max_y = mx;
  if (n_invalid) *n_invalid = bad;
  return CV_OK;
}

void cv_lumstats_merge(cv_lumstats *into, const cv_lumstats *from) {
  into->sum_log += from->sum_log;
  into->weight += from->weight;
  if (from->max_l > into->max_l) into->max_l = from->max_l;
  into->n_pixels += from->n_pixels;
  into->n_invalid += from->n_invalid;
}

int cv_lumstats_lwa(const cv_lumstats *s, double *lwa) {
  if (!s || !(s->weight > 0.0) || !isfinite(s->weight) || !isfinite(s->sum_log)) return 0;
  double v = exp(s->sum_log / s->weight);
  if (!(v > 0.0) || !isfinite(v)) return 0;
  *lwa = v;
  return 1;
}

/* Smallest angle between unit g and the directions from the eye to the
 * segment a..b (given relative to the eye).  The directions form a great-
 * circle arc; the closest point of the arc is g projected onto its plane when
 * that lies between the ends, otherwise an end. */
static double seg_min_angle(const double a[3], const double b[3], const double g[3]) {
  double la = sqrt(dot3(a, a)), lb = sqrt(dot3(b, b));
  double ca = la > 0 ? dot3(a, g) / la : 1.0, cb = lb > 0 ? dot3(b, g) / lb : 1.0;
  double best = fmax(ca, cb);
  double m[3];
  cross3(a, b, m);
  double lm = sqrt(dot3(m, m));
  if (lm > 1e-15 * la * lb) {
    double gm = dot3(g, m) / lm;
    double p[3];
    for (int k = 0; k < 3; k++) p[k] = g[k] - gm * m[k] / lm;
    double c1[3], c2[3];
    cross3(a, p, c1);
    cross3(p, b, c2);
    double lp = sqrt(dot3(p, p));
    if (lp > 0 && dot3(c1, m) >= 0 && dot3(c2, m) >= 0) {
      double cp = dot3(p, g) / lp; /* = lp for unit g */
      if (cp > best) best = cp;
    }
  }
  return acos(fmax(-1.0, fmin(1.0, best)));
}

int cv_foveal_touches(const double pa[3], const double pb[3], const double pc[3],
                      const double eye[3], const double gaze[3], double half_angle_rad) {
  double g[3];
  if (!pa || !pb || !pc || !eye || !gaze) return 0;
  if (!finite3(pa) || !finite3(pb) || !finite3(pc) || !finite3(eye) || !unit_gaze(gaze, g))
    return 0;
  if (!(half_angle_rad >= 0.0)) return 0;
  double e1[3], e2[3], n[3], a[3];
  for (int k = 0; k < 3; k++) {
    e1[k] = pb[k] - pa[k];
    e2[k] = pc[k] - pa[k];
    a[k] = pa[k] - eye[k];
  }
  cross3(e1, e2, n);
  /* Does the gaze ray itself hit the rectangle? */
  double gn = dot3(g, n);
  if (gn != 0.0) {
    double t = dot3(a, n) / gn;
    if (t > 0.0) {
      double q[3];
      for (int k = 0; k < 3; k++) q[k] = eye[k] + t * g[k] - pa[k];
      double s = dot3(q, e1) / dot3(e1, e1), u = dot3(q, e2) / dot3(e2, e2);
      if (s >= 0.0 && s <= 1.0 && u >= 0.0 && u <= 1.0) return 1;
    }
  }
  /* Otherwise the closest direction lies on the boundary (the rectangle's
   * image on the sphere is geodesically convex). */
  double c[4][3];
  for (int k = 0; k < 3; k++) {
    c[0][k] = a[k];
    c[1][k] = a[k] + e1[k];
    c[2][k] = a[k] + e1[k] + e2[k];
    c[3][k] = a[k] + e2[k];
  }
  for (int i = 0; i < 4; i++)
    if (seg_min_angle(c[i], c[(i + 1) & 3], g) <= half_angle_rad) return 1;
  return 0;
}
