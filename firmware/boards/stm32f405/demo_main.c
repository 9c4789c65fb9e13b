/* USART demo image playscope-fw: 20 kHz control tick (onset_tick + comp_step), status on USART1. */
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "bench_tick.h"
#include "port_board.h"
#include "port_console.h"

#ifndef DEMO_TICK_HZ
/* DEMO_TICK_HZ: control tick rate in Hz. Default 20000 (50 us). */
#define DEMO_TICK_HZ 20000u
#endif

#ifndef DEMO_STATUS_TICKS
/* DEMO_STATUS_TICKS: ticks between two status lines. Default DEMO_TICK_HZ (1 s). */
#define DEMO_STATUS_TICKS DEMO_TICK_HZ
#endif

static ctl_loop_t loop;
static volatile uint32_t tick_count;
static volatile int32_t last_q_ref_q16;
static volatile uint32_t tick_cycles_max;   /* longest tick seen, core cycles */

/* SysTick callback: one control tick, timed with the same cycle counter. */
static void control_tick(void)
{
    uint64_t c0 = port_cycles();
    last_q_ref_q16 = ctl_loop_tick(&loop, port_ticks_us());
    tick_count = tick_count + 1u;
    int64_t spent = (int64_t)(port_cycles() - c0);
    /* Only QEMU without -icount yields spent < 0: its counter follows host time and the
     * host may stall mid-tick; such samples say nothing about the firmware. */
    if (spent >= 0 && spent > (int64_t)tick_cycles_max) {
        tick_cycles_max = (uint32_t)spent;
    }
}


/* Q16.16 as a signed decimal with three fractional digits (truncated). */
static void put_q16(int32_t v_q16)
{
    uint32_t mag = v_q16 < 0 ? 0u - (uint32_t)v_q16 : (uint32_t)v_q16;
    if (v_q16 < 0) {
        console_put_str("-");
    }
    console_put_u32(mag >> 16);
    console_put_str(".");
    uint32_t milli = ((mag & 0xFFFFu) * 1000u) >> 16;
    char frac[3] = {(char)('0' + milli / 100u), (char)('0' + milli / 10u % 10u), (char)('0' + milli % 10u)};
    port_uart_write(frac, sizeof frac);
}

static void put_status(void)
{
    console_put_str("status: ticks=");
    console_put_u32(tick_count);
    console_put_str(" t_us=");
    console_put_u32(port_ticks_us());
    console_put_str(" c_ref=");
    put_q16(loop.c_ref_q16);
    console_put_str(" q_ref=");
    put_q16(last_q_ref_q16);
    console_put_str(" reversals=");
    console_put_u32(loop.reversals);
    console_put_str(" onset_events=");
    console_put_u32(loop.onset_events);
    console_put_str(" tick_cycles_max=");
    console_put_u32(tick_cycles_max);
    console_put_str("\r\n");
}

int main(void)
{
    port_init();
    console_put_str("\r\nplayscope-fw " PS_FW_VERSION " on STM32F405: control tick ");
    console_put_u32(DEMO_TICK_HZ);
    console_put_str(" Hz, core ");
    console_put_u32(port_core_hz());
    console_put_str(" Hz; send 'q' to stop\r\n");

    int st = ctl_loop_init(&loop, DEMO_TICK_HZ);
    if (st != 0) {
        console_put_str("built-in table refused by calib_load, status ");
        console_put_u32((uint32_t)st);
        console_put_str("\r\n");
        return 2;
    }
    if (!port_tick_start(DEMO_TICK_HZ, control_tick)) {
        console_put_str("tick rate not reachable from the core clock\r\n");
        return 3;
    }

    uint32_t next_status = DEMO_STATUS_TICKS;
    for (;;) {
        port_wait_for_interrupt();
        if ((int32_t)(tick_count - next_status) >= 0) {
            next_status += DEMO_STATUS_TICKS;
            put_status();
        }
        uint8_t cmd;
        if (port_uart_read(&cmd, 1) == 1 && cmd == 'q') {
            put_status();
            console_put_str("bye\r\n");
            return 0;
        }
    }
}
