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
/* 32-bit integer hash (for deriving per-vertex / per-pixel seeds). */
uint32_t cv_hash_u32(uint32_t x);
/* Combines a seed with a value, order-dependent. */
uint32_t cv_hash_combine(uint32_t seed, uint32_t v);

#endif
