// Shared by the fragment stages (prepended after #version and the variant
// #defines).  Rec.709 luminance, Drago et al. 2003 (eq. 4) and Drago's
// Rec.709-style transfer with gamma 2.2, written to give the numbers of
// src/tonemap/drago.c (cv_drago_map, cv_rec709_transfer, cv_drago_image) in
// float; the uniforms are exactly cv_drago_consts (plus the table's, below).
// cv_emit() writes the outputs the variant asks for:
//   OUT_LUM      location 0, float: luminance Y (linear)
//   OUT_DISPLAY  location 0, vec4: Drago display value (TRANSFER: + Rec.709 curve)
//   OUT_HDR      location 1, vec4: linear radiance

const vec3 CV_Y = vec3(0.2126, 0.7152, 0.0722);

#ifdef OUT_DISPLAY
uniform float lwa, lwmax_a, scale, p_exp, ld_top;

#ifdef DRAGO_EXACT
// ln(1 + x) without the cancellation of log(1.0 + x) in float for small x
// (the CPU uses log1p): a 4-term series below 1e-2 (relative error < 2e-9).
float cv_log1p(float x) {
  if (x < 1e-2) return x * (1.0 - x * (0.5 - x * (1.0 / 3.0 - x * 0.25)));
  return log(1.0 + x);
}

// Display value in [0, 1] of world luminance lw (cd/m2), as cv_drago_map.
float cv_drago(float lw) {
  if (!(lw > 0.0)) return 0.0;  // 0, negative, NaN
  float x = lw / lwa;              // +Inf ends at the saturation below
  if (x >= lwmax_a) return ld_top;  // at and beyond Lwmax: the curve's top (monotone)
  float ld = scale * cv_log1p(x) / log(2.0 + 8.0 * pow(x / lwmax_a, p_exp));
  if (!(ld > 0.0)) return 0.0;
  return min(ld, ld_top);
}

// Drago's Rec.709 transfer, as cv_rec709_transfer.
float cv_rec709(float e) {
  if (!(e > 0.0)) return 0.0;
  e = min(e, 1.0);
  return e <= 0.012 ? 6.75 * e : 1.099 * pow(e, 0.9 / 2.2) - 0.099;
}
vec3 cv_rec709v(vec3 e) { return vec3(cv_rec709(e.r), cv_rec709(e.g), cv_rec709(e.b)); }
#else
// The same two curves without log and pow: a rasterizer without a GPU
// (llvmpipe) runs every instruction of a shader for every pixel, branches
// included, and log, log, pow + 3 pow per pixel were a third of the shading
// pass.  Drago comes from a table (renderer.c, tone_table): a piecewise
// cubic in y = x / Lwmax' whose segment is picked by y's float exponent and
// top 4 mantissa bits (16 segments per octave, so no log is needed) and
// evaluated at the remaining 19 mantissa bits; the renderer checks each table
// it builds against cv_drago_map and falls back to DRAGO_EXACT beyond 2e-6
// (relative, floor 1e-4).  The transfer is a polynomial (cv_pow_9_22).
uniform samplerBuffer u_tone;  // RGBA32F: cubic coefficients per segment
uniform float u_lut_k;         // 1 / (lwa * lwmax_a): y = lw * u_lut_k = x / Lwmax'
uniform float u_lut_tail;      // Ld / y below the Drago table (y < 2^-126)

// The table's cubic at y in [2^-126, 1).
float cv_drago_table(float y) {
  int b = floatBitsToInt(y);
  int j = clamp((b >> 19) - 16, 0, LUT_DRAGO_SEGS - 1);  // exponent 1 and on
  float f = float(b & 0x7FFFF) * (1.0 / 524288.0);
  vec4 c = texelFetch(u_tone, j);
  return c.x + f * (c.y + f * (c.z + f * c.w));
}

// Display value in [0, 1] of world luminance lw (cd/m2), as cv_drago_map.
float cv_drago(float lw) {
  if (!(lw > 0.0)) return 0.0;      // 0, negative, NaN
  float x = lw / lwa;               // +Inf ends at the saturation below
  if (x >= lwmax_a) return ld_top;  // at and beyond Lwmax: the curve's top (monotone)
  float y = min(lw * u_lut_k, 0.99999994);
  float ld = y < 1.17549435e-38 ? y * u_lut_tail : cv_drago_table(y);
  if (!(ld > 0.0)) return 0.0;
  return min(ld, ld_top);
}

// e^(9/22) on [2^-7, 1] without pow: e = m 2^k from the float's bits (m in
// [1, 2), k in -7..0); m^(9/22) by a degree-6 polynomial in m - 1.5 (fit at
// Chebyshev nodes: 3.4e-7 at most in float), 2^(9k/22) one of 8 constants.
vec3 cv_pow_9_22(vec3 e) {
  ivec3 b = floatBitsToInt(e);
  ivec3 nk = 127 - (b >> 23);
  vec3 u = intBitsToFloat((b & 0x7FFFFF) | 0x3F800000) - 1.5;
  vec3 p = 1.1804221 + u * (0.321935777 + u * (-0.0634124726 + u * (0.0223396216 +
           u * (-0.00963720176 + u * (0.00524419423 + u * -0.00270038019)))));
  bvec3 b1 = notEqual(nk & 1, ivec3(0)), b2 = notEqual(nk & 2, ivec3(0));
  vec3 lo = mix(mix(vec3(1.0), vec3(0.753097773), b1), mix(vec3(0.567156255), vec3(0.427124113), b1), b2);
  vec3 hi = mix(mix(vec3(0.321666211), vec3(0.242246121), b1), mix(vec3(0.182435006), vec3(0.137391403), b1), b2);
  return p * mix(lo, hi, notEqual(nk & 4, ivec3(0)));
}

// Drago's Rec.709 transfer per channel, as cv_rec709_transfer.
vec3 cv_rec709v(vec3 e) {
  vec3 c = min(e, vec3(1.0));
  vec3 t = 1.099 * cv_pow_9_22(c) - 0.099;
  t = mix(t, 6.75 * c, lessThanEqual(c, vec3(0.012)));
  return mix(vec3(0.0), t, greaterThan(e, vec3(0.0)));  // 0, negative, NaN -> 0
}
#endif
layout(location = 0) out vec4 o_display;
#endif

#ifdef OUT_HDR
layout(location = 1) out vec4 o_hdr;
#endif
#ifdef OUT_LUM
layout(location = 0) out float o_lum;
#endif

void cv_emit(vec3 L) {
#ifdef OUT_LUM
  o_lum = dot(L, CV_Y);
#endif
#ifdef OUT_HDR
  o_hdr = vec4(L, 1.0);
#endif
#ifdef OUT_DISPLAY
  // Colour scaled by Ld/Lw, clamped per channel (cv_drago_image).
  float lw = dot(L, CV_Y);
  float s = lw > 0.0 ? cv_drago(lw) / lw : 0.0;
  vec3 e = min(L * s, vec3(1.0));
#ifdef TRANSFER
  e = cv_rec709v(e);
#endif
  o_display = vec4(e, 1.0);
#endif
}
