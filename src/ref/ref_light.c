/* Reference lighting: piecewise-constant lat-long map, alias table, sun
 * (see ref_light.h). */
#include "ref/ref_light.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "light/sky.h"
#include "sh/latlong.h"

struct cv_ref_light {
  cv_envmap *world;  /* piecewise-constant radiance, world frame */
  cv_sky *sky;       /* analytic sky for the background (sky kind only) */
  int constant;      /* 1: constant environment (background = rgb[0]) */
  double const_rgb[3];
  double R[9];       /* car-to-world */
  int w, h;
  double *omega;     /* h: solid angle of a pixel of row y */
  /* Alias table over the w*h pixels. */
  double total;      /* sum Y Omega (0: black map, no table) */
  double *prob;      /* w*h: p_i */
  double *alias_q;   /* w*h: acceptance probability of slot i */
  uint32_t *alias_i; /* w*h: alias of slot i */
  int has_sun;
  double sun_world[3], sun_E[3];
  char what[1200];
};

void cv_ref_light_destroy(cv_ref_light *l) {
  if (!l) return;
  cv_envmap_destroy(l->world);
  cv_sky_destroy(l->sky);
  free(l->omega);
  free(l->prob);
  free(l->alias_q);
  free(l->alias_i);
  free(l);
}

/* Vose's alias method: O(n) construction from probabilities p (sum 1). */
static int build_alias(size_t n, const double *p, double *q, uint32_t *al) {
  uint32_t *small = malloc(n * sizeof *small), *large = malloc(n * sizeof *large);
  double *s = malloc(n * sizeof *s);
  if (!small || !large || !s) {
    free(small);
    free(large);
    free(s);
    return CV_ERR_NOMEM;
  }
  size_t ns = 0, nl = 0;
  for (size_t i = 0; i < n; i++) {
    s[i] = p[i] * (double)n;
    al[i] = (uint32_t)i;
    if (s[i] < 1.0) small[ns++] = (uint32_t)i;
    else large[nl++] = (uint32_t)i;
  }
  while (ns && nl) {
    uint32_t a = small[--ns], g = large[nl - 1];
    q[a] = s[a];
    al[a] = g;
    s[g] = (s[g] + s[a]) - 1.0;
    if (s[g] < 1.0) {
      nl--;
      small[ns++] = g;
    }
  }
  while (nl) q[large[--nl]] = 1.0;
  while (ns) q[small[--ns]] = 1.0; /* round-off leftovers */
  free(small);
  free(large);
  free(s);
  return CV_OK;
}

/* Solid angles and the sampling table of l->world. */
static int build_table(cv_ref_light *l) {
  const cv_image *img = l->world->img;
  l->w = img->w;
  l->h = img->h;
  size_t n = (size_t)l->w * l->h;
  l->omega = malloc((size_t)l->h * sizeof *l->omega);
  l->prob = malloc(n * sizeof *l->prob);
  if (!l->omega || !l->prob) return CV_ERR_NOMEM;
  double total = 0;
  for (int y = 0; y < l->h; y++) {
    l->omega[y] = cv_latlong_pixel_solid_angle(y, l->w, l->h);
    for (int x = 0; x < l->w; x++) {
      const float *c = cv_image_at(img, x, y);
      double Y = cv_luminance(c[0], c[1], c[2]);
      double e = Y > 0 ? Y * l->omega[y] : 0;
      l->prob[(size_t)y * l->w + x] = e;
      total += e;
    }
  }
  l->total = total;
  if (!(total > 0)) return CV_OK;
  for (size_t i = 0; i < n; i++) l->prob[i] /= total;
  l->alias_q = malloc(n * sizeof *l->alias_q);
  l->alias_i = malloc(n * sizeof *l->alias_i);
  if (!l->alias_q || !l->alias_i) return CV_ERR_NOMEM;
  return build_alias(n, l->prob, l->alias_q, l->alias_i);
}

static void identity(double R[9]) {
  memset(R, 0, 9 * sizeof *R);
  R[0] = R[4] = R[8] = 1;
}

int cv_ref_light_from_map(const cv_envmap *world, const double R[9], cv_ref_light **out,
                          cv_err *err) {
  *out = NULL;
  if (!world || !world->img)
    return cv_err_set(err, CV_ERR_INVALID, "reference lighting: no environment map");
  cv_ref_light *l = calloc(1, sizeof *l);
  if (!l) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  if (R) memcpy(l->R, R, sizeof l->R);
  else identity(l->R);
  int st = cv_envmap_clone(world, &l->world);
  if (!st) st = build_table(l);
  if (st) {
    cv_ref_light_destroy(l);
    return cv_err_set(err, st, "reference lighting: %s", cv_status_str(st));
  }
  snprintf(l->what, sizeof l->what, "%d x %d map", l->w, l->h);
  *out = l;
  return CV_OK;
}

void cv_ref_light_set_sun(cv_ref_light *l, const double dir_world[3], const double E[3]) {
  double n = sqrt(dir_world[0] * dir_world[0] + dir_world[1] * dir_world[1] +
                  dir_world[2] * dir_world[2]);
  l->has_sun = n > 0 && (E[0] > 0 || E[1] > 0 || E[2] > 0);
  for (int k = 0; k < 3; k++) {
    l->sun_world[k] = n > 0 ? dir_world[k] / n : 0;
    l->sun_E[k] = E[k];
  }
}

/* Loads, blends and scales the maps of spec into one world-frame map. */
static int load_maps(const cv_light_spec *spec, cv_envmap **world, cv_err *err) {
  cv_envmap *maps[CV_MAX_ENV_MAPS] = {0};
  int st = CV_OK;
  *world = NULL;
  for (int i = 0; i < spec->n_env && !st; i++) st = cv_envmap_load(spec->env[i], &maps[i], err);
  if (!st) {
    if (spec->n_env == 1 && spec->weight[0] == 1.0) {
      *world = maps[0];
      maps[0] = NULL;
    } else {
      st = cv_envmap_blend((const cv_envmap *const *)maps, spec->weight, spec->n_env,
                           maps[0]->img->w, maps[0]->img->h, world, err);
    }
  }
  if (!st && spec->scale != 1.0) {
    size_t n = (size_t)(*world)->img->w * (*world)->img->h * 3;
    for (size_t i = 0; i < n; i++) (*world)->img->px[i] *= (float)spec->scale;
  }
  for (int i = 0; i < CV_MAX_ENV_MAPS; i++) cv_envmap_destroy(maps[i]);
  return st;
}

int cv_ref_light_build(const cv_light_spec *spec, cv_ref_light **out, cv_err *err) {
  *out = NULL;
  double R[9];
  cv_car_rotation(spec->yaw_deg, spec->pitch_deg, spec->roll_deg, R);
  cv_envmap *world = NULL;
  cv_sky *sky = NULL;
  int st = CV_OK;
  if (spec->kind == CV_LIGHT_ENV) {
    if (spec->n_env < 1) return cv_err_set(err, CV_ERR_CONFIG, "lighting: no environment map");
    st = load_maps(spec, &world, err);
  } else if (spec->kind == CV_LIGHT_SKY) {
    double el = spec->sun_elevation_deg * M_PI / 180, az = spec->sun_azimuth_deg * M_PI / 180;
    double sd[3] = {sin(az) * cos(el), sin(el), -cos(az) * cos(el)};
    cv_image *img = NULL;
    st = cv_sky_create(spec->turbidity, sd, spec->ground_albedo, &sky, err);
    if (!st && (st = cv_sky_to_latlong(sky, 1024, 512, &img, NULL)))
      cv_err_set(err, st, "lighting: cannot tabulate the sky");
    if (!st) st = cv_envmap_from_image(img, &world, err);
    cv_image_destroy(img);
  } else if (spec->kind == CV_LIGHT_CONSTANT) {
    if ((st = cv_envmap_create(8, 4, &world))) {
      cv_err_set(err, st, "out of memory");
    } else {
      for (int i = 0; i < 8 * 4; i++)
        for (int c = 0; c < 3; c++) world->img->px[3 * i + c] = (float)spec->constant[c];
    }
  } else {
    st = cv_err_set(err, CV_ERR_CONFIG, "no lighting given (--env, --env-constant or --sky)");
  }
  cv_ref_light *l = NULL;
  if (!st) st = cv_ref_light_from_map(world, R, &l, err);
  cv_envmap_destroy(world);
  if (st) {
    cv_sky_destroy(sky);
    return st;
  }
  if (spec->kind == CV_LIGHT_SKY) {
    double dir[3], E[3];
    cv_sky_sun(sky, dir, E, NULL);
    cv_ref_light_set_sun(l, dir, E);
    l->sky = sky;
    snprintf(l->what, sizeof l->what, "Preetham sky (turbidity %g, sun elevation %g, azimuth %g)",
             spec->turbidity, spec->sun_elevation_deg, spec->sun_azimuth_deg);
  } else if (spec->kind == CV_LIGHT_CONSTANT) {
    l->constant = 1;
    memcpy(l->const_rgb, spec->constant, sizeof l->const_rgb);
    snprintf(l->what, sizeof l->what, "constant environment %g %g %g", spec->constant[0],
             spec->constant[1], spec->constant[2]);
  } else {
    snprintf(l->what, sizeof l->what, "%s%s (%d x %d), scale %g", spec->env[0],
             spec->n_env > 1 ? " and more, blended" : "", l->w, l->h, spec->scale);
  }
  *out = l;
  return CV_OK;
}

static void car_to_world(const double R[9], const double d[3], double w[3]) {
  for (int i = 0; i < 3; i++) w[i] = R[3 * i] * d[0] + R[3 * i + 1] * d[1] + R[3 * i + 2] * d[2];
}

static void world_to_car(const double R[9], const double w[3], double d[3]) {
  for (int i = 0; i < 3; i++) d[i] = R[i] * w[0] + R[3 + i] * w[1] + R[6 + i] * w[2];
}

/* Pixel index of world direction w. */
static size_t pixel_of(const cv_ref_light *l, const double w[3]) {
  double u, v;
  cv_latlong_uv(w, &u, &v);
  int x = (int)(u * l->w), y = (int)(v * l->h);
  if (x >= l->w) x = l->w - 1;
  if (x < 0) x = 0;
  if (y >= l->h) y = l->h - 1;
  if (y < 0) y = 0;
  return (size_t)y * l->w + x;
}

void cv_ref_light_env(const cv_ref_light *l, const double d[3], double rgb[3]) {
  double w[3];
  car_to_world(l->R, d, w);
  const float *c = l->world->img->px + 3 * pixel_of(l, w);
  for (int k = 0; k < 3; k++) rgb[k] = c[k];
}

void cv_ref_light_background(const cv_ref_light *l, const double d[3], float rgb[3]) {
  double w[3];
  car_to_world(l->R, d, w);
  if (l->constant) {
    for (int k = 0; k < 3; k++) rgb[k] = (float)l->const_rgb[k];
  } else if (l->sky) {
    double r[3];
    cv_sky_radiance(l->sky, w, r);
    for (int k = 0; k < 3; k++) rgb[k] = (float)r[k];
  } else {
    const float wf[3] = {(float)w[0], (float)w[1], (float)w[2]};
    cv_envmap_lookup(l->world, wf, rgb);
  }
}

double cv_ref_light_pdf(const cv_ref_light *l, const double d[3]) {
  if (!(l->total > 0)) return 0;
  double w[3];
  car_to_world(l->R, d, w);
  size_t i = pixel_of(l, w);
  return l->prob[i] / l->omega[i / (size_t)l->w];
}

int cv_ref_light_sample(const cv_ref_light *l, double u1, double u2, double u3, double d[3],
                        double rgb[3], double *pdf) {
  if (!(l->total > 0)) return 0;
  size_t n = (size_t)l->w * l->h;
  double s = u1 * (double)n;
  size_t slot = (size_t)s;
  if (slot >= n) slot = n - 1;
  size_t i = (s - (double)slot) < l->alias_q[slot] ? slot : l->alias_i[slot];
  int x = (int)(i % (size_t)l->w), y = (int)(i / (size_t)l->w);
  /* Uniform in solid angle inside the cell: u uniform, cos(theta) uniform. */
  double c0 = cos(M_PI * y / l->h), c1 = cos(M_PI * (y + 1) / l->h);
  double ct = c0 + u3 * (c1 - c0), st = sqrt(fmax(0.0, 1 - ct * ct));
  double v = acos(ct) / M_PI, u = (x + u2) / l->w;
  double w[3];
  cv_latlong_dir(u, v, w);
  /* cv_latlong_dir gives the polar angle from v; rebuild with exact ct/st so
   * the direction stays inside the cell whatever acos rounds to. */
  double hl = sqrt(w[0] * w[0] + w[2] * w[2]);
  if (hl > 0) {
    w[0] *= st / hl;
    w[2] *= st / hl;
  }
  w[1] = ct;
  world_to_car(l->R, w, d);
  const float *c = l->world->img->px + 3 * i;
  for (int k = 0; k < 3; k++) rgb[k] = c[k];
  *pdf = l->prob[i] / l->omega[y];
  return 1;
}

int cv_ref_light_sun(const cv_ref_light *l, double dir[3], double E[3]) {
  if (!l->has_sun) return 0;
  world_to_car(l->R, l->sun_world, dir);
  memcpy(E, l->sun_E, sizeof l->sun_E);
  return 1;
}

void cv_ref_light_print(FILE *f, const cv_ref_light *l) {
  fprintf(f, "reference lighting: %s; map power sum(Y*Omega) %.5g%s", l->what, l->total,
          l->total > 0 ? ", importance-sampled by luminance" : ", black");
  if (l->has_sun)
    fprintf(f, "; sun (world) %.3f %.3f %.3f, irradiance Y %.4g", l->sun_world[0],
            l->sun_world[1], l->sun_world[2],
            cv_luminance(l->sun_E[0], l->sun_E[1], l->sun_E[2]));
  fputc('\n', f);
}
