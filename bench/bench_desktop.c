/* Desktop throughput of the control tick (onset_tick + comp_step), built against the desktop-release core. */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "bench_tick.h"

enum { BENCH_TICK_HZ = 20000, REF_LEN = 1024 };

static ctl_loop_t loop;
static int32_t c_ref_q16[REF_LEN];
volatile int32_t bench_sink_q16;

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Prints "ticks_per_s=<best of 5 runs of n ticks>" for the same chain as bench_m4.c's core_chain. */
int main(int argc, char **argv)
{
    long n = argc > 1 ? atol(argv[1]) : 20000000L;
    if (ctl_loop_init(&loop, BENCH_TICK_HZ) != 0) {
        fprintf(stderr, "bench_desktop: demo table refused\n");
        return 1;
    }
    for (int i = 0; i < REF_LEN; i++) {
        int32_t phase = i < REF_LEN / 2 ? i : REF_LEN - i;
        c_ref_q16[i] = -30 * 65536 + phase * (60 * 65536 / (REF_LEN / 2));
    }
    double best_s = 1e30;
    for (int run = 0; run < 5; run++) {
        uint32_t t_us = 0;
        int32_t q = 0;
        onset_event_t ev;
        double t0 = now_s();
        for (long i = 0; i < n; i++) {
            t_us += 1000000u / BENCH_TICK_HZ;
            (void)onset_tick(&loop.onset, t_us, q, &ev);
            q = comp_step(&loop.comp, c_ref_q16[i % REF_LEN]);
        }
        double dt = now_s() - t0;
        bench_sink_q16 = q;
        if (dt < best_s) {
            best_s = dt;
        }
    }
    printf("ticks=%ld best_s=%.6f ticks_per_s=%.0f ns_per_tick=%.2f\n", n, best_s, (double)n / best_s,
           1e9 * best_s / (double)n);
    return 0;
}
