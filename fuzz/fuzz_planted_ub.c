/* libFuzzer target with a planted signed overflow on inputs starting "UB": fuzz/run.sh feeds it
 * that input and requires the process to die, so a build that only reports UB fails the run. */
#include <stddef.h>
#include <stdint.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size >= 2 && data[0] == 'U' && data[1] == 'B') {
        volatile int32_t x = INT32_MAX;
        int32_t y = x + (int32_t)data[1]; /* signed overflow: UB */
        return y == 0;
    }
    return 0;
}
