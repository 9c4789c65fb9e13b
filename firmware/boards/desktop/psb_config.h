/* Virtual board configuration: the instrument it stands for and the limits no table may widen. */
#ifndef PSB_CONFIG_H
#define PSB_CONFIG_H

#include "ps_table.h"

#ifndef PSB_INSTRUMENT_ID
/* PSB_INSTRUMENT_ID: id of the instrument the board drives (ps_vboard --instrument ID overrides it);
 * a table for another is refused. Default PST_INSTRUMENT_DEFAULT (1), what `playscope tables` writes. */
#define PSB_INSTRUMENT_ID PST_INSTRUMENT_DEFAULT
#endif
#ifndef PSB_Q_UNIT
/* PSB_Q_UNIT: unit of the actuator (ps_vboard --unit mm|deg overrides it). Default PST_Q_UNIT_MM. */
#define PSB_Q_UNIT PST_Q_UNIT_MM
#endif
#ifndef PSB_Q_ABS_Q16
/* PSB_Q_ABS_Q16: the board commands q within +-this (Q16.16 units; ps_vboard --q-limit). Default 100. */
#define PSB_Q_ABS_Q16 (100 * 65536)
#endif
#ifndef PSB_C_ABS_Q16
/* PSB_C_ABS_Q16: the instrument bends within +-this (Q16.16 deg; ps_vboard --c-limit). Default 180 deg. */
#define PSB_C_ABS_Q16 (180 * 65536)
#endif
#ifndef PSB_B_MAX_Q16
/* PSB_B_MAX_Q16: largest play the instrument can have (Q16.16 units; ps_vboard --b-max). Default 10. */
#define PSB_B_MAX_Q16 (10 * 65536)
#endif

/* The board's limits as the link holds every table to them. */
static inline pst_limits_t psb_limits(void)
{
    return (pst_limits_t){.instrument_id = PSB_INSTRUMENT_ID, .q_unit = PSB_Q_UNIT, .q_min_q16 = -PSB_Q_ABS_Q16,
                          .q_max_q16 = PSB_Q_ABS_Q16, .c_min_q16 = -PSB_C_ABS_Q16, .c_max_q16 = PSB_C_ABS_Q16,
                          .b_max_q16 = PSB_B_MAX_Q16};
}

#endif /* PSB_CONFIG_H */
