/* The few STM32F405 / Cortex-M4 registers this board uses (RM0090, ARMv7-M ARM), by address. */
#ifndef STM32F405_REGS_H
#define STM32F405_REGS_H

#include <stdint.h>

/* One 32-bit memory-mapped register; volatile so every access reaches the bus.
 * STM32F405_REG_MODEL (desktop tests only): the registers live in a register-level model
 * instead (tests/link/support/stm32f4_flash_model.c), and the accessors below, which the
 * flash-sector driver uses for every access, call into it so that each access has the
 * hardware's side effects (unlock sequence, busy flag, program and erase). */
#ifndef STM32F405_REG_MODEL
#define REG32(addr) (*(volatile uint32_t *)(uintptr_t)(addr))
#define REG8(addr) (*(volatile uint8_t *)(uintptr_t)(addr))
static inline uint32_t reg_read(volatile uint32_t *reg)
{
    return *reg;
}
static inline void reg_write(volatile uint32_t *reg, uint32_t v)
{
    *reg = v;
}
/* One byte written to the flash memory array (a program access when FLASH_CR.PG is set). */
static inline void flash_write8(uintptr_t addr, uint8_t v)
{
    *(volatile uint8_t *)addr = v;
}
#else
volatile uint32_t *stm32f405_model_reg(uintptr_t addr);
#define REG32(addr) (*stm32f405_model_reg((uintptr_t)(addr)))
uint32_t reg_read(volatile uint32_t *reg);
void reg_write(volatile uint32_t *reg, uint32_t v);
void flash_write8(uintptr_t addr, uint8_t v);
#endif

/* RCC: clock tree and peripheral clock gates. */
#define RCC_BASE 0x40023800u
#define RCC_CR REG32(RCC_BASE + 0x00u)
#define RCC_PLLCFGR REG32(RCC_BASE + 0x04u)
#define RCC_CFGR REG32(RCC_BASE + 0x08u)
#define RCC_AHB1ENR REG32(RCC_BASE + 0x30u)
#define RCC_AHB2ENR REG32(RCC_BASE + 0x34u)
#define RCC_APB2ENR REG32(RCC_BASE + 0x44u)
#define RCC_AHB2ENR_OTGFSEN (1u << 7)
#define RCC_CR_HSIRDY (1u << 1)
#define RCC_CR_PLLON (1u << 24)
#define RCC_CR_PLLRDY (1u << 25)
#define RCC_CFGR_SW_PLL (2u << 0)
#define RCC_CFGR_SWS_MASK (3u << 2)
#define RCC_CFGR_SWS_PLL (2u << 2)
#define RCC_CFGR_PPRE1_DIV4 (5u << 10)
#define RCC_CFGR_PPRE2_DIV2 (4u << 13)
#define RCC_AHB1ENR_GPIOAEN (1u << 0)
#define RCC_APB2ENR_USART1EN (1u << 4)

/* Flash interface (RM0090 3.9): wait states must be raised before the core clock is;
 * KEYR/SR/CR drive sector erase and programming (pss_flash_stm32f4.c). */
#define FLASH_BASE 0x40023C00u
#define FLASH_ACR REG32(FLASH_BASE + 0x00u)
#define FLASH_KEYR REG32(FLASH_BASE + 0x04u)
#define FLASH_SR REG32(FLASH_BASE + 0x0Cu)
#define FLASH_CR REG32(FLASH_BASE + 0x10u)
#define FLASH_ACR_LATENCY_5WS 5u
#define FLASH_ACR_PRFTEN (1u << 8)
#define FLASH_ACR_ICEN (1u << 9)
#define FLASH_ACR_DCEN (1u << 10)
#define FLASH_ACR_DCRST (1u << 12)
#define FLASH_KEY1 0x45670123u             /* unlock sequence (RM0090 3.5.1) */
#define FLASH_KEY2 0xCDEF89ABu
#define FLASH_SR_EOP (1u << 0)              /* end of operation (only with CR.EOPIE) */
#define FLASH_SR_OPERR (1u << 1)
#define FLASH_SR_WRPERR (1u << 4)           /* write protection */
#define FLASH_SR_PGAERR (1u << 5)           /* programming alignment */
#define FLASH_SR_PGPERR (1u << 6)           /* access size differs from CR.PSIZE */
#define FLASH_SR_PGSERR (1u << 7)           /* programming sequence */
#define FLASH_SR_BSY (1u << 16)
#define FLASH_SR_ERRORS (FLASH_SR_OPERR | FLASH_SR_WRPERR | FLASH_SR_PGAERR | FLASH_SR_PGPERR | FLASH_SR_PGSERR)
#define FLASH_CR_PG (1u << 0)
#define FLASH_CR_SER (1u << 1)
#define FLASH_CR_MER (1u << 2)
#define FLASH_CR_SNB_SHIFT 3u               /* SNB[3:0], bits 6:3 */
#define FLASH_CR_SNB_MASK (0xFu << 3)
#define FLASH_CR_PSIZE_SHIFT 8u             /* 0: x8, 1: x16, 2: x32, 3: x64 */
#define FLASH_CR_PSIZE_MASK (3u << 8)
#define FLASH_CR_PSIZE_X8 (0u << 8)         /* byte parallelism: valid over the whole 1.8-3.6 V */
#define FLASH_CR_STRT (1u << 16)
#define FLASH_CR_EOPIE (1u << 24)
#define FLASH_CR_LOCK (1u << 31)

/* GPIOA: PA9 = USART1_TX, PA10 = USART1_RX (AF7); PA11/PA12 = OTG_FS DM/DP (AF10). */
#define GPIOA_BASE 0x40020000u
#define GPIOA_MODER REG32(GPIOA_BASE + 0x00u)
#define GPIOA_OSPEEDR REG32(GPIOA_BASE + 0x08u)
#define GPIOA_PUPDR REG32(GPIOA_BASE + 0x0Cu)
#define GPIOA_IDR REG32(GPIOA_BASE + 0x10u)
#define GPIOA_AFRH REG32(GPIOA_BASE + 0x24u)

/* USART1 on APB2. */
#define USART1_BASE 0x40011000u
#define USART1_SR REG32(USART1_BASE + 0x00u)
#define USART1_DR REG32(USART1_BASE + 0x04u)
#define USART1_BRR REG32(USART1_BASE + 0x08u)
#define USART1_CR1 REG32(USART1_BASE + 0x0Cu)
#define USART_SR_ORE (1u << 3)
#define USART_SR_RXNE (1u << 5)
#define USART_SR_TXE (1u << 7)
#define USART_CR1_RE (1u << 2)
#define USART_CR1_TE (1u << 3)
#define USART_CR1_RXNEIE (1u << 5)
#define USART_CR1_UE (1u << 13)
#define USART1_IRQN 37u

/* SysTick (ARMv7-M system timer). */
#define SYST_CSR REG32(0xE000E010u)
#define SYST_RVR REG32(0xE000E014u)
#define SYST_CVR REG32(0xE000E018u)
#define SYST_CSR_ENABLE (1u << 0)
#define SYST_CSR_TICKINT (1u << 1)
#define SYST_CSR_CLKSOURCE_CPU (1u << 2)
#define SYST_RVR_MAX 0x00FFFFFFu

/* System control block and NVIC. */
#define SCB_ICSR REG32(0xE000ED04u)
#define SCB_ICSR_PENDSTSET (1u << 26)
#define SCB_VTOR REG32(0xE000ED08u)
#define SCB_SHPR3 REG32(0xE000ED20u)
#define SCB_CPACR REG32(0xE000ED88u)
#define SCB_CPACR_CP10_CP11_FULL (0xFu << 20)
#define NVIC_ISER(n) REG32(0xE000E100u + 4u * (n))
#define NVIC_IPR8(irq) REG8(0xE000E400u + (irq))

/* OTG_FS core, device mode (RM0090 ch. 34), used by dcd_otgfs.c. */
/* OTG_FS core global registers (RM0090 34.16.2) */
#define OTG_FS_BASE 0x50000000u
#define OTG_FS_GOTGCTL REG32(OTG_FS_BASE + 0x000u)
#define OTG_FS_GAHBCFG REG32(OTG_FS_BASE + 0x008u)
#define OTG_FS_GUSBCFG REG32(OTG_FS_BASE + 0x00Cu)
#define OTG_FS_GRSTCTL REG32(OTG_FS_BASE + 0x010u)
#define OTG_FS_GINTSTS REG32(OTG_FS_BASE + 0x014u)
#define OTG_FS_GINTMSK REG32(OTG_FS_BASE + 0x018u)
#define OTG_FS_GRXSTSP REG32(OTG_FS_BASE + 0x020u)
#define OTG_FS_GRXFSIZ REG32(OTG_FS_BASE + 0x024u)
#define OTG_FS_DIEPTXF0 REG32(OTG_FS_BASE + 0x028u)   /* also called GNPTXFSIZ: endpoint 0 TX FIFO */
#define OTG_FS_GCCFG REG32(OTG_FS_BASE + 0x038u)
#define OTG_FS_DIEPTXF(n) REG32(OTG_FS_BASE + 0x104u + 4u * ((n) - 1u))
/* Device registers (RM0090 34.16.4) */
#define OTG_FS_DCFG REG32(OTG_FS_BASE + 0x800u)
#define OTG_FS_DCTL REG32(OTG_FS_BASE + 0x804u)
#define OTG_FS_DIEPMSK REG32(OTG_FS_BASE + 0x810u)
#define OTG_FS_DOEPMSK REG32(OTG_FS_BASE + 0x814u)
#define OTG_FS_DAINT REG32(OTG_FS_BASE + 0x818u)
#define OTG_FS_DAINTMSK REG32(OTG_FS_BASE + 0x81Cu)
#define OTG_FS_DIEPCTL(n) REG32(OTG_FS_BASE + 0x900u + 0x20u * (n))
#define OTG_FS_DIEPINT(n) REG32(OTG_FS_BASE + 0x908u + 0x20u * (n))
#define OTG_FS_DIEPTSIZ(n) REG32(OTG_FS_BASE + 0x910u + 0x20u * (n))
#define OTG_FS_DTXFSTS(n) REG32(OTG_FS_BASE + 0x918u + 0x20u * (n))
#define OTG_FS_DOEPCTL(n) REG32(OTG_FS_BASE + 0xB00u + 0x20u * (n))
#define OTG_FS_DOEPINT(n) REG32(OTG_FS_BASE + 0xB08u + 0x20u * (n))
#define OTG_FS_DOEPTSIZ(n) REG32(OTG_FS_BASE + 0xB10u + 0x20u * (n))
#define OTG_FS_PCGCCTL REG32(OTG_FS_BASE + 0xE00u)
#define OTG_FS_FIFO(n) REG32(OTG_FS_BASE + 0x1000u + 0x1000u * (n)) /* push (IN) / pop (RX) window of endpoint n */

/* Bits */
#define OTG_FS_GUSBCFG_PHYSEL (1u << 6)
#define OTG_FS_GUSBCFG_TRDT(x) ((uint32_t)(x) << 10)
#define OTG_FS_GUSBCFG_FDMOD (1u << 30)
#define OTG_FS_GRSTCTL_CSRST (1u << 0)
#define OTG_FS_GRSTCTL_RXFFLSH (1u << 4)
#define OTG_FS_GRSTCTL_TXFFLSH (1u << 5)
#define OTG_FS_GRSTCTL_TXFNUM_ALL (0x10u << 6)
#define OTG_FS_GRSTCTL_AHBIDL (1u << 31)
#define OTG_FS_GCCFG_PWRDWN (1u << 16)        /* transceiver on */
#define OTG_FS_GCCFG_NOVBUSSENS (1u << 21)    /* no VBUS pin: treat VBUS as always present */
#define OTG_FS_GINT_RXFLVL (1u << 4)
#define OTG_FS_GINT_USBSUSP (1u << 11)
#define OTG_FS_GINT_USBRST (1u << 12)
#define OTG_FS_GINT_ENUMDNE (1u << 13)
#define OTG_FS_GINT_IEPINT (1u << 18)
#define OTG_FS_GINT_OEPINT (1u << 19)
#define OTG_FS_DCFG_DSPD_FS (3u << 0)         /* full speed, internal PHY */
#define OTG_FS_DCFG_DAD_MASK (0x7Fu << 4)
#define OTG_FS_DCTL_SDIS (1u << 1)            /* soft disconnect */
#define OTG_FS_DCTL_CGINAK (1u << 8)
#define OTG_FS_EPCTL_USBAEP (1u << 15)
#define OTG_FS_EPCTL_EPTYP_BULK (2u << 18)
#define OTG_FS_EPCTL_STALL (1u << 21)
#define OTG_FS_EPCTL_TXFNUM(n) ((uint32_t)(n) << 22)
#define OTG_FS_EPCTL_CNAK (1u << 26)
#define OTG_FS_EPCTL_SNAK (1u << 27)
#define OTG_FS_EPCTL_SD0PID (1u << 28)
#define OTG_FS_EPCTL_EPDIS (1u << 30)
#define OTG_FS_EPCTL_EPENA (1u << 31)
#define OTG_FS_EPINT_XFRC (1u << 0)
#define OTG_FS_DOEPINT_STUP (1u << 3)
#define OTG_FS_TSIZ_PKTCNT(n) ((uint32_t)(n) << 19)
#define OTG_FS_DOEPTSIZ0_STUPCNT3 (3u << 29)
#define OTG_FS_RXSTS_EPNUM(s) ((s) & 0xFu)
#define OTG_FS_RXSTS_BCNT(s) (((s) >> 4) & 0x7FFu)
#define OTG_FS_RXSTS_PKTSTS(s) (((s) >> 17) & 0xFu)

#endif /* STM32F405_REGS_H */
