/* Simulated NOR flash: erase to 0xFF, program ANDs bits, power can be cut after any byte. */
#include "storage/pss_flash_sim.h"

#include <string.h>

/* Spend one byte of the power budget; false once power is gone. */
static int spend(pss_sim_t *sim)
{
    if (sim->dead)
        return 0;
    if (sim->budget_bytes == 0) {
        sim->dead = 1;
        return 0;
    }
    if (sim->budget_bytes > 0)
        sim->budget_bytes--;
    return 1;
}

static int sim_erase(void *ctx, uint8_t slot)
{
    pss_sim_t *sim = ctx;
    if (slot > 1)
        return -1;
    uint8_t *m = sim->mem + (uint32_t)slot * sim->slot_size;
    for (uint32_t i = 0; i < sim->slot_size; i++) {
        if (!spend(sim))
            return -1;
        m[i] = 0xFF;
        sim->n_erase_bytes++;
    }
    return 0;
}

static int sim_program(void *ctx, uint8_t slot, uint32_t off, const uint8_t *data, uint32_t len)
{
    pss_sim_t *sim = ctx;
    if (slot > 1 || off > sim->slot_size || len > sim->slot_size - off)
        return -1;
    uint8_t *m = sim->mem + (uint32_t)slot * sim->slot_size + off;
    for (uint32_t i = 0; i < len; i++) {
        if (!spend(sim))
            return -1;
        m[i] &= data[i]; /* NOR: programming can only clear bits */
        sim->n_program_bytes++;
    }
    return 0;
}

static int sim_read(void *ctx, uint8_t slot, uint32_t off, uint8_t *out, uint32_t len)
{
    pss_sim_t *sim = ctx;
    if (slot > 1 || off > sim->slot_size || len > sim->slot_size - off)
        return -1;
    memcpy(out, sim->mem + (uint32_t)slot * sim->slot_size + off, len);
    return 0;
}

void pss_sim_init(pss_sim_t *sim, uint8_t *mem, uint32_t slot_size, int erase_all)
{
    memset(sim, 0, sizeof(*sim));
    sim->mem = mem;
    sim->slot_size = slot_size;
    sim->budget_bytes = -1;
    if (erase_all)
        memset(mem, 0xFF, 2u * slot_size);
    sim->port.slot_size = slot_size;
    sim->port.erase = sim_erase;
    sim->port.program = sim_program;
    sim->port.read = sim_read;
    sim->port.ctx = sim;
}

void pss_sim_power_on(pss_sim_t *sim, int64_t budget_bytes)
{
    sim->dead = 0;
    sim->budget_bytes = budget_bytes;
}
