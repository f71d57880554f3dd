/* Sampling tables of a tabulated BRDF and their continuous inversion (see
 * brdf_sample.h for the density). */
#include "lcd/brdf_sample.h"

#include <stdlib.h>
#include <string.h>

void cv_brdf_sampler_destroy(cv_brdf_sampler *s) {
  if (!s) return;
  free(s->lum);
  free(s->ccum);
  free(s->mcum);
  free(s->xg);
  free(s->dx);
  free(s->cs_phi);
  free(s->cs_th);
  free(s->mguide);
  free(s->cguide);
  free(s);
}

/* guide[g] = the largest cell i in [0, n) with cdf[i] <= g/G of cdf[n]
 * (n cells, n + 1 entries; guide[G] = n - 1). */
static void build_guide(const float *cdf, int n, uint16_t *guide) {
  const float tot = cdf[n];
  int i = 0;
  for (int g = 0; g <= CV_BRDF_GUIDE; g++) {
    const float x = tot * ((float)g / CV_BRDF_GUIDE);
    while (i < n - 1 && cdf[i + 1] <= x) i++;
    guide[g] = (uint16_t)i;
  }
}

int cv_brdf_sampler_create(const cv_brdf *b, cv_brdf_sampler **out) {
  *out = NULL;
  const int nt = b->n_theta, np = b->n_phi, na = nt - 1;
  const size_t ne = (size_t)nt * nt * np;
  cv_brdf_sampler *s = calloc(1, sizeof *s);
  if (!s) return CV_ERR_NOMEM;
  s->brdf = b;
  s->nt = nt;
  s->np = np;
  s->inv_dt = (float)(1 / b->d_theta);
  s->inv_dp = (float)(1 / b->d_phi);
  s->dp = (float)b->d_phi;
  s->lum = malloc(ne * sizeof(float));
  s->ccum = malloc(ne * sizeof(float));
  s->mcum = malloc((size_t)nt * nt * sizeof(float));
  s->xg = malloc((size_t)nt * sizeof(float));
  s->dx = malloc((size_t)na * sizeof(float));
  s->cs_phi = malloc(2 * (size_t)np * sizeof(float));
  s->cs_th = malloc(2 * (size_t)nt * sizeof(float));
  s->mguide = malloc((size_t)nt * (CV_BRDF_GUIDE + 1) * sizeof(uint16_t));
  s->cguide = malloc((size_t)nt * nt * (CV_BRDF_GUIDE + 1) * sizeof(uint16_t));
  if (!s->lum || !s->ccum || !s->mcum || !s->xg || !s->dx || !s->cs_phi || !s->cs_th ||
      !s->mguide || !s->cguide) {
    cv_brdf_sampler_destroy(s);
    return CV_ERR_NOMEM;
  }
  int grey = 1;
  for (size_t i = 0; i < ne && grey; i++)
    grey = b->f[3 * i] == b->f[3 * i + 1] && b->f[3 * i] == b->f[3 * i + 2];
  s->grey = grey;
  for (size_t i = 0; i < ne; i++) {
    const float *e = b->f + 3 * i;
    s->lum[i] = grey ? e[0] : (float)(0.2126 * e[0] + 0.7152 * e[1] + 0.0722 * e[2]);
  }
  for (int a = 0; a < nt; a++) {
    double sa = sin(a * b->d_theta);
    s->xg[a] = a == nt - 1 ? 1.0f : (float)(sa * sa);
  }
  for (int a = 0; a < na; a++) s->dx[a] = s->xg[a + 1] - s->xg[a];
  for (int c = 0; c < np; c++) {
    s->cs_phi[2 * c] = (float)cos(c * b->d_phi);
    s->cs_phi[2 * c + 1] = (float)sin(c * b->d_phi);
  }
  for (int a = 0; a < nt; a++) {
    s->cs_th[2 * a] = (float)cos(a * b->d_theta);
    s->cs_th[2 * a + 1] = (float)sin(a * b->d_theta);
  }
  /* cumulative sums in double, stored in float: rounding a non-decreasing
   * sequence keeps it non-decreasing, which the inversion needs */
  for (size_t r = 0; r < (size_t)nt * nt; r++) {
    const float *y = s->lum + r * np;
    float *c = s->ccum + r * np;
    double acc = 0;
    c[0] = 0;
    for (int j = 0; j < np - 1; j++) {
      acc += b->d_phi * 0.5 * ((double)y[j] + y[j + 1]);
      c[j + 1] = (float)acc;
    }
  }
  for (int k = 0; k < nt; k++) {
    float *m = s->mcum + (size_t)k * nt;
    const float *c = s->ccum + (size_t)k * nt * np;
    double acc = 0;
    m[0] = 0;
    for (int a = 0; a < na; a++) {
      acc += (double)s->dx[a] * 0.5 * ((double)c[(size_t)a * np + np - 1] + c[(size_t)(a + 1) * np + np - 1]);
      m[a + 1] = (float)acc;
    }
  }
  for (int k = 0; k < nt; k++)
    build_guide(s->mcum + (size_t)k * nt, na, s->mguide + (size_t)k * (CV_BRDF_GUIDE + 1));
  for (size_t r = 0; r < (size_t)nt * nt; r++)
    build_guide(s->ccum + r * np, np - 1, s->cguide + r * (CV_BRDF_GUIDE + 1));
  *out = s;
  return CV_OK;
}

/* The mixed tables of view bins (k, t): rows k and k + 1 with weights
 * w0 = 1 - t and w1 = t, always both (an exact 0 * x when t = 0), and one
 * expression per quantity so that the search and the density read the
 * same float values. */
typedef struct view_rows {
  const float *m0, *m1;              /* mcum of slices k, k+1 */
  float w0, w1;
} view_rows;

static inline float mix_m(const view_rows *v, int a) { return v->w0 * v->m0[a] + v->w1 * v->m1[a]; }

/* Four grid rows (slice k, k+1) x (theta row a, a+1) with weights: the row
 * interpolated at s within cell a and mixed over the view. */
typedef struct quad_rows {
  const float *r00, *r01, *r10, *r11; /* [slice][row] */
  float q00, q01, q10, q11;           /* w0 (1-s), w0 s, w1 (1-s), w1 s */
} quad_rows;

static inline float mix_q(const quad_rows *q, int j) {
  return (q->q00 * q->r00[j] + q->q10 * q->r10[j]) + (q->q01 * q->r01[j] + q->q11 * q->r11[j]);
}

/* Largest i in [0, n - 1] with cdf(i) <= x, for a non-decreasing mixed
 * cdf with cdf(0) <= x, starting from the bracket [guide[gi], guide[gi+1]]
 * of the nearest stored row (v = x / total in [0, 1)): a branch-free binary
 * search inside it, then a walk for where the mixture leaves it (rare:
 * the mixed rows are close to the nearest one). */
#define GUIDED_SEARCH(name, type, mix)                                                    \
  static inline int name(const type *q, int n, float x, const uint16_t *guide, float v) { \
    int gi = (int)(v * CV_BRDF_GUIDE);                                                     \
    gi = gi < 0 ? 0 : (gi > CV_BRDF_GUIDE - 1 ? CV_BRDF_GUIDE - 1 : gi);                   \
    int lo = guide[gi], len = guide[gi + 1] - lo + 1;                                      \
    while (len > 1) {                                                                      \
      int half = len >> 1;                                                                 \
      lo = mix(q, lo + half) <= x ? lo + half : lo;                                        \
      len -= half;                                                                         \
    }                                                                                      \
    while (lo > 0 && mix(q, lo) > x) lo--;                                                 \
    while (lo < n - 1 && mix(q, lo + 1) <= x) lo++;                                        \
    return lo;                                                                             \
  }
GUIDED_SEARCH(search_m, view_rows, mix_m)
GUIDED_SEARCH(search_q, quad_rows, mix_q)

/* Inverse CDF on [0, 1] of the linear density (1 - s) ga + s gb (ga, gb >= 0,
 * not both 0) at xi in [0, 1]: s = xi (ga + gb) / (ga + sqrt((1 - xi) ga^2 +
 * xi gb^2)), the cancellation-free root of ga s + (gb - ga) s^2 / 2 =
 * xi (ga + gb) / 2. */
static inline float lin_inv(float xi, float ga, float gb) {
  float d = ga + sqrtf((1 - xi) * ga * ga + xi * gb * gb);
  float s = d > 0 ? xi * (ga + gb) / d : xi;
  return s < 0 ? 0 : (s > 1 ? 1 : s);
}

static inline void setup_view(const cv_brdf_sampler *s, int k, float t, view_rows *v) {
  v->m0 = s->mcum + (size_t)k * s->nt;
  v->m1 = v->m0 + s->nt;
  v->w0 = 1 - t;
  v->w1 = t;
}

static inline void setup_quad(const cv_brdf_sampler *s, const float *base, int k, int a,
                              float w0, float w1, float sx, quad_rows *q) {
  const size_t np = (size_t)s->np, slice = (size_t)s->nt * np;
  q->r00 = base + (size_t)k * slice + (size_t)a * np;
  q->r01 = q->r00 + np;
  q->r10 = q->r00 + slice;
  q->r11 = q->r10 + np;
  q->q00 = w0 * (1 - sx);
  q->q01 = w0 * sx;
  q->q10 = w1 * (1 - sx);
  q->q11 = w1 * sx;
}

/* Density from the float steps (see brdf_sample.h): in (x, phi_i),
 *   p = [dM / (M dx_a)] [Ctot / ((S_a + S_a+1)/2)] [dC_b / Ctot]
 *       [g / (((g_b + g_b+1)/2) dphi)] / 2,
 * and p(w) = 2 cos(theta) p; Ctot cancels. */
static inline float density(float cos_i, float dM, float M, float dx, float Ssum, float dC,
                            float gsum, float g, float dphi) {
  float den = M * dx * Ssum * gsum * dphi;
  return den > 0 ? 4 * cos_i * dM * dC * g / den : 0.0f;
}

int cv_brdf_sample(const cv_brdf_sampler *s, int k, float t, const float u[2], float wi[3],
                   float *theta_i, float *phi_d, float *pdf, float f_rgb[3]) {
  const int nt = s->nt, np = s->np, na = nt - 1, nb = np - 1;
  view_rows v;
  setup_view(s, k, t, &v);
  const float M = mix_m(&v, na);
  if (!(M > 0)) return 0;
  /* theta_i: the cell, then x within it */
  float x0 = u[0] * M;
  if (x0 >= M) x0 = nextafterf(M, 0);
  const int kd = t < 0.5f ? k : k + 1; /* the nearest stored slice guides the searches */
  const int a = search_m(&v, na, x0, s->mguide + (size_t)kd * (CV_BRDF_GUIDE + 1), u[0]);
  const float Ma = mix_m(&v, a), dM = mix_m(&v, a + 1) - Ma;
  if (!(dM > 0)) return 0;
  float xi = (x0 - Ma) / dM;
  xi = xi < 0 ? 0 : (xi > 1 ? 1 : xi);
  const size_t np_ = (size_t)np, slice = (size_t)nt * np_;
  const float *c0 = s->ccum + (size_t)k * slice + (size_t)a * np_ + nb;
  const float Sa = v.w0 * c0[0] + v.w1 * c0[slice], Sb = v.w0 * c0[np_] + v.w1 * c0[slice + np_];
  const float sx = lin_inv(xi, Sa, Sb);
  const float x = s->xg[a] + sx * s->dx[a];
  /* phi_d along the row interpolated at sx */
  quad_rows qc, ql;
  setup_quad(s, s->ccum, k, a, v.w0, v.w1, sx, &qc);
  const float Ctot = mix_q(&qc, nb);
  if (!(Ctot > 0)) return 0;
  const float side = u[1] < 0.5f ? -1.0f : 1.0f;
  const float vv = u[1] < 0.5f ? 2 * u[1] : 2 - 2 * u[1];
  float x1 = vv * Ctot;
  if (x1 >= Ctot) x1 = nextafterf(Ctot, 0);
  const int ad = sx < 0.5f ? a : a + 1;
  const int b = search_q(&qc, nb, x1, s->cguide + ((size_t)kd * nt + (size_t)ad) * (CV_BRDF_GUIDE + 1), vv);
  const float Cb = mix_q(&qc, b), dC = mix_q(&qc, b + 1) - Cb;
  if (!(dC > 0)) return 0;
  float xi2 = (x1 - Cb) / dC;
  xi2 = xi2 < 0 ? 0 : (xi2 > 1 ? 1 : xi2);
  setup_quad(s, s->lum, k, a, v.w0, v.w1, sx, &ql);
  const float gb = mix_q(&ql, b), gb1 = mix_q(&ql, b + 1);
  const float r = lin_inv(xi2, gb, gb1);
  const float g = (1 - r) * gb + r * gb1;
  /* direction: sin^2 = x exactly; phi = phi_b + e by angle addition with
   * short series for e < one step (|error| < 1e-9 at 1 degree) */
  const float st = sqrtf(x), ct = sqrtf(1 - x);
  const float e = r * s->dp, e2 = e * e;
  const float ce = 1 - e2 * (0.5f - e2 * (1.0f / 24)), se = e * (1 - e2 * (1.0f / 6));
  const float *cp = s->cs_phi + 2 * b;
  wi[0] = st * (cp[0] * ce - cp[1] * se);
  wi[1] = side * st * (cp[1] * ce + cp[0] * se);
  wi[2] = ct;
  /* theta = theta_a + d with sin d = sin(theta - theta_a) < one step:
   * asin by its series (|error| < 2e-10 rad at 1 degree), no atan2 */
  const float *ca = s->cs_th + 2 * a;
  const float y = st * ca[0] - ct * ca[1];
  float fi = y * (1 + y * y * (1.0f / 6)) * s->inv_dt;
  fi = fi < 0 ? 0 : (fi > 1 ? 1 : fi);
  const float th = ((float)a + fi) / s->inv_dt, ph = ((float)b + r) * s->dp;
  *theta_i = th;
  *phi_d = ph;
  const float p = density(ct, dM, M, s->dx[a], Sa + Sb, dC, gb + gb1, g, s->dp);
  *pdf = p;
  if (f_rgb) {
    if (s->grey) {
      /* the trilinear f from the corners just read (theta fraction fi) */
      quad_rows qf = ql;
      qf.q00 = v.w0 * (1 - fi), qf.q01 = v.w0 * fi, qf.q10 = v.w1 * (1 - fi), qf.q11 = v.w1 * fi;
      f_rgb[0] = f_rgb[1] = f_rgb[2] = (1 - r) * mix_q(&qf, b) + r * mix_q(&qf, b + 1);
    } else {
      cv_brdf_eval_bins(s, k, t, th, ph, f_rgb);
    }
  }
  return p > 0;
}

float cv_brdf_pdf_cs(const cv_brdf_sampler *s, int k, float t, float cos_i, float sin2_i,
                     float theta_i, float phi_d) {
  if (!(cos_i > 0)) return 0;
  const int nt = s->nt, np = s->np, na = nt - 1, nb = np - 1;
  view_rows v;
  setup_view(s, k, t, &v);
  const float M = mix_m(&v, na);
  if (!(M > 0)) return 0;
  int a = (int)(theta_i * s->inv_dt);
  if (a < 0) a = 0;
  if (a > na - 1) a = na - 1;
  float sx = (sin2_i - s->xg[a]) / s->dx[a];
  sx = sx < 0 ? 0 : (sx > 1 ? 1 : sx);
  float xp = phi_d * s->inv_dp;
  if (!(xp > 0)) xp = 0;
  int b = (int)xp;
  if (b > nb - 1) b = nb - 1;
  float r = xp - (float)b;
  r = r > 1 ? 1 : r;
  const float dM = mix_m(&v, a + 1) - mix_m(&v, a);
  const size_t np_ = (size_t)np, slice = (size_t)nt * np_;
  const float *c0 = s->ccum + (size_t)k * slice + (size_t)a * np_ + nb;
  const float Sa = v.w0 * c0[0] + v.w1 * c0[slice], Sb = v.w0 * c0[np_] + v.w1 * c0[slice + np_];
  quad_rows qc, ql;
  setup_quad(s, s->ccum, k, a, v.w0, v.w1, sx, &qc);
  setup_quad(s, s->lum, k, a, v.w0, v.w1, sx, &ql);
  const float dC = mix_q(&qc, b + 1) - mix_q(&qc, b);
  const float gb = mix_q(&ql, b), gb1 = mix_q(&ql, b + 1);
  const float g = (1 - r) * gb + r * gb1;
  return density(cos_i, dM, M, s->dx[a], Sa + Sb, dC, gb + gb1, g, s->dp);
}
