// PRT shading of the visible surfaces: the vertex radiance interpolated over
// the triangle (as the CPU reference `cave shade --view` interpolates it at
// the ray's hit), plus, with SUN, the sun's direct light with shadow-map
// visibility per pixel:  E/pi * albedo * max(0, n_t . s) * V, n_t the
// triangle's normal as in cv_sun_direct, the albedo interpolated from the
// vertices (cv_sun_direct averages the fan triangles' albedos per vertex
// and the result is interpolated the same way).  OUT_LUM gives the luminance pass; OUT_DISPLAY / OUT_HDR the
// tone-mapped and linear shading pass (common.glsl).

in vec3 v_rad;
in vec3 v_pos;

#ifdef SUN
in vec3 v_alb;                     // vertex albedo (the fan's hat-weighted mean)
uniform sampler2DShadow u_shadow;  // depth compare, bilinear PCF
uniform mat4 u_shadow_mat;         // scene frame -> shadow map [0,1]^3
uniform vec3 u_sun_dir;            // unit, towards the sun
uniform vec3 u_sun_e;              // RGB irradiance / pi
uniform float u_shadow_bias;       // offset along the normal, metres
uniform vec3 u_eye;                // the eye, scene frame

vec3 cv_sun_direct() {
  // The triangle's own normal, from the screen derivatives of the position
  // (exact: the position is linear over the triangle), turned towards the
  // eye, then flipped for back faces: the winding normal n_t of
  // cv_sun_direct.  (gl_PrimitiveID would also give it, but makes Mesa's
  // draw module assemble primitives one by one: 2x slower on llvmpipe.)
  vec3 n = normalize(cross(dFdx(v_pos), dFdy(v_pos)));
  if (dot(n, u_eye - v_pos) < 0.0) n = -n;
  if (!gl_FrontFacing) n = -n;
  float c = dot(n, u_sun_dir);
  if (c <= 0.0) return vec3(0.0);
  vec4 s = u_shadow_mat * vec4(v_pos + n * u_shadow_bias, 1.0);
  return u_sun_e * v_alb * (c * texture(u_shadow, s.xyz));
}
#endif

// The dashboard LCD (cv_renderer_set_panel): within 3 mm of the panel
// rectangle the final-gather image replaces the PRT radiance.
uniform int u_panel_on;
uniform sampler2D u_panel;
uniform vec3 u_panel_c, u_panel_u, u_panel_v, u_panel_n;
uniform vec2 u_panel_half;

void main() {
  vec3 L = v_rad;
#ifdef SUN
  L += cv_sun_direct();
#endif
  if (u_panel_on != 0) {
    vec3 d = v_pos - u_panel_c;
    float a = dot(d, u_panel_u), b = dot(d, u_panel_v);
    if (abs(a) <= u_panel_half.x && abs(b) <= u_panel_half.y && abs(dot(d, u_panel_n)) < 0.003)
      L = texture(u_panel, vec2(0.5 + 0.5 * a / u_panel_half.x, 0.5 - 0.5 * b / u_panel_half.y)).rgb;
  }
  cv_emit(L);
}
