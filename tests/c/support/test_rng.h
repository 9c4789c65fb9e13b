/* Deterministic pseudo-random numbers for property tests (xorshift64*, Box-Muller). */
#ifndef TEST_RNG_H
#define TEST_RNG_H

#include <math.h>
#include <stdint.h>

typedef struct { uint64_t s; } test_rng_t;

static inline void test_rng_seed(test_rng_t *r, uint64_t seed) { r->s = seed ? seed : 0x9E3779B97F4A7C15ull; }

static inline uint64_t test_rng_u64(test_rng_t *r)
{
    r->s ^= r->s >> 12;
    r->s ^= r->s << 25;
    r->s ^= r->s >> 27;
    return r->s * 0x2545F4914F6CDD1Dull;
}

/* Uniform in [lo, hi). */
static inline double test_rng_uniform(test_rng_t *r, double lo, double hi)
{
    return lo + (hi - lo) * (double)(test_rng_u64(r) >> 11) * (1.0 / 9007199254740992.0);
}

/* Standard normal. */
static inline double test_rng_normal(test_rng_t *r)
{
    double u1 = test_rng_uniform(r, 1e-12, 1.0), u2 = test_rng_uniform(r, 0.0, 1.0);
    return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}

#endif /* TEST_RNG_H */
