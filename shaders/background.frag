// The HDR environment behind the windows (pixels no opaque triangle covers),
// looked up in a lat-long map with the project's convention
// (docs/conventions.md): u = 0.5 + atan2(d.x, -d.z)/(2 pi), v = acos(d.y)/pi,
// v = 0 the top row.  Same outputs as prt.frag (common.glsl).

noperspective in vec4 v_near;
noperspective in vec4 v_far;
uniform sampler2D u_bg;  // RGB lat-long, wraps in u

void main() {
  const float PI = 3.14159265358979;
  vec3 d = normalize(v_far.xyz / v_far.w - v_near.xyz / v_near.w);
  float u = 0.5 + atan(d.x, -d.z) / (2.0 * PI);
  float v = acos(clamp(d.y, -1.0, 1.0)) / PI;
  cv_emit(textureLod(u_bg, vec2(u, v), 0.0).rgb);
}
