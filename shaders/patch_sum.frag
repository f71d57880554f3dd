// Patch means of the display target on the GPU (render_post.c; Bimber et
// al. 2006, section 3.4: the down-sampling of equation 7), in two passes of
// double-precision sums with exact area weights, so that the means equal
// cv_downsample_to_patches (src/compensate/resample.c) on the CPU within
// double rounding:
//   COLUMNS  target nu x H: per patch column u and pixel row y, the sum of
//            w_x * I(x, y) over the pixels x that overlap u;
//   ROWS     target nu x nv: per patch (u, v), the sum of w_y * S(u, y) over
//            the rows y that overlap v.
// The weights w are the lengths of the overlaps in pixel units (core/
// overlaps.h), made on the CPU once per grid: u_ent holds (pixel, weight's
// low bits, high bits, 0) per entry, cell c's entries are u_first[u_base + c]
// .. u_first[u_base + c + 1] - 1.  Each sum leaves as a double split into two
// floats (hi = float(s), lo = float(s - hi)): o_hi + o_lo is s within 2^-48.
// Rows are GL's, bottom up: row 0 is the surface's v = 0 edge.

uniform sampler2D u_src;    // COLUMNS: the display image; ROWS: the hi part of COLUMNS
uniform sampler2D u_src_lo; // ROWS: the lo part of COLUMNS
uniform usamplerBuffer u_ent;
uniform isamplerBuffer u_first;
uniform int u_base;
layout(location = 0) out vec4 o_hi;
layout(location = 1) out vec4 o_lo;

void main() {
  ivec2 o = ivec2(gl_FragCoord.xy);
#ifdef COLUMNS
  int cell = o.x;
#else
  int cell = o.y;
#endif
  int k0 = texelFetch(u_first, u_base + cell).r, k1 = texelFetch(u_first, u_base + cell + 1).r;
  dvec3 s = dvec3(0.0);
  for (int k = k0; k < k1; k++) {
    uvec4 e = texelFetch(u_ent, k);
    double w = packDouble2x32(e.yz);
#ifdef COLUMNS
    s += w * dvec3(texelFetch(u_src, ivec2(int(e.x), o.y), 0).rgb);
#else
    ivec2 p = ivec2(o.x, int(e.x));
    s += w * (dvec3(texelFetch(u_src, p, 0).rgb) + dvec3(texelFetch(u_src_lo, p, 0).rgb));
#endif
  }
  vec3 hi = vec3(s);
  o_hi = vec4(hi, 1.0);
  o_lo = vec4(vec3(s - dvec3(hi)), 1.0);
}
