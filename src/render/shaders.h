/* The GLSL sources of shaders/ embedded at build time (embed_shaders.cmake
 * generates the table), and their lookup by file name.  Internal to the
 * render module. */
#ifndef CV_RENDER_SHADERS_H
#define CV_RENDER_SHADERS_H

typedef struct cv_shader_source {
  const char *name; /* file name, e.g. "prt.frag"; NULL ends the table */
  const char *text; /* NUL-terminated GLSL */
} cv_shader_source;

extern const cv_shader_source cv_shader_sources[];

/* Source of shaders/<name>, or NULL when no such file was embedded. */
const char *cv_shader_find(const char *name);

#endif
