/* Console text over the port UART without printf (keeps newlib's formatter out of small images). */
#ifndef PORT_CONSOLE_H
#define PORT_CONSOLE_H

#include <stdint.h>

/* Write a NUL-terminated string to the UART (port_uart_write). */
void console_put_str(const char *s);

/* Write v in decimal, no padding. */
void console_put_u32(uint32_t v);

#endif /* PORT_CONSOLE_H */
