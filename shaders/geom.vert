// The vertex stage of every geometry pass (depth, luminance, shading, unlit,
// shadow map).  One source for all of them, and `invariant gl_Position`, so
// the depth-only pass and the shading pass compute bit-identical depths and
// the shading pass can test with GL_EQUAL (Dmitriev et al. 2004, section 4.2).
// DEPTH_ONLY drops the varyings; SUN adds the sun's (prt.frag), PANEL the
// position for the LCD test, TEXTURE the albedo texture's (u, v) and layer.

layout(location = 0) in vec3 a_pos;  // scene frame, metres
layout(location = 1) in vec4 a_rad;  // relit radiance (relight.vert); w unused
uniform mat4 u_mvp;                  // scene frame -> clip
invariant gl_Position;

#ifndef DEPTH_ONLY
out vec3 v_rad;
#endif
#ifdef PANEL
out vec3 v_pos;
#endif
#ifdef TEXTURE
layout(location = 3) in vec3 a_uvl;  // u, v (origin at the image's bottom-left), layer (-1: none)
out vec2 v_uv;
flat out float v_layer;
#endif
#ifdef SUN
layout(location = 2) in vec3 a_alb;  // vertex albedo (the sun's direct term)
uniform mat4 u_shadow_q;             // scene frame -> shadow-map texel space (prt.frag)
uniform vec3 u_sun_e;                // RGB irradiance / pi
out vec3 v_sq;                       // the point in shadow-map texel space
out vec3 v_sun;                      // E/pi * albedo
#endif

void main() {
  gl_Position = u_mvp * vec4(a_pos, 1.0);
#ifndef DEPTH_ONLY
  v_rad = a_rad.xyz;
#endif
#ifdef PANEL
  v_pos = a_pos;
#endif
#ifdef TEXTURE
  v_uv = a_uvl.xy;
  v_layer = a_uvl.z;
#endif
#ifdef SUN
  // Affine in the position, so the (perspective-correct) interpolation is
  // exact and the fragment stage needs no matrix.
  v_sq = (u_shadow_q * vec4(a_pos, 1.0)).xyz;
  v_sun = u_sun_e * a_alb;
#endif
}
