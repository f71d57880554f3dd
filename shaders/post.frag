// The projector image on the GPU (render_post.c): Bimber et al. 2006's
// equation 7 with a patch-resolution delta, I = clamp(I0 - up(delta), 0, 1),
// then Drago's Rec.709 transfer, into an 8-bit target that the window shows
// as it is.  up() is cv_upsample_from_patches (src/compensate/resample.c):
// bilinear between patch centres, clamped beyond the outer ones (in float:
// the CPU's double differs by ~1e-7, a code at most; double cost llvmpipe
// 1.5x the pass), from per-column (u0, u1, f) and per-row (v0, v1, f)
// tables made on the CPU once per grid; the delta is a nu x nv RGB32F
// texture (row v = 0 at the bottom, as GL's rows).  Without a delta
// (u_delta_on 0) the image is only clamped and encoded.  Compiled with
// OUT_DISPLAY (common.glsl's transfer and o_display).

uniform sampler2D u_src;      // display-linear image (Drago, no transfer)
uniform sampler2D u_delta;    // nu x nv
uniform samplerBuffer u_cols; // per pixel column: u0, u1, f
uniform samplerBuffer u_rows; // per GL row: v0, v1, f
uniform int u_delta_on;

void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec3 i0 = texelFetch(u_src, p, 0).rgb;
  vec3 v = i0;
  if (u_delta_on != 0) {
    vec3 cu = texelFetch(u_cols, p.x).xyz, cv = texelFetch(u_rows, p.y).xyz;
    ivec2 a = ivec2(cu.xy), b = ivec2(cv.xy);
    float f = cu.z, fv = cv.z;
    vec3 r0 = mix(texelFetch(u_delta, ivec2(a.x, b.x), 0).rgb, texelFetch(u_delta, ivec2(a.y, b.x), 0).rgb, f);
    vec3 r1 = mix(texelFetch(u_delta, ivec2(a.x, b.y), 0).rgb, texelFetch(u_delta, ivec2(a.y, b.y), 0).rgb, f);
    v = i0 - mix(r0, r1, fv);
  }
  // !(v >= 0): negative and NaN to 0, as cv_apply_patch_delta
  v = mix(v, vec3(0.0), not(greaterThanEqual(v, vec3(0.0))));
  v = min(v, vec3(1.0));
  o_display = vec4(cv_rec709v(v), 1.0);
}
