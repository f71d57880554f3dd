/* Analytic clear-sky daylight: Preetham, Shirley & Smits, "A Practical
 * Analytic Model for Daylight", SIGGRAPH 1999.  The sky dome is the Perez
 * distribution of luminance Y and chromaticity x, y (turbidity-dependent
 * coefficients and zenith values of the paper's Appendix A.2), converted
 * xyY -> XYZ -> linear Rec.709 RGB; the sun is a separate directional light
 * whose spectral radiance is attenuated by Rayleigh, aerosol (Angstrom),
 * ozone, mixed-gas and water-vapour transmittances (Appendix A.1 / Iqbal).
 *
 * Units: radiance in cd/m^2 in the sense that the Rec.709 luminance
 * 0.2126729 R + 0.7151522 G + 0.0721750 B of an RGB triple is its luminance
 * in cd/m^2 (the paper's zenith Y is in kcd/m^2 and is scaled by 1000).  Sun
 * irradiance is given the same way, its luminance in lux.
 *
 * Frame: world, +Y up; directions are unit vectors.
 *
 * Approximations, stated:
 * - The paper's fit covers a sun at or above the horizon.  For a sun below
 *   it (down to any depth) the sky is evaluated with the sun moved up to the
 *   horizon at the same azimuth (a crude twilight, too bright for a sun far
 *   below), and the sun light is zero.
 * - Below the horizon (d.y <= 0) the radiance is a constant ground:
 *   ground_albedo * (E_sky + E_sun) / pi per RGB channel, E being the
 *   horizontal illuminance of the sky dome (integrated numerically) and of
 *   the sun: a grey Lambertian ground, unoccluded, without the ground's own
 *   light reflected back by the sky.
 * - Colour: the CIE 1931 matching functions are the multi-lobe Gaussian fit
 *   of Wyman, Sloan & Shirley (JCGT 2(2), 2013), about 1% from the tables;
 *   the sun spectrum is sampled every 10 nm from 380 to 750 nm (the paper's
 *   table), so mixed-gas absorption (lines at 760 nm) does not enter.
 * - RGB channels that come out negative (colours outside the Rec.709 gamut,
 *   e.g. a deep red low sun) are set to 0 and counted. */
#ifndef CV_LIGHT_SKY_H
#define CV_LIGHT_SKY_H

#include "core/image.h"
#include "core/status.h"

/* Solid angle of the sun's disc used by cv_sky_sun (sr). */
#define CV_SUN_SOLID_ANGLE 6.8e-5

typedef struct cv_sky cv_sky;

/* Builds the sky for turbidity in [2, 10], unit sun direction (world, +Y up;
 * renormalised if its length is within 1e-3 of 1) and ground albedo in
 * [0, 1].  *out owned by the caller (cv_sky_destroy).  Errors (err: one line
 * naming the parameter and the expected range): CV_ERR_RANGE, CV_ERR_INVALID
 * (NULL or non-finite), CV_ERR_NOMEM. */
int cv_sky_create(double turbidity, const double sun_dir[3], double ground_albedo, cv_sky **out,
                  cv_err *err);

/* Frees the sky; accepts NULL. */
void cv_sky_destroy(cv_sky *sky);

/* Sky radiance (RGB, see units) in unit direction d, without the sun disc;
 * the constant ground radiance for d.y <= 0.  Returns the number of RGB
 * channels clamped to 0 (0 for in-gamut colours).  Non-finite or zero d
 * gives the ground radiance. */
int cv_sky_radiance(const cv_sky *sky, const double d[3], double rgb[3]);

/* The sun as a directional light: dir = the (unit) sun direction,
 * rgb_irradiance = its RGB irradiance on a surface facing it (luminance in
 * lux), solid_angle = CV_SUN_SOLID_ANGLE (divide to get the disc's radiance).
 * All zero irradiance when the sun is at or below the horizon.  Any output
 * pointer may be NULL. */
void cv_sky_sun(const cv_sky *sky, double dir[3], double rgb_irradiance[3], double *solid_angle);

/* What the model computed, for logs and tests. */
typedef struct cv_sky_info {
  double turbidity, ground_albedo;
  double sun_elevation_deg;   /* of the given direction (may be < 0) */
  double model_sun_elevation_deg; /* used by the sky dome (>= 0) */
  double zenith_xyY[3];       /* zenith chromaticity x, y and luminance Y in cd/m^2 */
  double sun_xyz[3];          /* sun XYZ illuminance at normal incidence (Y in lux) */
  double sun_rgb[3];          /* as cv_sky_sun */
  double sky_horizontal_rgb[3]; /* sky-dome illuminance on a horizontal plane */
  double sky_horizontal_lux;  /* its luminance */
  double ground_rgb[3];       /* radiance below the horizon */
  int sun_rgb_clamped;        /* channels of the sun colour clamped to 0 */
  long sky_rgb_clamped;       /* channels clamped while integrating the dome */
} cv_sky_info;

void cv_sky_get_info(const cv_sky *sky, cv_sky_info *info);

/* Perez et al. 1993 distribution F(theta, gamma) = (1 + A e^(B / cos theta))
 * (1 + C e^(D gamma) + E cos^2 gamma) for coefficients c[5] = A..E;
 * theta from the zenith, gamma from the sun, radians, cos theta > 0.
 * Exposed for tests. */
double cv_perez(const double c[5], double theta, double gamma);

/* Renders the sky (without the sun disc) into a new w x h x 3 lat-long
 * image (sh/latlong.h layout), one sample at each pixel centre.  *out owned
 * by the caller (cv_image_destroy); n_clamped (may be NULL) receives the
 * number of channels clamped to 0.  Errors: CV_ERR_INVALID (w < 1, h < 2,
 * NULL), CV_ERR_NOMEM. */
int cv_sky_to_latlong(const cv_sky *sky, int w, int h, cv_image **out, long *n_clamped);

#endif
