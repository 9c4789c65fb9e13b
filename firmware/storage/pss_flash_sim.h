/* Simulated NOR flash in caller-provided RAM that can lose power after any byte (tests, QEMU image). */
#ifndef PSS_FLASH_SIM_H
#define PSS_FLASH_SIM_H

#include <stdint.h>
#include "storage/pss_store.h"

/* mem holds 2 * slot_size bytes (slot A then B). budget_bytes counts bytes erased or
 * programmed; when it reaches zero the operation in progress stops after the bytes
 * already done and fails, and every later erase/program fails too (power is gone) until
 * pss_sim_power_on(). Negative budget = unlimited. Erase proceeds from the start of the
 * slot, byte by byte, as a model of a sector erase cut short. */
typedef struct {
    uint8_t *mem;
    uint32_t slot_size;
    int64_t budget_bytes;
    uint32_t n_erase_bytes;      /* bytes erased so far (statistics for the tests) */
    uint32_t n_program_bytes;    /* bytes programmed so far */
    uint8_t dead;                /* power was cut */
    pss_flash_t port;            /* hand &sim->port to pss_mount() */
} pss_sim_t;

/* Bind a simulated flash to mem (2 * slot_size bytes), fully erased if erase_all. */
void pss_sim_init(pss_sim_t *sim, uint8_t *mem, uint32_t slot_size, int erase_all);

/* Restore power; contents stay as the cut left them. budget_bytes as above. */
void pss_sim_power_on(pss_sim_t *sim, int64_t budget_bytes);

#endif /* PSS_FLASH_SIM_H */
