/* Decoded environment maps kept by path (envmap_cache.h). */
#include "light/envmap_cache.h"

#include <stdlib.h>
#include <string.h>

typedef struct entry {
  char *path;
  cv_envmap *map;
  uint64_t used; /* tick of the last request */
} entry;

struct cv_envmap_cache {
  entry e[CV_ENVMAP_CACHE_MAX];
  int n;
  uint64_t tick, decoded, hits;
};

int cv_envmap_cache_create(cv_envmap_cache **out) {
  if (!out) return CV_ERR_INVALID;
  *out = calloc(1, sizeof **out);
  return *out ? CV_OK : CV_ERR_NOMEM;
}

void cv_envmap_cache_destroy(cv_envmap_cache *c) {
  if (!c) return;
  for (int i = 0; i < c->n; i++) free(c->e[i].path), cv_envmap_destroy(c->e[i].map);
  free(c);
}

/* The slot for a new entry: a free one, else the least recently used (emptied). */
static entry *free_slot(cv_envmap_cache *c) {
  if (c->n < CV_ENVMAP_CACHE_MAX) return &c->e[c->n++];
  entry *old = &c->e[0];
  for (int i = 1; i < c->n; i++)
    if (c->e[i].used < old->used) old = &c->e[i];
  free(old->path), cv_envmap_destroy(old->map);
  memset(old, 0, sizeof *old);
  return old;
}

int cv_envmap_cache_load(cv_envmap_cache *c, const char *path, cv_envmap **out, cv_err *err) {
  if (!c || !path || !out) return cv_envmap_load(path, out, err);
  *out = NULL;
  c->tick++;
  for (int i = 0; i < c->n; i++)
    if (c->e[i].path && !strcmp(c->e[i].path, path)) {
      c->e[i].used = c->tick;
      c->hits++;
      const int st = cv_envmap_clone(c->e[i].map, out);
      return st ? cv_err_set(err, st, "%s: out of memory copying the environment map", path) : CV_OK;
    }
  cv_envmap *m = NULL;
  int st = cv_envmap_load(path, &m, err);
  if (st) return st;
  c->decoded++;
  char *p = strdup(path);
  if (!p || (st = cv_envmap_clone(m, out))) {
    free(p), cv_envmap_destroy(m);
    return cv_err_set(err, CV_ERR_NOMEM, "%s: out of memory keeping the environment map", path);
  }
  entry *e = free_slot(c);
  e->path = p, e->map = m, e->used = c->tick;
  return CV_OK;
}

void cv_envmap_cache_counts(const cv_envmap_cache *c, uint64_t *decoded, uint64_t *hits) {
  if (decoded) *decoded = c ? c->decoded : 0;
  if (hits) *hits = c ? c->hits : 0;
}
