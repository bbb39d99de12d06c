/*
 * numpy's standard normals in plain C99 (libc and libm only): the same numbers, bit for bit,
 * as numpy.random.default_rng(entropy).standard_normal(...).
 *
 * - numpy.random.SeedSequence(entropy) with its default pool of 4 words, and
 *   generate_state(4, uint64) (numpy/random/bit_generator.pyx);
 * - the PCG64 bit generator (XSL-RR 128/64) seeded from those four words as numpy's
 *   PCG64._seed_seq / pcg64_set_seed do (numpy/random/src/pcg64);
 * - next_double = (next_uint64 >> 11) * 2^-53 and numpy's ziggurat
 *   random_standard_normal (numpy/random/src/distributions/distributions.c), with its
 *   tables (ziggurat_constants.h).
 *
 * The 128-bit state is held as two 64-bit halves, so the layout is the same on every
 * compiler; the product uses unsigned __int128 under GCC and Clang, 32-bit pieces
 * otherwise.
 */
#ifndef AUV_NUMPY_RANDOM_H
#define AUV_NUMPY_RANDOM_H

#include <stdint.h>

#if (defined(__GNUC__) || defined(__clang__)) && !defined(_WIN32)   /* no ELF visibility in a DLL */
#define NPR_HIDDEN __attribute__((visibility("hidden")))
#else
#define NPR_HIDDEN
#endif

/* a PCG64 generator: 128-bit state and increment (the increment is odd) */
typedef struct {
    uint64_t state_hi, state_lo, inc_hi, inc_lo;
} NprPcg64;

/* numpy.random.default_rng(entropy): the entropy is a list of non-negative integers, each
   split into 32-bit words lowest first (0 is one word), as numpy's
   _coerce_to_uint32_array does; a single integer seed is a list of one. At most 16. */
NPR_HIDDEN void npr_seed(NprPcg64 *g, const uint64_t *entropy, int n);

NPR_HIDDEN uint64_t npr_next_uint64(NprPcg64 *g);
NPR_HIDDEN double npr_next_double(NprPcg64 *g);            /* in [0, 1), 53 bits */
NPR_HIDDEN double npr_standard_normal(NprPcg64 *g);        /* numpy's ziggurat */

#endif
