/* Travel-domain relaxation: per-tick direct model and inverse (relax.h). */
#include "relax.h"

void relax_reset(relax_state_t *s, int32_t x0_q16)
{
    s->r_q32 = (int64_t)x0_q16 * 65536;
    s->v_prev_q16 = x0_q16;
}

int32_t relax_direct(relax_state_t *s, const relax_params_t *rp, int32_t x_q16)
{
    return relax_direct_inline(s, rp, x_q16);
}

int32_t relax_inverse(relax_state_t *s, const relax_params_t *rp, int32_t v_q16)
{
    return relax_inverse_inline(s, rp, v_q16);
}
