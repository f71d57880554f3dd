/* Embedded textures written to the texture cache (see texture_embed.h). */
#include "io/texture_embed.h"

#include <errno.h>
#include <inttypes.h>
#include <limits.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/hash.h"
#include "core/outfile.h"
#include "io/png.h"

/* mkdir -p of path (modified in place and restored). */
static int make_dirs(char *path) {
  for (char *p = path + 1; *p; p++) {
    if (*p != '/') continue;
    *p = '\0';
    int bad = mkdir(path, 0777) && errno != EEXIST;
    *p = '/';
    if (bad) return -1;
  }
  return mkdir(path, 0777) && errno != EEXIST ? -1 : 0;
}

/* The cache folder (created) into dir. */
static int cache_dir(char *dir, size_t n, cv_err *err) {
  const char *env = getenv("CAVE_TEXTURE_DIR"), *xdg = getenv("XDG_CACHE_HOME"),
             *home = getenv("HOME");
  int len;
  if (env && *env) len = snprintf(dir, n, "%s", env);
  else if (xdg && *xdg) len = snprintf(dir, n, "%s/cave/textures", xdg);
  else if (home && *home) len = snprintf(dir, n, "%s/.cache/cave/textures", home);
  else
    return cv_err_set(err, CV_ERR_CONFIG,
                      "embedded texture: no texture cache (set CAVE_TEXTURE_DIR, or HOME)");
  if (len < 0 || (size_t)len >= n)
    return cv_err_set(err, CV_ERR_RANGE, "embedded texture: cache path too long");
  if (make_dirs(dir))
    return cv_err_set(err, CV_ERR_IO, "embedded texture: cannot create the cache %s: %s", dir,
                      strerror(errno));
  return CV_OK;
}

/* The embedded texture ref names, or NULL. */
static const struct aiTexture *find(const struct aiScene *sc, const char *ref, long *index) {
  *index = -1;
  if (ref[0] == '*') {
    char *end;
    errno = 0;
    long i = strtol(ref + 1, &end, 10);
    if (end == ref + 1 || *end || errno) return NULL;
    *index = i;
    return i >= 0 && (unsigned long)i < sc->mNumTextures ? sc->mTextures[i] : NULL;
  }
  const char *base = strrchr(ref, '/');
  base = base ? base + 1 : ref;
  for (unsigned i = 0; i < sc->mNumTextures; i++) {
    const struct aiTexture *t = sc->mTextures[i];
    if (!t || !t->mFilename.length) continue;
    const char *f = t->mFilename.data, *fb = strrchr(f, '/');
    fb = fb ? fb + 1 : f;
    if (!strcmp(f, ref) || !strcmp(fb, base)) {
      *index = i;
      return t;
    }
  }
  return NULL;
}

int cv_texture_embedded_file(const struct aiScene *sc, const char *ref, char *out, size_t n,
                             cv_err *err) {
  long index;
  const struct aiTexture *t = find(sc, ref, &index);
  if (!t) {
    if (ref[0] != '*') return 0;
    cv_err_set(err, CV_ERR_FORMAT, "embedded texture '%s': the model has %u embedded textures",
               ref, sc->mNumTextures);
    return -1;
  }
  const uint8_t *bytes = (const uint8_t *)t->pcData;
  uint8_t *rgba = NULL;
  size_t nbytes;
  const char *ext;
  if (t->mHeight == 0) { /* compressed: mWidth bytes */
    nbytes = t->mWidth;
    if (nbytes >= 8 && !memcmp(bytes, "\x89PNG\r\n\x1a\n", 8)) ext = "png";
    else if (nbytes >= 3 && bytes[0] == 0xff && bytes[1] == 0xd8 && bytes[2] == 0xff) ext = "jpg";
    else {
      cv_err_set(err, CV_ERR_UNSUPPORTED,
                 "embedded texture %ld ('%s', format hint '%.8s'): neither PNG nor JPEG bytes",
                 index, ref, t->achFormatHint);
      return -1;
    }
  } else { /* raw aiTexel (b, g, r, a) */
    const size_t np = (size_t)t->mWidth * t->mHeight;
    if (t->mWidth > 65536 || t->mHeight > 65536 || !(rgba = malloc(4 * np + 1))) {
      cv_err_set(err, CV_ERR_NOMEM, "embedded texture %ld: %u x %u texels", index, t->mWidth,
                 t->mHeight);
      return -1;
    }
    for (size_t i = 0; i < np; i++) {
      rgba[4 * i] = t->pcData[i].r, rgba[4 * i + 1] = t->pcData[i].g;
      rgba[4 * i + 2] = t->pcData[i].b, rgba[4 * i + 3] = t->pcData[i].a;
    }
    bytes = rgba;
    nbytes = 4 * np;
    ext = "png";
  }
  char dir[PATH_MAX], path[PATH_MAX + 64];
  uint64_t h = cv_hash64(bytes, nbytes);
  if (rgba) h = cv_hash64_u64(cv_hash64_u64(h, t->mWidth), t->mHeight);
  int rc = -1;
  if (cache_dir(dir, sizeof dir, err)) goto done;
  snprintf(path, sizeof path, "%s/embedded-%016" PRIx64 ".%s", dir, h, ext);
  if (access(path, R_OK) != 0) {
    if (rgba) {
      if (cv_png_write(path, (int)t->mWidth, (int)t->mHeight, 4, rgba, err)) goto done;
    } else {
      cv_outfile of;
      if (cv_outfile_open(&of, path, 1, err)) goto done;
      if (fwrite(bytes, 1, nbytes, of.f) != nbytes) {
        cv_outfile_abort(&of);
        cv_err_set(err, CV_ERR_IO, "%s: cannot write: %s", path, strerror(errno));
        goto done;
      }
      if (cv_outfile_commit(&of, err)) goto done;
    }
  }
  char abs[PATH_MAX];
  const char *p = realpath(path, abs) ? abs : path;
  if (strlen(p) >= n) {
    cv_err_set(err, CV_ERR_RANGE, "%s: path longer than %zu bytes", p, n - 1);
    goto done;
  }
  memcpy(out, p, strlen(p) + 1);
  rc = 1;
done:
  free(rgba);
  return rc;
}
