/* Float image buffers (see image.h). */
#include "core/image.h"

#include <stdint.h>
#include <stdlib.h>

#include "core/status.h"

int cv_image_create(int w, int h, int c, cv_image **out) {
  *out = NULL;
  if (w <= 0 || h <= 0 || c <= 0 || c > 4) return CV_ERR_INVALID;
  if ((size_t)w > SIZE_MAX / (size_t)h / (size_t)c / sizeof(float)) return CV_ERR_NOMEM;
  cv_image *img = malloc(sizeof *img);
  if (!img) return CV_ERR_NOMEM;
  img->px = calloc((size_t)w * (size_t)h * (size_t)c, sizeof(float));
  if (!img->px) {
    free(img);
    return CV_ERR_NOMEM;
  }
  img->w = w;
  img->h = h;
  img->c = c;
  *out = img;
  return CV_OK;
}

void cv_image_destroy(cv_image *img) {
  if (!img) return;
  free(img->px);
  free(img);
}
