/* Scene lighting in the car frame (see scene_light.h). */
#include "prt/scene_light.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "light/calibrate.h"
#include "light/envmap.h"
#include "light/envmap_cache.h"
#include "light/sky.h"
#include "light/sun.h"
#include "sh/latlong.h"
#include "sh/sh.h"

struct cv_scene_light {
  cv_light_spec spec;
  cv_lighting l;       /* car frame */
  double R[9];         /* car-to-world rotation */
  cv_envmap *world;    /* full map in the world frame (background), env only */
  cv_sky *sky;         /* sky only */
  double sun_world[3];
  double sun_fraction; /* env: energy fraction of the extracted sun */
  double sun_solid_angle;
  int sun_pixels;
  double map_lux;      /* env: E_h of the map before scaling (its own units) */
  double factor;       /* env: the multiplier applied (scale or calibration) */
  cv_envmap *residual; /* world-frame map that the SH lighting projects (env, sky) */
  int bands;
  cv_dir_light *extra; /* split lights, car frame */
  int n_extra;
  double extra_fraction; /* their share of the residual's luminous energy */
};

static void scale_map(cv_envmap *e, double f) {
  size_t n = (size_t)e->img->w * e->img->h * 3;
  for (size_t i = 0; i < n; i++) e->img->px[i] *= (float)f;
}

/* --illuminance: every map at its blender-data default (auto), or the blend
 * at the given lux.  The multiplier goes to *factor. */
static int calibrate_maps(const cv_light_spec *spec, cv_envmap **maps, double *factor,
                          cv_err *err) {
  if (spec->illuminance != CV_ILLUMINANCE_AUTO) return CV_OK;
  for (int i = 0; i < spec->n_env; i++) {
    double lux = cv_blender_map_default_lux(spec->env[i]);
    if (!(lux > 0))
      return cv_err_set(err, CV_ERR_CONFIG,
                        "lighting: illuminance auto: %s is not a blender-data map with a "
                        "documented level; give the illuminance in lux", spec->env[i]);
    double E = cv_envmap_horizontal_illuminance(maps[i]);
    if (!(E > 0))
      return cv_err_set(err, CV_ERR_CONFIG, "lighting: %s: the upper hemisphere is black, "
                        "cannot calibrate its illuminance", spec->env[i]);
    scale_map(maps[i], lux / E);
    if (i == 0) *factor = lux / E;
  }
  return CV_OK;
}

void cv_scene_light_destroy(cv_scene_light *sl) {
  if (!sl) return;
  cv_envmap_destroy(sl->world);
  cv_envmap_destroy(sl->residual);
  cv_sky_destroy(sl->sky);
  free(sl->extra);
  free(sl);
}

/* Projects a world-frame map and rotates the coefficients into the car frame:
 * f_car(d) = f_world(R d), i.e. f_world rotated by R^T. */
static int project_to_car(const cv_envmap *env, int bands, const double R[9], cv_lighting *l) {
  if (bands == 0) return CV_OK; /* background and sun only */
  double world[3 * 64];
  int st = cv_envmap_project_sh(env, bands, world);
  if (st) return st;
  double Rt[9];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) Rt[3 * i + j] = R[3 * j + i];
  cv_sh_rotation *rot;
  if ((st = cv_sh_rotation_create(bands, Rt, &rot))) return st;
  cv_sh_rotate(rot, world, l->sh, 3);
  cv_sh_rotation_destroy(rot);
  l->bands = bands;
  return CV_OK;
}

static void to_car(const double R[9], const double w[3], double c[3]) {
  for (int i = 0; i < 3; i++) c[i] = R[i] * w[0] + R[3 + i] * w[1] + R[6 + i] * w[2];
}

int cv_scene_light_build(const cv_light_spec *spec, int bands, cv_scene_light **out, cv_err *err) {
  return cv_scene_light_build_cached(spec, bands, NULL, out, err);
}

int cv_scene_light_build_cached(const cv_light_spec *spec, int bands, cv_envmap_cache *cache,
                                cv_scene_light **out, cv_err *err) {
  *out = NULL;
  if (bands != 0 && (bands < 2 || bands > 8))
    return cv_err_set(err, CV_ERR_RANGE, "lighting: bands %d, expected 2..8 (or 0: no SH)", bands);
  cv_scene_light *sl = calloc(1, sizeof *sl);
  if (!sl) return cv_err_set(err, CV_ERR_NOMEM, "out of memory");
  sl->spec = *spec;
  sl->bands = bands;
  cv_car_rotation(spec->yaw_deg, spec->pitch_deg, spec->roll_deg, sl->R);
  int st = CV_OK;
  cv_envmap *maps[CV_MAX_ENV_MAPS] = {0}, *residual = NULL;
  if (spec->kind == CV_LIGHT_ENV && spec->illuminance != 0 && spec->scale != 1.0) {
    st = cv_err_set(err, CV_ERR_CONFIG, "lighting: scale %g and illuminance both set the level; "
                    "give one", spec->scale);
    goto done;
  }
  if (spec->kind == CV_LIGHT_ENV) {
    for (int i = 0; i < spec->n_env && !st; i++) st = cv_envmap_cache_load(cache, spec->env[i], &maps[i], err);
    if (st || (st = calibrate_maps(spec, maps, &sl->factor, err))) goto done;
    if (spec->illuminance == 0 && spec->n_env == 1)
      sl->map_lux = cv_envmap_horizontal_illuminance(maps[0]);
    if (spec->n_env == 1 && spec->weight[0] == 1.0) {
      sl->world = maps[0];
      maps[0] = NULL;
    } else {
      st = cv_envmap_blend((const cv_envmap *const *)maps, spec->weight, spec->n_env,
                           maps[0]->img->w, maps[0]->img->h, &sl->world, err);
      if (st) goto done;
    }
    if (spec->illuminance != CV_ILLUMINANCE_AUTO) sl->factor = spec->scale;
    if (spec->illuminance > 0) {
      sl->map_lux = cv_envmap_horizontal_illuminance(sl->world);
      if (!(sl->map_lux > 0)) {
        st = cv_err_set(err, CV_ERR_CONFIG, "lighting: %s: the upper hemisphere is black, "
                        "cannot calibrate its illuminance", spec->env[0]);
        goto done;
      }
      sl->factor = spec->illuminance / sl->map_lux;
      scale_map(sl->world, sl->factor);
    } else if (spec->illuminance == 0 && spec->scale != 1.0) {
      scale_map(sl->world, spec->scale);
    }
    const cv_envmap *proj = sl->world;
    if (spec->extract_sun) {
      cv_sun_params sp;
      cv_sun_params_default(&sp);
      cv_sun_info si;
      if ((st = cv_sun_extract(sl->world, &sp, &si, &residual))) {
        cv_err_set(err, st, "sun extraction failed on %s", spec->env[0]);
        goto done;
      }
      if (si.found) {
        sl->l.has_sun = 1;
        memcpy(sl->sun_world, si.dir, sizeof si.dir);
        memcpy(sl->l.sun_E, si.rgb, sizeof si.rgb);
        sl->sun_fraction = si.energy_fraction;
        sl->sun_solid_angle = si.solid_angle;
        sl->sun_pixels = (int)si.pixels;
        proj = residual;
      }
    }
    if ((st = project_to_car(proj, bands, sl->R, &sl->l))) {
      cv_err_set(err, st, "SH projection of %s failed", spec->env[0]);
      goto done;
    }
    if (proj == residual) {
      sl->residual = residual;
      residual = NULL;
    } else if ((st = cv_envmap_clone(sl->world, &sl->residual))) {
      cv_err_set(err, st, "out of memory");
      goto done;
    }
  } else if (spec->kind == CV_LIGHT_SKY) {
    double el = spec->sun_elevation_deg * M_PI / 180, az = spec->sun_azimuth_deg * M_PI / 180;
    double sd[3] = {sin(az) * cos(el), sin(el), -cos(az) * cos(el)};
    if ((st = cv_sky_create(spec->turbidity, sd, spec->ground_albedo, &sl->sky, err))) goto done;
    cv_image *img;
    long clamped = 0;
    if ((st = cv_sky_to_latlong(sl->sky, 512, 256, &img, &clamped))) {
      cv_err_set(err, st, "cannot tabulate the sky");
      goto done;
    }
    st = cv_envmap_from_image(img, &residual, err);
    cv_image_destroy(img);
    if (st || (st = project_to_car(residual, bands, sl->R, &sl->l))) goto done;
    sl->residual = residual;
    residual = NULL;
    double E[3], sa;
    cv_sky_sun(sl->sky, sl->sun_world, E, &sa);
    if (E[0] + E[1] + E[2] > 0) {
      sl->l.has_sun = 1;
      memcpy(sl->l.sun_E, E, sizeof E);
      sl->sun_solid_angle = sa;
    }
  } else if (spec->kind == CV_LIGHT_CONSTANT) {
    sl->l.bands = bands;
    if (bands > 0)
      for (int c = 0; c < 3; c++) sl->l.sh[c] = spec->constant[c] * sqrt(4 * M_PI);
  } else {
    st = cv_err_set(err, CV_ERR_CONFIG, "no lighting given (--env, --env-constant or --sky)");
    goto done;
  }
  if (sl->l.has_sun) to_car(sl->R, sl->sun_world, sl->l.sun_dir);
done:
  for (int i = 0; i < CV_MAX_ENV_MAPS; i++) cv_envmap_destroy(maps[i]);
  cv_envmap_destroy(residual);
  if (st) {
    cv_scene_light_destroy(sl);
    return st;
  }
  *out = sl;
  return CV_OK;
}

typedef struct {
  double score, e, E[3], dir[3];
} split_cell;

static int cmp_cell(const void *a, const void *b) {
  const split_cell *x = a, *y = b;
  return (x->score < y->score) - (x->score > y->score); /* descending */
}

/* Energy, colour and centroid of every cell of the residual (world frame). */
static void cell_sums(const cv_envmap *env, int gw, int gh, split_cell *cells) {
  const cv_image *img = env->img;
  memset(cells, 0, (size_t)gw * gh * sizeof *cells);
  for (int y = 0; y < img->h; y++) {
    double om = cv_latlong_pixel_solid_angle(y, img->w, img->h);
    int cy = (int)((long)y * gh / img->h);
    for (int x = 0; x < img->w; x++) {
      split_cell *c = &cells[cy * gw + (int)((long)x * gw / img->w)];
      const float *p = cv_image_at(img, x, y);
      double Y = cv_luminance(p[0], p[1], p[2]) * om, d[3];
      cv_latlong_pixel_dir(x, y, img->w, img->h, d);
      c->e += Y;
      for (int k = 0; k < 3; k++) {
        c->E[k] += p[k] * om;
        c->dir[k] += Y * d[k];
      }
    }
  }
}

/* Fraction of probe points that see world direction w through a window. */
static double window_fraction(const cv_tracer *tr, const double R[9], const double w[3],
                              const float *probes, int np) {
  if (!tr || np == 0) return 1;
  double d[3];
  to_car(R, w, d);
  const float df[3] = {(float)d[0], (float)d[1], (float)d[2]};
  int seen = 0;
  for (int i = 0; i < np; i++) seen += cv_rt_reaches_env(cv_tracer_rt(tr), probes + 3 * i, df, 0);
  return (double)seen / np;
}

int cv_scene_light_split(cv_scene_light *sl, const cv_tracer *tr, int k, int grid_w,
                         cv_err *err) {
  if (k < 0 || k > 4096 || grid_w < 4 || grid_w > 1024 || grid_w % 2)
    return cv_err_set(err, CV_ERR_RANGE, "split: %d lights on a %d-wide grid, expected 0..4096 "
                      "and an even width 4..1024", k, grid_w);
  free(sl->extra);
  sl->extra = NULL;
  sl->n_extra = 0;
  sl->extra_fraction = 0;
  if (k == 0 || !sl->residual) return CV_OK;
  if (sl->bands == 0) return cv_err_set(err, CV_ERR_INVALID, "split: the lighting was built without SH");
  const int gw = grid_w, gh = grid_w / 2, ncell = gw * gh;
  split_cell *cells = malloc((size_t)ncell * sizeof *cells);
  float *probes = malloc(3 * 256 * sizeof *probes);
  cv_envmap *rest = NULL;
  int st = CV_OK, np = 0;
  if (!cells || !probes || cv_envmap_clone(sl->residual, &rest)) {
    st = cv_err_set(err, CV_ERR_NOMEM, "out of memory");
    goto done;
  }
  if (tr) {
    size_t nv = cv_tracer_vertex_count(tr);
    size_t step = nv > 256 ? nv / 256 : 1;
    for (size_t v = 0; v < nv && np < 256; v += step) {
      float dir[3];
      uint32_t tri;
      if (cv_tracer_sample(tr, (uint32_t)v, 0, 0x51u, probes + 3 * np, dir, &tri)) np++;
    }
  }
  cell_sums(rest, gw, gh, cells);
  double total = 0;
  for (int i = 0; i < ncell; i++) {
    total += cells[i].e;
    double l = sqrt(cells[i].dir[0] * cells[i].dir[0] + cells[i].dir[1] * cells[i].dir[1] +
                    cells[i].dir[2] * cells[i].dir[2]);
    if (!(cells[i].e > 0) || !(l > 0)) {
      cells[i].score = 0;
      continue;
    }
    for (int c = 0; c < 3; c++) cells[i].dir[c] /= l;
    cells[i].score = cells[i].e * window_fraction(tr, sl->R, cells[i].dir, probes, np);
  }
  /* Selection by score: sort a copy for the k-th best score, then take the
   * cells at or above it in grid order (so the map can be cut by index). */
  split_cell *sorted = malloc((size_t)ncell * sizeof *sorted);
  if (!sorted) {
    st = cv_err_set(err, CV_ERR_NOMEM, "out of memory");
    goto done;
  }
  memcpy(sorted, cells, (size_t)ncell * sizeof *cells);
  qsort(sorted, (size_t)ncell, sizeof *sorted, cmp_cell);
  int n = k < ncell ? k : ncell;
  while (n > 0 && !(sorted[n - 1].score > 0)) n--;
  double thr = n > 0 ? sorted[n - 1].score : INFINITY;
  free(sorted);
  sl->extra = calloc((size_t)(n > 0 ? n : 1), sizeof *sl->extra);
  char *chosen = calloc((size_t)ncell, 1);
  if (!sl->extra || !chosen) {
    free(chosen);
    st = cv_err_set(err, CV_ERR_NOMEM, "out of memory");
    goto done;
  }
  double taken = 0;
  for (int i = 0; i < ncell && sl->n_extra < n; i++) { /* ties: lowest index first */
    if (!(cells[i].score >= thr) || !(cells[i].score > 0)) continue;
    chosen[i] = 1;
    cv_dir_light *L = &sl->extra[sl->n_extra++];
    to_car(sl->R, cells[i].dir, L->dir);
    memcpy(L->E, cells[i].E, sizeof L->E);
    taken += cells[i].e;
  }
  sl->extra_fraction = total > 0 ? taken / total : 0;
  /* Remove the chosen cells from the map and re-project the rest. */
  cv_image *img = rest->img;
  for (int y = 0; y < img->h; y++) {
    int cy = (int)((long)y * gh / img->h);
    for (int x = 0; x < img->w; x++)
      if (chosen[cy * gw + (int)((long)x * gw / img->w)]) {
        float *p = cv_image_at(img, x, y);
        p[0] = p[1] = p[2] = 0;
      }
  }
  free(chosen);
  if ((st = project_to_car(rest, sl->bands, sl->R, &sl->l)))
    cv_err_set(err, st, "split: SH projection failed");
done:
  free(cells);
  free(probes);
  cv_envmap_destroy(rest);
  return st;
}

int cv_scene_light_extra(const cv_scene_light *sl, const cv_dir_light **lights) {
  *lights = sl->extra;
  return sl->n_extra;
}

cv_lighting cv_scene_light_sh(const cv_scene_light *sl) { return sl->l; }

void cv_scene_light_residual(const cv_scene_light *sl, const float d[3], float rgb[3]) {
  if (!sl->residual) {
    for (int k = 0; k < 3; k++) rgb[k] = (float)sl->spec.constant[k];
    return;
  }
  float w[3];
  for (int i = 0; i < 3; i++)
    w[i] = (float)(sl->R[3 * i] * d[0] + sl->R[3 * i + 1] * d[1] + sl->R[3 * i + 2] * d[2]);
  cv_envmap_lookup(sl->residual, w, rgb);
}

void cv_scene_light_background(const cv_scene_light *sl, const float d[3], float rgb[3]) {
  double w[3];
  for (int i = 0; i < 3; i++) w[i] = sl->R[3 * i] * d[0] + sl->R[3 * i + 1] * d[1] + sl->R[3 * i + 2] * d[2];
  if (sl->world) {
    float wf[3] = {(float)w[0], (float)w[1], (float)w[2]};
    cv_envmap_lookup(sl->world, wf, rgb);
  } else if (sl->sky) {
    double r[3];
    cv_sky_radiance(sl->sky, w, r);
    for (int k = 0; k < 3; k++) rgb[k] = (float)r[k];
  } else {
    for (int k = 0; k < 3; k++) rgb[k] = (float)sl->spec.constant[k];
  }
}

void cv_scene_light_print(FILE *f, const cv_scene_light *sl) {
  const cv_light_spec *s = &sl->spec;
  if (s->kind == CV_LIGHT_ENV) {
    fprintf(f, "lighting: %d env map%s (%s", s->n_env, s->n_env > 1 ? "s" : "", s->env[0]);
    for (int i = 1; i < s->n_env; i++) fprintf(f, ", %s", s->env[i]);
    fprintf(f, "), scale %g, yaw %g pitch %g roll %g\n", sl->factor, s->yaw_deg, s->pitch_deg,
            s->roll_deg);
    if (s->illuminance > 0)
      fprintf(f, "lighting: calibrated to %g lux horizontal illuminance (the map's %.4g x %.4g)\n",
              s->illuminance, sl->map_lux, sl->factor);
    else if (s->illuminance == CV_ILLUMINANCE_AUTO)
      fprintf(f, "lighting: each map at its blender-data default illuminance (%s: %g lux)\n",
              s->env[0], cv_blender_map_default_lux(s->env[0]));
    else if (s->scale == 1.0 && s->n_env == 1 && cv_blender_map_default_lux(s->env[0]) > 0)
      fprintf(f, "note: %s is relative (horizontal illuminance %.4g in its own units); "
                 "--illuminance auto sets its documented level, %g lux\n",
              s->env[0], sl->map_lux, cv_blender_map_default_lux(s->env[0]));
  } else if (s->kind == CV_LIGHT_SKY) {
    fprintf(f, "lighting: Preetham sky, turbidity %g, sun elevation %g azimuth %g deg\n",
            s->turbidity, s->sun_elevation_deg, s->sun_azimuth_deg);
  } else {
    fprintf(f, "lighting: constant environment %g %g %g\n", s->constant[0], s->constant[1],
            s->constant[2]);
  }
  if (sl->l.has_sun) {
    double Y = 0.2126 * sl->l.sun_E[0] + 0.7152 * sl->l.sun_E[1] + 0.0722 * sl->l.sun_E[2];
    fprintf(f,
            "sun: found, direction (world) %.3f %.3f %.3f, irradiance %.4g (luminance units), "
            "solid angle %.3g sr",
            sl->sun_world[0], sl->sun_world[1], sl->sun_world[2], Y, sl->sun_solid_angle);
    if (s->kind == CV_LIGHT_ENV)
      fprintf(f, ", %.1f%% of the map's energy in %d pixels; split out of PRT", 100 * sl->sun_fraction,
              sl->sun_pixels);
    fputc('\n', f);
  } else if (s->kind != CV_LIGHT_CONSTANT) {
    fprintf(f, "sun: none (%s)\n", s->kind == CV_LIGHT_ENV && !s->extract_sun
                                       ? "extraction off"
                                       : "no compact region above the energy threshold");
  }
  if (sl->n_extra)
    fprintf(f, "split: %d window-visible regions as directional lights (%.1f%% of the residual "
            "map's energy), exact visibility\n", sl->n_extra, 100 * sl->extra_fraction);
}
