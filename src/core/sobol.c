/* Owen-scrambled Sobol sequence (see sobol.h). */
#include "core/sobol.h"

/* Direction numbers V[dim][bit] of Joe & Kuo's new-joe-kuo-6.21201 (dims 1..8
 * of their file; dim 0 = van der Corput), expanded to 32 bits by the
 * standard recurrence from (s, a, m): (1,0,{1}) (2,1,{1,3}) (3,1,{1,3,1})
 * (3,2,{1,1,1}) (4,1,{1,1,3,3}) (4,4,{1,3,5,13}) (5,2,{1,1,5,5,17}).
 * tests/core checks the expansion against that recurrence. */
static const uint32_t dirnum[CV_SOBOL_DIMS][32] = {
    {0x80000000u, 0x40000000u, 0x20000000u, 0x10000000u, 0x08000000u, 0x04000000u, 0x02000000u, 0x01000000u, 0x00800000u, 0x00400000u, 0x00200000u, 0x00100000u, 0x00080000u, 0x00040000u, 0x00020000u, 0x00010000u, 0x00008000u, 0x00004000u, 0x00002000u, 0x00001000u, 0x00000800u, 0x00000400u, 0x00000200u, 0x00000100u, 0x00000080u, 0x00000040u, 0x00000020u, 0x00000010u, 0x00000008u, 0x00000004u, 0x00000002u, 0x00000001u},
    {0x80000000u, 0xc0000000u, 0xa0000000u, 0xf0000000u, 0x88000000u, 0xcc000000u, 0xaa000000u, 0xff000000u, 0x80800000u, 0xc0c00000u, 0xa0a00000u, 0xf0f00000u, 0x88880000u, 0xcccc0000u, 0xaaaa0000u, 0xffff0000u, 0x80008000u, 0xc000c000u, 0xa000a000u, 0xf000f000u, 0x88008800u, 0xcc00cc00u, 0xaa00aa00u, 0xff00ff00u, 0x80808080u, 0xc0c0c0c0u, 0xa0a0a0a0u, 0xf0f0f0f0u, 0x88888888u, 0xccccccccu, 0xaaaaaaaau, 0xffffffffu},
    {0x80000000u, 0xc0000000u, 0x60000000u, 0x90000000u, 0xe8000000u, 0x5c000000u, 0x8e000000u, 0xc5000000u, 0x68800000u, 0x9cc00000u, 0xee600000u, 0x55900000u, 0x80680000u, 0xc09c0000u, 0x60ee0000u, 0x90550000u, 0xe8808000u, 0x5cc0c000u, 0x8e606000u, 0xc5909000u, 0x6868e800u, 0x9c9c5c00u, 0xeeee8e00u, 0x5555c500u, 0x8000e880u, 0xc0005cc0u, 0x60008e60u, 0x9000c590u, 0xe8006868u, 0x5c009c9cu, 0x8e00eeeeu, 0xc5005555u},
    {0x80000000u, 0xc0000000u, 0x20000000u, 0x50000000u, 0xf8000000u, 0x74000000u, 0xa2000000u, 0x93000000u, 0xd8800000u, 0x25400000u, 0x59e00000u, 0xe6d00000u, 0x78080000u, 0xb40c0000u, 0x82020000u, 0xc3050000u, 0x208f8000u, 0x51474000u, 0xfbea2000u, 0x75d93000u, 0xa0858800u, 0x914e5400u, 0xdbe79e00u, 0x25db6d00u, 0x58800080u, 0xe54000c0u, 0x79e00020u, 0xb6d00050u, 0x800800f8u, 0xc00c0074u, 0x200200a2u, 0x50050093u},
    {0x80000000u, 0x40000000u, 0x20000000u, 0xb0000000u, 0xf8000000u, 0xdc000000u, 0x7a000000u, 0x9d000000u, 0x5a800000u, 0x2fc00000u, 0xa1600000u, 0xf0b00000u, 0xda880000u, 0x6fc40000u, 0x81620000u, 0x40bb0000u, 0x22878000u, 0xb3c9c000u, 0xfb65a000u, 0xddb2d000u, 0x78022800u, 0x9c0b3c00u, 0x5a0fb600u, 0x2d0ddb00u, 0xa2878080u, 0xf3c9c040u, 0xdb65a020u, 0x6db2d0b0u, 0x800228f8u, 0x400b3cdcu, 0x200fb67au, 0xb00ddb9du},
    {0x80000000u, 0x40000000u, 0x60000000u, 0x30000000u, 0xc8000000u, 0x24000000u, 0x56000000u, 0xfb000000u, 0xe0800000u, 0x70400000u, 0xa8600000u, 0x14300000u, 0x9ec80000u, 0xdf240000u, 0xb6d60000u, 0x8bbb0000u, 0x48008000u, 0x64004000u, 0x36006000u, 0xcb003000u, 0x2880c800u, 0x54402400u, 0xfe605600u, 0xef30fb00u, 0x7e48e080u, 0xaf647040u, 0x1eb6a860u, 0x9f8b1430u, 0xd6c81ec8u, 0xbb249f24u, 0x80d6d6d6u, 0x40bbbbbbu},
    {0x80000000u, 0xc0000000u, 0xa0000000u, 0xd0000000u, 0x58000000u, 0x94000000u, 0x3e000000u, 0xe3000000u, 0xbe800000u, 0x23c00000u, 0x1e200000u, 0xf3100000u, 0x46780000u, 0x67840000u, 0x78460000u, 0x84670000u, 0xc6788000u, 0xa784c000u, 0xd846a000u, 0x5467d000u, 0x9e78d800u, 0x33845400u, 0xe6469e00u, 0xb7673300u, 0x20f86680u, 0x104477c0u, 0xf8668020u, 0x4477c010u, 0x668020f8u, 0x77c01044u, 0x8020f866u, 0xc0104477u},
    {0x80000000u, 0x40000000u, 0xa0000000u, 0x50000000u, 0x88000000u, 0x24000000u, 0x12000000u, 0x2d000000u, 0x76800000u, 0x9e400000u, 0x08200000u, 0x64100000u, 0xb2280000u, 0x7d140000u, 0xfea20000u, 0xba490000u, 0x1a248000u, 0x491b4000u, 0xc4b5a000u, 0xe3739000u, 0xf6800800u, 0xde400400u, 0xa8200a00u, 0x34100500u, 0x3a280880u, 0x59140240u, 0xeca20120u, 0x974902d0u, 0x6ca48768u, 0xd75b49e4u, 0xcc95a082u, 0x87639641u},
};

uint32_t cv_sobol_u32(uint32_t index, int dim) {
  uint32_t x = 0;
  for (int b = 0; index; b++, index >>= 1)
    if (index & 1u) x ^= dirnum[dim][b];
  return x;
}

static inline uint32_t reverse_bits(uint32_t x) {
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  x = ((x >> 4) & 0x0F0F0F0Fu) | ((x & 0x0F0F0F0Fu) << 4);
  return __builtin_bswap32(x);
}

/* The same by shifts and masks only (vectorises where bswap does not). */
static inline uint32_t reverse_bits_sm(uint32_t x) {
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  x = ((x >> 4) & 0x0F0F0F0Fu) | ((x & 0x0F0F0F0Fu) << 4);
  x = ((x >> 8) & 0x00FF00FFu) | ((x & 0x00FF00FFu) << 8);
  return (x >> 16) | (x << 16);
}

/* Burley 2020, listing 2: a hash whose low bits depend only on lower bits
 * (Laine-Karras), applied to reversed bits = nested uniform (Owen) scramble. */
static inline uint32_t lk_permutation(uint32_t x, uint32_t seed) {
  x += seed;
  x ^= x * 0x6c50b47cu;
  x ^= x * 0xb82f1e52u;
  x ^= x * 0xc7afe638u;
  x ^= x * 0x8d22f6e6u;
  return x;
}

static inline uint32_t owen(uint32_t x, uint32_t seed) {
  return reverse_bits(lk_permutation(reverse_bits(x), seed));
}

uint32_t cv_hash_u32(uint32_t x) {
  /* lowbias32 by Chris Wellons */
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

uint32_t cv_hash_combine(uint32_t seed, uint32_t v) {
  return seed ^ (cv_hash_u32(v) + 0x9e3779b9u + (seed << 6) + (seed >> 2));
}

static inline float to_unit(uint32_t x) {
  /* top 24 bits: exactly representable, strictly below 1 */
  return (float)(x >> 8) * 0x1p-24f;
}

void cv_sobol_owen_n(uint32_t index, uint32_t seed, int ndims, float *u) {
  uint32_t i = owen(index, seed);
  for (int d = 0; d < ndims; d++)
    u[d] = to_unit(owen(cv_sobol_u32(i, d), cv_hash_combine(seed, (uint32_t)d + 1u)));
}

float cv_sobol_owen(uint32_t index, int dim, uint32_t seed) {
  uint32_t i = owen(index, seed);
  return to_unit(owen(cv_sobol_u32(i, dim), cv_hash_combine(seed, (uint32_t)dim + 1u)));
}

static inline uint32_t reverse_byte(uint32_t v) { return reverse_bits(v) >> 24; }

void cv_sobol_tab_init(cv_sobol_tab *tab) {
  for (int d = 0; d < CV_SOBOL_DIMS; d++)
    for (int b = 0; b < 4; b++)
      for (uint32_t v = 0; v < 256; v++) {
        /* byte b of the scrambled index y = lk(reverse(index)) is byte 3 - b
         * of i = reverse(y), bit-reversed */
        const uint32_t vi = reverse_byte(v);
        uint32_t x = 0;
        for (int j = 0; j < 8; j++)
          if (vi & (1u << j)) x ^= dirnum[d][8 * (3 - b) + j];
        tab->t[b][v][d] = reverse_bits(x); /* stored reversed: owen() starts there */
      }
}

void cv_sobol_dim_seeds(uint32_t seed, int ndims, uint32_t *dim_seeds) {
  for (int d = 0; d < ndims; d++) dim_seeds[d] = cv_hash_combine(seed, (uint32_t)d + 1u);
}

void cv_sobol_owen_tab(const cv_sobol_tab *tab, uint32_t index, uint32_t seed,
                       const uint32_t *dim_seeds, int ndims, float *u) {
  /* the shuffled index owen(index, seed) = reverse(y): the tables are
   * indexed by the bytes of y, which saves its reversal */
  const uint32_t y = lk_permutation(reverse_bits(index), seed);
  const uint32_t y0 = y & 255u, y1 = (y >> 8) & 255u, y2 = (y >> 16) & 255u, y3 = y >> 24;
  uint32_t xr[CV_SOBOL_DIMS], z[CV_SOBOL_DIMS];
  const int n = ndims < CV_SOBOL_DIMS ? ndims : CV_SOBOL_DIMS;
  /* bit-reversed Sobol components (reversal is linear over XOR), then
   * their scrambles in a separate loop of independent lanes (the compiler
   * vectorises it: the reversal by shifts and masks, no byte swap) */
  for (int d = 0; d < n; d++)
    xr[d] = tab->t[0][y0][d] ^ tab->t[1][y1][d] ^ tab->t[2][y2][d] ^ tab->t[3][y3][d];
  for (int d = 0; d < n; d++) z[d] = reverse_bits_sm(lk_permutation(xr[d], dim_seeds[d]));
  for (int d = 0; d < n; d++) u[d] = to_unit(z[d]);
}
