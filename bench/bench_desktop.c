/* Desktop throughput of the production loop (psa_tick, compensation mode, realistic reference), desktop-release build. */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "ps_fixed.h"
#include "ps_table.h"
#include "psa_builtin_table.h"
#include "psa_loop.h"
#include "bench_traj.h"

enum { TICK_HZ = 20000, REF_LEN = 1 << 16 };

static psa_loop_t loop;
static calib_t cal;
static union {
    uint32_t align;
    uint8_t bytes[PST_MAX_TABLE_SIZE];
} blob;
static int32_t c_ref_q16[REF_LEN];
volatile int32_t bench_sink_q16;

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Prints "ticks_per_s=<best of 5 runs of n ticks>" for the trajectory of bench_m4.c's
 * tick_comp_realistic (reference precomputed, so only psa_tick is timed). */
int main(int argc, char **argv)
{
    long n = argc > 1 ? atol(argv[1]) : 20000000L;
    psa_config_t c = {.onset = onset_default_config(), .smooth = true,
                      .lim = comp_smoothing_from_rates(200 * PS_Q16_ONE, 20000 * PS_Q16_ONE, TICK_HZ)};
    psa_init(&loop, &c);
    if (calib_load(&cal, blob.bytes, psa_builtin_table(blob.bytes, sizeof blob.bytes)) != CALIB_OK ||
        !psa_set_table(&loop, &cal) || !psa_set_mode(&loop, PSA_MODE_COMPENSATION)) {
        fprintf(stderr, "bench_desktop: demo table refused\n");
        return 1;
    }
    bench_tri_t ref;
    bench_tri_init(&ref, 30 * PS_Q16_ONE, TICK_HZ / 4, TICK_HZ / 2, 7u);
    for (int i = 0; i < REF_LEN; i++)
        c_ref_q16[i] = bench_tri_next(&ref);
    double best_s = 1e30;
    uint32_t t_us = 0;
    for (int run = 0; run < 5; run++) {
        int32_t q = 0;
        onset_event_t ev;
        bool ready;
        double t0 = now_s();
        for (long i = 0; i < n; i++) {
            t_us += 1000000u / TICK_HZ;
            q = psa_tick(&loop, t_us, c_ref_q16[i & (REF_LEN - 1)], q, &ev, &ready);
        }
        double dt = now_s() - t0;
        bench_sink_q16 = q;
        if (dt < best_s)
            best_s = dt;
    }
    printf("ticks=%ld best_s=%.6f ticks_per_s=%.0f ns_per_tick=%.2f\n", n, best_s, (double)n / best_s,
           1e9 * best_s / (double)n);
    return 0;
}
