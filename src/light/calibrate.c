/* Env-map light levels (see calibrate.h). */
#include "light/calibrate.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

double cv_envmap_horizontal_illuminance(const cv_envmap *env) {
  const cv_image *im = env->img;
  const double dphi = 2 * M_PI / im->w, dtheta = M_PI / im->h;
  double E = 0;
  for (int j = 0; j < im->h; j++) {
    const double theta = (j + 0.5) * dtheta; /* v = theta / pi, from +Y */
    const double c = cos(theta);
    if (c <= 0) continue;
    double row = 0;
    for (int i = 0; i < im->w; i++) {
      const float *p = &im->px[3 * ((size_t)j * im->w + i)];
      row += cv_luminance(p[0], p[1], p[2]);
    }
    E += row * c * sin(theta) * dphi * dtheta;
  }
  return E;
}

int cv_envmap_calibration(const char *path, const cv_envmap *env, double illuminance,
                          double *factor, cv_err *err) {
  double lux = illuminance < 0 ? cv_blender_map_default_lux(path) : illuminance;
  if (!(lux > 0))
    return cv_err_set(err, CV_ERR_CONFIG, "illuminance auto: %s is not a blender-data map with "
                      "a documented level; give the illuminance in lux", path);
  double E = cv_envmap_horizontal_illuminance(env);
  if (!(E > 0))
    return cv_err_set(err, CV_ERR_CONFIG, "%s: the upper hemisphere is black, cannot calibrate "
                      "its illuminance", path);
  *factor = lux / E;
  return CV_OK;
}

/* Representative values for the scenes the maps show (not measurements of
 * the original scenes): overcast to sunny daylight outdoors, a lit room,
 * a street at night, golden hour. */
static const struct {
  const char *name;
  double lux;
} k_blender_maps[] = {
    {"city.exr", 30000},    {"courtyard.exr", 20000}, {"forest.exr", 10000},
    {"interior.exr", 500},  {"night.exr", 10},        {"studio.exr", 1000},
    {"sunrise.exr", 2000},  {"sunset.exr", 2000},
};

/* 1 when path's folder is blender-data's world folder. */
static int in_blender_dir(const char *path) {
  char dir[PATH_MAX], a[PATH_MAX], b[PATH_MAX];
  const char *slash = strrchr(path, '/');
  if (!slash) return 0;
  size_t n = (size_t)(slash - path);
  if (n >= sizeof dir) return 0;
  memcpy(dir, path, n);
  dir[n] = '\0';
  return realpath(dir, a) && realpath(CAVE_BLENDER_WORLD_DIR, b) && !strcmp(a, b);
}

double cv_blender_map_default_lux(const char *path) {
  if (!in_blender_dir(path)) return 0;
  const char *base = strrchr(path, '/') + 1;
  for (size_t i = 0; i < sizeof k_blender_maps / sizeof k_blender_maps[0]; i++)
    if (!strcmp(base, k_blender_maps[i].name)) return k_blender_maps[i].lux;
  return 0;
}
