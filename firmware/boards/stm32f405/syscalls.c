/* newlib system calls for the STM32F405: stdout/stderr to USART1, stdin from it, heap below the stack. */
#include <errno.h>
#include <stdint.h>
#include <sys/stat.h>

#include "port_board.h"

/* From stm32f405.ld: the heap runs from the end of .bss up to the reserved stack. */
extern uint8_t __heap_start;
extern uint8_t __heap_limit;

/* Prototypes newlib expects us to provide (it declares none of them in a public header). */
int _write(int fd, const char *buf, int len);
int _read(int fd, char *buf, int len);
void *_sbrk(ptrdiff_t incr);
int _close(int fd);
int _fstat(int fd, struct stat *st);
int _isatty(int fd);
int _lseek(int fd, int off, int whence);
void _exit(int code);
int _kill(int pid, int sig);
int _getpid(void);
void _init(void);
void _fini(void);

/* Terminals want CR LF; tests and logs are written with bare LF. */
int _write(int fd, const char *buf, int len)
{
    if (fd != 1 && fd != 2) {
        errno = EBADF;
        return -1;
    }
    int start = 0;
    for (int i = 0; i < len; i++) {
        if (buf[i] == '\n') {
            port_uart_write(buf + start, (size_t)(i - start));
            port_uart_write("\r\n", 2);
            start = i + 1;
        }
    }
    port_uart_write(buf + start, (size_t)(len - start));
    return len;
}

/* Blocks until at least one byte arrived, as a terminal read would. */
int _read(int fd, char *buf, int len)
{
    if (fd != 0) {
        errno = EBADF;
        return -1;
    }
    if (len <= 0) {
        return 0;
    }
    size_t n;
    while ((n = port_uart_read(buf, (size_t)len)) == 0u) {
        port_wait_for_interrupt();
    }
    return (int)n;
}

/* Refuses to grow into the stack reservation instead of silently overlapping it. */
void *_sbrk(ptrdiff_t incr)
{
    static uint8_t *brk = &__heap_start;
    if (incr > &__heap_limit - brk || incr < &__heap_start - brk) {
        errno = ENOMEM;
        return (void *)-1;
    }
    uint8_t *old = brk;
    brk += incr;
    return old;
}

int _close(int fd)
{
    (void)fd;
    errno = EBADF;
    return -1;
}

/* Character device, so newlib line-buffers stdout instead of allocating a 1 KiB block buffer. */
int _fstat(int fd, struct stat *st)
{
    (void)fd;
    st->st_mode = S_IFCHR;
    return 0;
}

int _isatty(int fd)
{
    return fd >= 0 && fd <= 2;
}

int _lseek(int fd, int off, int whence)
{
    (void)fd;
    (void)off;
    (void)whence;
    errno = ESPIPE;
    return -1;
}

void _exit(int code)
{
    port_exit(code);
}

/* abort() raises SIGABRT through _kill: end with the conventional 134 (128 + 6). */
int _kill(int pid, int sig)
{
    (void)pid;
    port_exit(128 + sig);
}

int _getpid(void)
{
    return 1;
}

/* exit() runs __libc_fini_array, which calls _fini from crti.o; we link -nostartfiles and
 * have no .init/.fini code, so both hooks are empty (the arrays come from the linker script). */
void _init(void)
{
}

void _fini(void)
{
}
