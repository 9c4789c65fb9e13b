/* STM32F405 flash port for the A/B store: sectors 10 and 11 (128 KiB each), RM0090 section 3. */
#ifndef PSS_FLASH_STM32F4_H
#define PSS_FLASH_STM32F4_H

#include "storage/pss_store.h"

/* The port for the slots the linker script reserves (__table_slot_a/_b, __table_slot_size).
 * Erase and program stall the CPU (single bank; code runs from the same flash): a sector
 * erase takes about 1-2 s, during which the control tick does not run. Only commit
 * does this, and commit is only allowed while the board is idle. */
const pss_flash_t *pss_stm32f4_flash(void);

#endif /* PSS_FLASH_STM32F4_H */
