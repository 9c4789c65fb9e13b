/* STM32F405 link firmware: the protocol handler on USART1 with a 1 kHz control tick. */
#include <stdbool.h>
#include <stdint.h>

#include "port_board.h"
#include "psb_config.h"
#include "link/psl_link.h"
#if PSL_FLASH_HW
#include "pss_flash_stm32f4.h"
#else
#include <string.h>

#include "storage/pss_flash_sim.h"
#endif

#ifndef PSL_TICK_HZ
/* PSL_TICK_HZ: control tick of the link firmware's main loop. Default 1000. */
#define PSL_TICK_HZ 1000u
#endif

enum {
    RAM_SLOT_SIZE = 4096,        /* QEMU build: table slots in RAM (QEMU has no flash controller) */
    RX_PIECE = 64,               /* bytes taken from the UART ring per loop pass */
};

static psl_t link;

static void uart_write(void *ctx, const uint8_t *frame, size_t len)
{
    (void)ctx;
    port_uart_write(frame, len);
}

/* Board id from the STM32 96-bit unique id (RM0090 39.1). QEMU's netduinoplus2 maps no
 * system memory there (the read faults), so the RAM-slot image used under QEMU reports a
 * fixed id instead. */
static void read_uid(uint32_t id[3])
{
#if PSL_FLASH_HW
    const volatile uint32_t *uid = (const volatile uint32_t *)0x1FFF7A10u;
    for (int i = 0; i < 3; i++)
        id[i] = uid[i];
#else
    id[0] = 0x51454D55u; /* "QEMU" */
    id[1] = 0;
    id[2] = 0;
#endif
}

#if !PSL_FLASH_HW
/* Linker script symbols (stm32f405.ld): the table sectors 10/11. */
extern uint8_t __table_slot_a[], __table_slot_b[];
#endif

int main(void)
{
    port_init();
    port_tick_start(PSL_TICK_HZ, NULL);
    psl_config_t cfg = psl_default_config(PSL_TICK_HZ);
    read_uid(cfg.board_id);
    cfg.limits = psb_limits();
    /* The recovery pin held at reset: slots erased. QEMU 7.2 models no GPIO (its GPIOA is an
     * unimplemented-device stub that reads 0), so under QEMU the pin is never seen high. */
    cfg.recover = psb_recovery_requested();
#if PSL_FLASH_HW
    const pss_flash_t *flash = pss_stm32f4_flash();
#else
    /* The RAM slots start as the first RAM_SLOT_SIZE bytes of sectors 10/11, whatever the
     * programming port (under QEMU: -device loader) left there: a board booted on an exhausted
     * counter or on erased sectors boots as the flash image would. Writes stay in RAM (QEMU's
     * flash is ROM to the guest); sectors nothing was loaded into read 0, no valid record. */
    static uint8_t ram_flash[2 * RAM_SLOT_SIZE];
    static pss_sim_t sim;
    pss_sim_init(&sim, ram_flash, RAM_SLOT_SIZE, 0);
    memcpy(ram_flash, __table_slot_a, RAM_SLOT_SIZE);
    memcpy(ram_flash + RAM_SLOT_SIZE, __table_slot_b, RAM_SLOT_SIZE);
    const pss_flash_t *flash = &sim.port;
#endif
    psl_init(&link, &cfg, flash, uart_write, 0);

    const uint32_t tick_us = 1000000u / PSL_TICK_HZ;
    uint32_t next_us = port_ticks_us();
    int32_t q_q16 = 0;
    uint8_t rx[RX_PIECE];
    for (;;) {
        size_t n = port_uart_read(rx, sizeof rx);
        if (n > 0)
            psl_rx(&link, rx, n);
        /* Run every tick that is due; the motor is ideal here (q = last set-point). */
        while ((int32_t)(port_ticks_us() - next_us) >= 0) {
            q_q16 = psl_tick(&link, next_us, q_q16);
            next_us += tick_us;
        }
        /* Between ticks: an on-line B sample, if one is queued (psl_background). It may
         * delay the ticks due meanwhile by up to its cost (0.17 ms at most at 168 MHz); they
         * catch up above on the next pass. */
        bool busy = psl_background(&link);
        if (n == 0 && !busy)
            port_wait_for_interrupt();
    }
}
