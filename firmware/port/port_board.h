/* Board port API: the few hardware services the firmware apps, tests and bench need. */
#ifndef PORT_BOARD_H
#define PORT_BOARD_H

/* Each board (firmware/boards/<board>/) implements every function below. Algorithm code
 * in firmware/core/ never includes this header: it stays hardware-free so the desktop
 * tests compile the very same files. Times are uint32_t microseconds that wrap every
 * 71.6 min (common/ps_fixed.h); differences are taken modulo 2^32. */

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* Per-tick callback, run in interrupt context at the rate given to port_tick_start(). */
typedef void (*port_tick_fn)(void);

/* Bring up clocks and the console UART (interrupts enabled on return). Call once, first. */
void port_init(void);

/* Core clock in Hz as configured by port_init(). */
uint32_t port_core_hz(void);

/* Start the periodic control tick at tick_hz (must divide port_core_hz() into a whole
 * number of cycles and of microseconds); fn may be NULL to only run the time base.
 * Returns false if the rate cannot be made exactly. */
bool port_tick_start(uint32_t tick_hz, port_tick_fn fn);

/* Microseconds since port_tick_start(), wrapping modulo 2^32. Valid in thread mode and
 * inside the tick callback. */
uint32_t port_ticks_us(void);

/* Core clock cycles since port_tick_start(), 64-bit (never wraps in practice). Same
 * validity as port_ticks_us(); used by the bench to count work between two reads. */
uint64_t port_cycles(void);

/* Send len bytes on the console UART; blocks until all are queued. Returns len. */
size_t port_uart_write(const void *buf, size_t len);

/* Copy up to max received bytes into buf without blocking. Returns the count (0 if none). */
size_t port_uart_read(void *buf, size_t max);

/* Stop the program with exit status code (emulator: process exit code; hardware: halts
 * with interrupts off). Never returns. */
void port_exit(int code) __attribute__((noreturn));

/* Sleep until the next interrupt (tick or UART), to idle the main loop. */
void port_wait_for_interrupt(void);

#endif /* PORT_BOARD_H */
