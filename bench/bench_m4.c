/* Cortex-M4 bench ELF: core clock cycles for N control ticks, printed as BENCH lines; run under QEMU -icount. */
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "bench_pi.h"
#include "bench_tick.h"
#include "port_board.h"
#include "port_console.h"

/* Under `-icount shift=0` QEMU advances virtual time 1 ns per instruction, and SysTick
 * counts virtual core cycles (168 MHz), so cycles * 1000 / 168 = instructions. The
 * calibration loop (2 instructions per iteration) checks that ratio on every run. */

#ifndef BENCH_TICKS
/* BENCH_TICKS: control ticks per measurement. Default 100000. */
#define BENCH_TICKS 100000u
#endif

enum {
    BENCH_TICK_HZ = 20000,       /* what the reference speed and smoothing assume */
    BENCH_TIMEBASE_HZ = 1000,    /* SysTick period of the cycle counter (ISR cost ~0.003 %) */
    CAL_ITERATIONS = 1000000,
    REF_LEN = 1024,              /* precomputed c* samples, a power of two */
    REF_HOLD_LOG2 = 5,           /* each held 32 ticks: a +-30 deg triangle of 1.6 s at 20 kHz */
};

static ctl_loop_t loop;
static comp_t comp_plain;           /* same table, no smoothing: eq. 4 as written */
static int32_t c_ref_q16[REF_LEN];  /* a triangle sampled as the demo's, so comp_step sees reversals */
static volatile int32_t sink_q16;


/* One result line: "BENCH <name> cycles=<c> iterations=<n>". */
static void report(const char *name, uint32_t cycles, uint32_t iterations)
{
    console_put_str("BENCH ");
    console_put_str(name);
    console_put_str(" cycles=");
    console_put_u32(cycles);
    console_put_str(" iterations=");
    console_put_u32(iterations);
    console_put_str("\r\n");
}

/* Exactly 2 instructions per iteration (subs, bne), to calibrate cycles against instructions. */
static uint32_t measure_calibration(void)
{
    uint64_t c0 = port_cycles();
    uint32_t n = CAL_ITERATIONS;
    __asm volatile("1: subs %0, %0, #1\n\tbne 1b" : "+r"(n) : : "cc");
    return (uint32_t)(port_cycles() - c0);
}

/* The loop around the chain alone (time step, reference load, store): subtracted below. */
__attribute__((noinline)) static uint32_t measure_overhead(void)
{
    uint32_t t_us = 0;
    int32_t q = 0;
    uint64_t c0 = port_cycles();
    for (uint32_t i = 0; i < BENCH_TICKS; i++) {
        t_us += 1000000u / BENCH_TICK_HZ;
        q = c_ref_q16[(i >> REF_HOLD_LOG2) % REF_LEN];
        __asm volatile("" : "+r"(q), "+r"(t_us));  /* keep the loop, as if calls used them */
    }
    sink_q16 = q;
    return (uint32_t)(port_cycles() - c0);
}

/* onset_tick (records the encoder sample in the history, checks the timeout) + comp_step. */
__attribute__((noinline)) static uint32_t measure_core_chain(void)
{
    uint32_t t_us = 0;
    int32_t q = 0;
    onset_event_t ev;
    uint64_t c0 = port_cycles();
    for (uint32_t i = 0; i < BENCH_TICKS; i++) {
        t_us += 1000000u / BENCH_TICK_HZ;
        (void)onset_tick(&loop.onset, t_us, q, &ev);
        q = comp_step(&loop.comp, c_ref_q16[(i >> REF_HOLD_LOG2) % REF_LEN]);
        __asm volatile("" : "+r"(q), "+r"(t_us));
    }
    sink_q16 = q;
    return (uint32_t)(port_cycles() - c0);
}

__attribute__((noinline)) static uint32_t measure_onset_tick(void)
{
    uint32_t t_us = 0;
    int32_t q = 0;
    onset_event_t ev;
    uint64_t c0 = port_cycles();
    for (uint32_t i = 0; i < BENCH_TICKS; i++) {
        t_us += 1000000u / BENCH_TICK_HZ;
        q = c_ref_q16[(i >> REF_HOLD_LOG2) % REF_LEN];
        (void)onset_tick(&loop.onset, t_us, q, &ev);
        __asm volatile("" : "+r"(q), "+r"(t_us));
    }
    sink_q16 = q;
    return (uint32_t)(port_cycles() - c0);
}

__attribute__((noinline)) static uint32_t measure_comp_step(void)
{
    uint32_t t_us = 0;
    int32_t q = 0;
    uint64_t c0 = port_cycles();
    for (uint32_t i = 0; i < BENCH_TICKS; i++) {
        t_us += 1000000u / BENCH_TICK_HZ;
        q = comp_step(&loop.comp, c_ref_q16[(i >> REF_HOLD_LOG2) % REF_LEN]);
        __asm volatile("" : "+r"(q), "+r"(t_us));
    }
    sink_q16 = q;
    return (uint32_t)(port_cycles() - c0);
}

__attribute__((noinline)) static uint32_t measure_comp_step_plain(void)
{
    uint32_t t_us = 0;
    int32_t q = 0;
    uint64_t c0 = port_cycles();
    for (uint32_t i = 0; i < BENCH_TICKS; i++) {
        t_us += 1000000u / BENCH_TICK_HZ;
        q = comp_step(&comp_plain, c_ref_q16[(i >> REF_HOLD_LOG2) % REF_LEN]);
        __asm volatile("" : "+r"(q), "+r"(t_us));
    }
    sink_q16 = q;
    return (uint32_t)(port_cycles() - c0);
}

/* One lut_eval (f^-1 at c*): comp_step makes two. */
__attribute__((noinline)) static uint32_t measure_lut_eval(void)
{
    uint32_t t_us = 0;
    int32_t q = 0;
    uint64_t c0 = port_cycles();
    for (uint32_t i = 0; i < BENCH_TICKS; i++) {
        t_us += 1000000u / BENCH_TICK_HZ;
        q = lut_eval(&loop.cal.f_inv, c_ref_q16[(i >> REF_HOLD_LOG2) % REF_LEN]);
        __asm volatile("" : "+r"(q), "+r"(t_us));
    }
    sink_q16 = q;
    return (uint32_t)(port_cycles() - c0);
}

/* The demo's whole tick (reference generation, reversal bookkeeping, onset_tick, comp_step). */
__attribute__((noinline)) static uint32_t measure_demo_tick(void)
{
    uint32_t t_us = 0;
    uint64_t c0 = port_cycles();
    for (uint32_t i = 0; i < BENCH_TICKS; i++) {
        t_us += 1000000u / BENCH_TICK_HZ;
        sink_q16 = ctl_loop_tick(&loop, t_us);
    }
    return (uint32_t)(port_cycles() - c0);
}


/* ---- Transition model (table v2, 16 operators): average and worst single tick. ----
 * Averages: BENCH_TICKS ticks between two port_cycles() reads, the reference generator's
 * own cost (measured alone) subtracted. Worst: every tick timed alone by two reads of the
 * SysTick counter with its interrupt off (no ISR inside a window), the empty window's
 * cost subtracted; resolution one core cycle = 1000/168 = 6 instructions. */
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)

static calib_t pi_cal;
static comp_t pi_comp;

enum { PI_REALISTIC = 0, PI_STRESS = 1, PI_JUMP = 2 };
enum { PI_WORK_GEN = 0, PI_WORK_COMP = 1, PI_WORK_TICK = 2 };

static void pi_ref_init(bench_ref_t *r, int kind)
{
    if (kind == PI_REALISTIC)
        bench_ref_init(r, 17u, 5000u, 10000u); /* a reversal every 0.25-0.5 s at 20 kHz */
    else if (kind == PI_STRESS)
        bench_ref_init(r, 17u, 512u, 512u);    /* a reversal every 512 ticks */
    else
        bench_ref_init(r, 17u, 1u, 1u);        /* a reversal and a 12-54 deg jump every tick */
}

static void pi_reset_all(void)
{
    comp_smoothing_t lim = comp_smoothing_from_rates(200 * 65536, 20000 * 65536, BENCH_TICK_HZ);
    comp_reset(&pi_comp, &pi_cal, &lim, 0);
    onset_config_t oc = onset_default_config();
    onset_init(&loop.onset, &oc);
}

/* BENCH_TICKS ticks of work (generator only, comp_step, or onset_tick + comp_step). */
__attribute__((noinline)) static uint32_t measure_pi_bulk(int kind, int work)
{
    bench_ref_t ref;
    pi_ref_init(&ref, kind);
    pi_reset_all();
    uint32_t t_us = 0;
    int32_t q = 0;
    onset_event_t ev;
    uint64_t c0 = port_cycles();
    for (uint32_t i = 0; i < BENCH_TICKS; i++) {
        t_us += 1000000u / BENCH_TICK_HZ;
        int32_t c = bench_ref_next(&ref);
        if (work == PI_WORK_TICK)
            (void)onset_tick(&loop.onset, t_us, q, &ev);
        if (work != PI_WORK_GEN)
            c = comp_step(&pi_comp, c);
        q = c;
        __asm volatile("" : "+r"(q), "+r"(t_us));
    }
    sink_q16 = q;
    return (uint32_t)(port_cycles() - c0);
}

/* Largest single-tick window in core cycles over BENCH_TICKS ticks (work as above;
 * PI_WORK_GEN times an empty window: the overhead to subtract). */
__attribute__((noinline)) static uint32_t measure_pi_worst(int kind, int work)
{
    bench_ref_t ref;
    pi_ref_init(&ref, kind);
    pi_reset_all();
    const uint32_t period = SYST_RVR + 1u;
    uint32_t t_us = 0, worst = 0;
    int32_t q = 0;
    onset_event_t ev;
    SYST_CSR &= ~2u; /* TICKINT off: the counter runs, no interrupt */
    for (uint32_t i = 0; i < BENCH_TICKS; i++) {
        t_us += 1000000u / BENCH_TICK_HZ;
        int32_t c = bench_ref_next(&ref);
        __asm volatile("" ::: "memory");
        uint32_t v0 = SYST_CVR;
        if (work == PI_WORK_TICK)
            (void)onset_tick(&loop.onset, t_us, q, &ev);
        if (work != PI_WORK_GEN)
            c = comp_step(&pi_comp, c);
        uint32_t v1 = SYST_CVR;
        q = c;
        __asm volatile("" : "+r"(q), "+r"(t_us));
        uint32_t d = v0 >= v1 ? v0 - v1 : v0 + period - v1; /* down-counter, at most one wrap */
        worst = d > worst ? d : worst;
    }
    SYST_CSR |= 2u;
    sink_q16 = q;
    return worst;
}

static void report_pi(void)
{
    if (bench_pi_load(&pi_cal) != 0) {
        console_put_str("BENCH pi table refused\r\n");
        return;
    }
    static const char *const names[2][3] = {
        {"pi_real_gen", "pi_real_comp", "pi_real_tick"},
        {"pi_stress_gen", "pi_stress_comp", "pi_stress_tick"},
    };
    static const char *const worst_names[2][3] = {
        {"pi_real_gen_worst", "pi_real_comp_worst", "pi_real_tick_worst"},
        {"pi_stress_gen_worst", "pi_stress_comp_worst", "pi_stress_tick_worst"},
    };
    for (int kind = 0; kind < 2; kind++) {
        for (int work = 0; work < 3; work++) {
            report(names[kind][work], measure_pi_bulk(kind, work), BENCH_TICKS);
            report(worst_names[kind][work], measure_pi_worst(kind, work), 1);
        }
    }
    /* Beyond any real reference, for the worst case alone: every tick reverses and jumps
     * far enough to release and re-engage nearly all 16 operators. */
    report("pi_jump_gen_worst", measure_pi_worst(PI_JUMP, PI_WORK_GEN), 1);
    report("pi_jump_comp_worst", measure_pi_worst(PI_JUMP, PI_WORK_COMP), 1);
    report("pi_jump_tick_worst", measure_pi_worst(PI_JUMP, PI_WORK_TICK), 1);
}

int main(void)
{
    port_init();
    if (ctl_loop_init(&loop, BENCH_TICK_HZ) != 0 || !port_tick_start(BENCH_TIMEBASE_HZ, NULL)) {
        console_put_str("BENCH setup failed\r\n");
        return 1;
    }
    /* +-30 deg triangle over REF_LEN << REF_HOLD_LOG2 ticks: a reversal every 0.82 s at
     * 20 kHz, a plausible teleoperation reference (the offset ramp lasts ~17 ms of it). */
    for (int i = 0; i < REF_LEN; i++) {
        int32_t phase = i < REF_LEN / 2 ? i : REF_LEN - i;
        c_ref_q16[i] = -30 * 65536 + phase * (60 * 65536 / (REF_LEN / 2));
    }
    comp_reset(&comp_plain, &loop.cal, NULL, 0);
    console_put_str("BENCH core_hz=");
    console_put_u32(port_core_hz());
    console_put_str("\r\n");
    report("calibration_2insn", measure_calibration(), CAL_ITERATIONS);
    report("overhead", measure_overhead(), BENCH_TICKS);
    report("core_chain", measure_core_chain(), BENCH_TICKS);
    report("onset_tick", measure_onset_tick(), BENCH_TICKS);
    report("comp_step", measure_comp_step(), BENCH_TICKS);
    report("comp_step_plain", measure_comp_step_plain(), BENCH_TICKS);
    report("lut_eval", measure_lut_eval(), BENCH_TICKS);
    report("demo_tick", measure_demo_tick(), BENCH_TICKS);
    report_pi();
    console_put_str("BENCH done\r\n");
    return 0;
}
