/* Planted undefined behaviour: proves the sanitised build stops at the first report instead of
 * printing it and carrying on (-fno-sanitize-recover=all, halt_on_error). Run by the ctest
 * "sanitizer_stops_on_ub", which passes only if this program dies at the overflow. */
#include <stdint.h>
#include <stdio.h>

int main(void)
{
    volatile int32_t x = INT32_MAX; /* volatile: the compiler cannot fold the overflow away */
    int32_t y = x + 1;              /* signed overflow: UB */
    printf("continued past the undefined behaviour (y = %d)\n", (int)y);
    return 0;
}
