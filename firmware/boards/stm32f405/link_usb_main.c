/* STM32F405 link firmware over USB (OTG FS, vendor interface 1209:0001): compiled only, QEMU has no OTG. */
#include <stdint.h>

#include "port_board.h"
#include "psb_config.h"
#include "link/psl_link.h"
#include "pss_flash_stm32f4.h"
#include "link/usb/psu_dcd.h"
#include "link/usb/psu_device.h"

#ifndef PSL_TICK_HZ
/* PSL_TICK_HZ: control tick of the link firmware's main loop. Default 1000. */
#define PSL_TICK_HZ 1000u
#endif

void psu_stm32_otgfs_poll(void);

static psl_t link;
static psu_dev_t usb;

static void usb_rx(void *ctx, const uint8_t *data, size_t len)
{
    psl_rx((psl_t *)ctx, data, len);
}

int main(void)
{
    port_init();
    port_tick_start(PSL_TICK_HZ, NULL);
    psl_config_t cfg = psl_default_config(PSL_TICK_HZ);
    const volatile uint32_t *uid = (const volatile uint32_t *)0x1FFF7A10u; /* RM0090 39.1 */
    for (int i = 0; i < 3; i++)
        cfg.board_id[i] = uid[i];
    cfg.limits = psb_limits();
    cfg.recover = psb_recovery_requested(); /* the recovery pin held at reset: slots erased */
    psu_config_t ucfg = {.board_id = {cfg.board_id[0], cfg.board_id[1], cfg.board_id[2]},
                         .bcd_device = (uint16_t)(cfg.fw_version >> 8), .rx = usb_rx, .rx_ctx = &link};
    psu_init(&usb, &ucfg);
    psl_init(&link, &cfg, pss_stm32f4_flash(), psu_write_frame, &usb);
    psu_dcd_init(&usb);

    const uint32_t tick_us = 1000000u / PSL_TICK_HZ;
    uint32_t next_us = port_ticks_us();
    int32_t q_q16 = 0;
    for (;;) {
        /* Requests and answers both run here, between ticks: no ISR shares the handler. */
        psu_stm32_otgfs_poll();
        while ((int32_t)(port_ticks_us() - next_us) >= 0) {
            q_q16 = psl_tick(&link, next_us, q_q16);
            next_us += tick_us;
        }
        (void)psl_background(&link); /* an on-line B sample between ticks, if one is queued */
    }
}
