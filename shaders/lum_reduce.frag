// The luminance statistics of the HDR target on the GPU (cave run's
// wall-eyes, cv_renderer_shade_stats): the HDR frame need not be read back
// for them.  Per output pixel o (u_out = its image size) over the footprint
// of the resolved HDR image (u_size pixels; the target holds u_ss x u_ss
// texels per pixel, box-averaged as downsample.frag does):
//   x: sum of w * Y over its valid pixels, w = the area the pixel shares with
//      the footprint (integer units of 1 / u_out^2: exact);
//   y: sum of w;
//   z: the largest valid Y;
//   w: its invalid pixels (a NaN, Inf or negative channel), each counted by
//      the one footprint that holds its centre, so the counts add up to the
//      image's.
// Y is Rec.709 luminance (CV_Y).  Written as o_lum = x / y (NaN without a
// valid pixel: the luminance image the CPU reads back, 4 bytes a pixel) and
// o_mb = (z, w), which lum_block.frag reduces further so that the largest Y
// and the invalid count come back in a few bytes.  src/tonemap/foveal.c
// cv_lum_downsample does the same on the CPU in double; tests/render
// compares them.

uniform sampler2D u_src;
uniform ivec2 u_size;  // resolved HDR pixels (W, H)
uniform ivec2 u_out;   // output pixels
uniform int u_ss;      // supersampling factor of the target (1 or 2)
layout(location = 0) out float o_lum;
layout(location = 1) out vec2 o_mb;

vec3 cv_pixel(ivec2 p) {
  if (u_ss == 1) return texelFetch(u_src, p, 0).rgb;
  ivec2 q = 2 * p;
  return (0.25 * (texelFetch(u_src, q, 0) + texelFetch(u_src, q + ivec2(1, 0), 0) +
                  texelFetch(u_src, q + ivec2(0, 1), 0) + texelFetch(u_src, q + ivec2(1, 1), 0))).rgb;
}

// NaN, Inf or negative (by bits: immune to fast-math assumptions)
bool cv_invalid(vec3 c) {
  uvec3 b = floatBitsToUint(c);
  bvec3 special = equal(b & 0x7f800000u, uvec3(0x7f800000u));
  bvec3 neg = greaterThan(b, uvec3(0x80000000u));  // sign set and not -0.0
  return any(special) || any(neg);
}

void main() {
  ivec2 o = ivec2(gl_FragCoord.xy);
  // footprint [o * size / out, (o + 1) * size / out) in pixels, in units of
  // 1 / out: [o * size, (o + 1) * size)
  ivec2 a = o * u_size, b = (o + 1) * u_size;
  ivec2 p0 = a / u_out, p1 = (b + u_out - 1) / u_out;
  float s = 0.0, sw = 0.0, mx = 0.0, bad = 0.0;
  for (int y = p0.y; y < p1.y; y++) {
    int wy = min((y + 1) * u_out.y, b.y) - max(y * u_out.y, a.y);
    bool own_y = 2 * a.y <= (2 * y + 1) * u_out.y && (2 * y + 1) * u_out.y < 2 * b.y;
    for (int x = p0.x; x < p1.x; x++) {
      int wx = min((x + 1) * u_out.x, b.x) - max(x * u_out.x, a.x);
      vec3 c = cv_pixel(ivec2(x, y));
      if (cv_invalid(c)) {
        bool own_x = 2 * a.x <= (2 * x + 1) * u_out.x && (2 * x + 1) * u_out.x < 2 * b.x;
        if (own_x && own_y) bad += 1.0;
        continue;
      }
      float Y = dot(c, CV_Y), w = float(wx * wy);
      s += w * Y;
      sw += w;
      mx = max(mx, Y);
    }
  }
  o_lum = sw > 0.0 ? s / sw : uintBitsToFloat(0x7fc00000u);
  o_mb = vec2(mx, bad);
}
