/* Textures embedded in a model (glTF .glb buffers and data URIs, FBX, ...:
 * assimp's aiScene.mTextures, referenced as "*N" or by the file name the
 * model gives) written to files, so that the .prt can name them like any
 * other texture (docs/prt-format.md: a path per material).
 *
 * The files go to the texture cache: $CAVE_TEXTURE_DIR, else
 * $XDG_CACHE_HOME/cave/textures, else $HOME/.cache/cave/textures (created).
 * Each is named by the FNV-1a 64 hash of its bytes (embedded-<hash>.png or
 * .jpg): the same texture gives the same path, so bakes stay reproducible,
 * and a file already there is not rewritten.  Compressed textures (PNG or
 * JPEG bytes, told by their signature) are written as they are; raw texels
 * (aiTexel BGRA, mHeight > 0) as an 8-bit RGBA PNG.  A file appears only
 * when complete (temporary file + rename). */
#ifndef CV_IO_TEXTURE_EMBED_H
#define CV_IO_TEXTURE_EMBED_H

#include <stddef.h>

#include <assimp/scene.h>

#include "core/status.h"

/* If ref names a texture embedded in sc ("*N", or an mFilename equal to ref
 * or to its last path component), writes it to the cache and puts the
 * file's absolute path in out (n bytes): returns 1.  Returns 0 when ref is
 * not embedded (*err untouched), -1 on an error (*err: the texture, the
 * file, what went wrong; e.g. an index past mNumTextures, a compressed
 * format other than PNG/JPEG, an unwritable cache). */
int cv_texture_embedded_file(const struct aiScene *sc, const char *ref, char *out, size_t n,
                             cv_err *err);

#endif
