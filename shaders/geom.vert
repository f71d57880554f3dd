// The vertex stage of every geometry pass (depth, luminance, shading, unlit,
// shadow map).  One source for all of them, and `invariant gl_Position`, so
// the depth-only pass and the shading pass compute bit-identical depths and
// the shading pass can test with GL_EQUAL (Dmitriev et al. 2004, section 4.2).
// DEPTH_ONLY drops the varyings.

layout(location = 0) in vec3 a_pos;  // scene frame, metres
layout(location = 1) in vec4 a_rad;  // relit radiance (relight.vert); w unused
uniform mat4 u_mvp;                  // scene frame -> clip
invariant gl_Position;

#ifndef DEPTH_ONLY
out vec3 v_rad;
out vec3 v_pos;
#endif
#ifdef SUN
layout(location = 2) in vec3 a_alb;  // vertex albedo (the sun's direct term)
out vec3 v_alb;
#endif

void main() {
  gl_Position = u_mvp * vec4(a_pos, 1.0);
#ifndef DEPTH_ONLY
  v_rad = a_rad.xyz;
  v_pos = a_pos;
#endif
#ifdef SUN
  v_alb = a_alb;
#endif
}
