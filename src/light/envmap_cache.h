/* Decoded environment maps kept by path, so a caller that rebuilds its
 * lighting often (a wall-eye's LCD worker: a new scene light for every
 * lighting key of a drive) decodes each EXR file once instead of every time.
 *
 * A cache is not thread-safe: one per thread.  It holds at most
 * CV_ENVMAP_CACHE_MAX maps (the least recently used is dropped).  A file
 * changed on disk after its first load is not reread (the service's maps
 * are fixed for a run). */
#ifndef CV_LIGHT_ENVMAP_CACHE_H
#define CV_LIGHT_ENVMAP_CACHE_H

#include <stdint.h>

#include "light/envmap.h"

#define CV_ENVMAP_CACHE_MAX 16

typedef struct cv_envmap_cache cv_envmap_cache;

/* Errors: CV_ERR_INVALID (NULL), CV_ERR_NOMEM. */
int cv_envmap_cache_create(cv_envmap_cache **out);
/* Frees the cache and its maps; accepts NULL. */
void cv_envmap_cache_destroy(cv_envmap_cache *c);

/* A new copy of the map at path (*out owned by the caller), decoded by
 * cv_envmap_load on the first request for that path.  c may be NULL: then
 * exactly cv_envmap_load.  Errors as cv_envmap_load (a failed load is not
 * cached). */
int cv_envmap_cache_load(cv_envmap_cache *c, const char *path, cv_envmap **out, cv_err *err);

/* Decodes done and requests answered from the cache so far. */
void cv_envmap_cache_counts(const cv_envmap_cache *c, uint64_t *decoded, uint64_t *hits);

#endif
