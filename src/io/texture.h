/* Diffuse albedo textures: a PNG (libpng) or JPEG (libjpeg) file,
 * sRGB-encoded as glTF's baseColorTexture and MTL's map_Kd are, decoded to
 * linear RGB floats, and bilinear lookup with repeat wrapping (glTF's
 * default sampler).  Embedded textures are written to files by the import
 * (mesh_import.h) and read from there like any other. */
#ifndef CV_IO_TEXTURE_H
#define CV_IO_TEXTURE_H

#include "core/image.h"
#include "core/status.h"

/* Reads the PNG or JPEG at path (told apart by the file's first bytes, not
 * its name) into a new 3-channel linear-RGB image *out (gray is replicated,
 * alpha dropped; sRGB decoded by IEC 61966-2-1).  Errors: CV_ERR_IO (cannot
 * open), CV_ERR_FORMAT (neither format; a corrupt file, libjpeg's warnings
 * included: they mean decoded garbage; CMYK JPEG; over 32768 texels a side),
 * CV_ERR_NOMEM; the message names the file. */
int cv_texture_load(const char *path, cv_image **out, cv_err *err);

/* Scales each channel of the linear texture t so that its mean equals
 * albedo, the material's stored albedo (the model's colour factor times the
 * texture's mean, or an albedo override: docs/scene-config.md): per pixel
 * the surface then has the albedo the bake gave other surfaces' bounces, the
 * colour factor included (glTF: base colour = factor x texture).  Channels
 * whose mean is 0 are left as they are. */
void cv_texture_match_mean(cv_image *t, const float albedo[3]);

/* Bilinear sample at (u, v), origin at the image's bottom-left (assimp's
 * convention: v = 0 is the last row), texel centres at (i + 0.5) / w,
 * coordinates wrapped (repeat).  rgb gets 3 floats. */
void cv_texture_sample(const cv_image *t, double u, double v, float rgb[3]);

#endif
