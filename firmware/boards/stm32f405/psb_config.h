/* STM32F405 board configuration: the instrument this board drives and the limits no table may widen. */
#ifndef PSB_CONFIG_H
#define PSB_CONFIG_H

#include <stdbool.h>
#include <stdint.h>
#include "ps_table.h"
#include "stm32f405_regs.h"

#ifndef PSB_INSTRUMENT_ID
/* PSB_INSTRUMENT_ID: id of the instrument this board drives; a table for another is refused
 * (`playscope tables --instrument` writes it). Default PST_INSTRUMENT_DEFAULT (1). */
#define PSB_INSTRUMENT_ID PST_INSTRUMENT_DEFAULT
#endif
#ifndef PSB_Q_UNIT
/* PSB_Q_UNIT: unit of the actuator, PST_Q_UNIT_MM (cable) or PST_Q_UNIT_DEG (motor angle). Default mm. */
#define PSB_Q_UNIT PST_Q_UNIT_MM
#endif
#ifndef PSB_Q_MIN_Q16
/* PSB_Q_MIN_Q16: lower end of the travel the board may command (Q16.16 units). Default -20 mm. */
#define PSB_Q_MIN_Q16 (-20 * 65536)
#endif
#ifndef PSB_Q_MAX_Q16
/* PSB_Q_MAX_Q16: upper end of the travel the board may command (Q16.16 units). Default +20 mm. */
#define PSB_Q_MAX_Q16 (20 * 65536)
#endif
#ifndef PSB_C_MIN_Q16
/* PSB_C_MIN_Q16: lowest bending angle the instrument reaches (Q16.16 deg). Default -180 deg. */
#define PSB_C_MIN_Q16 (-180 * 65536)
#endif
#ifndef PSB_C_MAX_Q16
/* PSB_C_MAX_Q16: highest bending angle the instrument reaches (Q16.16 deg). Default +180 deg. */
#define PSB_C_MAX_Q16 (180 * 65536)
#endif
#ifndef PSB_B_MAX_Q16
/* PSB_B_MAX_Q16: largest play the instrument can have (Q16.16 units). Default 5 mm. */
#define PSB_B_MAX_Q16 (5 * 65536)
#endif
#ifndef PSB_RECOVERY_PIN
/* PSB_RECOVERY_PIN: GPIOA pin read at boot (pull-down); held high (a jumper to 3V3, or the user
 * button of boards that wire it to PA0) it erases both table slots: the physical path out of an
 * exhausted generation counter (docs/robustness.md). Default 0 (PA0). */
#define PSB_RECOVERY_PIN 0u
#endif

/* The board's limits as the link holds every table to them. */
static inline pst_limits_t psb_limits(void)
{
    return (pst_limits_t){.instrument_id = PSB_INSTRUMENT_ID, .q_unit = PSB_Q_UNIT, .q_min_q16 = PSB_Q_MIN_Q16,
                          .q_max_q16 = PSB_Q_MAX_Q16, .c_min_q16 = PSB_C_MIN_Q16, .c_max_q16 = PSB_C_MAX_Q16,
                          .b_max_q16 = PSB_B_MAX_Q16};
}

/* True while the recovery pin is held high at boot: GPIOA clocked, the pin an input with its
 * pull-down, a few cycles to settle, then read. Boot time only. */
static inline bool psb_recovery_requested(void)
{
    RCC_AHB1ENR |= RCC_AHB1ENR_GPIOAEN;
    GPIOA_MODER &= ~(3u << (2u * PSB_RECOVERY_PIN));
    GPIOA_PUPDR = (GPIOA_PUPDR & ~(3u << (2u * PSB_RECOVERY_PIN))) | (2u << (2u * PSB_RECOVERY_PIN));
    for (volatile int i = 0; i < 1000; i++)
        ;
    return (GPIOA_IDR >> PSB_RECOVERY_PIN) & 1u;
}

#endif /* PSB_CONFIG_H */
