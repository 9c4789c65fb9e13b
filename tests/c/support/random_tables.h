/* Random but physically plausible calibration tables for property tests. */
#ifndef RANDOM_TABLES_H
#define RANDOM_TABLES_H

#include "ref_model.h"
#include "table_fixture.h"
#include "test_rng.h"

/* Parameters of B(q) = b0 + sum a_k exp(-(q - m_k)^2 / (2 s_k^2)) and of
 * f(q) = sign * (g1 q + sum c_k tanh((q - m_k) / s_k)), strictly monotone. */
typedef struct {
    double b0, ba[3], bm[3], bs[3];
    double g1, fc[3], fm[3], fs[3];
    int f_sign;
} random_table_t;

/* Draw one table over q in [-4, 4] and build its blob; fills ref_b/ref_f (double copies of the
 * entries, so the reference sees exactly the fixed-point table's function). */
size_t random_table_build(test_rng_t *r, fixture_blob_t *blob, ref_pwl_t *ref_b, ref_pwl_t *ref_f,
                          int f_sign);

#endif /* RANDOM_TABLES_H */
