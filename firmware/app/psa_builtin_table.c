/* The built-in table: small, plausible, exercises both B and f. */
#include "psa_builtin_table.h"

#include <string.h>

#include "ps_fixed.h"
#include "ps_table.h"
#include "table_write.h"

enum {
    BUILTIN_N = 33,                 /* grid entries, q = -16 .. +16 mm */
    BUILTIN_X0_Q16 = -16 * PS_Q16_ONE,
    BUILTIN_STEP_Q16 = PS_Q16_ONE,  /* 1 mm, a power of two in raw units */
};

size_t psa_builtin_table(uint8_t *buf, size_t cap)
{
    return psa_builtin_table_ops(buf, cap, PST_F_COARSE, 0, NULL, NULL);
}

size_t psa_builtin_table_ops(uint8_t *buf, size_t cap, uint8_t f_kind, uint16_t n_ops, const int32_t *r_q16,
                             const int32_t *w_q16)
{
    int32_t b_q16[BUILTIN_N], f_q16[BUILTIN_N];
    for (int i = 0; i < BUILTIN_N; i++) {
        int32_t q_mm = i - 16;
        b_q16[i] = 3 * PS_Q16_ONE / 2 + q_mm * (PS_Q16_ONE / 50);
        f_q16[i] = 3 * q_mm * PS_Q16_ONE + q_mm * q_mm * (PS_Q16_ONE / 25);
    }
    pst_header_t h;
    memset(&h, 0, sizeof h);
    h.generation = 1;
    h.q_unit = PST_Q_UNIT_MM;
    h.f_kind = f_kind;
    h.q_min_q16 = BUILTIN_X0_Q16;
    h.q_max_q16 = BUILTIN_X0_Q16 + (BUILTIN_N - 1) * BUILTIN_STEP_Q16;
    h.b = (pst_grid_t){.x0_q16 = BUILTIN_X0_Q16, .step_q16 = BUILTIN_STEP_Q16, .n = BUILTIN_N};
    h.f = h.b;
    h.pi.n = n_ops;
    return table_write(buf, cap, &h, b_q16, f_q16, r_q16, w_q16);
}
