/* Lookup of the embedded GLSL sources (see shaders.h). */
#include "render/shaders.h"

#include <string.h>

const char *cv_shader_find(const char *name) {
  for (const cv_shader_source *s = cv_shader_sources; s->name; s++)
    if (!strcmp(s->name, name)) return s->text;
  return NULL;
}
