/* Fast float sine/cosine of a turn fraction and arctangent, for sampling
 * directions (LCD final gather, light/env_sample.h), where a few 1e-7 of
 * error in a direction is far below a table cell (the env map's cells are
 * 2 pi / 256 = 0.025 rad wide, the BRDF's 1 degree) and the libm calls
 * (sincosf, atan2f: not inlined, not vectorised) showed in the gather's
 * profile.
 *
 * cv_fast_sincos2pi(u): sin and cos of 2 pi u for any finite u (reduced to
 * the nearest quarter turn, |r| <= 1/8 turn, then Taylor polynomials to
 * x^9 / x^8, whose truncation error at pi/4 is below 3e-9); max absolute
 * error CV_FAST_SINCOS_MAX_ERR over u in [-1, 1] (tests/core measures it on
 * 2^20 + 1 points of [0, 1]: 9.2e-8, float rounding).
 *
 * cv_fast_atan2(y, x): Cephes' atanf (reduction to |t| <= tan(pi/8), a
 * degree-9 odd polynomial, Moshier 1989) with the quadrant of atan2;
 * max absolute error CV_FAST_ATAN2_MAX_ERR radians (measured 2.7e-7);
 * atan2(0, 0) = 0 like libm's for +0. */
#ifndef CV_CORE_FAST_TRIG_H
#define CV_CORE_FAST_TRIG_H

#define CV_FAST_SINCOS_MAX_ERR 3e-7
#define CV_FAST_ATAN2_MAX_ERR 1e-6

static inline void cv_fast_sincos2pi(float u, float *s, float *c) {
  const float q = __builtin_roundf(4.0f * u);
  const float r = u - 0.25f * q; /* |r| <= 1/8 */
  const float x = 6.28318530717958647692f * r, x2 = x * x;
  const float sn =
      x * (1.0f + x2 * (-1.0f / 6 + x2 * (1.0f / 120 + x2 * (-1.0f / 5040 + x2 * (1.0f / 362880)))));
  const float cs =
      1.0f + x2 * (-0.5f + x2 * (1.0f / 24 + x2 * (-1.0f / 720 + x2 * (1.0f / 40320))));
  const int k = (int)q & 3;
  *s = k == 0 ? sn : (k == 1 ? cs : (k == 2 ? -sn : -cs));
  *c = k == 0 ? cs : (k == 1 ? -sn : (k == 2 ? -cs : sn));
}

/* atan of t in [0, inf). */
static inline float cv_fast_atan_pos(float t) {
  float base = 0.0f;
  if (t > 2.414213562373095f) { /* tan(3 pi / 8) */
    base = 1.5707963267948966f;
    t = -1.0f / t;
  } else if (t > 0.4142135623730950f) { /* tan(pi / 8) */
    base = 0.7853981633974483f;
    t = (t - 1.0f) / (t + 1.0f);
  }
  const float z = t * t;
  return base + ((((8.05374449538e-2f * z - 1.38776856032e-1f) * z + 1.99777106478e-1f) * z -
                  3.33329491539e-1f) * z * t + t);
}

static inline float cv_fast_atan2(float y, float x) {
  const float ax = x < 0 ? -x : x, ay = y < 0 ? -y : y;
  if (!(ax > 0)) return ay > 0 ? (y > 0 ? 1.5707963267948966f : -1.5707963267948966f) : 0.0f;
  float a = cv_fast_atan_pos(ay / ax);
  if (x < 0) a = 3.14159265358979323846f - a;
  return y < 0 ? -a : a;
}

#endif
