/* STM32F405 flash driver for the table slots, written against RM0090 (section 3.6, FLASH registers). */
#include "pss_flash_stm32f4.h"

#include <stdint.h>
#include <string.h>

/* Linker script symbols: only their addresses matter. */
extern uint8_t __table_slot_a[], __table_slot_b[], __table_slot_size[];

#define FLASH_BASE_ADDR 0x40023C00u
#define FLASH_REG(off) (*(volatile uint32_t *)(FLASH_BASE_ADDR + (off)))
#define FLASH_ACR_R FLASH_REG(0x00u)
#define FLASH_KEYR_R FLASH_REG(0x04u)
#define FLASH_SR_R FLASH_REG(0x0Cu)
#define FLASH_CR_R FLASH_REG(0x10u)

enum {
    KEY1 = 0x45670123u,          /* unlock sequence (RM0090 3.5.1) */
    KEY2 = 0xCDEF89ABu,
    SR_EOP = 1u << 0,
    SR_OPERR = 1u << 1,
    SR_WRPERR = 1u << 4,
    SR_PGAERR = 1u << 5,
    SR_PGPERR = 1u << 6,
    SR_PGSERR = 1u << 7,
    SR_BSY = 1u << 16,
    SR_ERRORS = SR_OPERR | SR_WRPERR | SR_PGAERR | SR_PGPERR | SR_PGSERR,
    CR_PG = 1u << 0,
    CR_SER = 1u << 1,
    CR_SNB_SHIFT = 3,            /* SNB[3:0] at bits 6:3 */
    CR_PSIZE_X8 = 0u << 8,       /* byte parallelism: valid over the whole 1.8-3.6 V range */
    CR_STRT = 1u << 16,
    CR_LOCK = 1u << 31,
    ACR_DCEN = 1u << 10,
    ACR_DCRST = 1u << 12,
    SECTOR_SLOT_A = 10,          /* 0x080C0000, see stm32f405.ld */
};

static uint8_t *slot_base(uint8_t slot)
{
    return slot == 0 ? __table_slot_a : __table_slot_b;
}

static uint32_t slot_size(void)
{
    return (uint32_t)(uintptr_t)__table_slot_size;
}

static void wait_idle(void)
{
    while (FLASH_SR_R & SR_BSY)
        ;
}

static void unlock(void)
{
    if (FLASH_CR_R & CR_LOCK) {
        FLASH_KEYR_R = KEY1;
        FLASH_KEYR_R = KEY2;
    }
    FLASH_SR_R = SR_ERRORS | SR_EOP; /* clear stale flags (write 1 to clear) */
}

/* Relock and flush the data cache, which may hold lines of the old contents. */
static int finish(void)
{
    uint32_t sr = FLASH_SR_R;
    FLASH_CR_R = CR_LOCK;
    uint32_t acr = FLASH_ACR_R;
    if (acr & ACR_DCEN) {
        FLASH_ACR_R = acr & ~ACR_DCEN;
        FLASH_ACR_R = (acr & ~ACR_DCEN) | ACR_DCRST;
        FLASH_ACR_R = acr;
    }
    return (sr & SR_ERRORS) ? -1 : 0;
}

static int f4_erase(void *ctx, uint8_t slot)
{
    (void)ctx;
    if (slot > 1)
        return -1;
    wait_idle();
    unlock();
    FLASH_CR_R = CR_SER | ((uint32_t)(SECTOR_SLOT_A + slot) << CR_SNB_SHIFT) | CR_PSIZE_X8;
    FLASH_CR_R |= CR_STRT;
    wait_idle();
    return finish();
}

static int f4_program(void *ctx, uint8_t slot, uint32_t off, const uint8_t *data, uint32_t len)
{
    (void)ctx;
    if (slot > 1 || off > slot_size() || len > slot_size() - off)
        return -1;
    volatile uint8_t *dst = (volatile uint8_t *)(slot_base(slot) + off);
    wait_idle();
    unlock();
    FLASH_CR_R = CR_PG | CR_PSIZE_X8;
    for (uint32_t i = 0; i < len; i++) {
        dst[i] = data[i];
        wait_idle();
        if (FLASH_SR_R & SR_ERRORS)
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
