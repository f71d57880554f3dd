// PRT relighting of every vertex (Sloan et al. 2002; Dmitriev et al. 2004,
// section 4.1), run once per lighting change as a point draw with
// transform feedback and the rasterizer off: the exit radiance lands in a
// vertex buffer that every geometry pass of every wall-eye then reads.
// Same sums as src/prt/relight.c (cv_prt_relight), in float:
//   L_c = albedo_c * sum_i l_c,i td_i + sum_i (l_c,i + s_c,i) ti_c,i
// with s the sun's SH projection (its indirect light; the direct sun is
// added per pixel with a shadow map in prt.frag), plus the split window
// lights' per-vertex direct light (u_split) before the clamp, as
// cv_prt_relight_ex.  Negative (SH ringing) and
// non-finite channels are set to 0 and counted in the captured w.
//
// u_transfer: NC + 1 texels per vertex: texel i = (td_i, ti_R,i, ti_G,i,
// ti_B,i) for i < NC, then the vertex albedo.  NC (coefficients) is a
// compile-time #define so the loop unrolls.

uniform samplerBuffer u_transfer;
uniform vec4 u_l[NC];   // lighting without the sun, RGB in xyz
uniform vec4 u_ls[NC];  // lighting plus the sun's (and split lights') SH projection
uniform samplerBuffer u_split;  // split window lights' direct light, one texel per vertex
uniform int u_split_on;         // 1 while split lights are set (cv_renderer_set_split)
out vec4 v_out;         // captured: radiance RGB, channels clamped

void main() {
  int base = gl_VertexID * (NC + 1);
  vec3 d = vec3(0.0), ind = vec3(0.0);
  for (int i = 0; i < NC; i++) {
    vec4 t = texelFetch(u_transfer, base + i);
    d += u_l[i].xyz * t.x;
    ind += u_ls[i].xyz * t.yzw;
  }
  vec3 rad = texelFetch(u_transfer, base + NC).xyz * d + ind;
  if (u_split_on != 0) rad += texelFetch(u_split, gl_VertexID).xyz;
  float n = 0.0;
  for (int c = 0; c < 3; c++) {
    if (isnan(rad[c]) || isinf(rad[c]) || rad[c] < 0.0) {
      rad[c] = 0.0;
      n += 1.0;
    }
  }
  v_out = vec4(rad, n);
  gl_Position = vec4(0.0, 0.0, 0.0, 1.0);
}
