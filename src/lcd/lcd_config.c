/* The "lcd" settings block (see lcd_config.h), on cJSON. */
#include "lcd/lcd_config.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/json_keys.h"
#include "lcd/brdf.h"

void cv_lcd_config_default(cv_lcd_config *c) {
  memset(c, 0, sizeof *c);
  c->width = 400;
  c->height = 0;
  c->spp = 40;
  c->rounds = 1;
  snprintf(c->brdf, sizeof c->brdf, "%s", CV_BRDF_BUILTIN_ANTIGLARE);
  c->content_luminance = CV_LCD_WHITE_DEFAULT;
  c->black_luminance = -1;
  c->cr_min = 3;
  c->age = 40;
  c->pigment = 0.5;
  c->eye_tolerance = 0.005;
  c->brdf_fraction = 0.9;
  c->seed = 1;
  c->env_width = 1024;
  c->sun_samples = 16;
  c->clamp = 0;
}

static int num(const char *file, const cJSON *o, const char *key, double lo, double hi,
               int integer, double *out, cv_err *err) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  if (!v) return CV_OK;
  if (!cJSON_IsNumber(v) || !isfinite(v->valuedouble))
    return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.%s: expected a number", file, key);
  if (v->valuedouble < lo || v->valuedouble > hi)
    return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.%s: %g is outside [%g, %g]", file, key,
                      v->valuedouble, lo, hi);
  if (integer && v->valuedouble != floor(v->valuedouble))
    return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.%s: expected an integer", file, key);
  *out = v->valuedouble;
  return CV_OK;
}

static int path_field(const char *file, const char *base, const cJSON *o, const char *key,
                      int allow_builtin, char out[CV_PATH_MAX], cv_err *err) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  if (!v) return CV_OK;
  if (!cJSON_IsString(v))
    return cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.%s: expected a file name (string)", file, key);
  const char *s = v->valuestring;
  if (!s[0] || s[0] == '/' || (allow_builtin && !strncmp(s, "builtin:", 8)))
    snprintf(out, CV_PATH_MAX, "%s", s);
  else
    snprintf(out, CV_PATH_MAX, "%s/%s", base, s);
  return CV_OK;
}

double cv_lcd_config_black(const cv_lcd_config *c) {
  return c->black_luminance >= 0 ? c->black_luminance : CV_LCD_BLACK_LEVEL * c->content_luminance;
}

static int load(const char *path, int scene, cv_lcd_config *c, cv_err *err) {
  FILE *f = fopen(path, "rb");
  if (!f) return cv_err_set(err, CV_ERR_IO, "%s: cannot open (%s)", path, strerror(errno));
  size_t cap = 4096, n = 0;
  char *buf = malloc(cap);
  while (buf) {
    if (n + 1 >= cap) {
      char *nb = realloc(buf, cap * 2);
      if (!nb) {
        free(buf);
        buf = NULL;
        break;
      }
      buf = nb;
      cap *= 2;
    }
    size_t got = fread(buf + n, 1, cap - 1 - n, f);
    n += got;
    if (!got) break;
  }
  fclose(f);
  if (!buf) return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  buf[n] = 0;
  const char *end = NULL;
  cJSON *root = cJSON_ParseWithOpts(buf, &end, 0);
  if (!root) {
    int line, col;
    char what[128];
    cv_json_syntax_error(buf, end, &line, &col, what, sizeof what);
    free(buf);
    return cv_err_set(err, CV_ERR_CONFIG, "%s: line %d, column %d: %s", path, line, col, what);
  }
  free(buf);
  char base[CV_PATH_MAX];
  snprintf(base, sizeof base, "%s", path);
  char *slash = strrchr(base, '/');
  if (slash) *slash = 0;
  else snprintf(base, sizeof base, ".");
  int st = CV_OK;
  const cJSON *o = cJSON_GetObjectItemCaseSensitive(root, "lcd");
  static const char *const top[] = {"lcd", NULL};
  static const char *const keys[] = {"resolution", "spp", "rounds", "brdf", "content",
                                     "content_luminance", "eye_tolerance", "brdf_fraction",
                                     "seed", "env_width", "sun_samples", "clamp",
                                     "black_luminance", "cr_min", "age", "pigment", NULL};
  char list[600];
  const cJSON *it;
  if (!cJSON_IsObject(root)) {
    st = cv_err_set(err, CV_ERR_CONFIG, "%s: expected an object with an \"lcd\" field", path);
    goto done;
  }
  cJSON_ArrayForEach(it, root) {
    if (!scene && !cv_json_key_allowed(it->string, top)) {
      char kbuf[128];
      st = cv_err_set(err, CV_ERR_CONFIG, "%s: %s: unknown field (expected lcd)", path,
                      cv_json_key_show(it->string, kbuf, sizeof kbuf));
      goto done;
    }
  }
  if (!o) goto done;
  if (!cJSON_IsObject(o)) {
    st = cv_err_set(err, CV_ERR_CONFIG, "%s: lcd: expected an object", path);
    goto done;
  }
  cJSON_ArrayForEach(it, o) {
    if (!cv_json_key_allowed(it->string, keys)) {
      char kbuf[128];
      cv_json_key_list(keys, list, sizeof list);
      st = cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.%s: unknown field (expected one of: %s)", path,
                      cv_json_key_show(it->string, kbuf, sizeof kbuf), list);
      goto done;
    }
  }
  const cJSON *res = cJSON_GetObjectItemCaseSensitive(o, "resolution");
  if (res) {
    const cJSON *a = cJSON_GetArrayItem(res, 0), *b = cJSON_GetArrayItem(res, 1);
    if (!cJSON_IsArray(res) || cJSON_GetArraySize(res) != 2 || !cJSON_IsNumber(a) ||
        !cJSON_IsNumber(b) || a->valuedouble != floor(a->valuedouble) ||
        b->valuedouble != floor(b->valuedouble) || a->valuedouble < 1 || a->valuedouble > 16384 ||
        b->valuedouble < 1 || b->valuedouble > 16384) {
      st = cv_err_set(err, CV_ERR_CONFIG, "%s: lcd.resolution: expected [width, height], integers in 1..16384", path);
      goto done;
    }
    c->width = (int)a->valuedouble;
    c->height = (int)b->valuedouble;
  }
  double d;
  d = c->spp;
  if ((st = num(path, o, "spp", 1, 65536, 1, &d, err))) goto done;
  c->spp = (int)d;
  d = c->rounds;
  if ((st = num(path, o, "rounds", 1, 100000, 1, &d, err))) goto done;
  c->rounds = (int)d;
  if ((st = num(path, o, "content_luminance", 0, 1e6, 0, &c->content_luminance, err))) goto done;
  if ((st = num(path, o, "eye_tolerance", 1e-5, 1, 0, &c->eye_tolerance, err))) goto done;
  if ((st = num(path, o, "brdf_fraction", 0, 1, 0, &c->brdf_fraction, err))) goto done;
  d = c->seed;
  if ((st = num(path, o, "seed", 0, 4294967295.0, 1, &d, err))) goto done;
  c->seed = (uint32_t)d;
  d = c->env_width;
  if ((st = num(path, o, "env_width", 16, 16384, 1, &d, err))) goto done;
  c->env_width = (int)d;
  d = c->sun_samples;
  if ((st = num(path, o, "sun_samples", 1, 4096, 1, &d, err))) goto done;
  c->sun_samples = (int)d;
  if ((st = num(path, o, "clamp", 0, 1e30, 0, &c->clamp, err))) goto done;
  if ((st = num(path, o, "black_luminance", 0, 1e6, 0, &c->black_luminance, err))) goto done;
  if ((st = num(path, o, "cr_min", 1, 1000, 0, &c->cr_min, err))) goto done;
  if ((st = num(path, o, "age", 0, 150, 0, &c->age, err))) goto done;
  if ((st = num(path, o, "pigment", 0, 1, 0, &c->pigment, err))) goto done;
  if (cv_lcd_config_black(c) > c->content_luminance) {
    st = cv_err_set(err, CV_ERR_CONFIG,
                    "%s: lcd.black_luminance: %g is above the white lcd.content_luminance %g",
                    path, cv_lcd_config_black(c), c->content_luminance);
    goto done;
  }
  if ((st = path_field(path, base, o, "brdf", 1, c->brdf, err))) goto done;
  st = path_field(path, base, o, "content", 0, c->content, err);
done:
  cJSON_Delete(root);
  return st;
}

int cv_lcd_config_load(const char *path, cv_lcd_config *c, cv_err *err) {
  return load(path, 0, c, err);
}

int cv_lcd_config_load_scene(const char *path, cv_lcd_config *c, cv_err *err) {
  return load(path, 1, c, err);
}
