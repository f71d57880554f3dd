/* Incremental 64-bit FNV-1a hashing, used to fingerprint the inputs of a
 * bake (mesh, materials, environment maps, settings) so that a cached result
 * can be reused only when the inputs are byte-for-byte identical.
 *
 * The hash is defined over bytes; the typed helpers feed values in
 * little-endian order whatever the host, so identical inputs give the same
 * hash on any machine.  FNV-1a: h = (h XOR byte) * 0x100000001b3, starting
 * from the offset basis 0xcbf29ce484222325 (Fowler, Noll, Vo;
 * http://www.isthe.com/chongo/tech/comp/fnv/).  Not a cryptographic hash. */
#ifndef CV_CORE_HASH_H
#define CV_CORE_HASH_H

#include <stddef.h>
#include <stdint.h>

/* The FNV-1a 64-bit offset basis: the hash of zero bytes. */
uint64_t cv_hash64_init(void);

/* Feeds n bytes of data (may be NULL when n == 0) into running hash h and
 * returns the new hash. */
uint64_t cv_hash64_update(uint64_t h, const void *data, size_t n);

/* Feeds the 8 bytes of v, least significant first. */
uint64_t cv_hash64_u64(uint64_t h, uint64_t v);

/* Feeds the IEEE-754 bit pattern of v (8 bytes, little-endian).  -0.0 is
 * folded to +0.0 and every NaN to one canonical NaN so that equal values
 * hash equally. */
uint64_t cv_hash64_double(uint64_t h, double v);

/* Feeds the bit patterns of n floats (4 bytes each, little-endian), with the
 * same -0.0 / NaN folding as cv_hash64_double. */
uint64_t cv_hash64_floats(uint64_t h, const float *v, size_t n);

/* Feeds the length of s (as u64) then its bytes without the terminator, so
 * that ("ab","c") and ("a","bc") hash differently.  NULL hashes like "" but
 * with a distinct length marker (UINT64_MAX). */
uint64_t cv_hash64_str(uint64_t h, const char *s);

/* Hash of a whole buffer: cv_hash64_update(cv_hash64_init(), data, n). */
uint64_t cv_hash64(const void *data, size_t n);

#endif
