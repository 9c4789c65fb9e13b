/* STM32F405 flash driver for the table slots, written against RM0090 (section 3.6, FLASH registers). */
#include "pss_flash_stm32f4.h"

#include <stdint.h>
#include <string.h>

#include "stm32f405_regs.h"

#ifndef STM32F405_REG_MODEL
/* Linker script symbols: only their addresses matter. */
extern uint8_t __table_slot_a[], __table_slot_b[], __table_slot_size[];
static uint8_t *slot_base(uint8_t slot)
{
    return slot == 0 ? __table_slot_a : __table_slot_b;
}
static uint32_t slot_size(void)
{
    return (uint32_t)(uintptr_t)__table_slot_size;
}
#else
/* Desktop tests: the flash array of the register-level model. */
uint8_t *stm32f405_model_slot_base(uint8_t slot);
uint32_t stm32f405_model_slot_size(void);
static uint8_t *slot_base(uint8_t slot)
{
    return stm32f405_model_slot_base(slot);
}
static uint32_t slot_size(void)
{
    return stm32f405_model_slot_size();
}
#endif

enum { SECTOR_SLOT_A = 10 }; /* 0x080C0000, see stm32f405.ld; slot B is sector 11 */

static void wait_idle(void)
{
    while (reg_read(&FLASH_SR) & FLASH_SR_BSY)
        ;
}

static void unlock(void)
{
    if (reg_read(&FLASH_CR) & FLASH_CR_LOCK) {
        reg_write(&FLASH_KEYR, FLASH_KEY1);
        reg_write(&FLASH_KEYR, FLASH_KEY2);
    }
    reg_write(&FLASH_SR, FLASH_SR_ERRORS | FLASH_SR_EOP); /* clear stale flags (write 1 to clear) */
}

/* Relock and flush the data cache, which may hold lines of the old contents. */
static int finish(void)
{
    uint32_t sr = reg_read(&FLASH_SR);
    reg_write(&FLASH_CR, FLASH_CR_LOCK);
    uint32_t acr = reg_read(&FLASH_ACR);
    if (acr & FLASH_ACR_DCEN) {
        reg_write(&FLASH_ACR, acr & ~FLASH_ACR_DCEN);
        reg_write(&FLASH_ACR, (acr & ~FLASH_ACR_DCEN) | FLASH_ACR_DCRST);
        reg_write(&FLASH_ACR, acr);
    }
    return (sr & FLASH_SR_ERRORS) ? -1 : 0;
}

/* Sector erase (RM0090 3.6.3): BSY clear, unlock, SER + SNB, then STRT; wait for BSY. */
static int f4_erase(void *ctx, uint8_t slot)
{
    (void)ctx;
    if (slot > 1)
        return -1;
    wait_idle();
    unlock();
    uint32_t cr = FLASH_CR_SER | ((uint32_t)(SECTOR_SLOT_A + slot) << FLASH_CR_SNB_SHIFT) | FLASH_CR_PSIZE_X8;
    reg_write(&FLASH_CR, cr);
    reg_write(&FLASH_CR, cr | FLASH_CR_STRT);
    wait_idle();
    return finish();
}

/* Programming (RM0090 3.6.4): BSY clear, unlock, PG with PSIZE x8, one byte access per
 * byte, waiting for BSY after each; stops at the first error flag. */
static int f4_program(void *ctx, uint8_t slot, uint32_t off, const uint8_t *data, uint32_t len)
{
    (void)ctx;
    if (slot > 1 || off > slot_size() || len > slot_size() - off)
        return -1;
    uintptr_t dst = (uintptr_t)(slot_base(slot) + off);
    wait_idle();
    unlock();
    reg_write(&FLASH_CR, FLASH_CR_PG | FLASH_CR_PSIZE_X8);
    for (uint32_t i = 0; i < len; i++) {
        flash_write8(dst + i, data[i]);
        wait_idle();
        if (reg_read(&FLASH_SR) & FLASH_SR_ERRORS)
            break;
    }
    return finish();
}

static int f4_read(void *ctx, uint8_t slot, uint32_t off, uint8_t *out, uint32_t len)
{
    (void)ctx;
    if (slot > 1 || off > slot_size() || len > slot_size() - off)
        return -1;
    memcpy(out, slot_base(slot) + off, len);
    return 0;
}

const pss_flash_t *pss_stm32f4_flash(void)
{
    static pss_flash_t port;
    port.slot_size = slot_size();
    port.erase = f4_erase;
    port.program = f4_program;
    port.read = f4_read;
    port.ctx = 0;
    return &port;
}
