/* Float image buffers: w x h pixels of c interleaved channels, row 0 at the
 * top.  Used for HDR environment maps, rendered views and PNG previews. */
#ifndef CV_CORE_IMAGE_H
#define CV_CORE_IMAGE_H

#include <stddef.h>

typedef struct cv_image {
  int w, h, c;  /* width, height, channels (1..4) */
  float *px;    /* w*h*c floats, owned by the image */
} cv_image;

/* Allocates a zeroed image; *out owned by the caller (cv_image_destroy).
 * Returns CV_ERR_INVALID for non-positive sizes, CV_ERR_NOMEM. */
int cv_image_create(int w, int h, int c, cv_image **out);
/* Frees the image; accepts NULL. */
void cv_image_destroy(cv_image *img);
/* Pointer to pixel (x, y); no bounds check. */
static inline float *cv_image_at(const cv_image *img, int x, int y) {
  return img->px + ((size_t)y * (size_t)img->w + (size_t)x) * (size_t)img->c;
}

#endif
