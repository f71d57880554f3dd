// PRT shading of the visible surfaces: the vertex radiance interpolated over
// the triangle (as the CPU reference `cave shade --view` interpolates it at
// the ray's hit), plus, with SUN, the sun's direct light with shadow-map
// visibility per pixel:  E/pi * albedo * max(0, n_t . s) * V, n_t the
// triangle's normal as in cv_sun_direct, the albedo interpolated from the
// vertices (cv_sun_direct averages the fan triangles' albedos per vertex
// and the result is interpolated the same way).  OUT_LUM gives the luminance pass; OUT_DISPLAY / OUT_HDR the
// tone-mapped and linear shading pass (common.glsl).

in vec3 v_rad;

#ifdef SUN
in vec3 v_sq;                 // shadow-map texel space: texel centres at integers, z = depth
in vec3 v_sun;                // E/pi * vertex albedo (the fan's hat-weighted mean)
uniform sampler2D u_shadow;   // the sun's depth map, fetched (compared here)
uniform ivec2 u_shadow_size;  // the map's texels (the texture's lower-left part)
uniform vec4 u_shadow_k;      // xyz: D^2, w: -D_z (D: the texel-space matrix's axis scales)
uniform float u_shadow_bias;  // offset along the normal, metres
uniform float u_sigma;        // +-1: orientation of this view and of the shadow map

vec3 cv_sun_direct() {
  // The triangle's own normal from the screen derivatives of the interpolated
  // texel-space point q = A p + t (exact: q is linear over the triangle).
  // A = D R with R a rotation whose third row is -s (shadow_texel_space), so
  // the scene-frame normal n ~ A^T n_q = R^T D n_q, and with m = D^2 n_q:
  //   n . s = -D_z n_q.z / |D n_q|,  A (n * bias) = bias * m / |D n_q|,
  // |D n_q| = sqrt(n_q . m).  u_sigma turns the screen-derivative normal
  // (towards the eye in every view: its sign depends only on the
  // projection) into the triangle's winding normal n_t of cv_sun_direct,
  // with the flip for back faces.  (gl_PrimitiveID would also give n_t, but
  // makes Mesa's draw module assemble primitives one by one: 2x slower on
  // llvmpipe.)
  vec3 nq = cross(dFdx(v_sq), dFdy(v_sq));
  vec3 m = u_shadow_k.xyz * nq;
  float inv = inversesqrt(dot(nq, m)) * (gl_FrontFacing ? u_sigma : -u_sigma);
  float c = u_shadow_k.w * nq.z * inv;
  // Bilinear percentage-closer filtering (the 2x2 texels around the point,
  // compared with GL's LEQUAL, then weighted), by a gather or texelFetch:
  // llvmpipe's shadow sampler costs several times these four fetches.
  vec3 q = v_sq + (u_shadow_bias * inv) * m;
  vec2 fl = floor(q.xy), f = q.xy - fl;
  ivec2 i = clamp(ivec2(fl), ivec2(0), u_shadow_size - 2);
#ifdef GL_ARB_texture_gather
  // One gather instead of four fetches (llvmpipe: 5-8% of the shading pass
  // at 1440^2): the 2x2 footprint whose lower-left texel is i, asked for at
  // texel coordinate i + 1 (a bilinear footprint starts at floor(c - 0.5);
  // the float rounding of (i + 1) / size moves c by far less than 0.5).
  vec4 d = textureGather(u_shadow, (vec2(i) + 1.0) / vec2(textureSize(u_shadow, 0))).wzxy;
#else
  vec4 d = vec4(texelFetch(u_shadow, i, 0).r, texelFetch(u_shadow, i + ivec2(1, 0), 0).r,
                texelFetch(u_shadow, i + ivec2(0, 1), 0).r, texelFetch(u_shadow, i + ivec2(1, 1), 0).r);
#endif
  vec4 lit = step(vec4(q.z), d);  // q.z <= depth
  float vis = mix(mix(lit.x, lit.y, f.x), mix(lit.z, lit.w, f.x), f.y);
  return c > 0.0 ? v_sun * (c * vis) : vec3(0.0);  // c NaN (degenerate) -> 0
}
#endif

#ifdef PANEL
// The dashboard LCD (cv_renderer_set_panel): within 3 mm of the panel
// rectangle the final-gather image replaces the PRT radiance.  A variant of
// its own: llvmpipe would pay for the test and the texture fetch on every
// pixel even behind a uniform that is off.
in vec3 v_pos;  // scene frame
uniform sampler2D u_panel;
uniform vec3 u_panel_c, u_panel_u, u_panel_v, u_panel_n;
uniform vec2 u_panel_half;
#endif

#ifdef TEXTURE
// Albedo textures (render_texture.c): the PRT stores a textured receiver's
// transfer without its albedo, so the texel (sRGB decoded by the GL,
// trilinear, repeat) multiplies the radiance.  Sampled outside the branch:
// implicit derivatives need uniform control flow.
in vec2 v_uv;
flat in float v_layer;  // -1: untextured triangle
uniform sampler2DArray u_albedo;
#endif

void main() {
  vec3 L = v_rad;
#ifdef SUN
  L += cv_sun_direct();
#endif
#ifdef TEXTURE
  vec3 texel = texture(u_albedo, vec3(v_uv, max(v_layer, 0.0))).rgb;
  if (v_layer >= 0.0) L *= texel;
#endif
#ifdef PANEL
  vec3 d = v_pos - u_panel_c;
  float a = dot(d, u_panel_u), b = dot(d, u_panel_v);
  if (abs(a) <= u_panel_half.x && abs(b) <= u_panel_half.y && abs(dot(d, u_panel_n)) < 0.003)
    L = texture(u_panel, vec2(0.5 + 0.5 * a / u_panel_half.x, 0.5 - 0.5 * b / u_panel_half.y)).rgb;
#endif
  cv_emit(L);
}
