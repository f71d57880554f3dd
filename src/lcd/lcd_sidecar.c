/* The scene's lcd block baked with the .prt (lcd_config.h, "the lcd block
 * baked with a scene"): written by `cave bake`, read by `cave lcd` and
 * `cave run` when they are given the .prt alone. */
#include "lcd/lcd_config.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/outfile.h"
#include "io/json_keys.h"

void cv_lcd_sidecar_path(const char *prt, char *out, size_t n) { snprintf(out, n, "%s.lcd.json", prt); }

/* The whole file as a string (owned by the caller), or NULL with err set. */
static char *slurp(const char *path, cv_err *err) {
  FILE *f = fopen(path, "rb");
  if (!f) {
    cv_err_set(err, CV_ERR_IO, "%s: cannot open (%s)", path, strerror(errno));
    return NULL;
  }
  size_t cap = 4096, n = 0;
  char *buf = malloc(cap);
  while (buf) {
    if (n + 1 >= cap) {
      char *nb = realloc(buf, cap * 2);
      if (!nb) break;
      buf = nb, cap *= 2;
      continue;
    }
    const size_t got = fread(buf + n, 1, cap - 1 - n, f);
    n += got;
    if (!got) {
      buf[n] = '\0';
      fclose(f);
      return buf;
    }
  }
  free(buf);
  fclose(f);
  cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", path);
  return NULL;
}

/* A path field of the block (key in o) made absolute against dir. */
static int absolute_field(cJSON *o, const char *key, const char *dir, int builtin_ok) {
  cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
  if (!cJSON_IsString(v) || !v->valuestring[0] || v->valuestring[0] == '/' ||
      (builtin_ok && !strncmp(v->valuestring, "builtin:", 8)))
    return CV_OK; /* absolute, built-in, or wrong (the loader names it) */
  char joined[2 * CV_PATH_MAX + 2], real[PATH_MAX];
  snprintf(joined, sizeof joined, "%s/%s", dir, v->valuestring);
  const char *use = realpath(joined, real) ? real : joined;
  return cJSON_ReplaceItemInObjectCaseSensitive(o, key, cJSON_CreateString(use)) ? CV_OK
                                                                                 : CV_ERR_NOMEM;
}

/* The block's brdf and content paths, and every panel's, made absolute. */
static int absolute_paths(cJSON *lcd, const char *dir) {
  int st = absolute_field(lcd, "brdf", dir, 1);
  if (!st) st = absolute_field(lcd, "content", dir, 0);
  cJSON *ps = cJSON_GetObjectItemCaseSensitive(lcd, "panels"), *e;
  if (cJSON_IsArray(ps))
    cJSON_ArrayForEach(e, ps) {
      if (!st && cJSON_IsObject(e)) st = absolute_field(e, "brdf", dir, 1);
      if (!st && cJSON_IsObject(e)) st = absolute_field(e, "content", dir, 0);
    }
  return st;
}

/* Removes a sidecar of an earlier bake (none: 0). */
static int remove_stale(const char *side, int *removed, cv_err *err) {
  if (unlink(side) == 0) {
    *removed = 1;
    return CV_OK;
  }
  if (errno == ENOENT) return CV_OK;
  return cv_err_set(err, CV_ERR_IO, "%s: cannot remove the lcd block of an earlier bake (%s)",
                    side, strerror(errno));
}

int cv_lcd_sidecar_write(const char *scene_json, const char *prt_path, uint64_t prt_hash,
                         int *written, int *removed, cv_err *err) {
  char side[CV_PATH_MAX + 16];
  cv_lcd_sidecar_path(prt_path, side, sizeof side);
  *written = *removed = 0;
  if (!scene_json) return remove_stale(side, removed, err);
  char *txt = slurp(scene_json, err);
  if (!txt) return err->status ? err->status : CV_ERR_IO;
  cJSON *root = cJSON_Parse(txt);
  free(txt);
  if (!root) return cv_err_set(err, CV_ERR_CONFIG, "%s: not valid JSON", scene_json);
  cJSON *lcd = cJSON_DetachItemFromObjectCaseSensitive(root, "lcd");
  cJSON_Delete(root);
  if (!lcd) return remove_stale(side, removed, err);
  char dir[PATH_MAX], absconf[PATH_MAX], tmp[CV_PATH_MAX];
  snprintf(tmp, sizeof tmp, "%s", scene_json);
  char *slash = strrchr(tmp, '/');
  if (slash) *slash = '\0';
  if (!realpath(slash ? (tmp[0] ? tmp : "/") : ".", dir) || !realpath(scene_json, absconf)) {
    cJSON_Delete(lcd);
    return cv_err_set(err, CV_ERR_IO, "%s: cannot resolve its folder (%s)", scene_json, strerror(errno));
  }
  cJSON *out = cJSON_CreateObject();
  char hex[24];
  snprintf(hex, sizeof hex, "%016llx", (unsigned long long)prt_hash);
  int st = out && !absolute_paths(lcd, dir) && cJSON_AddStringToObject(out, "prt_input_hash", hex) &&
                   cJSON_AddStringToObject(out, "scene_config", absconf)
               ? CV_OK
               : CV_ERR_NOMEM;
  if (!st && out) cJSON_AddItemToObject(out, "lcd", lcd), lcd = NULL;
  char *text = st ? NULL : cJSON_Print(out);
  cJSON_Delete(lcd);
  cJSON_Delete(out);
  if (!text) return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory", side);
  cv_outfile o;
  st = cv_outfile_open(&o, side, 1, err);
  if (!st) {
    fprintf(o.f, "%s\n", text);
    st = cv_outfile_commit(&o, err);
  }
  free(text);
  *written = st == CV_OK;
  return st;
}

int cv_lcd_sidecar_load(const char *prt_path, uint64_t prt_hash, cv_lcd_config *c, int *found,
                        char *scene_config, size_t n, cv_err *err) {
  char side[CV_PATH_MAX + 16];
  cv_lcd_sidecar_path(prt_path, side, sizeof side);
  *found = 0;
  if (scene_config && n) scene_config[0] = '\0';
  if (access(side, F_OK) != 0) return CV_OK;
  char *txt = slurp(side, err);
  if (!txt) return err->status ? err->status : CV_ERR_IO;
  cJSON *root = cJSON_Parse(txt);
  free(txt);
  if (!cJSON_IsObject(root)) {
    cJSON_Delete(root);
    return cv_err_set(err, CV_ERR_CONFIG, "%s: expected a JSON object (the lcd block `cave bake` "
                      "writes next to %s)", side, prt_path);
  }
  static const char *const top[] = {"prt_input_hash", "scene_config", "lcd", NULL};
  const cJSON *it;
  int st = CV_OK;
  cJSON_ArrayForEach(it, root) {
    char kbuf[128];
    if (!st && !cv_json_key_allowed(it->string, top))
      st = cv_err_set(err, CV_ERR_CONFIG, "%s: %s: unknown field (expected prt_input_hash, "
                      "scene_config, lcd)", side, cv_json_key_show(it->string, kbuf, sizeof kbuf));
  }
  const cJSON *h = cJSON_GetObjectItemCaseSensitive(root, "prt_input_hash");
  const cJSON *sc = cJSON_GetObjectItemCaseSensitive(root, "scene_config");
  char hex[24];
  snprintf(hex, sizeof hex, "%016llx", (unsigned long long)prt_hash);
  if (!st && (!cJSON_IsString(h) || strcmp(h->valuestring, hex)))
    st = cv_err_set(err, CV_ERR_CONFIG,
                    "%s: prt_input_hash: %s, but %s has input hash %s: the lcd block of another "
                    "bake (bake again, or remove the file)", side,
                    cJSON_IsString(h) ? h->valuestring : "(missing)", prt_path, hex);
  if (!st && cJSON_IsString(sc) && scene_config && n) snprintf(scene_config, n, "%s", sc->valuestring);
  cJSON_Delete(root);
  if (!st) st = cv_lcd_config_load_scene(side, c, err);
  *found = st == CV_OK;
  return st;
}
