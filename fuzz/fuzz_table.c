/* libFuzzer target: arbitrary bytes as a calibration table into calib_load (the upload's final check). */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "calib.h"
#include "ps_crc32.h"

static calib_t cal;
static uint32_t blob[(PST_MAX_TABLE_SIZE + 3) / 4 + 1];

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
    if (calib_load(&cal, b, size) == CALIB_OK) {
        /* An accepted table must evaluate anywhere without faults. */
        for (int32_t x = -(1 << 30); x < (1 << 30); x += 1 << 26) {
            (void)lut_eval(&cal.f, x);
            (void)lut_eval(&cal.f_inv, x);
            (void)lut_eval(&cal.z_up, x);
        }
    }
    return 0;
}
