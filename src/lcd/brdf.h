/* Tabulated isotropic BRDFs for the LCD panel (Dmitriev et al. 2004,
 * section 4.3: "the measured data resolution is up to one degree and we use
 * the bilinear interpolation to derive intermediate values").
 *
 * A cv_brdf holds f(theta_i, theta_o, phi_d) in 1/sr, RGB, on a regular grid
 * of n_theta points over [0, 90] degrees for both polar angles and n_phi
 * points over [0, 180] degrees for the azimuth difference
 * phi_d = |phi_i - phi_o| folded into [0, pi] (isotropy: f depends only on
 * |phi_i - phi_o|).  phi_d = 180 degrees is the mirror side, 0 the
 * retro-reflection side.  The default grid is 1 degree: 91 x 91 x 181.
 * Values between grid points are interpolated linearly in each of the three
 * angles (bilinear in (theta_i, phi_d) on each theta_o slice, linear between
 * slices).  "o" is the viewing (eye) direction, "i" the direction light
 * arrives from; storage is theta_o slowest, so the slice for one view
 * direction is contiguous.
 *
 * Three sources (cv_brdf_load picks by content or name):
 *   - the project's table file (docs/brdf-format.md, magic "CAVEBRDF");
 *   - the MERL binary format (Matusik et al. 2003): three int32 (90, 90,
 *     180), then R, G, B planes of 90*90*180 doubles over (theta_half,
 *     theta_diff, phi_diff), scaled by 1/1500, 1.15/1500, 1.66/1500;
 *     negative values mark missing samples.  It is resampled (nearest
 *     MERL cell, as MERL's reference code looks up) onto the 1-degree grid;
 *   - "builtin:antiglare": an anti-glare LCD surface after Kelley, Jones &
 *     Germer (NIST 1998), specular + haze + Lambertian, tabulated at 1 degree.
 *
 * Validation on load: NaN/Inf are rejected naming the file and the entry;
 * negative entries of a table file are rejected (f >= 0); the directional
 * albedo rho(theta) = integral f cos(theta_i) dw_i is computed for every
 * grid theta and values above 1 are reported (cv_brdf_report), not fatal. */
#ifndef CV_LCD_BRDF_H
#define CV_LCD_BRDF_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"

#define CV_BRDF_MAGIC "CAVEBRDF"
#define CV_BRDF_VERSION 1
#define CV_BRDF_BUILTIN_ANTIGLARE "builtin:antiglare"

typedef struct cv_brdf {
  int n_theta;   /* grid points of theta_i and theta_o over [0, pi/2] (>= 2) */
  int n_phi;     /* grid points of phi_d over [0, pi] (>= 2) */
  double d_theta, d_phi; /* grid steps, radians */
  float *f;      /* [theta_o][theta_i][phi_d][3], 1/sr, >= 0, finite; owned */
  uint64_t hash; /* FNV-1a of the grid sizes and values (for cache keys) */
  char source[256]; /* file name or builtin name, for messages */
} cv_brdf;

/* What validation found. */
typedef struct cv_brdf_report {
  double albedo_max;        /* max over grid theta_o and channels of rho */
  double albedo_max_deg;    /* theta_o (degrees) where it occurs */
  int albedo_violations;    /* grid theta_o values where rho > 1 + 1e-3 in any channel */
  double first_violation_deg; /* the smallest such theta_o, or -1 */
  uint64_t merl_missing;    /* MERL: negative (missing) entries, read as 0 */
  uint64_t merl_missing_used; /* MERL: grid points of the table that fell on one */
} cv_brdf_report;

/* Allocates a zeroed table (*out owned by the caller, cv_brdf_destroy).
 * Errors: CV_ERR_RANGE (n_theta < 2 or > 1801, n_phi < 2 or > 3601),
 * CV_ERR_NOMEM. */
int cv_brdf_alloc(int n_theta, int n_phi, cv_brdf **out);
void cv_brdf_destroy(cv_brdf *b);

/* Pointer to the RGB entry of grid point (theta_o index, theta_i index,
 * phi index); no bounds check. */
static inline float *cv_brdf_at(const cv_brdf *b, int io, int ii, int ip) {
  return b->f + (((size_t)io * (size_t)b->n_theta + (size_t)ii) * (size_t)b->n_phi + (size_t)ip) * 3;
}

/* f at angles in radians (theta in [0, pi/2], phi_d in [0, pi]; values
 * outside are clamped), trilinear between grid points. */
void cv_brdf_eval(const cv_brdf *b, double theta_i, double theta_o, double phi_d, float rgb[3]);

/* Recomputes b->hash after the values were changed in place. */
void cv_brdf_rehash(cv_brdf *b);

/* Exact integral of the interpolated f cos(theta_i) over theta_i cell a
 * (both ends [a, a+1] grid steps) and one phi_d step, for the cell's corner
 * values: f00, f01 at theta_a (phi_b, phi_b+1), f10, f11 at theta_a+1:
 *   d_phi * (wa * (f00 + f01) / 2 + wb * (f10 + f11) / 2),
 * with wa, wb the integrals of (1 - s) and s times cos(theta) sin(theta)
 * d theta over the cell (s = (theta - theta_a) / d_theta). */
void cv_brdf_cell_weights(double d_theta, int a, double *wa, double *wb);

/* Checks values and computes the directional albedo (the exact integral of
 * the interpolated table, cell by cell with cv_brdf_cell_weights, both
 * azimuth sides).  Errors
 * (err: "<source>: entry theta_o=.. theta_i=.. phi_d=.. deg channel G is
 * NaN"): CV_ERR_NONFINITE, CV_ERR_RANGE (negative).  rep may be NULL.
 * albedo_rgb (may be NULL) receives 3*n_theta values, rho per grid theta_o. */
int cv_brdf_validate(const cv_brdf *b, cv_brdf_report *rep, double *albedo_rgb, cv_err *err);

/* Reads the project's table format, a MERL binary, or the built-in name
 * CV_BRDF_BUILTIN_ANTIGLARE (default parameters), then validates.  *out
 * owned by the caller; rep may be NULL.  Errors name the file: CV_ERR_IO
 * (cannot open/read), CV_ERR_FORMAT (neither format, wrong sizes, version,
 * truncated or trailing bytes), CV_ERR_NONFINITE / CV_ERR_RANGE (the entry),
 * CV_ERR_NOMEM. */
int cv_brdf_load(const char *path, cv_brdf **out, cv_brdf_report *rep, cv_err *err);

/* Writes the table format (temp file + rename).  err names the path. */
int cv_brdf_write(const char *path, const cv_brdf *b, cv_err *err);

/* Reads a MERL binary and resamples it onto an n_theta x n_phi grid (91 x
 * 181 for 1 degree).  Missing (negative) MERL samples read as 0 and are
 * counted in rep.  Errors as cv_brdf_load. */
int cv_brdf_load_merl(const char *path, int n_theta, int n_phi, cv_brdf **out,
                      cv_brdf_report *rep, cv_err *err);

/* MERL's own lookup: RGB f (1/sr) for directions given by polar and
 * azimuth angles (radians), nearest MERL cell; raw = the 3*90*90*180
 * doubles of the file.  A negative (missing) sample returns negative values. */
void cv_brdf_merl_lookup(const double *raw, double theta_in, double phi_in, double theta_out,
                         double phi_out, double rgb[3]);
/* Index into one MERL plane for a direction pair (exposed for tests). */
size_t cv_brdf_merl_index(double theta_in, double phi_in, double theta_out, double phi_out);

/* Anti-glare display surface after Kelley, Jones & Germer (1998): a
 * Lambertian part plus a narrow "specular" and a wider "haze" lobe about the
 * mirror direction, each a normalised Gaussian in the angle alpha between
 * w_i and the mirror of w_o:
 *   f = rd/pi + (rs g(alpha; sigma_s) + rh g(alpha; sigma_h)) * 2 / (cos_i + cos_o)
 *   g(alpha; s) = exp(-alpha^2 / (2 s^2)) / (2 pi s^2)
 * so each lobe reflects about its r (rs, rh) away from grazing; the
 * symmetric 2/(cos_i + cos_o) keeps f reciprocal.  Grey (same in R, G, B). */
typedef struct cv_antiglare_params {
  double rd;           /* Lambertian reflectance (default 0.008) */
  double rs;           /* specular lobe reflectance (default 0.01) */
  double sigma_s_deg;  /* its width (default 1.0) */
  double rh;           /* haze lobe reflectance (default 0.04) */
  double sigma_h_deg;  /* its width (default 6.0) */
} cv_antiglare_params;

void cv_antiglare_default(cv_antiglare_params *p);
/* Tabulates the model (*out owned by the caller).  Errors: CV_ERR_RANGE
 * (negative reflectance, width not in (0, 90], grid sizes), CV_ERR_NOMEM. */
int cv_brdf_antiglare(const cv_antiglare_params *p, int n_theta, int n_phi, cv_brdf **out);

#endif
