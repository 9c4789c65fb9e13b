/* Register-level model of the STM32F4 flash interface: see stm32f4_flash_model.h for what it does and
 * where in RM0090 each behaviour comes from. Implements the accessors of stm32f405_regs.h under
 * STM32F405_REG_MODEL, so the real driver runs unchanged against it. */
#include "stm32f4_flash_model.h"

#include <string.h>

#define STM32F405_REG_MODEL 1
#include "stm32f405_regs.h"

enum {
    SECTOR_FIRST = 10,           /* the model holds sectors 10 and 11 */
    ROW_BYTES = 16,              /* 128-bit programming row */
};

static stm32f4m_t *model;
static uint32_t other_regs[64]; /* any register the model does not implement: plain storage */

void stm32f4m_power_on(stm32f4m_t *m, int64_t budget_bytes)
{
    m->acr = 0;
    m->sr = 0;
    m->cr = FLASH_CR_LOCK;       /* reset value 0x80000000 */
    m->key_state = 0;
    m->busy_left = 0;
    m->dead = 0;
    m->budget_bytes = budget_bytes;
}

void stm32f4m_init(stm32f4m_t *m, uint8_t *mem, uint32_t sector_size, int erase_all)
{
    memset(m, 0, sizeof *m);
    m->mem = mem;
    m->sector_size = sector_size;
    m->busy_reads = 3;
    if (erase_all)
        memset(mem, 0xFF, 2u * sector_size);
    stm32f4m_power_on(m, -1);
    model = m;
}

/* The driver's view of the slots: the model's array stands at sectors 10 and 11. */
uint8_t *stm32f405_model_slot_base(uint8_t slot)
{
    return model->mem + (uint32_t)slot * model->sector_size;
}

uint32_t stm32f405_model_slot_size(void)
{
    return model->sector_size;
}

volatile uint32_t *stm32f405_model_reg(uintptr_t addr)
{
    switch (addr) {
    case FLASH_BASE + 0x00u: return &model->acr;
    case FLASH_BASE + 0x0Cu: return &model->sr;
    case FLASH_BASE + 0x10u: return &model->cr;
    case FLASH_BASE + 0x04u: return &other_regs[0]; /* KEYR: write-only, reads 0 */
    default: return &other_regs[1 + (addr / 4u) % 63u];
    }
}

/* One byte of work; false when the power budget ran out before it (the chip is then dead). */
static int spend(stm32f4m_t *m)
{
    if (m->budget_bytes == 0) {
        m->dead = 1;
        return 0;
    }
    if (m->budget_bytes > 0)
        m->budget_bytes--;
    return 1;
}

static void start_busy(stm32f4m_t *m)
{
    m->sr |= FLASH_SR_BSY;
    m->busy_left = m->busy_reads;
}

static void finish_ok(stm32f4m_t *m)
{
    if (m->cr & FLASH_CR_EOPIE)
        m->sr |= FLASH_SR_EOP;
}

static void erase_sector(stm32f4m_t *m, uint32_t snb)
{
    if (snb < SECTOR_FIRST || snb > SECTOR_FIRST + 1u) {
        m->violations++; /* outside the modelled (table) sectors: the driver must never */
        return;
    }
    if (m->wrp_sectors & (1u << snb)) {
        m->sr |= FLASH_SR_WRPERR;
        return;
    }
    start_busy(m);
    m->n_sector_erases++;
    uint8_t *s = m->mem + (snb - SECTOR_FIRST) * m->sector_size;
    for (uint32_t i = 0; i < m->sector_size; i++) {
        if (!spend(m))
            return;
        s[i] = 0xFF;
        m->n_erase_bytes++;
    }
    finish_ok(m);
}

static void write_cr(stm32f4m_t *m, uint32_t v)
{
    if (m->sr & FLASH_SR_BSY)
        m->violations++; /* RM0090 3.9.7: not while an operation is ongoing */
    if (m->cr & FLASH_CR_LOCK)
        return;          /* locked: the write has no effect */
    m->cr = v & ~FLASH_CR_STRT;
    if (v & FLASH_CR_LOCK) {
        m->cr |= FLASH_CR_LOCK;
        m->key_state = 0;
        return;
    }
    if (v & FLASH_CR_STRT) {
        if ((v & FLASH_CR_PG) || !(v & (FLASH_CR_SER | FLASH_CR_MER)))
            m->sr |= FLASH_SR_PGSERR;
        else if (v & FLASH_CR_MER)
            m->violations++; /* a mass erase would wipe the firmware */
        else
            erase_sector(m, (v & FLASH_CR_SNB_MASK) >> FLASH_CR_SNB_SHIFT);
    }
}

uint32_t reg_read(volatile uint32_t *reg)
{
    stm32f4m_t *m = model;
    if (m->dead)
        return reg == &m->sr ? FLASH_SR_OPERR : 0u;
    if (reg == &m->sr && (m->sr & FLASH_SR_BSY)) {
        uint32_t v = m->sr;
        if (m->busy_left == 0 || --m->busy_left == 0)
            m->sr &= ~FLASH_SR_BSY;
        return v;
    }
    if (reg == &other_regs[0])
        return 0; /* KEYR reads as zero */
    return *reg;
}

void reg_write(volatile uint32_t *reg, uint32_t v)
{
    stm32f4m_t *m = model;
    if (m->dead)
        return;
    if (reg == &m->sr) {
        m->sr &= ~(v & (FLASH_SR_ERRORS | FLASH_SR_EOP)); /* rc_w1 */
    } else if (reg == &m->cr) {
        write_cr(m, v);
    } else if (reg == &other_regs[0]) {                      /* KEYR */
        if (m->key_state == 0 && v == FLASH_KEY1) {
            m->key_state = 1;
        } else if (m->key_state == 1 && v == FLASH_KEY2) {
            m->key_state = 0;
            m->cr &= ~FLASH_CR_LOCK;
            m->n_unlocks++;
        } else {
            m->key_state = 2; /* wrong sequence: locked until reset, bus error */
            m->cr |= FLASH_CR_LOCK;
            m->violations++;
        }
        if (m->key_state == 2)
            m->cr |= FLASH_CR_LOCK;
    } else if (reg == &m->acr) {
        if ((v & FLASH_ACR_DCRST) && (v & FLASH_ACR_DCEN))
            m->violations++;
        m->acr = v & ~FLASH_ACR_DCRST; /* DCRST: the reset happens, the bit does not stay */
    } else {
        *reg = v;
    }
}

void flash_write8(uintptr_t addr, uint8_t v)
{
    stm32f4m_t *m = model;
    if (m->dead)
        return;
    if (m->sr & FLASH_SR_BSY)
        m->violations++; /* the bus would stall; the driver waits for BSY instead */
    uintptr_t base = (uintptr_t)m->mem;
    if (addr < base || addr >= base + 2u * m->sector_size) {
        m->violations++;
        return;
    }
    uint32_t off = (uint32_t)(addr - base);
    uint32_t snb = SECTOR_FIRST + off / m->sector_size;
    if (!(m->cr & FLASH_CR_PG) || (m->cr & FLASH_CR_LOCK) || (m->sr & (FLASH_SR_PGAERR | FLASH_SR_PGPERR | FLASH_SR_PGSERR))) {
        m->sr |= FLASH_SR_PGSERR;
        return;
    }
    uint32_t psize = (m->cr & FLASH_CR_PSIZE_MASK) >> FLASH_CR_PSIZE_SHIFT;
    if (psize != 0u) { /* a byte access needs PSIZE x8 */
        m->sr |= FLASH_SR_PGPERR;
        return;
    }
    if (off / ROW_BYTES != (off + 1u - 1u) / ROW_BYTES) { /* one byte is always within a row */
        m->sr |= FLASH_SR_PGAERR;
        return;
    }
    if (m->wrp_sectors & (1u << snb)) {
        m->sr |= FLASH_SR_WRPERR;
        return;
    }
    start_busy(m);
    if (!spend(m))
        return;
    m->mem[off] &= v;
    m->n_program_bytes++;
    finish_ok(m);
}
