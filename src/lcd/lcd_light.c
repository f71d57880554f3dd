/* The LCD gather's lighting state (gather.h, cv_lcd_light): from an
 * environment map in the car frame or from the scene's lighting. */
#include "lcd/gather_internal.h"

/* --- lighting ------------------------------------------------------------ */

void cv_lcd_light_destroy(cv_lcd_light *l) {
  if (!l) return;
  cv_envmap_destroy(l->env);
  cv_env_sampler_destroy(l->env_smp);
  free(l->vrad);
  free(l);
}

/* Takes ownership of env and vrad (freed on error). */
static int light_finish(cv_envmap *env, float *vrad, size_t nv, int has_sun, const double sd[3],
                        const double sE[3], cv_lcd_light **out) {
  *out = NULL;
  cv_lcd_light *l = calloc(1, sizeof *l);
  if (!l) {
    cv_envmap_destroy(env);
    free(vrad);
    return CV_ERR_NOMEM;
  }
  l->env = env;
  l->vrad = vrad;
  l->nv = nv;
  int st = cv_env_sampler_create(env, &l->env_smp);
  if (st) {
    cv_lcd_light_destroy(l);
    return st;
  }
  snprintf(l->sun_source, sizeof l->sun_source, "none");
  if (has_sun) {
    double len = sqrt(sd[0] * sd[0] + sd[1] * sd[1] + sd[2] * sd[2]);
    if (!(len > 0) || !isfinite(len) || !isfinite(sE[0]) || !isfinite(sE[1]) || !isfinite(sE[2])) {
      cv_lcd_light_destroy(l);
      return CV_ERR_NONFINITE;
    }
    l->has_sun = 1;
    for (int k = 0; k < 3; k++) {
      l->sun_dir[k] = (float)(sd[k] / len);
      l->sun_E[k] = (float)(sE[k] > 0 ? sE[k] : 0);
    }
    snprintf(l->sun_source, sizeof l->sun_source, "given");
  }
  double mx = 0;
  size_t npx = (size_t)env->img->w * env->img->h * 3;
  for (size_t i = 0; i < npx; i++) mx = fmax(mx, env->img->px[i]);
  for (size_t i = 0; i < 3 * nv; i++) {
    if (!isfinite(vrad[i]) || vrad[i] < 0) {
      vrad[i] = 0;
      l->vrad_fixed++;
    }
    mx = fmax(mx, vrad[i]);
  }
  l->max_radiance = mx;
  uint64_t h = cv_hash64_init();
  h = cv_hash64_u64(h, (uint64_t)env->img->w);
  h = cv_hash64_u64(h, (uint64_t)env->img->h);
  h = cv_hash64_floats(h, env->img->px, npx);
  h = cv_hash64_u64(h, (uint64_t)nv);
  h = cv_hash64_floats(h, vrad, 3 * nv);
  h = cv_hash64_u64(h, (uint64_t)l->has_sun);
  h = cv_hash64_floats(h, l->sun_dir, 3);
  h = cv_hash64_floats(h, l->sun_E, 3);
  l->hash = h;
  *out = l;
  return CV_OK;
}

int cv_lcd_light_create(const cv_envmap *env_car, const float *vrad, size_t nv, int has_sun,
                        const double sun_dir[3], const double sun_E[3], cv_lcd_light **out) {
  *out = NULL;
  if (!env_car || !env_car->img || (has_sun && (!sun_dir || !sun_E))) return CV_ERR_INVALID;
  cv_envmap *env;
  int st = cv_envmap_clone(env_car, &env);
  if (st) return st;
  float *v = calloc(3 * nv + 1, sizeof(float));
  if (!v) {
    cv_envmap_destroy(env);
    return CV_ERR_NOMEM;
  }
  if (vrad) memcpy(v, vrad, 3 * nv * sizeof(float));
  return light_finish(env, v, nv, has_sun, sun_dir, sun_E, out);
}

int cv_lcd_light_from_scene(const cv_scene_light *sl, const cv_light_spec *spec, const cv_prt *p,
                            const cv_tracer *tr, int sun_samples, int env_w, cv_lcd_light **out,
                            cv_err *err) {
  *out = NULL;
  if (!sl || !spec || !p || env_w < 4 || env_w > 16384 || sun_samples < 1)
    return cv_err_set(err, CV_ERR_INVALID, "lcd lighting: invalid arguments");
  int env_h = env_w / 2;
  cv_envmap *tab = NULL, *residual = NULL;
  float *vrad = NULL;
  int st = cv_envmap_create(env_w, env_h, &tab);
  if (st) return cv_err_set(err, st, "lcd lighting: out of memory");
  /* car-frame lat-long table (layout of sh/latlong.h) */
  for (int y = 0; y < env_h; y++) {
    double th = M_PI * (y + 0.5) / env_h;
    for (int x = 0; x < env_w; x++) {
      double ph = 2 * M_PI * ((x + 0.5) / env_w - 0.5);
      float d[3] = {(float)(sin(th) * sin(ph)), (float)cos(th), (float)(-sin(th) * cos(ph))};
      cv_scene_light_background(sl, d, cv_image_at(tab->img, x, y));
    }
  }
  cv_lighting lt = cv_scene_light_sh(sl);
  int has_sun = 0;
  double sd[3] = {0, 0, 0}, sE[3] = {0, 0, 0};
  const char *src = "none";
  if (lt.has_sun && spec->kind == CV_LIGHT_ENV) {
    cv_sun_info si;
    if ((st = cv_sun_extract(tab, NULL, &si, &residual))) {
      cv_envmap_destroy(tab);
      return cv_err_set(err, st, "lcd lighting: sun extraction failed");
    }
    if (si.found) {
      cv_envmap_destroy(tab);
      tab = residual;
      residual = NULL;
      has_sun = 1;
      memcpy(sd, si.dir, sizeof sd);
      memcpy(sE, si.rgb, sizeof sE);
      src = "extracted from the car-frame background";
    } else {
      cv_envmap_destroy(residual);
      residual = NULL;
      src = "kept in the background (not compact in the car-frame table)";
    }
  } else if (lt.has_sun) {
    has_sun = 1;
    memcpy(sd, lt.sun_dir, sizeof sd);
    memcpy(sE, lt.sun_E, sizeof sE);
    src = "analytic sky";
  }
  vrad = malloc(3 * p->nv * sizeof(float) + 1);
  if (!vrad) {
    cv_envmap_destroy(tab);
    return cv_err_set(err, CV_ERR_NOMEM, "lcd lighting: out of memory");
  }
  cv_relight_stats rs;
  if ((st = cv_prt_relight(p, &lt, tr, sun_samples, vrad, &rs)) ||
      (st = cv_prt_fold_texture_means(p, vrad))) { /* textures as their mean albedo */
    cv_envmap_destroy(tab);
    free(vrad);
    return cv_err_set(err, st, "lcd lighting: relighting failed (%s)", cv_status_str(st));
  }
  if ((st = light_finish(tab, vrad, p->nv, has_sun, sd, sE, out)))
    return cv_err_set(err, st, "lcd lighting: %s", cv_status_str(st));
  snprintf((*out)->sun_source, sizeof (*out)->sun_source, "%s", src);
  return CV_OK;
}
