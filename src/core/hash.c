/* 64-bit FNV-1a (see hash.h). */
#include "core/hash.h"

#include <math.h>
#include <string.h>

#define CV_FNV64_BASIS 0xcbf29ce484222325ull
#define CV_FNV64_PRIME 0x100000001b3ull

uint64_t cv_hash64_init(void) { return CV_FNV64_BASIS; }

uint64_t cv_hash64_update(uint64_t h, const void *data, size_t n) {
  const unsigned char *p = data;
  for (size_t i = 0; i < n; ++i) {
    h ^= p[i];
    h *= CV_FNV64_PRIME;
  }
  return h;
}

uint64_t cv_hash64_u64(uint64_t h, uint64_t v) {
  unsigned char b[8];
  for (int i = 0; i < 8; ++i) b[i] = (unsigned char)(v >> (8 * i));
  return cv_hash64_update(h, b, 8);
}

uint64_t cv_hash64_double(uint64_t h, double v) {
  uint64_t bits;
  if (v == 0.0) v = 0.0; /* folds -0.0 */
  if (isnan(v)) {
    bits = 0x7ff8000000000000ull;
  } else {
    memcpy(&bits, &v, sizeof bits);
  }
  return cv_hash64_u64(h, bits);
}

uint64_t cv_hash64_floats(uint64_t h, const float *v, size_t n) {
  for (size_t i = 0; i < n; ++i) {
    float f = v[i];
    uint32_t bits;
    if (f == 0.0f) f = 0.0f;
    if (isnan(f)) {
      bits = 0x7fc00000u;
    } else {
      memcpy(&bits, &f, sizeof bits);
    }
    unsigned char b[4] = {(unsigned char)bits, (unsigned char)(bits >> 8),
                          (unsigned char)(bits >> 16), (unsigned char)(bits >> 24)};
    h = cv_hash64_update(h, b, 4);
  }
  return h;
}

uint64_t cv_hash64_str(uint64_t h, const char *s) {
  if (!s) return cv_hash64_u64(h, UINT64_MAX);
  size_t n = strlen(s);
  h = cv_hash64_u64(h, (uint64_t)n);
  return cv_hash64_update(h, s, n);
}

uint64_t cv_hash64(const void *data, size_t n) {
  return cv_hash64_update(cv_hash64_init(), data, n);
}
