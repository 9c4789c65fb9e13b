/* USART image playscope-fw: the production loop (psa_tick) at 20 kHz in compensation mode on a
 * +-30 deg triangle reference, with the built-in table (psa_builtin_table); status on USART1. */
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "psa_builtin_table.h"
#include "psa_loop.h"
#include "ps_fixed.h"
#include "ps_table.h"
#include "port_board.h"
#include "port_console.h"

#ifndef FW_TICK_HZ
/* FW_TICK_HZ: control tick rate in Hz. Default 20000 (50 us). */
#define FW_TICK_HZ 20000u
#endif

#ifndef FW_STATUS_TICKS
/* FW_STATUS_TICKS: ticks between two status lines. Default FW_TICK_HZ (1 s). */
#define FW_STATUS_TICKS FW_TICK_HZ
#endif

enum {
    FW_C_AMPL_Q16 = 30 * PS_Q16_ONE, /* reference triangle +-30 deg ... */
    FW_C_PERIOD_MS = 2000,           /* ... with a 2 s period */
};

static psa_loop_t loop;
static union {
    uint32_t align;                    /* calib_load reads the entries in place */
    uint8_t bytes[PST_MAX_TABLE_SIZE];
} table;
static calib_t cal;
static int32_t c_ref_q16, c_step_q16;  /* the image's reference generator */
static int32_t q_meas_q16;             /* ideal motor: it reached last tick's q* */
static volatile uint32_t reversals, onset_events;
static volatile uint32_t tick_count;
static volatile int32_t last_q_ref_q16;
static volatile uint32_t tick_cycles_max;   /* longest tick seen, core cycles */

/* Stack high-water mark: the free stack is painted at boot, and the status line reports
 * how deep the paint has been overwritten (main, the SysTick tick and the USART interrupt
 * nested). bench_firmware.sh sizes nothing from it; the reservation is checked against it. */
#define STACK_PAINT 0xA5A5A5A5u
extern uint32_t __stack_limit, __stack_top;

static void stack_paint(void)
{
    /* Up to 64 bytes below this frame: what is live above it stays untouched. */
    uintptr_t sp = (uintptr_t)__builtin_frame_address(0) - 64u;
    for (volatile uint32_t *p = &__stack_limit; (uintptr_t)p < sp; p++) {
        *p = STACK_PAINT;
    }
}

static uint32_t stack_used_bytes(void)
{
    const uint32_t *p = &__stack_limit;
    while (p < &__stack_top && *p == STACK_PAINT) {
        p++;
    }
    return (uint32_t)((uintptr_t)&__stack_top - (uintptr_t)p);
}

/* SysTick callback: one control tick, timed with the same cycle counter. */
static void control_tick(void)
{
    uint64_t c0 = port_cycles();
    int32_t c_next = c_ref_q16 + c_step_q16;
    if (c_next > FW_C_AMPL_Q16 || c_next < -FW_C_AMPL_Q16) {
        c_step_q16 = -c_step_q16;
        c_next = c_ref_q16 + c_step_q16;
        reversals = reversals + 1u;
    }
    c_ref_q16 = c_next;
    onset_event_t ev;
    bool ev_ready;
    q_meas_q16 = psa_tick(&loop, port_ticks_us(), c_ref_q16, q_meas_q16, &ev, &ev_ready);
    last_q_ref_q16 = q_meas_q16;
    if (ev_ready) {
        onset_events = onset_events + 1u;
    }
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
    put_q16(c_ref_q16);
    console_put_str(" q_ref=");
    put_q16(last_q_ref_q16);
    console_put_str(" reversals=");
    console_put_u32(reversals);
    console_put_str(" onset_events=");
    console_put_u32(onset_events);
    console_put_str(" tick_cycles_max=");
    console_put_u32(tick_cycles_max);
    console_put_str(" stack_used=");
    console_put_u32(stack_used_bytes());
    console_put_str("\r\n");
}

int main(void)
{
    stack_paint();
    port_init();
    console_put_str("\r\nplayscope-fw " PS_FW_VERSION " on STM32F405: control tick ");
    console_put_u32(FW_TICK_HZ);
    console_put_str(" Hz, core ");
    console_put_u32(port_core_hz());
    console_put_str(" Hz; send 'q' to stop\r\n");

    /* Compensation with the transition smoothing this image always had: 200 mm/s, 20000 mm/s^2
     * (a 1.5 mm offset step takes ~17 ms). */
    psa_config_t lc = {.onset = onset_default_config(), .smooth = true,
                       .lim = comp_smoothing_from_rates(200 * PS_Q16_ONE, 20000 * PS_Q16_ONE, FW_TICK_HZ)};
    psa_init(&loop, &lc);
    int st = (int)calib_load(&cal, table.bytes, psa_builtin_table(table.bytes, sizeof table.bytes));
    if (st == CALIB_OK && !(psa_set_table(&loop, &cal) && psa_set_mode(&loop, PSA_MODE_COMPENSATION))) {
        st = -1;
    }
    /* 4 amplitudes per period: step = 4 A / (period * tick_hz); computed once, here. */
    c_step_q16 = (int32_t)(4u * (uint32_t)FW_C_AMPL_Q16 / (FW_TICK_HZ / 1000u * FW_C_PERIOD_MS));
    if (st != 0) {
        console_put_str("built-in table refused (calib_load status, or -1: the loop), ");
        console_put_u32((uint32_t)st);
        console_put_str("\r\n");
        return 2;
    }
    if (!port_tick_start(FW_TICK_HZ, control_tick)) {
        console_put_str("tick rate not reachable from the core clock\r\n");
        return 3;
    }

    uint32_t next_status = FW_STATUS_TICKS;
    for (;;) {
        port_wait_for_interrupt();
        if ((int32_t)(tick_count - next_status) >= 0) {
            next_status += FW_STATUS_TICKS;
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
