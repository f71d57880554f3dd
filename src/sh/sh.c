/* Real spherical harmonics: evaluation, projection, rotation, convolution
 * and windowing (see sh.h for the basis and the conventions). */
#include "sh/sh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/status.h"
#include "sh/latlong.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* ---------------------------------------------------------------------------
 * Evaluation.
 *
 * y_lm = N_l^m(z) * C_m(x, y)  (m > 0),  N_l^|m|(z) * S_|m|(x, y)  (m < 0),
 * where C_m + i S_m = (x + i y)^m = sin^m(th) e^{i m ph} carries the azimuth
 * and the sin^m(th) factor, and N_l^m(z) = sqrt(2) K_lm P_l^m(z) / sin^m(th)
 * is a polynomial in z.  N_m^m is a constant (kNmm), N_{m+1}^m and the rest
 * follow the normalised three-term recurrence
 *   N_l^m = A_lm z N_{l-1}^m + B_lm N_{l-2}^m,
 *   A_lm = sqrt((4l^2 - 1) / (l^2 - m^2)),
 *   B_lm = -sqrt((2l+1) ((l-1)^2 - m^2) / ((2l-3) (l^2 - m^2)))
 * (Sloan, "Efficient Spherical Harmonic Evaluation", JCGT 2(2), 2013, uses
 * the same recurrences to generate unrolled code; here the compiler unrolls
 * a loop for each constant n).  Tables printed from 40-digit arithmetic. */
static const double kNmm[CV_SH_MAX_BANDS] = {
    2.8209479177387814e-1, 4.8860251190291992e-1, 5.4627421529603954e-1,
    5.9004358992664351e-1, 6.2583573544917613e-1, 6.5638205684017010e-1,
    6.8318410519191432e-1, 7.0716273252459618e-1};
static const double kA[CV_SH_MAX_BANDS][CV_SH_MAX_BANDS] = {
    {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {1.7320508075688773, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {1.9364916731037084, 2.2360679774997897, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {1.9720265943665387, 2.0916500663351889, 2.6457513110645906, 0.0, 0.0, 0.0, 0.0, 0.0},
    {1.9843134832984429, 2.0493901531919197, 2.29128784747792, 3.0, 0.0, 0.0, 0.0, 0.0},
    {1.9899748742132399, 2.0310096011589901, 2.1712405933672377, 2.4874685927665499,
     3.3166247903553998, 0.0, 0.0, 0.0},
    {1.9930434571835663, 2.0213149892370278, 2.1139418156609704, 2.3013683530231088,
     2.6739483914241875, 3.6055512754639893, 0.0, 0.0},
    {1.9948914348241345, 2.0155644370746374, 2.0816659994661327, 2.2079402165819617,
     2.4308621740219887, 2.8504385627478449, 3.8729833462074169, 0.0},
};
static const double kB[CV_SH_MAX_BANDS][CV_SH_MAX_BANDS] = {
    {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {-1.1180339887498948, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {-1.0183501544346311, -0.93541434669348535, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {-1.0062305898749054, -0.97979589711327124, -0.86602540378443865, 0.0, 0.0, 0.0, 0.0,
     0.0},
    {-1.0028530728448139, -0.99103120896511485, -0.94760708295868567, -0.82915619758884996,
     0.0, 0.0, 0.0, 0.0},
    {-1.0015420209622192, -0.99522670305623858, -0.97361012046232688, -0.92518488865161455,
     -0.80622577482985497, 0.0, 0.0, 0.0},
    {-1.0009272139219581, -0.99715504402183205, -0.98473192783466186, -0.95940322360024695,
     -0.90909090909090909, -0.79056941504209483, 0.0, 0.0},
};

/* One body for float and double; `n` is a compile-time constant at every call
 * site below, so with always_inline the loops unroll and the table reads fold
 * into immediate constants. */
#define CV_SH_EVAL_BODY(T, n, d, out)                                 \
  do {                                                                \
    const T x_ = (d)[0], y_ = (d)[1], z_ = (d)[2];                    \
    T c_ = (T)1, s_ = (T)0;                                           \
    _Pragma("GCC unroll 8")                                           \
    for (int m = 0; m < (n); m++) {                                   \
      T p2 = (T)0, p1 = (T)kNmm[m];                                   \
      if (m == 0) {                                                   \
        (out)[0] = p1;                                                \
      } else {                                                        \
        (out)[m * m + 2 * m] = p1 * c_;                               \
        (out)[m * m] = p1 * s_;                                       \
      }                                                               \
      _Pragma("GCC unroll 8")                                         \
      for (int l = m + 1; l < (n); l++) {                             \
        const T p = (T)kA[l][m] * z_ * p1 + (T)kB[l][m] * p2;         \
        if (m == 0) {                                                 \
          (out)[l * l + l] = p;                                       \
        } else {                                                      \
          (out)[l * l + l + m] = p * c_;                              \
          (out)[l * l + l - m] = p * s_;                              \
        }                                                             \
        p2 = p1;                                                      \
        p1 = p;                                                       \
      }                                                               \
      const T cn_ = x_ * c_ - y_ * s_;                                \
      s_ = x_ * s_ + y_ * c_;                                         \
      c_ = cn_;                                                       \
    }                                                                 \
  } while (0)

static inline __attribute__((always_inline)) void eval_f(int n, const float *d, float *y) {
  CV_SH_EVAL_BODY(float, n, d, y);
}
static inline __attribute__((always_inline)) void eval_d(int n, const double *d, double *y) {
  CV_SH_EVAL_BODY(double, n, d, y);
}

void cv_sh_eval(int n, const float d[3], float *y) {
  switch (n) {
  case 1: eval_f(1, d, y); break;
  case 2: eval_f(2, d, y); break;
  case 3: eval_f(3, d, y); break;
  case 4: eval_f(4, d, y); break;
  case 5: eval_f(5, d, y); break;
  case 6: eval_f(6, d, y); break;
  case 7: eval_f(7, d, y); break;
  case 8: eval_f(8, d, y); break;
  default: break;
  }
}

void cv_sh_eval_d(int n, const double d[3], double *y) {
  switch (n) {
  case 1: eval_d(1, d, y); break;
  case 2: eval_d(2, d, y); break;
  case 3: eval_d(3, d, y); break;
  case 4: eval_d(4, d, y); break;
  case 5: eval_d(5, d, y); break;
  case 6: eval_d(6, d, y); break;
  case 7: eval_d(7, d, y); break;
  case 8: eval_d(8, d, y); break;
  default: break;
  }
}

void cv_sh_eval_sum(int n, const double *coeffs, int nchan, const double d[3],
                    double *out) {
  for (int ch = 0; ch < nchan; ch++) out[ch] = 0.0;
  if (n < 1 || n > CV_SH_MAX_BANDS) return;
  double y[CV_SH_MAX_COEFFS];
  cv_sh_eval_d(n, d, y);
  for (int i = 0; i < n * n; i++)
    for (int ch = 0; ch < nchan; ch++) out[ch] += coeffs[(size_t)nchan * i + ch] * y[i];
}

/* ---------------------------------------------------------------------------
 * Projection. */

int cv_sh_project_latlong(const cv_image *env, int n, double *coeffs) {
  if (!env || !coeffs || !env->px || n < 1 || n > CV_SH_MAX_BANDS) return CV_ERR_INVALID;
  if (env->w < 1 || env->h < 1 || (env->c != 1 && env->c != 3 && env->c != 4))
    return CV_ERR_INVALID;
  const int w = env->w, h = env->h, c = env->c, nc = n * n, stride = 3 * nc;
  memset(coeffs, 0, sizeof(double) * (size_t)stride);
  /* One partial sum per row, merged in row order below: deterministic for
   * any thread count and schedule. */
  double *rows = calloc((size_t)h * (size_t)stride, sizeof(double));
  double *trig = malloc(2 * ((size_t)w + (size_t)h) * sizeof *trig);
  if (!rows || !trig) {
    free(rows), free(trig);
    return CV_ERR_NOMEM;
  }
  const double *sa = trig, *ca = trig + w, *stt = trig + 2 * w, *ctt = trig + 2 * w + h;
  cv_latlong_trig(w, h, trig, trig + w, trig + 2 * w, trig + 2 * w + h);
  int nonfinite = 0;
#pragma omp parallel for schedule(dynamic, 4) reduction(| : nonfinite)
  for (int yy = 0; yy < h; yy++) {
    double *acc = rows + (size_t)yy * (size_t)stride;
    const double dw = cv_latlong_pixel_solid_angle(yy, w, h);
    double basis[CV_SH_MAX_COEFFS];
    for (int xx = 0; xx < w; xx++) {
      const float *p = cv_image_at(env, xx, yy);
      double L[3];
      if (c == 1) {
        L[0] = L[1] = L[2] = p[0];
      } else {
        L[0] = p[0];
        L[1] = p[1];
        L[2] = p[2];
      }
      if (!isfinite(L[0]) || !isfinite(L[1]) || !isfinite(L[2])) {
        nonfinite = 1;
        continue;
      }
      double d[3];
      cv_latlong_trig_dir(sa[xx], ca[xx], stt[yy], ctt[yy], d); /* = cv_latlong_pixel_dir */
      cv_sh_eval_d(n, d, basis);
      for (int i = 0; i < nc; i++) {
        const double b = basis[i];
        acc[3 * i + 0] += L[0] * b;
        acc[3 * i + 1] += L[1] * b;
        acc[3 * i + 2] += L[2] * b;
      }
    }
    for (int k = 0; k < stride; k++) acc[k] *= dw;
  }
  if (!nonfinite) {
    for (int yy = 0; yy < h; yy++) {
      const double *acc = rows + (size_t)yy * (size_t)stride;
      for (int k = 0; k < stride; k++) coeffs[k] += acc[k];
    }
  }
  free(rows), free(trig);
  return nonfinite ? CV_ERR_NONFINITE : CV_OK;
}

/* P_count(t) and its derivative, by the three-term recurrence. */
static void legendre_pd(int count, double t, double *p, double *dp) {
  double p0 = 1.0, p1 = t;
  for (int j = 2; j <= count; j++) {
    const double p2 = ((2.0 * j - 1.0) * t * p1 - (j - 1.0) * p0) / j;
    p0 = p1;
    p1 = p2;
  }
  *p = p1;
  *dp = count * (t * p1 - p0) / (t * t - 1.0);
}

int cv_gauss_legendre(int count, double *x, double *w) {
  if (count < 1 || !x || !w) return CV_ERR_INVALID;
  /* Newton on P_count from the usual cosine initial guess; the roots are
   * symmetric, so compute the positive half and mirror. */
  for (int k = 0; k < (count + 1) / 2; k++) {
    double t = cos(M_PI * (k + 0.75) / (count + 0.5)), p, dp;
    for (int it = 0; it < 100; it++) {
      legendre_pd(count, t, &p, &dp);
      const double dt = p / dp;
      t -= dt;
      if (fabs(dt) < 1e-15) break;
    }
    legendre_pd(count, t, &p, &dp);
    const double wk = 2.0 / ((1.0 - t * t) * dp * dp);
    x[k] = -t; /* ascending order */
    w[k] = wk;
    x[count - 1 - k] = t;
    w[count - 1 - k] = wk;
  }
  if (count % 2 == 1) x[count / 2] = 0.0;
  return CV_OK;
}

int cv_sh_project_fn(int n, int samples_theta, cv_sh_fn f, void *user, double *coeffs) {
  if (!f || !coeffs || n < 1 || n > CV_SH_MAX_BANDS || samples_theta < 1 ||
      samples_theta > 4096)
    return CV_ERR_INVALID;
  const int nt = samples_theta, np = 2 * samples_theta, nc = n * n;
  memset(coeffs, 0, sizeof(double) * 3 * (size_t)nc);
  double *gx = malloc(sizeof(double) * (size_t)nt);
  double *gw = malloc(sizeof(double) * (size_t)nt);
  if (!gx || !gw) {
    free(gx);
    free(gw);
    return CV_ERR_NOMEM;
  }
  cv_gauss_legendre(nt, gx, gw);
  const double dphi = 2.0 * M_PI / np;
  double basis[CV_SH_MAX_COEFFS];
  for (int k = 0; k < nt; k++) {
    const double z = gx[k], st = sqrt(fmax(0.0, 1.0 - z * z));
    const double wk = gw[k] * dphi;
    for (int j = 0; j < np; j++) {
      const double ph = (j + 0.5) * dphi;
      const double d[3] = {st * cos(ph), st * sin(ph), z};
      double rgb[3] = {0.0, 0.0, 0.0};
      f(d, user, rgb);
      if (!isfinite(rgb[0]) || !isfinite(rgb[1]) || !isfinite(rgb[2])) {
        memset(coeffs, 0, sizeof(double) * 3 * (size_t)nc);
        free(gx);
        free(gw);
        return CV_ERR_NONFINITE;
      }
      cv_sh_eval_d(n, d, basis);
      for (int i = 0; i < nc; i++) {
        const double b = basis[i] * wk;
        coeffs[3 * i + 0] += rgb[0] * b;
        coeffs[3 * i + 1] += rgb[1] * b;
        coeffs[3 * i + 2] += rgb[2] * b;
      }
    }
  }
  free(gx);
  free(gw);
  return CV_OK;
}

/* ---------------------------------------------------------------------------
 * Rotation (Ivanic & Ruedenberg 1996/1998).
 *
 * Band l's matrix M^l is built from M^1 (the 3x3 rotation re-ordered to the
 * (y, z, x) order of band 1) and M^{l-1}:
 *   M^l_{mn} = u_mn U_mn + v_mn V_mn + w_mn W_mn
 * with their coefficients u, v, w and functions U, V, W built on the helper
 * P, and the 1998 correction of V for m < 0 (the sqrt(1 + delta_{m,-1})
 * factor belongs to the P(-1, -m-1) term).  Terms whose coefficient is zero
 * are skipped: their P would index outside band l-1. */

struct cv_sh_rotation {
  int n;
  double *band[CV_SH_MAX_BANDS]; /* band[l]: (2l+1)^2, row-major, into mem */
  double mem[];
};

/* Element (i, j) of band l, centred indices -l..l. */
static inline double rot_at(const cv_sh_rotation *r, int l, int i, int j) {
  return r->band[l][(i + l) * (2 * l + 1) + (j + l)];
}

static double ir_P(const cv_sh_rotation *r, int i, int a, int b, int l) {
  const double ri1 = rot_at(r, 1, i, 1), rim1 = rot_at(r, 1, i, -1), ri0 = rot_at(r, 1, i, 0);
  if (b == l)
    return ri1 * rot_at(r, l - 1, a, l - 1) - rim1 * rot_at(r, l - 1, a, -l + 1);
  if (b == -l)
    return ri1 * rot_at(r, l - 1, a, -l + 1) + rim1 * rot_at(r, l - 1, a, l - 1);
  return ri0 * rot_at(r, l - 1, a, b);
}

static double ir_U(const cv_sh_rotation *r, int m, int n, int l) { return ir_P(r, 0, m, n, l); }

static double ir_V(const cv_sh_rotation *r, int m, int n, int l) {
  if (m == 0) return ir_P(r, 1, 1, n, l) + ir_P(r, -1, -1, n, l);
  if (m > 0) {
    const double d1 = (m == 1) ? 1.0 : 0.0;
    double v = ir_P(r, 1, m - 1, n, l) * sqrt(1.0 + d1);
    if (m != 1) v -= ir_P(r, -1, -m + 1, n, l);
    return v;
  }
  const double d1 = (m == -1) ? 1.0 : 0.0;
  double v = ir_P(r, -1, -m - 1, n, l) * sqrt(1.0 + d1);
  if (m != -1) v += ir_P(r, 1, m + 1, n, l);
  return v;
}

static double ir_W(const cv_sh_rotation *r, int m, int n, int l) {
  /* only called when w_mn != 0, i.e. |m| < l - 1, so m +- 1 stays in band l-1 */
  if (m > 0) return ir_P(r, 1, m + 1, n, l) + ir_P(r, -1, -m - 1, n, l);
  return ir_P(r, 1, m - 1, n, l) - ir_P(r, -1, -m + 1, n, l);
}

static void ir_band(cv_sh_rotation *r, int l) {
  double *M = r->band[l];
  const int sz = 2 * l + 1;
  for (int m = -l; m <= l; m++) {
    const int am = abs(m);
    for (int n = -l; n <= l; n++) {
      const double denom = (abs(n) == l) ? 2.0 * l * (2.0 * l - 1.0) : (double)(l + n) * (l - n);
      const double d0 = (m == 0) ? 1.0 : 0.0;
      double val = 0.0;
      const double uu = (double)(l + m) * (l - m);
      if (uu != 0.0) val += sqrt(uu / denom) * ir_U(r, m, n, l);
      const double vv = (1.0 + d0) * (l + am - 1.0) * (l + am);
      if (vv != 0.0) val += 0.5 * sqrt(vv / denom) * (1.0 - 2.0 * d0) * ir_V(r, m, n, l);
      const double ww = (double)(l - am - 1) * (l - am);
      if (m != 0 && ww != 0.0) val += -0.5 * sqrt(ww / denom) * ir_W(r, m, n, l);
      M[(m + l) * sz + (n + l)] = val;
    }
  }
}

int cv_sh_rotation_create(int n, const double R[9], cv_sh_rotation **out) {
  if (!out) return CV_ERR_INVALID;
  *out = NULL;
  if (!R || n < 1 || n > CV_SH_MAX_BANDS) return CV_ERR_INVALID;
  for (int k = 0; k < 9; k++)
    if (!isfinite(R[k])) return CV_ERR_INVALID;
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      double dot = 0.0;
      for (int k = 0; k < 3; k++) dot += R[3 * i + k] * R[3 * j + k];
      if (fabs(dot - (i == j ? 1.0 : 0.0)) > 1e-6) return CV_ERR_INVALID;
    }
  const double det = R[0] * (R[4] * R[8] - R[5] * R[7]) - R[1] * (R[3] * R[8] - R[5] * R[6]) +
                     R[2] * (R[3] * R[7] - R[4] * R[6]);
  if (det < 0.0) return CV_ERR_INVALID;

  size_t total = 0;
  for (int l = 0; l < n; l++) total += (size_t)(2 * l + 1) * (size_t)(2 * l + 1);
  cv_sh_rotation *r = malloc(sizeof *r + total * sizeof(double));
  if (!r) return CV_ERR_NOMEM;
  r->n = n;
  size_t off = 0;
  for (int l = 0; l < CV_SH_MAX_BANDS; l++) {
    r->band[l] = (l < n) ? r->mem + off : NULL;
    if (l < n) off += (size_t)(2 * l + 1) * (size_t)(2 * l + 1);
  }
  r->band[0][0] = 1.0;
  if (n > 1) {
    /* band 1 in (y, z, x) order: M1[a][b] = R[perm[a]][perm[b]] */
    static const int perm[3] = {1, 2, 0};
    for (int a = 0; a < 3; a++)
      for (int b = 0; b < 3; b++) r->band[1][3 * a + b] = R[3 * perm[a] + perm[b]];
  }
  for (int l = 2; l < n; l++) ir_band(r, l);
  *out = r;
  return CV_OK;
}

void cv_sh_rotation_destroy(cv_sh_rotation *rot) { free(rot); }

int cv_sh_rotation_bands(const cv_sh_rotation *rot) { return rot ? rot->n : 0; }

const double *cv_sh_rotation_band(const cv_sh_rotation *rot, int l) {
  if (!rot || l < 0 || l >= rot->n) return NULL;
  return rot->band[l];
}

void cv_sh_rotate(const cv_sh_rotation *rot, const double *in, double *out, int nchan) {
  double tmp[2 * CV_SH_MAX_BANDS - 1];
  for (int ch = 0; ch < nchan; ch++) {
    for (int l = 0; l < rot->n; l++) {
      const int sz = 2 * l + 1, off = l * l;
      const double *M = rot->band[l];
      for (int j = 0; j < sz; j++) tmp[j] = in[(size_t)nchan * (off + j) + ch];
      for (int i = 0; i < sz; i++) {
        double s = 0.0;
        for (int j = 0; j < sz; j++) s += M[i * sz + j] * tmp[j];
        out[(size_t)nchan * (off + i) + ch] = s;
      }
    }
  }
}

/* ---------------------------------------------------------------------------
 * Convolution and windowing. */

double cv_sh_cosine_lobe_factor(int l) {
  if (l < 0) return 0.0;
  if (l == 0) return M_PI;
  if (l == 1) return 2.0 * M_PI / 3.0;
  if (l % 2 == 1) return 0.0;
  /* l! / (2^l ((l/2)!)^2) = binomial(l, l/2) / 2^l, built as a product of
   * ratios to stay exact-ish for large l. */
  double ratio = 1.0;
  const int h = l / 2;
  for (int k = 1; k <= h; k++) ratio *= (double)(h + k) / (4.0 * k);
  const double sign = (h % 2 == 1) ? 1.0 : -1.0; /* (-1)^(l/2 - 1) */
  return 2.0 * M_PI * sign / ((l + 2.0) * (l - 1.0)) * ratio;
}

void cv_sh_convolve_cosine(int n, double *coeffs, int nchan) {
  for (int l = 0; l < n; l++) {
    const double a = cv_sh_cosine_lobe_factor(l);
    for (int i = l * l; i < (l + 1) * (l + 1); i++)
      for (int ch = 0; ch < nchan; ch++) coeffs[(size_t)nchan * i + ch] *= a;
  }
}

double cv_sh_window_weight(int n, int l, cv_sh_window_kind kind) {
  if (l <= 0 || n < 1) return 1.0;
  const double t = (double)l / n;
  switch (kind) {
  case CV_SH_WINDOW_HANN: return 0.5 * (1.0 + cos(M_PI * t));
  case CV_SH_WINDOW_LANCZOS: return sin(M_PI * t) / (M_PI * t);
  case CV_SH_WINDOW_NONE:
  default: return 1.0;
  }
}

void cv_sh_window(int n, double *coeffs, int nchan, cv_sh_window_kind kind) {
  for (int l = 1; l < n; l++) {
    const double wl = cv_sh_window_weight(n, l, kind);
    for (int i = l * l; i < (l + 1) * (l + 1); i++)
      for (int ch = 0; ch < nchan; ch++) coeffs[(size_t)nchan * i + ch] *= wl;
  }
}
