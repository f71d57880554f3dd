/* Preetham, Shirley & Smits 1999 analytic sky and sun (see sky.h). */
#include "light/sky.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sh/latlong.h"
#include "sh/sh.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

struct cv_sky {
  double turbidity, albedo;
  double sun_dir[3];   /* as given (normalised) */
  double model_sun[3]; /* elevation clamped to >= 0: what the dome uses */
  double theta_s;      /* zenith angle of model_sun */
  double perez_Y[5], perez_x[5], perez_y[5];
  double zenith_Y, zenith_x, zenith_y; /* Y in cd/m^2 */
  double norm_Y, norm_x, norm_y;       /* F(0, theta_s) */
  double sun_rgb[3], sun_xyz[3];
  int sun_clamped;
  double sky_h_rgb[3];
  long sky_clamped;
  double ground[3];
};

/* XYZ -> linear Rec.709 (sRGB primaries, D65 white), IEC 61966-2-1. */
static const double kXYZtoRGB[9] = {3.2404542, -1.5371385, -0.4985314,
                                    -0.9692660, 1.8760108,  0.0415560,
                                    0.0556434,  -0.2040259, 1.0572252};
/* Y row of its inverse: luminance of linear Rec.709 RGB. */
static double rgb_luminance(const double rgb[3]) {
  return 0.2126729 * rgb[0] + 0.7151522 * rgb[1] + 0.0721750 * rgb[2];
}

static int xyz_to_rgb(const double xyz[3], double rgb[3]) {
  int clamped = 0;
  for (int i = 0; i < 3; i++) {
    const double v = kXYZtoRGB[3 * i] * xyz[0] + kXYZtoRGB[3 * i + 1] * xyz[1] +
                     kXYZtoRGB[3 * i + 2] * xyz[2];
    if (v < 0.0 || !isfinite(v)) {
      rgb[i] = 0.0;
      clamped++;
    } else {
      rgb[i] = v;
    }
  }
  return clamped;
}

double cv_perez(const double c[5], double theta, double gamma) {
  const double cg = cos(gamma);
  return (1.0 + c[0] * exp(c[1] / cos(theta))) * (1.0 + c[2] * exp(c[3] * gamma) + c[4] * cg * cg);
}

/* ---- sky dome ------------------------------------------------------------ */

static int dome_radiance(const cv_sky *s, const double d[3], double rgb[3]) {
  /* d.y > 0 here */
  const double theta = acos(fmin(1.0, d[1]));
  double cg = d[0] * s->model_sun[0] + d[1] * s->model_sun[1] + d[2] * s->model_sun[2];
  cg = fmax(-1.0, fmin(1.0, cg));
  const double gamma = acos(cg);
  const double Y = s->zenith_Y * cv_perez(s->perez_Y, theta, gamma) / s->norm_Y;
  const double x = s->zenith_x * cv_perez(s->perez_x, theta, gamma) / s->norm_x;
  const double y = s->zenith_y * cv_perez(s->perez_y, theta, gamma) / s->norm_y;
  if (!(y > 0.0) || !isfinite(Y) || !isfinite(x)) {
    rgb[0] = rgb[1] = rgb[2] = 0.0;
    return 3;
  }
  const double xyz[3] = {x / y * Y, Y, (1.0 - x - y) / y * Y};
  return xyz_to_rgb(xyz, rgb);
}

int cv_sky_radiance(const cv_sky *sky, const double d[3], double rgb[3]) {
  const double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  if (!(len > 0.0) || !isfinite(len) || d[1] <= 0.0) {
    memcpy(rgb, sky->ground, sizeof(double) * 3);
    return 0;
  }
  const double u[3] = {d[0] / len, d[1] / len, d[2] / len};
  return dome_radiance(sky, u, rgb);
}

/* ---- sun (Preetham et al. Appendix A.1; Iqbal, "An Introduction to Solar
 * Radiation", 1983) -------------------------------------------------------- */

/* Extraterrestrial solar spectral radiance, W / (m^2 sr nm), 380..750 nm in
 * 10 nm steps (the paper's table, as in its sample code). */
static const double kSunSpectrum[38] = {
    16559.0, 16233.7, 21127.5, 25888.2, 25829.1, 24232.3, 26760.5, 29658.3,
    30545.4, 30057.5, 30663.7, 28830.4, 28712.1, 27825.0, 27100.6, 27233.6,
    26361.3, 25503.8, 25060.2, 25311.6, 25355.9, 25134.2, 24631.5, 24173.2,
    23685.3, 23212.1, 22827.7, 22339.8, 21970.2, 21526.7, 21097.9, 20728.3,
    20240.4, 19870.8, 19427.2, 19072.4, 18628.9, 18259.2};

/* Ozone absorption coefficient k_o (1/cm), Iqbal p. 127. */
static const double kOzoneWl[] = {300, 305, 310, 315, 320, 325, 330, 335, 340, 345, 350, 355,
                                  445, 450, 455, 460, 465, 470, 475, 480, 485, 490, 495,
                                  500, 505, 510, 515, 520, 525, 530, 535, 540, 545, 550,
                                  555, 560, 565, 570, 575, 580, 585, 590, 595, 600, 605,
                                  610, 620, 630, 640, 650, 660, 670, 680, 690, 700, 710,
                                  720, 730, 740, 750, 760, 770, 780, 790};
static const double kOzoneK[] = {10.0, 4.8,  2.7,  1.35, .8,   .380, .160, .075, .04,  .019, .007,
                                 .0,   .003, .003, .004, .006, .008, .009, .012, .014, .017, .021,
                                 .025, .03,  .035, .04,  .045, .048, .057, .063, .07,  .075, .08,
                                 .085, .095, .103, .110, .12,  .122, .12,  .118, .115, .12,  .125,
                                 .130, .12,  .105, .09,  .079, .067, .057, .048, .036, .028, .023,
                                 .018, .014, .011, .010, .009, .007, .004, .0,   .0};
/* Mixed gases k_g and water vapour k_wa (1/km and 1/cm), Iqbal p. 130. */
static const double kGasWl[] = {759, 760, 770, 771};
static const double kGasK[] = {0.0, 3.0, 0.210, 0.0};
static const double kWaterWl[] = {689, 690, 700, 710, 720, 730, 740, 750, 760, 770, 780, 790, 800};
static const double kWaterK[] = {0,      0.160e-1, 0.240e-1, 0.125e-1, 0.100e+1, 0.870, 0.610e-1,
                                 0.100e-2, 0.100e-4, 0.100e-4, 0.600e-3, 0.175e-1, 0.360e-1};

/* Piecewise-linear table lookup, 0 outside. */
static double table(const double *wl, const double *k, int n, double lambda) {
  if (lambda < wl[0] || lambda > wl[n - 1]) return 0.0;
  for (int i = 1; i < n; i++)
    if (lambda <= wl[i]) {
      const double t = (lambda - wl[i - 1]) / (wl[i] - wl[i - 1]);
      return k[i - 1] + t * (k[i] - k[i - 1]);
    }
  return 0.0;
}

/* Piecewise Gaussian of the Wyman-Sloan-Shirley CMF fit. */
static double g2(double x, double mu, double s1, double s2) {
  const double t = (x - mu) / (x < mu ? s1 : s2);
  return exp(-0.5 * t * t);
}
static void cie_cmf(double l, double xyz[3]) {
  xyz[0] = 1.056 * g2(l, 599.8, 37.9, 31.0) + 0.362 * g2(l, 442.0, 16.0, 26.7) -
           0.065 * g2(l, 501.1, 20.4, 26.2);
  xyz[1] = 0.821 * g2(l, 568.8, 46.9, 40.5) + 0.286 * g2(l, 530.9, 16.3, 31.1);
  xyz[2] = 1.217 * g2(l, 437.0, 11.8, 36.0) + 0.681 * g2(l, 459.0, 26.0, 13.8);
}

/* XYZ illuminance (Y in lux) of the attenuated sun at normal incidence for
 * sun zenith angle theta_s (radians, < pi/2). */
static void sun_xyz(double T, double theta_s, double out[3]) {
  const double th_deg = theta_s * 180.0 / M_PI;
  /* relative optical air mass (Kasten 1966) */
  const double m = 1.0 / (cos(theta_s) + 0.15 * pow(93.885 - th_deg, -1.253));
  const double beta = 0.04608 * T - 0.04586; /* Angstrom turbidity coefficient */
  const double alpha = 1.3, l_ozone = 0.35, w_water = 2.0;
  double acc[3] = {0.0, 0.0, 0.0};
  for (int i = 0; i < 38; i++) {
    const double lambda = 380.0 + 10.0 * i, um = lambda * 1e-3;
    const double tau_r = exp(-m * 0.008735 * pow(um, -4.08));
    const double tau_a = exp(-m * beta * pow(um, -alpha));
    const double tau_o = exp(-m * l_ozone * table(kOzoneWl, kOzoneK, 64, lambda));
    const double kg = table(kGasWl, kGasK, 4, lambda);
    const double tau_g = exp(-1.41 * kg * m / pow(1.0 + 118.93 * kg * m, 0.45));
    const double kwa = table(kWaterWl, kWaterK, 13, lambda);
    const double tau_wa =
        exp(-0.2385 * kwa * w_water * m / pow(1.0 + 20.07 * kwa * w_water * m, 0.45));
    const double L = kSunSpectrum[i] * tau_r * tau_a * tau_o * tau_g * tau_wa;
    double cmf[3];
    cie_cmf(lambda, cmf);
    for (int c = 0; c < 3; c++) acc[c] += L * cmf[c] * 10.0; /* 10 nm steps */
  }
  for (int c = 0; c < 3; c++) out[c] = 683.0 * acc[c] * CV_SUN_SOLID_ANGLE;
}

void cv_sky_sun(const cv_sky *sky, double dir[3], double rgb_irradiance[3], double *solid_angle) {
  if (dir) memcpy(dir, sky->sun_dir, sizeof(double) * 3);
  if (rgb_irradiance) memcpy(rgb_irradiance, sky->sun_rgb, sizeof(double) * 3);
  if (solid_angle) *solid_angle = CV_SUN_SOLID_ANGLE;
}

/* ---- construction --------------------------------------------------------- */

int cv_sky_create(double turbidity, const double sun_dir[3], double ground_albedo, cv_sky **out,
                  cv_err *err) {
  if (!out) return cv_err_set(err, CV_ERR_INVALID, "sky: no output pointer");
  *out = NULL;
  if (!sun_dir) return cv_err_set(err, CV_ERR_INVALID, "sky: no sun direction");
  if (!isfinite(turbidity) || turbidity < 2.0 || turbidity > 10.0)
    return cv_err_set(err, CV_ERR_RANGE, "sky: turbidity %g, expected 2..10", turbidity);
  if (!isfinite(ground_albedo) || ground_albedo < 0.0 || ground_albedo > 1.0)
    return cv_err_set(err, CV_ERR_RANGE, "sky: ground_albedo %g, expected 0..1", ground_albedo);
  const double len = sqrt(sun_dir[0] * sun_dir[0] + sun_dir[1] * sun_dir[1] + sun_dir[2] * sun_dir[2]);
  if (!isfinite(len) || fabs(len - 1.0) > 1e-3)
    return cv_err_set(err, CV_ERR_RANGE,
                      "sky: sun_dir (%g, %g, %g) has length %g, expected a unit vector",
                      sun_dir[0], sun_dir[1], sun_dir[2], len);
  cv_sky *s = calloc(1, sizeof *s);
  if (!s) return cv_err_set(err, CV_ERR_NOMEM, "sky: out of memory");
  const double T = turbidity;
  s->turbidity = T;
  s->albedo = ground_albedo;
  for (int i = 0; i < 3; i++) s->sun_dir[i] = sun_dir[i] / len;

  /* the dome's sun: the given one, lifted to the horizon if below */
  memcpy(s->model_sun, s->sun_dir, sizeof s->model_sun);
  if (s->model_sun[1] < 0.0) {
    const double h = hypot(s->model_sun[0], s->model_sun[2]);
    s->model_sun[1] = 0.0;
    if (h > 0.0) {
      s->model_sun[0] /= h;
      s->model_sun[2] /= h;
    } else { /* nadir: any azimuth */
      s->model_sun[0] = 0.0;
      s->model_sun[2] = -1.0;
    }
  }
  const double ts = acos(fmax(-1.0, fmin(1.0, s->model_sun[1])));
  s->theta_s = ts;

  /* Appendix A.2: Perez coefficients, linear in T */
  const double pY[5] = {0.1787 * T - 1.4630, -0.3554 * T + 0.4275, -0.0227 * T + 5.3251,
                        0.1206 * T - 2.5771, -0.0670 * T + 0.3703};
  const double px[5] = {-0.0193 * T - 0.2592, -0.0665 * T + 0.0008, -0.0004 * T + 0.2125,
                        -0.0641 * T - 0.8989, -0.0033 * T + 0.0452};
  const double py[5] = {-0.0167 * T - 0.2608, -0.0950 * T + 0.0092, -0.0079 * T + 0.2102,
                        -0.0441 * T - 1.6537, -0.0109 * T + 0.0529};
  memcpy(s->perez_Y, pY, sizeof pY);
  memcpy(s->perez_x, px, sizeof px);
  memcpy(s->perez_y, py, sizeof py);
  /* zenith luminance (kcd/m^2 -> cd/m^2) and chromaticity */
  const double chi = (4.0 / 9.0 - T / 120.0) * (M_PI - 2.0 * ts);
  s->zenith_Y = 1000.0 * ((4.0453 * T - 4.9710) * tan(chi) - 0.2155 * T + 2.4192);
  const double t3[4] = {ts * ts * ts, ts * ts, ts, 1.0};
  static const double Mx[3][4] = {{0.00166, -0.00375, 0.00209, 0.0},
                                  {-0.02903, 0.06377, -0.03202, 0.00394},
                                  {0.11693, -0.21196, 0.06052, 0.25886}};
  static const double My[3][4] = {{0.00275, -0.00610, 0.00317, 0.0},
                                  {-0.04214, 0.08970, -0.04153, 0.00516},
                                  {0.15346, -0.26756, 0.06670, 0.26688}};
  const double Tv[3] = {T * T, T, 1.0};
  s->zenith_x = s->zenith_y = 0.0;
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 4; j++) {
      s->zenith_x += Tv[i] * Mx[i][j] * t3[j];
      s->zenith_y += Tv[i] * My[i][j] * t3[j];
    }
  s->norm_Y = cv_perez(s->perez_Y, 0.0, ts);
  s->norm_x = cv_perez(s->perez_x, 0.0, ts);
  s->norm_y = cv_perez(s->perez_y, 0.0, ts);

  /* the sun */
  if (s->sun_dir[1] > 0.0) {
    sun_xyz(T, acos(fmin(1.0, s->sun_dir[1])), s->sun_xyz);
    s->sun_clamped = xyz_to_rgb(s->sun_xyz, s->sun_rgb);
  }

  /* horizontal illuminance of the dome: Gauss-Legendre in cos(theta) on
   * (0, 1) x uniform azimuth */
  enum { NT = 48, NP = 96 };
  double gx[NT], gw[NT];
  cv_gauss_legendre(NT, gx, gw);
  for (int k = 0; k < NT; k++) {
    const double ct = 0.5 * (gx[k] + 1.0), st = sqrt(1.0 - ct * ct);
    const double wk = 0.5 * gw[k] * ct * (2.0 * M_PI / NP);
    for (int j = 0; j < NP; j++) {
      const double ph = 2.0 * M_PI * (j + 0.5) / NP;
      const double d[3] = {st * cos(ph), ct, st * sin(ph)};
      double rgb[3];
      s->sky_clamped += dome_radiance(s, d, rgb);
      for (int c = 0; c < 3; c++) s->sky_h_rgb[c] += wk * rgb[c];
    }
  }
  const double sun_cos = fmax(0.0, s->sun_dir[1]);
  for (int c = 0; c < 3; c++)
    s->ground[c] = ground_albedo * (s->sky_h_rgb[c] + s->sun_rgb[c] * sun_cos) / M_PI;
  *out = s;
  return CV_OK;
}

void cv_sky_destroy(cv_sky *sky) { free(sky); }

void cv_sky_get_info(const cv_sky *s, cv_sky_info *info) {
  memset(info, 0, sizeof *info);
  info->turbidity = s->turbidity;
  info->ground_albedo = s->albedo;
  info->sun_elevation_deg = asin(fmax(-1.0, fmin(1.0, s->sun_dir[1]))) * 180.0 / M_PI;
  info->model_sun_elevation_deg = 90.0 - s->theta_s * 180.0 / M_PI;
  info->zenith_xyY[0] = s->zenith_x;
  info->zenith_xyY[1] = s->zenith_y;
  info->zenith_xyY[2] = s->zenith_Y;
  memcpy(info->sun_xyz, s->sun_xyz, sizeof info->sun_xyz);
  memcpy(info->sun_rgb, s->sun_rgb, sizeof info->sun_rgb);
  memcpy(info->sky_horizontal_rgb, s->sky_h_rgb, sizeof info->sky_horizontal_rgb);
  info->sky_horizontal_lux = rgb_luminance(s->sky_h_rgb);
  memcpy(info->ground_rgb, s->ground, sizeof info->ground_rgb);
  info->sun_rgb_clamped = s->sun_clamped;
  info->sky_rgb_clamped = s->sky_clamped;
}

int cv_sky_to_latlong(const cv_sky *sky, int w, int h, cv_image **out, long *n_clamped) {
  if (!out) return CV_ERR_INVALID;
  *out = NULL;
  if (n_clamped) *n_clamped = 0;
  if (!sky || w < 1 || h < 2) return CV_ERR_INVALID;
  cv_image *img = NULL;
  const int st = cv_image_create(w, h, 3, &img);
  if (st != CV_OK) return st;
  double *trig = malloc(2 * ((size_t)w + (size_t)h) * sizeof *trig);
  if (!trig) {
    cv_image_destroy(img);
    return CV_ERR_NOMEM;
  }
  cv_latlong_trig(w, h, trig, trig + w, trig + 2 * w, trig + 2 * w + h);
  const double *sa = trig, *ca = trig + w, *stt = trig + 2 * w, *ctt = trig + 2 * w + h;
  long clamped = 0;
#pragma omp parallel for schedule(static) reduction(+ : clamped)
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      double d[3], rgb[3];
      cv_latlong_trig_dir(sa[x], ca[x], stt[y], ctt[y], d); /* = cv_latlong_pixel_dir */
      clamped += cv_sky_radiance(sky, d, rgb);
      float *p = cv_image_at(img, x, y);
      for (int c = 0; c < 3; c++) p[c] = (float)rgb[c];
    }
  free(trig);
  if (n_clamped) *n_clamped = clamped;
  *out = img;
  return CV_OK;
}
