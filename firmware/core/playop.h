/* Direct model: play operator with position-dependent width B(q) then f (paper eqs. 2, 3). */
#ifndef PLAYOP_H
#define PLAYOP_H

#include <stdint.h>
#include "calib.h"

/* State of eq. 3 written in actuator space. z is the actuator position with the play
 * taken out ("centre"), so c = f(z). Going up, q pushes z once q - z exceeds B(z)/2, and
 * then z + B(z)/2 = q, i.e. c = f(z_up(q)) = f2(q) of eq. 2; going down c = f(z_down(q)) =
 * f1(q). Inside the band z stays and c[k] = c[k-1]. With z_up <= z_down this is
 *   z[k] = min(z_down(q[k]), max(z_up(q[k]), z[k-1])),   c[k] = f(z[k]),
 * the play operator of eq. 3 for a monotone f (either sign).
 * With a transition (table v2, cal->pi_dir.n > 0) the centre goes through the
 * Prandtl-Ishlinskii operator first: c = f(y), y = sum_i w_i P_{r_i}[z] (docs/method.md).
 * With a threshold map (table v3, cal->tmap.n > 0) the operators run on u = g(z):
 * y = sum_i w_i P_{r_i}[g(z)] (thresholds proportional to B; without operators y = g(z)).
 * With a relaxation (table v4, cal->relax.kappa_q16 != 0) f reads the relaxed y:
 * c = f(R[y]), R the travel-domain relaxation of relax.h. */
typedef struct {
    const calib_t *cal;
    int32_t z_q16;               /* centre position, actuator units */
    pi_state_t pi;               /* transition operators (unused when cal->pi_dir.n = 0) */
    relax_state_t relax;         /* relaxation on y (unused when cal->relax.kappa_q16 = 0) */
} playop_t;

/* Start at centre z0_q16 (e.g. the first q, with the play assumed centred); the
 * transition's operators start at rest there (p_i = z0, or g(z0) with a map, clamped to
 * their validated input range), the relaxation at rest at their output. */
void playop_reset(playop_t *p, const calib_t *cal, int32_t z0_q16);

/* One step of eq. 3: the bending angle c[k] (deg, Q16) for actuator position q_q16.
 * Error against the exact operator on the same tables: <= cal->z_err_q16 on z, then
 * through the map (max g' times that, plus 1/2 LSB and g's sampling), the transition
 * (Lipschitz constant sum w_i, plus 1/2 LSB of rounding) and f
 * (|f'| * y error + 1/2 LSB). n = 0 (or a v1 table): exactly the pure play of eq. 3.
 * Integer-only, no divide: O(1) between reversals, O(n) at one. */
int32_t playop_step(playop_t *p, int32_t q_q16);

#endif /* PLAYOP_H */
