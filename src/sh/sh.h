/* Real spherical harmonics (SH): basis evaluation, projection of lat-long
 * environment maps and analytic functions, rotation, clamped-cosine
 * convolution and windowing.  The PRT bake evaluates the basis once per ray;
 * the relighting side projects, rotates and windows lighting.
 *
 * Basis.  Real, orthonormal on the unit sphere (integral of y_i y_j over the
 * sphere = delta_ij), WITHOUT the Condon-Shortley phase, polar axis +Z:
 *   y_lm = sqrt(2) K_lm P_l^m(cos th) cos(m ph)     m > 0
 *   y_l0 =         K_l0 P_l^0(cos th)
 *   y_lm = sqrt(2) K_l|m| P_l^|m|(cos th) sin(|m| ph)  m < 0
 * with th = acos(d.z), ph = atan2(d.y, d.x), K_lm = sqrt((2l+1)/(4 pi)
 * (l-m)!/(l+m)!) and P_l^m >= 0 near the pole.  So band 1 is
 * sqrt(3/(4 pi)) * (d.y, d.z, d.x) for m = -1, 0, 1 (the real harmonics of
 * Ivanic & Ruedenberg 1996, whose rotation recurrence is used below).
 * Indexing is Sloan's: i = l*l + l + m; "n bands" means l = 0..n-1, n*n
 * coefficients, n in 1..CV_SH_MAX_BANDS (the project uses 2..8).
 * The polar axis is the basis's own +Z; nothing here depends on the world's
 * +Y-up convention except the lat-long mapping (sh/latlong.h).
 *
 * Coefficient layout.  Multi-channel expansions are interleaved per
 * coefficient: c[nchan*i + ch]; lighting is RGB, nchan = 3. */
#ifndef CV_SH_SH_H
#define CV_SH_SH_H

#include "core/image.h"

#define CV_SH_MAX_BANDS 8
#define CV_SH_MAX_COEFFS (CV_SH_MAX_BANDS * CV_SH_MAX_BANDS)

/* Coefficient index of (l, m), |m| <= l. */
static inline int cv_sh_index(int l, int m) { return l * l + l + m; }

/* Basis values y[0..n*n-1] at unit direction d, in float.  The hot path of
 * the bake: Cartesian recurrence (no trigonometry), unrolled per n.  d must
 * be unit length (the polynomials are exact only on the sphere).  Does
 * nothing for n outside 1..CV_SH_MAX_BANDS.  Max error against the double
 * version is a few float ulps of the largest basis value (tested). */
void cv_sh_eval(int n, const float d[3], float *y);

/* The same in double. */
void cv_sh_eval_d(int n, const double d[3], double *y);

/* Sum of an expansion at unit direction d: out[ch] = sum_i c[nchan*i+ch] y_i(d),
 * ch < nchan.  n in 1..CV_SH_MAX_BANDS (else out is zeroed). */
void cv_sh_eval_sum(int n, const double *coeffs, int nchan, const double d[3],
                    double *out);

/* Projects a lat-long map (sh/latlong.h) onto n bands:
 *   c[3*i+ch] = sum over pixels of L_ch(pixel) * y_i(d_centre) * dOmega_pixel
 * with the exact per-row pixel solid angle, so a constant map projects to
 * c_0 = L sqrt(4 pi) to rounding.  env has 1 channel (grey, replicated to RGB)
 * or 3-4 channels (the first three are RGB).  Sums are in double, one partial
 * sum per row, added in row order: the result does not depend on the number
 * of OpenMP threads.  coeffs (3*n*n doubles, caller's) is written.
 * Errors: CV_ERR_INVALID (n out of range, NULL, 2 channels),
 * CV_ERR_NONFINITE (a NaN/Inf pixel: coeffs zeroed), CV_ERR_NOMEM. */
int cv_sh_project_latlong(const cv_image *env, int n, double *coeffs);

/* An RGB function on the sphere, for cv_sh_project_fn: writes f(d) to rgb. */
typedef void (*cv_sh_fn)(const double d[3], void *user, double rgb[3]);

/* Projects f onto n bands by Gauss-Legendre quadrature in cos(th) (th from
 * +Z) with samples_theta nodes times 2*samples_theta uniform azimuths: exact
 * for any band-limited f of degree < samples_theta (products y_i y_j need
 * samples_theta >= n).  Smooth f converge spectrally.  coeffs = 3*n*n doubles.
 * Errors: CV_ERR_INVALID (n out of range, samples_theta < 1 or > 4096, NULL),
 * CV_ERR_NONFINITE (f returned NaN/Inf: coeffs zeroed), CV_ERR_NOMEM. */
int cv_sh_project_fn(int n, int samples_theta, cv_sh_fn f, void *user, double *coeffs);

/* Gauss-Legendre nodes x[k] (ascending) and weights w[k] on [-1, 1], k < count
 * (Newton on P_count, double accuracy).  Returns CV_ERR_INVALID for count < 1. */
int cv_gauss_legendre(int count, double *x, double *w);

/* SH rotation for n bands, built once per rotation matrix (opaque). */
typedef struct cv_sh_rotation cv_sh_rotation;

/* Builds the per-band rotation matrices for the 3x3 rotation R (row-major,
 * R[3*row+col], applied to column vectors: d' = R d) by the recurrence of
 * Ivanic & Ruedenberg, J. Phys. Chem. 100 (1996) 6342, with the corrections
 * of J. Phys. Chem. A 102 (1998) 9099.  Convention: if f'(d) = f(R^T d) (f
 * carried along by R: what was seen in direction a is now seen in R a), then
 * coeffs(f') = cv_sh_rotate(rotation(R), coeffs(f)).  Rotations compose as
 * rotation(R1 R2) = rotation(R1) after rotation(R2).  *out is owned by the
 * caller (cv_sh_rotation_destroy).  Errors: CV_ERR_INVALID (n out of range,
 * R not finite, not orthonormal to 1e-6 or a reflection), CV_ERR_NOMEM. */
int cv_sh_rotation_create(int n, const double R[9], cv_sh_rotation **out);
void cv_sh_rotation_destroy(cv_sh_rotation *rot);

/* Number of bands of a rotation. */
int cv_sh_rotation_bands(const cv_sh_rotation *rot);

/* Matrix of band l (l < bands): (2l+1)^2 doubles, row-major, row and column
 * index m + l; out_band = M in_band.  Owned by rot. */
const double *cv_sh_rotation_band(const cv_sh_rotation *rot, int l);

/* out = rotation applied to in, both n*n*nchan interleaved (c[nchan*i+ch]),
 * n = cv_sh_rotation_bands(rot).  in == out is allowed. */
void cv_sh_rotate(const cv_sh_rotation *rot, const double *in, double *out, int nchan);

/* Band factor A_l of the clamped cosine max(cos, 0) (Ramamoorthi & Hanrahan,
 * "An Efficient Representation for Irradiance Environment Maps", 2001): irradiance E_lm = A_l L_lm.  A_0 = pi, A_1 = 2 pi/3, odd
 * l > 1: 0, even l: 2 pi (-1)^(l/2-1) / ((l+2)(l-1)) * l! / (2^l ((l/2)!)^2)
 * (A_2 = pi/4, A_4 = -pi/24, A_6 = pi/64).  Equivalently, the lobe
 * max(d.a, 0) about unit axis a has coefficients A_l y_lm(a).  0 for l < 0. */
double cv_sh_cosine_lobe_factor(int l);

/* Turns radiance coefficients into irradiance coefficients in place:
 * multiplies band l by A_l (n bands, nchan interleaved channels). */
void cv_sh_convolve_cosine(int n, double *coeffs, int nchan);

typedef enum cv_sh_window_kind {
  CV_SH_WINDOW_NONE = 0,
  CV_SH_WINDOW_HANN,    /* w_l = (1 + cos(pi l / n)) / 2 */
  CV_SH_WINDOW_LANCZOS, /* w_l = sinc(l / n) = sin(pi l/n) / (pi l/n), w_0 = 1 */
} cv_sh_window_kind;

/* Window weight of band l for an n-band expansion (1 for NONE or l = 0). */
double cv_sh_window_weight(int n, int l, cv_sh_window_kind kind);

/* Multiplies band l of coeffs (n bands, nchan channels) by its window weight:
 * trades ringing (negative lobes around bright, compact light) for blur.
 * The weights equal 1 at l = 0, so the mean (and total energy) is kept. */
void cv_sh_window(int n, double *coeffs, int nchan, cv_sh_window_kind kind);

#endif
