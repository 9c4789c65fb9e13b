/* STM32F405 implementation of firmware/port/port_board.h: clocks, SysTick tick, USART1, semihosting exit. */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "port_board.h"
#include "stm32f405_regs.h"

#ifndef BOARD_UART_BAUD
/* BOARD_UART_BAUD: console USART1 baud rate (8N1). Default 115200. */
#define BOARD_UART_BAUD 115200u
#endif

#ifndef BOARD_UART_RX_LEN
/* BOARD_UART_RX_LEN: bytes of the USART1 receive ring, a power of two. Default 512. */
#define BOARD_UART_RX_LEN 512u
#endif
_Static_assert((BOARD_UART_RX_LEN & (BOARD_UART_RX_LEN - 1u)) == 0, "BOARD_UART_RX_LEN must be a power of two");

enum {
    HSI_HZ = 16000000,
    PLL_CORE_HZ = 168000000,
    PLL_WAIT_LOOPS = 100000,     /* PLL locks in ~100 us; far more than enough at 16 MHz */
    SEMIHOST_SYS_EXIT_EXTENDED = 0x20,
    SEMIHOST_ADP_STOPPED_APPLICATION_EXIT = 0x20026,
};

static uint32_t core_hz = HSI_HZ;
static uint32_t apb2_hz = HSI_HZ;

/* Time base, advanced by SysTick_Handler once per period. */
static volatile uint64_t tick_cycles_base;
static volatile uint32_t tick_us_base;
static uint32_t tick_period_cycles;
static uint32_t tick_period_us;
static uint32_t cycles_per_us;
static port_tick_fn tick_fn;

/* Receive ring filled by USART1_IRQHandler; head written by the ISR only, tail by readers. */
static volatile uint8_t rx_ring[BOARD_UART_RX_LEN];
static volatile uint32_t rx_head;
static volatile uint32_t rx_tail;

/* 168 MHz from the 16 MHz HSI (no crystal assumed): VCO = 16/16*336 = 336 MHz, /2 core,
 * /7 = 48 MHz for USB; APB1 = 42 MHz (max 42), APB2 = 84 MHz (max 84).
 * QEMU's netduinoplus2 leaves RCC unimplemented (every read is 0, the core always runs at
 * 168 MHz): a real part reads HSIRDY set at reset, so a zero CR means "emulated, skip". */
static void clock_init(void)
{
    if (RCC_CR == 0u) {
        core_hz = PLL_CORE_HZ;
        apb2_hz = PLL_CORE_HZ / 2;
        return;
    }
    FLASH_ACR = FLASH_ACR_LATENCY_5WS | FLASH_ACR_PRFTEN | FLASH_ACR_ICEN | FLASH_ACR_DCEN;
    RCC_PLLCFGR = (16u << 0) | (336u << 6) | (0u << 16) | (0u << 22) | (7u << 24);
    RCC_CFGR = RCC_CFGR_PPRE1_DIV4 | RCC_CFGR_PPRE2_DIV2;
    RCC_CR |= RCC_CR_PLLON;
    for (int i = 0; i < PLL_WAIT_LOOPS; i++) {
        if (RCC_CR & RCC_CR_PLLRDY) {
            RCC_CFGR = RCC_CFGR_PPRE1_DIV4 | RCC_CFGR_PPRE2_DIV2 | RCC_CFGR_SW_PLL;
            while ((RCC_CFGR & RCC_CFGR_SWS_MASK) != RCC_CFGR_SWS_PLL) {
            }
            core_hz = PLL_CORE_HZ;
            apb2_hz = PLL_CORE_HZ / 2;
            return;
        }
    }
    /* No lock: stay on the HSI with undivided buses, still a working (slower) board. */
    RCC_CFGR = 0u;
}

/* USART1 on PA9/PA10, 8N1, RX by interrupt into rx_ring, TX polled. QEMU's model drops
 * received bytes unless UE, TE and RE are all set, so all three go in one write. */
static void uart_init(void)
{
    RCC_AHB1ENR |= RCC_AHB1ENR_GPIOAEN;
    RCC_APB2ENR |= RCC_APB2ENR_USART1EN;
    GPIOA_MODER = (GPIOA_MODER & ~(0xFu << 18)) | (0xAu << 18);      /* PA9, PA10 alternate */
    GPIOA_PUPDR = (GPIOA_PUPDR & ~(0x3u << 20)) | (0x1u << 20);      /* RX pull-up: idle high */
    GPIOA_AFRH = (GPIOA_AFRH & ~(0xFFu << 4)) | (0x77u << 4);        /* AF7 = USART1 */
    /* Oversampling by 16: BRR = f_pclk / baud, rounded (mantissa and fraction packed). */
    USART1_BRR = (apb2_hz + BOARD_UART_BAUD / 2u) / BOARD_UART_BAUD;
    USART1_CR1 = USART_CR1_UE | USART_CR1_TE | USART_CR1_RE | USART_CR1_RXNEIE;
    NVIC_IPR8(USART1_IRQN) = 0x40u;  /* below SysTick (0x00): the control tick preempts */
    NVIC_ISER(USART1_IRQN / 32u) = 1u << (USART1_IRQN % 32u);
}

void port_init(void)
{
    __asm volatile("cpsid i" ::: "memory");
    clock_init();
    uart_init();
    __asm volatile("cpsie i" ::: "memory");
}

uint32_t port_core_hz(void)
{
    return core_hz;
}

bool port_tick_start(uint32_t tick_hz, port_tick_fn fn)
{
    if (tick_hz == 0u || core_hz % tick_hz != 0u || core_hz / tick_hz - 1u > SYST_RVR_MAX ||
        core_hz % 1000000u != 0u || 1000000u % tick_hz != 0u) {
        return false;
    }
    SYST_CSR = 0u;
    tick_period_cycles = core_hz / tick_hz;
    tick_period_us = 1000000u / tick_hz;
    cycles_per_us = core_hz / 1000000u;
    tick_cycles_base = 0u;
    tick_us_base = 0u;
    tick_fn = fn;
    SCB_SHPR3 = (SCB_SHPR3 & 0x00FFFFFFu);  /* SysTick at the highest priority: the control tick */
    SYST_RVR = tick_period_cycles - 1u;
    SYST_CVR = 0u;
    SYST_CSR = SYST_CSR_ENABLE | SYST_CSR_TICKINT | SYST_CSR_CLKSOURCE_CPU;
    return true;
}

void SysTick_Handler(void)
{
    tick_cycles_base += tick_period_cycles;
    tick_us_base += tick_period_us;
    if (tick_fn != NULL) {
        tick_fn();
    }
}

/* Snapshot of the time base: the periods counted by the ISR, and the cycles elapsed in
 * the current period. Correct in thread mode and inside the tick callback, even when a
 * wrap has happened but its interrupt is still pending (callback longer than a period,
 * or interrupts masked): PENDSTSET then says one period is missing from the base. */
static void tick_snapshot(uint64_t *base_cycles, uint32_t *base_us, uint32_t *in_period_cycles)
{
    for (;;) {
        uint64_t cycles = tick_cycles_base;
        uint32_t us = tick_us_base;
        uint32_t v1 = SYST_CVR;
        bool pending = (SCB_ICSR & SCB_ICSR_PENDSTSET) != 0u;
        uint32_t v2 = SYST_CVR;
        if (cycles != tick_cycles_base || v2 > v1) {
            continue;  /* the ISR ran, or the counter reloaded, between the reads */
        }
        if (pending) {
            cycles += tick_period_cycles;
            us += tick_period_us;
        }
        *base_cycles = cycles;
        *base_us = us;
        *in_period_cycles = SYST_RVR - v2;
        return;
    }
}

uint64_t port_cycles(void)
{
    uint64_t base;
    uint32_t us, in_period;
    tick_snapshot(&base, &us, &in_period);
    return base + in_period;
}

uint32_t port_ticks_us(void)
{
    if (cycles_per_us == 0u) {
        return 0u;  /* before port_tick_start() */
    }
    uint64_t base;
    uint32_t us, in_period;
    tick_snapshot(&base, &us, &in_period);
    return us + in_period / cycles_per_us;  /* the M4 divides in hardware (UDIV) */
}

size_t port_uart_write(const void *buf, size_t len)
{
    const uint8_t *p = buf;
    for (size_t i = 0; i < len; i++) {
        while ((USART1_SR & USART_SR_TXE) == 0u) {
        }
        USART1_DR = p[i];
    }
    return len;
}

void USART1_IRQHandler(void)
{
    /* Reading SR then DR clears RXNE and ORE; a full ring drops the newest byte. */
    uint32_t sr = USART1_SR;
    if (sr & (USART_SR_RXNE | USART_SR_ORE)) {
        uint8_t byte = (uint8_t)USART1_DR;
        uint32_t head = rx_head;
        if (head - rx_tail < BOARD_UART_RX_LEN) {
            rx_ring[head % BOARD_UART_RX_LEN] = byte;
            rx_head = head + 1u;
        }
    }
}

size_t port_uart_read(void *buf, size_t max)
{
    uint8_t *p = buf;
    size_t n = 0;
    uint32_t tail = rx_tail;
    uint32_t head = rx_head;
    while (n < max && tail != head) {
        p[n++] = rx_ring[tail % BOARD_UART_RX_LEN];
        tail++;
    }
    rx_tail = tail;
    return n;
}

void port_wait_for_interrupt(void)
{
    __asm volatile("wfi" ::: "memory");
}

/* ARM semihosting call: BKPT 0xAB with the operation in r0 and its argument in r1. With
 * no debugger or emulator attached it faults, which ends in Default_Handler's halt. */
static void semihost_call(uint32_t op, const void *arg)
{
    register uint32_t r0 __asm("r0") = op;
    register const void *r1 __asm("r1") = arg;
    __asm volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
}

void port_exit(int code)
{
    /* SYS_EXIT_EXTENDED carries the status; plain SYS_EXIT on 32-bit ARM only says 0 or 1. */
    const uint32_t block[2] = {SEMIHOST_ADP_STOPPED_APPLICATION_EXIT, (uint32_t)code};
    while ((USART1_SR & USART_SR_TXE) == 0u) {
    }
    semihost_call(SEMIHOST_SYS_EXIT_EXTENDED, block);
    __asm volatile("cpsid i" ::: "memory");
    for (;;) {
        __asm volatile("wfi");
    }
}
