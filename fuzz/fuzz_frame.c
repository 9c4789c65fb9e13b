/* libFuzzer target: arbitrary bytes into the frame parser and the board's protocol handler. */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "storage/pss_flash_sim.h"
#include "link/psl_link.h"

enum { SLOT = 4096 };

static psl_t board;
static pss_sim_t sim;
static uint8_t mem[2 * SLOT];
static size_t sent;

static void sink(void *ctx, const uint8_t *frame, size_t len)
{
    (void)ctx;
    (void)frame;
    sent += len;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* The input is a byte stream from the host; ticks are interleaved every 64 bytes so
 * streaming and the onset timeout run too. Sequence checks are what the fuzzer fights,
 * so the window is reset each run: a fresh board per input. */
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    pss_sim_init(&sim, mem, SLOT, 1);
    psl_config_t cfg = psl_default_config(1000);
    psl_init(&board, &cfg, &sim.port, sink, NULL);
    uint32_t t_us = 0;
    int32_t q = 0;
    for (size_t off = 0; off < size; off += 64) {
        size_t n = size - off < 64 ? size - off : 64;
        psl_rx(&board, data + off, n);
        q = psl_tick(&board, t_us, q);
        (void)psl_background(&board); /* the main loop's background step (on-line B) */
        t_us += 1000;
    }
    return 0;
}
