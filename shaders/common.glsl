// Shared by the fragment stages (prepended after #version and the variant
// #defines).  Rec.709 luminance, Drago et al. 2003 (eq. 4) and Drago's
// Rec.709-style transfer with gamma 2.2, written to give the numbers of
// src/tonemap/drago.c (cv_drago_map, cv_rec709_transfer, cv_drago_image) in
// float; the uniforms are exactly cv_drago_consts.  cv_emit() writes the
// outputs the variant asks for:
//   OUT_LUM      location 0, float: luminance Y (linear)
//   OUT_DISPLAY  location 0, vec4: Drago display value (TRANSFER: + Rec.709 curve)
//   OUT_HDR      location 1, vec4: linear radiance

const vec3 CV_Y = vec3(0.2126, 0.7152, 0.0722);

#ifdef OUT_DISPLAY
uniform float lwa, lwmax_a, scale, p_exp, ld_top;

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
  e = vec3(cv_rec709(e.r), cv_rec709(e.g), cv_rec709(e.b));
#endif
  o_display = vec4(e, 1.0);
#endif
}
