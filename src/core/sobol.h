/* Owen-scrambled Sobol points for quasi-Monte Carlo integration.
 *
 * Sobol (0,2)-sequence generator matrices from Joe & Kuo's
 * new-joe-kuo-6.21201 direction numbers (dimension 0 is van der Corput), and
 * Owen scrambling by hashing, with index shuffling, after Burley 2020,
 * "Practical Hash-based Owen Scrambling", JCGT 9(4).  Each (seed, dimension)
 * pair gets an independent nested uniform scramble, so different seeds give
 * statistically independent, still stratified, point sets.  Pure functions
 * of (index, dimension, seed): the same seed gives the same points on any
 * thread count or machine. */
#ifndef CV_CORE_SOBOL_H
#define CV_CORE_SOBOL_H

#include <stdint.h>

#define CV_SOBOL_DIMS 8

/* Unscrambled Sobol point component as a 32-bit fixed-point fraction;
 * dim in [0, CV_SOBOL_DIMS). */
uint32_t cv_sobol_u32(uint32_t index, int dim);
/* Owen-scrambled, shuffled Sobol component in [0, 1), for sample `index` of
 * the sequence identified by seed. */
float cv_sobol_owen(uint32_t index, int dim, uint32_t seed);
/* Fills u[0..ndims) with the scrambled components of one sample (the index is
 * shuffled once, so all dimensions of a sample stay consistent). */
void cv_sobol_owen_n(uint32_t index, uint32_t seed, int ndims, float *u);
/* Byte tables for fast generation: entry [b][v][d] is the bit-reversed XOR
 * of the direction numbers of dimension d selected by the shuffled index
 * i = reverse(y) whose byte b of y (y = the index's scramble before its
 * last reversal) has value v, so a point component costs 4 lookups instead
 * of up to 32 steps, the index shuffle skips its last reversal and the Owen
 * scramble of the component (which works on reversed bits) its first: the
 * values are those of cv_sobol_owen_n bit for bit (tests/core).
 * The dimensions of one (b, v) are adjacent, so the first four of them are
 * one 16-byte load (cv_sobol_owen_tab4).
 * 32 KiB; fill once with cv_sobol_tab_init and share read-only. */
typedef struct cv_sobol_tab {
  uint32_t t[4][256][CV_SOBOL_DIMS];
} cv_sobol_tab;

void cv_sobol_tab_init(cv_sobol_tab *tab);
/* Per-dimension scramble seeds of a sequence (dim_seeds[ndims]). */
void cv_sobol_dim_seeds(uint32_t seed, int ndims, uint32_t *dim_seeds);
/* Same values as cv_sobol_owen_n(index, seed, ndims, u), using the tables
 * and the seeds from cv_sobol_dim_seeds(seed, ...). */
void cv_sobol_owen_tab(const cv_sobol_tab *tab, uint32_t index, uint32_t seed,
                       const uint32_t *dim_seeds, int ndims, float *u);
/* cv_sobol_owen_tab for ndims = 4, inline (the LCD gather draws 4
 * dimensions a sample: the call, the dimension loop's bounds and the byte
 * swaps, which do not vectorise, cost it about half its time; tests/core
 * checks the values bit for bit against cv_sobol_owen_n). */
static inline uint32_t cv_sobol_rev_(uint32_t x) {
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  x = ((x >> 4) & 0x0F0F0F0Fu) | ((x & 0x0F0F0F0Fu) << 4);
  x = ((x >> 8) & 0x00FF00FFu) | ((x & 0x00FF00FFu) << 8);
  return (x >> 16) | (x << 16);
}
static inline uint32_t cv_sobol_lk_(uint32_t x, uint32_t seed) {
  x += seed; /* Burley 2020, listing 2 (as sobol.c) */
  x ^= x * 0x6c50b47cu;
  x ^= x * 0xb82f1e52u;
  x ^= x * 0xc7afe638u;
  x ^= x * 0x8d22f6e6u;
  return x;
}
#if defined(__GNUC__) && !defined(CV_SOBOL_SCALAR)
/* The four dimensions as the lanes of one GCC/Clang vector (SSE2 on
 * x86-64): the same integer operations lane by lane, so the same bits as
 * the scalar form below (tests/core). */
typedef uint32_t cv_sobol_v4_ __attribute__((vector_size(16)));
static inline cv_sobol_v4_ cv_sobol_ld4_(const uint32_t *p) {
  cv_sobol_v4_ v;
  __builtin_memcpy(&v, p, sizeof v);
  return v;
}
static inline void cv_sobol_owen_tab4(const cv_sobol_tab *tab, uint32_t index, uint32_t seed,
                                      const uint32_t dim_seeds[4], float u[4]) {
  const uint32_t y = cv_sobol_lk_(cv_sobol_rev_(index), seed);
  cv_sobol_v4_ x = cv_sobol_ld4_(tab->t[0][y & 255u]) ^ cv_sobol_ld4_(tab->t[1][(y >> 8) & 255u]) ^
                   cv_sobol_ld4_(tab->t[2][(y >> 16) & 255u]) ^ cv_sobol_ld4_(tab->t[3][y >> 24]);
  x += cv_sobol_ld4_(dim_seeds); /* cv_sobol_lk_ */
  x ^= x * 0x6c50b47cu;
  x ^= x * 0xb82f1e52u;
  x ^= x * 0xc7afe638u;
  x ^= x * 0x8d22f6e6u;
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1); /* cv_sobol_rev_ */
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  x = ((x >> 4) & 0x0F0F0F0Fu) | ((x & 0x0F0F0F0Fu) << 4);
  x = ((x >> 8) & 0x00FF00FFu) | ((x & 0x00FF00FFu) << 8);
  x = ((x >> 16) | (x << 16)) >> 8;
  for (int d = 0; d < 4; d++) u[d] = (float)x[d] * 0x1p-24f;
}
#else
static inline void cv_sobol_owen_tab4(const cv_sobol_tab *tab, uint32_t index, uint32_t seed,
                                      const uint32_t dim_seeds[4], float u[4]) {
  const uint32_t y = cv_sobol_lk_(cv_sobol_rev_(index), seed);
  const uint32_t y0 = y & 255u, y1 = (y >> 8) & 255u, y2 = (y >> 16) & 255u, y3 = y >> 24;
  uint32_t xr[4];
  for (int d = 0; d < 4; d++)
    xr[d] = tab->t[0][y0][d] ^ tab->t[1][y1][d] ^ tab->t[2][y2][d] ^ tab->t[3][y3][d];
  for (int d = 0; d < 4; d++)
    u[d] = (float)(cv_sobol_rev_(cv_sobol_lk_(xr[d], dim_seeds[d])) >> 8) * 0x1p-24f;
}
#endif

/* 32-bit integer hash (for deriving per-vertex / per-pixel seeds). */
uint32_t cv_hash_u32(uint32_t x);
/* Combines a seed with a value, order-dependent. */
uint32_t cv_hash_combine(uint32_t seed, uint32_t v);

#endif
