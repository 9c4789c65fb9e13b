/* Console text over the port UART, shared by the USART image and the M4 bench. */
#include "port_console.h"

#include <string.h>
#include "port_board.h"

void console_put_str(const char *s)
{
    port_uart_write(s, strlen(s));
}

void console_put_u32(uint32_t v)
{
    char buf[10];
    int n = 0;
    do {
        buf[sizeof buf - 1 - n++] = (char)('0' + v % 10u);
        v /= 10u;
    } while (v != 0u);
    port_uart_write(buf + sizeof buf - n, (size_t)n);
}
