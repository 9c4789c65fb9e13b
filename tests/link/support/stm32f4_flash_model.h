/* Register-level model of the STM32F4 flash interface (RM0090 rev 19, section 3), for desktop tests
 * of the real flash-sector driver (firmware/boards/stm32f405/pss_flash_stm32f4.c). */
#ifndef STM32F4_FLASH_MODEL_H
#define STM32F4_FLASH_MODEL_H

#include <stdint.h>

/* What the model implements, each from the reference manual:
 *  - FLASH_KEYR (3.5.1): KEY1 then KEY2 clears CR.LOCK; any other write, or the keys out of
 *    order, locks FLASH_CR until the next reset (the chip also raises a bus error: counted
 *    in violations).
 *  - FLASH_CR (3.9.7): ignored while LOCK is set; writing LOCK = 1 locks. STRT with SER
 *    erases sector SNB; SER and PG together, or STRT without SER/MER, is a PGSERR.
 *  - Programming (3.6.4): a write to the flash array with CR.PG set programs it; its size
 *    must equal CR.PSIZE (else PGPERR), lie within one 128-bit row (else PGAERR), and the
 *    sector must not be write-protected (WRPERR). A write without PG is a PGSERR. A cell
 *    only goes from 1 to 0 (NOR: the new value is old AND data). Programming is refused
 *    while an error flag from an earlier operation is still set (PGSERR).
 *  - FLASH_SR (3.9.5): BSY is set by an erase or program and reads as set for
 *    busy_reads reads of SR; EOP is set on success only when CR.EOPIE is; the error flags
 *    and EOP clear by writing 1. A write to CR while BSY is set is a sequence violation
 *    (the manual forbids it), counted in violations.
 *  - FLASH_ACR (3.9.1): stored; DCRST while DCEN is set is a violation (3.5.2 says reset
 *    the data cache only while it is disabled).
 * Only sectors 10 and 11 (the table slots) hold data; their size is sector_size (128 KiB
 * on the chip; tests may shrink it to sweep power cuts quickly, the registers are the same).
 * Power: budget_bytes counts bytes erased or programmed; when it runs out the current
 * operation stops where it is (an erase leaves the bytes after the cut as they were, a
 * program leaves the byte unprogrammed) and the chip is dead: every later access does
 * nothing and SR reads OPERR, so the driver returns an error, until stm32f4m_power_on(). */
typedef struct {
    uint8_t *mem;                /* 2 * sector_size bytes: sector 10, then 11 */
    uint32_t sector_size;
    uint32_t busy_reads;         /* SR reads that still see BSY after an operation starts */
    uint32_t wrp_sectors;        /* bit n set: sector n write-protected (nWRP cleared) */
    int64_t budget_bytes;        /* < 0: unlimited */
    /* registers */
    uint32_t acr, sr, cr;
    uint8_t key_state;           /* 0: expect KEY1, 1: expect KEY2, 2: locked until reset */
    uint32_t busy_left;
    uint8_t dead;
    /* statistics for the tests */
    uint32_t n_erase_bytes, n_program_bytes, n_unlocks, n_sector_erases, violations;
} stm32f4m_t;

/* Bind the model (the one the driver sees) to mem; reset registers (LOCK set); erase both
 * sectors if erase_all. busy_reads 3, no write protection, unlimited power. */
void stm32f4m_init(stm32f4m_t *m, uint8_t *mem, uint32_t sector_size, int erase_all);

/* Reset (power on): registers to their reset values, contents kept, new budget. */
void stm32f4m_power_on(stm32f4m_t *m, int64_t budget_bytes);

#endif /* STM32F4_FLASH_MODEL_H */
