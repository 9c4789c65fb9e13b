/* libFuzzer target: arbitrary bytes as a calibration table into calib_load and a board's calib_load_guarded. */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "calib.h"
#include "comp.h"
#include "playop.h"
#include "ps_crc32.h"

static calib_t cal;
static playop_t play;
static comp_t comp;
static uint32_t blob[(PST_MAX_TABLE_SIZE + 3) / 4 + 1];
/* A board's own limits (the virtual board's defaults): the binding and limit rules run too. */
static const pst_limits_t board = {.instrument_id = PST_INSTRUMENT_DEFAULT, .q_unit = PST_Q_UNIT_MM,
                                   .q_min_q16 = -100 * 65536, .q_max_q16 = 100 * 65536, .c_min_q16 = -180 * 65536,
                                   .c_max_q16 = 180 * 65536, .b_max_q16 = 10 * 65536};

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Half the inputs get their CRC resealed so the fuzzer reaches the grid and shape checks
 * behind it instead of stopping at the CRC every time. */
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size > sizeof(blob))
        size = sizeof(blob);
    memcpy(blob, data, size);
    uint8_t *b = (uint8_t *)blob;
    if (size >= sizeof(pst_header_t) && (b[size - 1] & 1)) {
        uint32_t total;
        memcpy(&total, b + 8, 4);
        if (total >= sizeof(pst_header_t) && total <= size) {
            uint32_t crc = calib_table_crc(b, total);
            memcpy(b + 12, &crc, 4);
        }
    }
    pst_plaus_report_t rep;
    calib_status_t on_board = calib_load_guarded(&cal, b, size, &board, &rep);
    /* What a board takes, the host's loader takes too (the board's rules only add to it). */
    if (calib_load(&cal, b, size) != CALIB_OK && on_board == CALIB_OK)
        __builtin_trap();
    if (calib_load(&cal, b, size) == CALIB_OK) {
        /* An accepted table must evaluate anywhere without faults. */
        for (int32_t x = -(1 << 30); x < (1 << 30); x += 1 << 26) {
            (void)lut_eval(&cal.f, x);
            (void)lut_eval(&cal.f_inv, x);
            (void)lut_eval(&cal.z_up, x);
        }
        /* And the direct model and the compensator, transition included, must run from
         * anywhere to anywhere, with reversals, without overflow (UBSan) or faults. */
        playop_reset(&play, &cal, -(1 << 30));
        comp_reset(&comp, &cal, NULL, 1 << 30);
        for (int k = 0; k < 64; k++) {
            int32_t x = (int32_t)((uint32_t)(k & 7) * 0x24924924u) ^ (k & 8 ? INT32_MIN : 0);
            (void)playop_step(&play, x);
            (void)comp_step(&comp, x);
        }
    }
    return 0;
}
