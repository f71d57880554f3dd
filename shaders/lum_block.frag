// The last step of the luminance statistics on the GPU (render_passes.c):
// per output pixel, the largest Y (x) and the sum of the invalid counts (y)
// of a block of u_block x u_block pixels of lum_reduce.frag's o_mb, so that
// only (lum_res / u_block)^2 pairs come back.  Counts stay exact in float
// below 2^24 pixels.

uniform sampler2D u_src;
uniform ivec2 u_size;  // o_mb's pixels
uniform int u_block;
layout(location = 0) out vec2 o_mb;

void main() {
  ivec2 o = ivec2(gl_FragCoord.xy) * u_block;
  ivec2 e = min(o + u_block, u_size);
  float mx = 0.0, bad = 0.0;
  for (int y = o.y; y < e.y; y++)
    for (int x = o.x; x < e.x; x++) {
      vec2 q = texelFetch(u_src, ivec2(x, y), 0).rg;
      mx = max(mx, q.x);
      bad += q.y;
    }
  o_mb = vec2(mx, bad);
}
