/* Cortex-M4 bench ELF: M4 instructions of the production loop's entry points, per call (average and
 * worst single call), under QEMU -icount; printed as BENCH lines that bench_firmware.sh tabulates. */
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "port_board.h"
#include "port_console.h"
#include "ps_fixed.h"
#include "ps_table.h"
#include "psa_builtin_table.h"
#include "b_online.h"
#include "f_online.h"
#include "psa_loop.h"
#include "stm32f405_regs.h"
#include "bench_traj.h"
#include "bench_pi.h"

/* Under `-icount shift=N` QEMU advances virtual time 2^N ns per instruction and SysTick
 * counts virtual core cycles (168 MHz), so instructions = cycles * 1e9 / (168e6 * 2^N).
 * Every call is timed on its own by two reads of the SysTick counter (its interrupt off,
 * so nothing else runs in between); the cost of the read pair alone is measured and
 * subtracted. A loop of exactly 2 instructions per iteration checks the conversion. */

#ifndef BENCH_TICKS
/* BENCH_TICKS: control ticks per trajectory. Default 200000 (10 s at 20 kHz). */
#define BENCH_TICKS 200000u
#endif

enum {
    TICK_HZ = 20000,             /* the rate the STM32 image runs the loop at */
    TICK_US = 1000000 / TICK_HZ,
    TIMEBASE_HZ = 20,            /* SysTick reload 8.4e6 cycles: one wrap at most per window */
    CAL_ITERATIONS = 100000,
    FRAME_TICKS = TICK_HZ / 25,  /* 25 Hz camera (paper V-D) */
    DELAY_TICKS = 80000 / TICK_US, /* t_delay 80 ms, onset_default_config() */
    FRAME_QUEUE = 4,             /* frames captured, not yet delivered: 2 at 80 ms */
    COMMITS = 16,
};

static psa_loop_t loop;
static calib_t cal[2];
static calib_t cal_pi;           /* the transition model: 16 play operators (bench_pi.c, pi-fw) */
static calib_t cal_pimap;        /* the same with a threshold map (table v3, bench_pi_map_load) */
static calib_t cal_pirelax;      /* the same plus the travel-domain relaxation (table v4, bench_pi_relax_load) */
static union {
    uint32_t align;
    uint8_t bytes[PST_MAX_TABLE_SIZE];
} blob;
static size_t blob_size;
static volatile int32_t sink_q16;
static uint32_t pair_cycles;     /* two back-to-back counter reads */

typedef struct {
    uint32_t n, sum, max;        /* calls, total and largest single-call cycles (read pair included) */
    uint32_t at_max;             /* which call (0-based) was the largest: names the worst tick */
} stat_t;

static inline uint32_t cyc(void)
{
    return SYST_CVR;
}

/* SysTick counts down and reloads at 0. */
static inline uint32_t since(uint32_t c0, uint32_t c1)
{
    return c0 >= c1 ? c0 - c1 : c0 + (SYST_RVR + 1u) - c1;
}

static void stat_add(stat_t *s, uint32_t cycles)
{
    if (cycles > s->max) {
        s->max = cycles;
        s->at_max = s->n;
    }
    s->n++;
    s->sum += cycles;
}

static const char *run_name = "";  /* the last report()ed run, to label its counts */

/* "BENCH <name> n=<calls> sum=<cycles> max=<cycles> pair=<cycles>" */
static void report(const char *name, const stat_t *s)
{
    run_name = name;
    console_put_str("BENCH ");
    console_put_str(name);
    console_put_str(" n=");
    console_put_u32(s->n);
    console_put_str(" sum=");
    console_put_u32(s->sum);
    console_put_str(" max=");
    console_put_u32(s->max);
    console_put_str(" pair=");
    console_put_u32(pair_cycles);
    console_put_str(" at_max=");
    console_put_u32(s->at_max);
    console_put_str("\r\n");
}

static void info(const char *name, uint32_t v)
{
    console_put_str("BENCH_INFO ");
    console_put_str(run_name);
    console_put_str(".");
    console_put_str(name);
    console_put_str("=");
    console_put_u32(v);
    console_put_str("\r\n");
}

static void measure_pair(void)
{
    pair_cycles = UINT32_MAX;
    for (int i = 0; i < 64; i++) {
        uint32_t c0 = cyc();
        __asm volatile("" ::: "memory");
        uint32_t c1 = cyc();
        uint32_t d = since(c0, c1);
        if (d < pair_cycles)
            pair_cycles = d;
    }
}

/* Exactly 2 instructions per iteration (subs, bne), to calibrate cycles against instructions. */
static void measure_calibration(void)
{
    stat_t s = {0};
    uint32_t n = CAL_ITERATIONS;
    uint32_t c0 = cyc();
    __asm volatile("1: subs %0, %0, #1\n\tbne 1b" : "+r"(n) : : "cc");
    uint32_t c1 = cyc();
    stat_add(&s, since(c0, c1));
    console_put_str("BENCH calibration_2insn iterations=");
    console_put_u32(CAL_ITERATIONS);
    console_put_str(" cycles=");
    console_put_u32(s.sum - pair_cycles);
    console_put_str("\r\n");
}

static psa_config_t loop_config(void)
{
    psa_config_t c = {.onset = onset_default_config(), .smooth = true};
    /* The USART image's smoothing: 200 mm/s, 20000 mm/s^2 (a 1.5 mm offset step in ~17 ms). */
    c.lim = comp_smoothing_from_rates(200 * PS_Q16_ONE, 20000 * PS_Q16_ONE, TICK_HZ);
    return c;
}

/* Compensation mode with table tab on a +-30 deg triangle with half-periods in
 * [half_min, half_max] ticks, sampled and held every `hold` ticks (1: a new c* every tick;
 * 20: a 1 kHz host); ideal motor (q measured = last q*). Times psa_tick. */
static void run_compensation(const char *name, const calib_t *tab, uint32_t half_min, uint32_t half_max,
                             uint32_t hold)
{
    psa_config_t c = loop_config();
    psa_init(&loop, &c);
    if (!psa_set_table(&loop, tab) || !psa_set_mode(&loop, PSA_MODE_COMPENSATION)) {
        console_put_str("BENCH setup failed (compensation)\r\n");
        port_exit(1);
    }
    bench_tri_t ref;
    bench_tri_init(&ref, 30 * PS_Q16_ONE, half_min, half_max, 7u);
    ref.hold = hold;
    stat_t s = {0};
    uint32_t t_us = 0, events = 0;
    int32_t q = 0;
    for (uint32_t k = 0; k < BENCH_TICKS; k++) {
        int32_t c_ref = bench_tri_next(&ref);
        t_us += TICK_US;
        onset_event_t ev;
        bool ready;
        uint32_t c0 = cyc();
        q = psa_tick(&loop, t_us, c_ref, q, &ev, &ready);
        uint32_t c1 = cyc();
        stat_add(&s, since(c0, c1));
        events += ready;
    }
    sink_q16 = q;
    report(name, &s);
    info("reversals", ref.reversals);
    info("onset_events", events);
}

/* The two core calls psa_tick makes in compensation, each timed alone on the same
 * trajectory: comp_step (eq. 4 with smoothing) and onset_tick (encoder history push). */
static void run_parts(const char *comp_name, const char *onset_name, const calib_t *tab)
{
    psa_config_t c = loop_config();
    static comp_t comp;
    static onset_t onset;
    comp_reset(&comp, tab, &c.lim, -30 * PS_Q16_ONE);
    onset_init(&onset, &c.onset);
    bench_tri_t ref;
    bench_tri_init(&ref, 30 * PS_Q16_ONE, TICK_HZ / 4, TICK_HZ / 2, 7u);
    stat_t sc = {0}, so = {0};
    uint32_t t_us = 0;
    int32_t q = 0;
    for (uint32_t k = 0; k < BENCH_TICKS; k++) {
        int32_t c_ref = bench_tri_next(&ref);
        t_us += TICK_US;
        onset_event_t ev;
        uint32_t c0 = cyc();
        bool r = onset_tick(&onset, t_us, q, &ev);
        uint32_t c1 = cyc();
        q = comp_step(&comp, c_ref);
        uint32_t c2 = cyc();
        stat_add(&so, since(c0, c1));
        stat_add(&sc, since(c1, c2));
        sink_q16 = r;
    }
    report(comp_name, &sc);
    if (onset_name)
        report(onset_name, &so);
}

/* Excitation mode over the built-in table's range (section III-B) at 3 mm/s with amplitude
 * ampl and advance adv; the plant is a 0.5 mm play seen by a 25 Hz camera 80 ms late,
 * when frames is set. Times psa_tick and, into *obs, every psa_observe_px. */
static void run_excitation(const char *name, int32_t ampl_q16, int32_t adv_q16, bool frames, stat_t *obs)
{
    psa_config_t c = loop_config();
    c.exc = (exc_config_t){.amplitude_q16 = ampl_q16, .advance_q16 = adv_q16,
                           .v_q32 = (int64_t)(((uint64_t)3 << 32) / TICK_HZ), .return_sweep = true};
    psa_init(&loop, &c);
    if (!psa_set_table(&loop, &cal[0]) || !psa_set_mode(&loop, PSA_MODE_EXCITATION)) {
        console_put_str("BENCH setup failed (excitation)\r\n");
        port_exit(1);
    }
    bench_plant_t plant;
    bench_plant_init(&plant, cal[0].q_min_q16, PS_Q16_ONE / 2, 8, 1966 /* 0.03 px */);
    struct {
        uint32_t t_us;
        int32_t u_q16, v_q16;
    } queue[FRAME_QUEUE];
    uint32_t nq = 0, ok = 0, events = 0, reversals_seen = 0;
    stat_t s = {0};
    uint32_t t_us = 0;
    int32_t q = cal[0].q_min_q16;
    for (uint32_t k = 0; k < BENCH_TICKS; k++) {
        t_us += TICK_US;
        onset_event_t ev;
        bool ready;
        uint32_t c0 = cyc();
        q = psa_tick(&loop, t_us, 0, q, &ev, &ready);
        uint32_t c1 = cyc();
        stat_add(&s, since(c0, c1));
        bench_plant_step(&plant, q);
        if (ready) {
            events++;
            ok += ev.reason == ONSET_OK;
            reversals_seen += ev.reason == ONSET_ERR_REVERSAL;
        }
        if (!frames)
            continue;
        if (k % FRAME_TICKS == 0 && nq < FRAME_QUEUE) {
            queue[nq].t_us = t_us + DELAY_TICKS * TICK_US;
            bench_plant_marker(&plant, &queue[nq].u_q16, &queue[nq].v_q16);
            nq++;
        }
        if (nq > 0 && (int32_t)(t_us - queue[0].t_us) >= 0) {
            uint32_t o0 = cyc();
            bool done = psa_observe_px(&loop, queue[0].t_us, queue[0].u_q16, queue[0].v_q16, true, &ev);
            uint32_t o1 = cyc();
            stat_add(obs, since(o0, o1));
            if (done) {
                events++;
                ok += ev.reason == ONSET_OK;
            }
            for (uint32_t i = 1; i < nq; i++)
                queue[i - 1] = queue[i];
            nq--;
        }
    }
    sink_q16 = q;
    report(name, &s);
    info("onset_events", events);
    info("onset_ok", ok);
    info("onset_superseded", reversals_seen);
}

/* The realistic excitation of run_excitation seen by a 25 Hz angle sensor instead of the
 * camera: c = 2 (u - 320 px) deg (16 deg per mm of the play's centre, the marker's noise
 * scaled), delivered 80 ms late. Times every psa_observe_deg into *obs. A separate function,
 * not a flag of run_excitation: the timed windows there then compile as they did (a flag
 * moved the px count by 1-4 instructions: the window includes the call's argument moves). */
static void run_observe_deg(const char *name, int32_t ampl_q16, int32_t adv_q16, stat_t *obs)
{
    psa_config_t c = loop_config();
    c.exc = (exc_config_t){.amplitude_q16 = ampl_q16, .advance_q16 = adv_q16,
                           .v_q32 = (int64_t)(((uint64_t)3 << 32) / TICK_HZ), .return_sweep = true};
    psa_init(&loop, &c);
    if (!psa_set_table(&loop, &cal[0]) || !psa_set_mode(&loop, PSA_MODE_EXCITATION)) {
        console_put_str("BENCH setup failed (excitation, deg)\r\n");
        port_exit(1);
    }
    bench_plant_t plant;
    bench_plant_init(&plant, cal[0].q_min_q16, PS_Q16_ONE / 2, 8, 1966 /* 0.03 px */);
    struct {
        uint32_t t_us;
        int32_t c_q16;
    } queue[FRAME_QUEUE];
    uint32_t nq = 0, ok = 0, events = 0;
    uint32_t t_us = 0;
    int32_t q = cal[0].q_min_q16;
    for (uint32_t k = 0; k < BENCH_TICKS; k++) {
        t_us += TICK_US;
        onset_event_t ev;
        bool ready;
        q = psa_tick(&loop, t_us, 0, q, &ev, &ready);
        bench_plant_step(&plant, q);
        if (ready) {
            events++;
            ok += ev.reason == ONSET_OK;
        }
        if (k % FRAME_TICKS == 0 && nq < FRAME_QUEUE) {
            int32_t u_q16, v_q16;
            bench_plant_marker(&plant, &u_q16, &v_q16);
            queue[nq].t_us = t_us + DELAY_TICKS * TICK_US;
            queue[nq].c_q16 = (u_q16 - 320 * PS_Q16_ONE) * 2;
            nq++;
        }
        if (nq > 0 && (int32_t)(t_us - queue[0].t_us) >= 0) {
            uint32_t o0 = cyc();
            bool done = psa_observe_deg(&loop, queue[0].t_us, queue[0].c_q16, true, &ev);
            uint32_t o1 = cyc();
            stat_add(obs, since(o0, o1));
            if (done) {
                events++;
                ok += ev.reason == ONSET_OK;
            }
            for (uint32_t i = 1; i < nq; i++)
                queue[i - 1] = queue[i];
            nq--;
        }
    }
    sink_q16 = q;
    report(name, obs);
    info("onset_events", events);
    info("onset_ok", ok);
}

/* What a table commit costs the loop: the CRC check, calib_load (f^-1 and envelope tables,
 * section IV) and psa_set_table, as psl's do_table_commit runs them (its flash write aside). */
static void run_commit(void)
{
    psa_config_t c = loop_config();
    psa_init(&loop, &c);
    stat_t s = {0};
    uint32_t bad = 0;
    for (uint32_t i = 0; i < COMMITS; i++) {
        calib_t *dst = &cal[1u - (i & 1u)];
        uint32_t c0 = cyc();
        uint32_t crc = calib_table_crc(blob.bytes, (uint32_t)blob_size);
        calib_status_t st = calib_load(dst, blob.bytes, blob_size);
        bool taken = psa_set_table(&loop, dst);
        uint32_t c1 = cyc();
        stat_add(&s, since(c0, c1));
        bad += st != CALIB_OK || !taken || crc == 0u;
    }
    report("table_commit", &s);
    info("commit_failures", bad);
}

/* On-line B update (b_online.c): b_online_sample on its own, the path an
 * observation that completes an onset takes (psa_observe_*'s hook), never psa_tick. Samples
 * spread over the travel at widths near the table's (every node's row of P in play): on the
 * built-in table's B (33 entries: 9 nodes) and on the costliest grid: 241 entries, 16 nodes (the
 * most nodes any grid gets; 256 entries would get 9). */
static b_online_t bench_bo;
static int32_t bench_b256[PST_MAX_ENTRIES];

static void time_b_online(const char *name, lut_t *b)
{
    b_online_config_t bc = b_online_default_config();
    if (b_online_init(&bench_bo, &bc, b) != B_ONLINE_OK) {
        console_put_str("BENCH setup failed (b_online)\r\n");
        port_exit(1);
    }
    stat_t s = {0};
    int32_t span = b->x_last_q16 - b->x0_q16;
    for (uint32_t i = 0; i < 256u; i++) {
        int32_t q = b->x0_q16 + (int32_t)(((int64_t)span * ((i * 97u) % 256u)) >> 8);
        int32_t w = lut_eval(b, q) + (int32_t)((i * 7919u) % 6554u) - 3277; /* +-0.05 units */
        uint32_t c0 = cyc();
        b_online_sample(&bench_bo, q, w);
        uint32_t c1 = cyc();
        stat_add(&s, since(c0, c1));
    }
    sink_q16 = b_online_entries(&bench_bo)[0];
    report(name, &s);
}

static void run_b_online(void)
{
    lut_t b_builtin = cal[0].b; /* a copy: re-pointed to the RAM grid, cal[0] keeps the flashed one */
    time_b_online("b_online_sample_builtin", &b_builtin);
    lut_t b_big;
    for (uint32_t j = 0; j < PST_MAX_ENTRIES; j++)
        bench_b256[j] = PS_Q16_ONE / 2 + (int32_t)(j * 64u);
    if (lut_init(&b_big, bench_b256, 241, 0, 1 << 10) != LUT_OK) {
        console_put_str("BENCH setup failed (b_online grid)\r\n");
        port_exit(1);
    }
    time_b_online("b_online_sample_241", &b_big);
    info("b_online_241_nodes", bench_bo.n_nodes);
}

/* On-line offset and gain of f (f_online.c). A reading: psa_f_regressor + f_online_sample, what
 * psa_observe_deg adds on the observation call when the learner is on (never psa_tick). A
 * publish: f_online_publish (the solve and the f^-1 rewrite into the spare copy, one pointer
 * store), what psa_background runs from the main loop every publish_every readings. A learning
 * step as the host mirror counts it (f_online_step: a reading's sample, and the publish when
 * due): its worst is the publish. On the built-in table and on the costliest f^-1 (close to
 * CALIB_DERIVED_MAX entries, f on PST_MAX_ENTRIES). */
static f_online_t bench_fo;
static int32_t bench_f256[PST_MAX_ENTRIES];
static int32_t bench_finv[CALIB_DERIVED_MAX];

static void time_f_online(const char *suffix, const lut_t *f, lut_t *f_inv, const calib_t *tab)
{
    char name[48];
    f_online_config_t fc = f_online_default_config();
    if (f_online_init(&bench_fo, &fc, f, f_inv) != F_ONLINE_OK) {
        console_put_str("BENCH setup failed (f_online)\r\n");
        port_exit(1);
    }
    psa_config_t c = loop_config();
    psa_init(&loop, &c);
    if (!psa_set_table(&loop, tab) || !psa_set_mode(&loop, PSA_MODE_COMPENSATION)) {
        console_put_str("BENCH setup failed (f_online loop)\r\n");
        port_exit(1);
    }
    int32_t lo = lut_eval(f, f->x0_q16), hi = lut_eval(f, f->x_last_q16);
    if (lo > hi) {
        int32_t t = lo;
        lo = hi;
        hi = t;
    }
    stat_t rd = {0}, pub = {0}, stp = {0};
    for (uint32_t i = 0; i < 240u; i++) {
        int32_t c_ref = lo + (int32_t)(((int64_t)(hi - lo) * ((i * 37u) % 240u)) / 240);
        (void)psa_set_reference(&loop, c_ref);
        int32_t read = c_ref + PS_Q16_ONE + (int32_t)((i * 7919u) % 13107u); /* +1..1.2 deg */
        int32_t x;
        uint32_t c0 = cyc();
        bool ok = psa_f_regressor(&loop, true, &x);
        bool due = f_online_sample(&bench_fo, x, read);
        uint32_t c1 = cyc();
        stat_add(&rd, since(c0, c1));
        uint32_t step = since(c0, c1);
        if (ok && due) {
            c0 = cyc();
            f_online_publish(&bench_fo);
            c1 = cyc();
            stat_add(&pub, since(c0, c1));
            step += since(c0, c1) - pair_cycles; /* one read pair per measured window */
        }
        stat_add(&stp, step);
    }
    sink_q16 = f_online_entries(&bench_fo)[0];
    f_online_stop(&bench_fo);
    strcpy(name, "f_online_reading_");
    strcat(name, suffix);
    report(name, &rd);
    strcpy(name, "f_online_publish_");
    strcat(name, suffix);
    report(name, &pub);
    strcpy(name, "f_online_step_");
    strcat(name, suffix);
    report(name, &stp);
}

static void run_f_online(void)
{
    lut_t f = cal[0].f, f_inv = cal[0].f_inv; /* copies: cal[0]'s f^-1 keeps the loader's entries */
    calib_t *tab = &cal[1];
    *tab = cal[0];
    tab->f_inv = f_inv;
    time_f_online("builtin", &f, &tab->f_inv, tab);
    info("f_online_builtin_inv_entries", tab->f_inv.n);
    /* f over 250 deg on 256 entries: its inverse takes 501 of the 512 entries (step 2^15 raw). */
    for (uint32_t j = 0; j < PST_MAX_ENTRIES; j++)
        bench_f256[j] = (int32_t)(((int64_t)j * 250 * PS_Q16_ONE) / (PST_MAX_ENTRIES - 1)) + (int32_t)((j * j) & 63u);
    lut_t fb, ib;
    if (lut_init(&fb, bench_f256, PST_MAX_ENTRIES, 0, 1 << 12) != LUT_OK ||
        lut_build_inverse(&fb, bench_finv, CALIB_DERIVED_MAX, &ib, NULL) != LUT_OK) {
        console_put_str("BENCH setup failed (f_online grid)\r\n");
        port_exit(1);
    }
    tab->f = fb;
    tab->f_inv = ib;
    time_f_online("big", &tab->f, &tab->f_inv, tab);
    info("f_online_big_inv_entries", tab->f_inv.n);
    info("f_online_t_bytes", (uint32_t)sizeof(f_online_t));
}

int main(void)
{
    port_init();
    blob_size = psa_builtin_table(blob.bytes, sizeof blob.bytes);
    if (calib_load(&cal[0], blob.bytes, blob_size) != CALIB_OK || !port_tick_start(TIMEBASE_HZ, NULL)) {
        console_put_str("BENCH setup failed\r\n");
        return 1;
    }
    SYST_CSR &= ~SYST_CSR_TICKINT; /* free-running counter: no interrupt inside a window */
    console_put_str("BENCH core_hz=");
    console_put_u32(port_core_hz());
    console_put_str("\r\n");
    measure_pair();
    measure_calibration();
    stat_t obs = {0}, obs_stress = {0};
    run_compensation("tick_comp_realistic", &cal[0], TICK_HZ / 4, TICK_HZ / 2, 1);
    run_compensation("tick_comp_held", &cal[0], TICK_HZ / 4, TICK_HZ / 2, TICK_HZ / 1000);
    run_parts("comp_step", "onset_tick", &cal[0]);
    run_compensation("tick_comp_stress", &cal[0], 512, 512, 1);
    if (bench_pi_load(&cal_pi) != CALIB_OK) {
        console_put_str("BENCH setup failed (transition table)\r\n");
        return 1;
    }
    run_compensation("tick_pi_realistic", &cal_pi, TICK_HZ / 4, TICK_HZ / 2, 1);
    run_compensation("tick_pi_stress", &cal_pi, 512, 512, 1);
    run_parts("comp_step_pi", NULL, &cal_pi);
    if (bench_pi_map_load(&cal_pimap) != CALIB_OK) {
        console_put_str("BENCH setup failed (threshold-map table)\r\n");
        return 1;
    }
    run_compensation("tick_pimap_realistic", &cal_pimap, TICK_HZ / 4, TICK_HZ / 2, 1);
    run_compensation("tick_pimap_stress", &cal_pimap, 512, 512, 1);
    run_parts("comp_step_pimap", NULL, &cal_pimap);
    if (bench_pi_relax_load(&cal_pirelax) != CALIB_OK) {
        console_put_str("BENCH setup failed (relaxation table)\r\n");
        return 1;
    }
    run_compensation("tick_pirelax_realistic", &cal_pirelax, TICK_HZ / 4, TICK_HZ / 2, 1);
    run_compensation("tick_pirelax_stress", &cal_pirelax, 512, 512, 1);
    run_parts("comp_step_pirelax", NULL, &cal_pirelax);
    run_excitation("tick_exc_realistic", PS_Q16_ONE * 13 / 10, PS_Q16_ONE * 35 / 100, true, &obs);
    report("observe_px", &obs);
    /* The same excitation seen by an angle sensor instead of the camera (psa_observe_deg). */
    stat_t obs_deg = {0};
    run_observe_deg("observe_deg", PS_Q16_ONE * 13 / 10, PS_Q16_ONE * 35 / 100, &obs_deg);
    /* 512 ticks of travel at 3 mm/s up, 504 down. */
    run_excitation("tick_exc_stress", (int32_t)((512ull * 3u << 16) / TICK_HZ),
                   (int32_t)((8ull * 3u << 16) / TICK_HZ), false, &obs_stress);
    run_commit();
    run_b_online();
    run_f_online();
    console_put_str("BENCH done\r\n");
    return 0;
}
