/* STM32F405 reset and vector table: FPU on, .data copied, .bss zeroed, then main(). */
#include <stdint.h>
#include <string.h>

#include "port_board.h"
#include "stm32f405_regs.h"

/* Linker script symbols (stm32f405.ld); only their addresses are meaningful. */
extern uint32_t __stack_top;
extern uint32_t __data_load, __data_start, __data_end;
extern uint32_t __bss_start, __bss_end;
extern void (*__init_array_start[])(void);
extern void (*__init_array_end[])(void);

int main(void);
void Reset_Handler(void);
void Default_Handler(void);
void reset_continue(void) __attribute__((noreturn, used));

/* Faults and unused interrupts land in Default_Handler unless a file defines them. */
#define WEAK_DEFAULT __attribute__((weak, alias("Default_Handler")))
void NMI_Handler(void) WEAK_DEFAULT;
void HardFault_Handler(void) WEAK_DEFAULT;
void MemManage_Handler(void) WEAK_DEFAULT;
void BusFault_Handler(void) WEAK_DEFAULT;
void UsageFault_Handler(void) WEAK_DEFAULT;
void SVC_Handler(void) WEAK_DEFAULT;
void DebugMon_Handler(void) WEAK_DEFAULT;
void PendSV_Handler(void) WEAK_DEFAULT;
void SysTick_Handler(void) WEAK_DEFAULT;
void USART1_IRQHandler(void) WEAK_DEFAULT;

typedef void (*vector_fn)(void);

enum {
    VECTORS_SYSTEM = 16,         /* initial SP + 15 core exceptions */
    VECTORS_IRQ = 82,            /* STM32F405 IRQ 0..81 (RM0090 table 61) */
};

/* Placed first in flash by the linker script; the core reads SP and PC from it at reset
 * (flash is aliased at address 0 when booting from main flash). */
__attribute__((section(".isr_vector"), used))
const vector_fn vector_table[VECTORS_SYSTEM + VECTORS_IRQ] = {
    [0] = (vector_fn)(uintptr_t)&__stack_top,
    [1] = Reset_Handler,
    [2] = NMI_Handler,
    [3] = HardFault_Handler,
    [4] = MemManage_Handler,
    [5] = BusFault_Handler,
    [6] = UsageFault_Handler,
    [11] = SVC_Handler,
    [12] = DebugMon_Handler,
    [14] = PendSV_Handler,
    [15] = SysTick_Handler,
    [VECTORS_SYSTEM ... VECTORS_SYSTEM + USART1_IRQN - 1] = Default_Handler,
    [VECTORS_SYSTEM + USART1_IRQN] = USART1_IRQHandler,
    [VECTORS_SYSTEM + USART1_IRQN + 1 ... VECTORS_SYSTEM + VECTORS_IRQ - 1] = Default_Handler,
};

/* Naked so that no compiler-generated code (which may touch s0..s31 under the hard-float
 * ABI) runs before CP10/CP11 are granted; any FPU instruction before that faults. */
__attribute__((naked)) void Reset_Handler(void)
{
    __asm volatile(
        "ldr r0, =0xE000ED88\n"  /* SCB_CPACR */
        "ldr r1, [r0]\n"
        "orr r1, r1, #(0xF << 20)\n"
        "str r1, [r0]\n"
        "dsb\n"
        "isb\n"                  /* the new access rights apply from the next instruction */
        "b reset_continue\n");
}

/* C part of the reset: RAM image set-up, constructors, main, exit with its status. */
void reset_continue(void)
{
    /* Plain word loops (not memcpy): newlib is not initialised yet. */
    const uint32_t *src = &__data_load;
    for (uint32_t *dst = &__data_start; dst < &__data_end;) {
        *dst++ = *src++;
    }
    for (uint32_t *dst = &__bss_start; dst < &__bss_end;) {
        *dst++ = 0;
    }
    SCB_VTOR = (uint32_t)(uintptr_t)vector_table;
    for (void (**fn)(void) = __init_array_start; fn < __init_array_end; fn++) {
        (*fn)();
    }
    port_exit(main());
}

/* A fault or an unexpected interrupt: report on the console and stop with status 99,
 * so a test under QEMU fails fast instead of hanging until its timeout. */
void Default_Handler(void)
{
    /* IPSR holds the exception number: 3 HardFault, 4 MemManage, 5 BusFault, 6 UsageFault,
     * 16 + n external IRQ n. Printed in decimal without printf (no heap, no stack hunger). */
    uint32_t ipsr;
    __asm volatile("mrs %0, ipsr" : "=r"(ipsr));
    char msg[] = "\r\n*** FAULT or unexpected interrupt: exception 000, halting\r\n";
    char *digits = strchr(msg, '0');
    digits[0] = (char)('0' + ipsr / 100u % 10u);
    digits[1] = (char)('0' + ipsr / 10u % 10u);
    digits[2] = (char)('0' + ipsr % 10u);
    port_uart_write(msg, sizeof msg - 1);
    port_exit(99);
}
