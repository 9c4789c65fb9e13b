/* psu_dcd.h chip port for the STM32F405 OTG_FS core (device mode, internal FS PHY), from RM0090 ch. 34. */
/*
 * COMPILED ONLY: QEMU's netduinoplus2 does not emulate the OTG peripheral, and no board was
 * at hand. Written against RM0090 rev 19, section 34 (OTG_FS), "Device programming model".
 * Polled: psu_stm32_otgfs_poll() is called from the main loop, not from the OTG interrupt,
 * so the core's events run in the same context as the link handler and its tick.
 * Board requirements: PA11/PA12 (DM/DP, AF10), a 48 MHz USB clock from PLLQ (the board's
 * PLL gives 336/7 = 48 MHz) and a crystal (HSE): HSI's 1 % is outside USB's 0.25 %.
 */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "psu_dcd.h"
#include "psu_device.h"

#define R32(a) (*(volatile uint32_t *)(uintptr_t)(a))

/* RCC / GPIOA (RM0090 7.3, 8.4) */
#define RCC_AHB1ENR R32(0x40023830u)
#define RCC_AHB2ENR R32(0x40023834u)
#define RCC_AHB2ENR_OTGFSEN (1u << 7)
#define GPIOA_MODER R32(0x40020000u)
#define GPIOA_OSPEEDR R32(0x40020008u)
#define GPIOA_AFRH R32(0x40020024u)

/* OTG_FS core global registers (RM0090 34.16.2) */
#define OTG 0x50000000u
#define GOTGCTL R32(OTG + 0x000u)
#define GAHBCFG R32(OTG + 0x008u)
#define GUSBCFG R32(OTG + 0x00Cu)
#define GRSTCTL R32(OTG + 0x010u)
#define GINTSTS R32(OTG + 0x014u)
#define GINTMSK R32(OTG + 0x018u)
#define GRXSTSP R32(OTG + 0x020u)
#define GRXFSIZ R32(OTG + 0x024u)
#define DIEPTXF0 R32(OTG + 0x028u)   /* also called GNPTXFSIZ: endpoint 0 TX FIFO */
#define GCCFG R32(OTG + 0x038u)
#define DIEPTXF(n) R32(OTG + 0x104u + 4u * ((n) - 1u))
/* Device registers (RM0090 34.16.4) */
#define DCFG R32(OTG + 0x800u)
#define DCTL R32(OTG + 0x804u)
#define DIEPMSK R32(OTG + 0x810u)
#define DOEPMSK R32(OTG + 0x814u)
#define DAINT R32(OTG + 0x818u)
#define DAINTMSK R32(OTG + 0x81Cu)
#define DIEPCTL(n) R32(OTG + 0x900u + 0x20u * (n))
#define DIEPINT(n) R32(OTG + 0x908u + 0x20u * (n))
#define DIEPTSIZ(n) R32(OTG + 0x910u + 0x20u * (n))
#define DTXFSTS(n) R32(OTG + 0x918u + 0x20u * (n))
#define DOEPCTL(n) R32(OTG + 0xB00u + 0x20u * (n))
#define DOEPINT(n) R32(OTG + 0xB08u + 0x20u * (n))
#define DOEPTSIZ(n) R32(OTG + 0xB10u + 0x20u * (n))
#define PCGCCTL R32(OTG + 0xE00u)
#define FIFO(n) R32(OTG + 0x1000u + 0x1000u * (n)) /* push (IN) / pop (RX) window of endpoint n */

/* Bits */
#define GUSBCFG_PHYSEL (1u << 6)
#define GUSBCFG_TRDT(x) ((uint32_t)(x) << 10)
#define GUSBCFG_FDMOD (1u << 30)
#define GRSTCTL_CSRST (1u << 0)
#define GRSTCTL_RXFFLSH (1u << 4)
#define GRSTCTL_TXFFLSH (1u << 5)
#define GRSTCTL_TXFNUM_ALL (0x10u << 6)
#define GRSTCTL_AHBIDL (1u << 31)
#define GCCFG_PWRDWN (1u << 16)        /* transceiver on */
#define GCCFG_NOVBUSSENS (1u << 21)    /* no VBUS pin: treat VBUS as always present */
#define GINT_RXFLVL (1u << 4)
#define GINT_USBSUSP (1u << 11)
#define GINT_USBRST (1u << 12)
#define GINT_ENUMDNE (1u << 13)
#define GINT_IEPINT (1u << 18)
#define GINT_OEPINT (1u << 19)
#define DCFG_DSPD_FS (3u << 0)         /* full speed, internal PHY */
#define DCFG_DAD_MASK (0x7Fu << 4)
#define DCTL_SDIS (1u << 1)            /* soft disconnect */
#define DCTL_CGINAK (1u << 8)
#define EPCTL_USBAEP (1u << 15)
#define EPCTL_EPTYP_BULK (2u << 18)
#define EPCTL_STALL (1u << 21)
#define EPCTL_TXFNUM(n) ((uint32_t)(n) << 22)
#define EPCTL_CNAK (1u << 26)
#define EPCTL_SNAK (1u << 27)
#define EPCTL_SD0PID (1u << 28)
#define EPCTL_EPDIS (1u << 30)
#define EPCTL_EPENA (1u << 31)
#define EPINT_XFRC (1u << 0)
#define DOEPINT_STUP (1u << 3)
#define TSIZ_PKTCNT(n) ((uint32_t)(n) << 19)
#define DOEPTSIZ0_STUPCNT3 (3u << 29)
#define RXSTS_EPNUM(s) ((s) & 0xFu)
#define RXSTS_BCNT(s) (((s) >> 4) & 0x7FFu)
#define RXSTS_PKTSTS(s) (((s) >> 17) & 0xFu)

enum {
    PKTSTS_OUT_DATA = 2,         /* OUT data packet received: BCNT bytes in the RX FIFO */
    PKTSTS_OUT_DONE = 3,         /* OUT transfer completed (XFRC follows) */
    PKTSTS_SETUP_DONE = 4,       /* SETUP stage done (STUP follows) */
    PKTSTS_SETUP_DATA = 6,       /* 8 setup bytes in the RX FIFO */
    N_EP = 2,                    /* endpoint 0 and 1 are used */
    /* FIFO RAM is 1.25 KB (320 words). RX: 128 words covers a setup burst plus two 64 B
     * packets with status words; TX: 16 words (one packet) for EP0, 64 words for EP1 IN
     * so four packets of a frame can be queued at once. Sizes in 32-bit words. */
    RX_FIFO_WORDS = 128,
    TX0_FIFO_WORDS = 16,
    TX1_FIFO_WORDS = 64,
    TRDT_AHB_GE_32MHZ = 6,       /* USB turnaround for HCLK >= 32 MHz (RM0090 34.17.3) */
};

typedef struct {
    uint8_t *buf;
    uint16_t len;                /* requested */
    uint16_t done;               /* bytes moved so far */
    uint16_t mps;
} ep_state_t;

static struct psu_dev *dev;
static ep_state_t in_ep[N_EP], out_ep[N_EP];
static uint8_t setup_pkt[8];

static void delay_cycles(volatile uint32_t n)
{
    while (n--)
        ;
}

static void flush_fifos(void)
{
    GRSTCTL = GRSTCTL_TXFFLSH | GRSTCTL_TXFNUM_ALL;
    while (GRSTCTL & GRSTCTL_TXFFLSH)
        ;
    GRSTCTL = GRSTCTL_RXFFLSH;
    while (GRSTCTL & GRSTCTL_RXFFLSH)
        ;
}

/* Endpoint 0 waits for up to three back-to-back SETUP packets (RM0090: STUPCNT = 3). */
static void ep0_arm_setup(void)
{
    DOEPTSIZ(0) = DOEPTSIZ0_STUPCNT3 | TSIZ_PKTCNT(1) | 3u * 8u;
    DOEPCTL(0) |= EPCTL_EPENA | EPCTL_CNAK;
}

void psu_dcd_init(struct psu_dev *d)
{
    dev = d;
    memset(in_ep, 0, sizeof in_ep);
    memset(out_ep, 0, sizeof out_ep);
    in_ep[0].mps = out_ep[0].mps = PSU_EP0_MPS;
    RCC_AHB1ENR |= 1u;           /* GPIOA */
    RCC_AHB2ENR |= RCC_AHB2ENR_OTGFSEN;
    /* PA11 = DM, PA12 = DP: alternate function 10, very high speed. */
    GPIOA_MODER = (GPIOA_MODER & ~(0xFu << 22)) | (0xAu << 22);
    GPIOA_OSPEEDR |= 0xFu << 22;
    GPIOA_AFRH = (GPIOA_AFRH & ~(0xFFu << 12)) | (0xAAu << 12);

    GUSBCFG |= GUSBCFG_PHYSEL;   /* read-only 1 on OTG_FS; set for clarity */
    while (!(GRSTCTL & GRSTCTL_AHBIDL))
        ;
    GRSTCTL |= GRSTCTL_CSRST;    /* core soft reset, clears in a few PHY clocks */
    while (GRSTCTL & GRSTCTL_CSRST)
        ;
    while (!(GRSTCTL & GRSTCTL_AHBIDL))
        ;
    GCCFG = GCCFG_PWRDWN | GCCFG_NOVBUSSENS;
    GUSBCFG = (GUSBCFG & ~(0xFu << 10)) | GUSBCFG_FDMOD | GUSBCFG_TRDT(TRDT_AHB_GE_32MHZ);
    delay_cycles(168000u * 25u / 4u); /* >= 25 ms for the forced device mode to take effect */
    PCGCCTL = 0;                 /* PHY clock not gated */
    DCFG = (DCFG & ~(DCFG_DAD_MASK | 3u)) | DCFG_DSPD_FS;

    GRXFSIZ = RX_FIFO_WORDS;
    DIEPTXF0 = ((uint32_t)TX0_FIFO_WORDS << 16) | RX_FIFO_WORDS;
    DIEPTXF(1) = ((uint32_t)TX1_FIFO_WORDS << 16) | (RX_FIFO_WORDS + TX0_FIFO_WORDS);
    flush_fifos();

    DIEPMSK = EPINT_XFRC;
    DOEPMSK = EPINT_XFRC | DOEPINT_STUP;
    GINTSTS = 0xFFFFFFFFu;       /* write-1-to-clear what a previous run left */
    /* Polled: the mask only selects what the OTG interrupt line would report; the status
     * bits are read in psu_stm32_otgfs_poll() either way. */
    GINTMSK = GINT_USBRST | GINT_ENUMDNE | GINT_RXFLVL | GINT_IEPINT | GINT_OEPINT | GINT_USBSUSP;
    GAHBCFG = 0;                 /* global interrupt off */
    (void)GOTGCTL;
    DCTL &= ~DCTL_SDIS;          /* connect: pull-up on DP */
}

void psu_dcd_set_address(uint8_t addr)
{
    /* The Synopsys core wants DAD programmed before the status stage (RM0090 34.17.5). */
    DCFG = (DCFG & ~DCFG_DAD_MASK) | ((uint32_t)addr << 4);
}

void psu_dcd_ep_open(uint8_t ep_addr, uint8_t type, uint16_t mps)
{
    uint8_t n = ep_addr & 0x7Fu;
    uint32_t ctl = (mps & 0x7FFu) | EPCTL_USBAEP | ((uint32_t)type << 18) | EPCTL_SD0PID | EPCTL_SNAK;
    if (n == 0 || n >= N_EP)
        return;
    if (ep_addr & PSU_EP_DIR_IN) {
        in_ep[n].mps = mps;
        DIEPCTL(n) = ctl | EPCTL_TXFNUM(n);
        DAINTMSK |= 1u << n;
    } else {
        out_ep[n].mps = mps;
        DOEPCTL(n) = ctl;
        DAINTMSK |= 1u << (16 + n);
    }
}

void psu_dcd_ep_close(uint8_t ep_addr)
{
    uint8_t n = ep_addr & 0x7Fu;
    if (n == 0 || n >= N_EP)
        return;
    if (ep_addr & PSU_EP_DIR_IN) {
        if (DIEPCTL(n) & EPCTL_EPENA)
            DIEPCTL(n) |= EPCTL_EPDIS | EPCTL_SNAK;
        DIEPCTL(n) &= ~EPCTL_USBAEP;
        DAINTMSK &= ~(1u << n);
        in_ep[n].buf = NULL;
    } else {
        if (DOEPCTL(n) & EPCTL_EPENA)
            DOEPCTL(n) |= EPCTL_EPDIS | EPCTL_SNAK;
        DOEPCTL(n) &= ~EPCTL_USBAEP;
        DAINTMSK &= ~(1u << (16 + n));
        out_ep[n].buf = NULL;
    }
}

/* Push the next whole packets of an IN transfer while the TX FIFO has room for them. */
static void fill_tx(uint8_t n)
{
    ep_state_t *e = &in_ep[n];
    while (e->buf && e->done < e->len) {
        uint16_t k = (uint16_t)(e->len - e->done);
        if (k > e->mps)
            k = e->mps;
        uint32_t words = (k + 3u) / 4u;
        if ((DTXFSTS(n) & 0xFFFFu) < words)
            return;
        for (uint32_t w = 0; w < words; w++) {
            uint32_t v = 0;
            for (uint32_t b = 0; b < 4 && w * 4 + b < k; b++)
                v |= (uint32_t)e->buf[e->done + w * 4 + b] << (8 * b);
            FIFO(n) = v;
        }
        e->done += k;
    }
}

bool psu_dcd_ep_xfer(uint8_t ep_addr, uint8_t *buf, uint16_t len)
{
    uint8_t n = ep_addr & 0x7Fu;
    if (n >= N_EP)
        return false;
    if (ep_addr & PSU_EP_DIR_IN) {
        ep_state_t *e = &in_ep[n];
        if (DIEPCTL(n) & EPCTL_EPENA)
            return false;
        uint32_t pkts = len == 0 ? 1u : (len + e->mps - 1u) / e->mps;
        /* EP0: XFRSIZ is 7 bits and PKTCNT 2 bits; the core's answers are <= 66 B. */
        e->buf = buf;
        e->len = len;
        e->done = 0;
        DIEPTSIZ(n) = TSIZ_PKTCNT(pkts) | len;
        DIEPCTL(n) |= EPCTL_EPENA | EPCTL_CNAK;
        if (len == 0)
            e->buf = NULL;
        fill_tx(n);
    } else {
        ep_state_t *e = &out_ep[n];
        if (n != 0 && (DOEPCTL(n) & EPCTL_EPENA))
            return false;
        uint32_t pkts = len == 0 ? 1u : (len + e->mps - 1u) / e->mps;
        e->buf = buf;
        e->len = len;
        e->done = 0;
        if (n == 0)
            DOEPTSIZ(0) = DOEPTSIZ0_STUPCNT3 | TSIZ_PKTCNT(1) | e->mps;
        else
            DOEPTSIZ(n) = TSIZ_PKTCNT(pkts) | (pkts * e->mps);
        DOEPCTL(n) |= EPCTL_EPENA | EPCTL_CNAK;
    }
    return true;
}

void psu_dcd_ep_stall(uint8_t ep_addr)
{
    uint8_t n = ep_addr & 0x7Fu;
    if (n >= N_EP)
        return;
    if (ep_addr & PSU_EP_DIR_IN)
        DIEPCTL(n) |= EPCTL_STALL;
    else
        DOEPCTL(n) |= EPCTL_STALL;
    if (n == 0)
        ep0_arm_setup();         /* the next SETUP clears an endpoint 0 stall */
}

void psu_dcd_ep_clear_stall(uint8_t ep_addr)
{
    uint8_t n = ep_addr & 0x7Fu;
    if (n == 0 || n >= N_EP)
        return;
    /* Clearing a halt restarts the data toggle at DATA0 (USB 2.0 9.4.5). */
    if (ep_addr & PSU_EP_DIR_IN)
        DIEPCTL(n) = (DIEPCTL(n) & ~EPCTL_STALL) | EPCTL_SD0PID;
    else
        DOEPCTL(n) = (DOEPCTL(n) & ~EPCTL_STALL) | EPCTL_SD0PID;
}

static void on_bus_reset(void)
{
    for (uint8_t n = 0; n < N_EP; n++)
        DOEPCTL(n) |= EPCTL_SNAK;
    DAINTMSK = (1u << 0) | (1u << 16);
    flush_fifos();
    DCFG &= ~DCFG_DAD_MASK;
    in_ep[1].buf = out_ep[1].buf = NULL;
    psu_dcd_event_reset(dev);
    ep0_arm_setup();
}

/* Drain one RX FIFO entry: setup bytes or OUT data into the armed transfer's buffer. */
static void on_rx(void)
{
    uint32_t sts = GRXSTSP;
    uint8_t n = (uint8_t)RXSTS_EPNUM(sts);
    uint16_t bcnt = (uint16_t)RXSTS_BCNT(sts);
    uint32_t words = (bcnt + 3u) / 4u;
    switch (RXSTS_PKTSTS(sts)) {
    case PKTSTS_SETUP_DATA:
        for (uint32_t w = 0; w < words; w++) {
            uint32_t v = FIFO(0);
            if (w < 2)
                memcpy(&setup_pkt[4 * w], &v, 4);
        }
        break;
    case PKTSTS_OUT_DATA: {
        ep_state_t *e = n < N_EP ? &out_ep[n] : NULL;
        for (uint32_t w = 0; w < words; w++) {
            uint32_t v = FIFO(0);
            for (uint32_t b = 0; b < 4 && w * 4 + b < bcnt; b++)
                if (e && e->buf && e->done < e->len)
                    e->buf[e->done++] = (uint8_t)(v >> (8 * b));
        }
        break;
    }
    default:                     /* OUT/SETUP done markers: handled by the endpoint interrupts */
        break;
    }
}

void psu_stm32_otgfs_poll(void);
/* Handle whatever the core reports; call from the main loop often (each pass). */
void psu_stm32_otgfs_poll(void)
{
    uint32_t st = GINTSTS & GINTMSK;
    if (st & GINT_USBRST) {
        GINTSTS = GINT_USBRST;
        on_bus_reset();
    }
    if (st & GINT_ENUMDNE) {
        GINTSTS = GINT_ENUMDNE;
        DIEPCTL(0) &= ~3u;       /* MPSIZ 00 = 64 bytes */
        DCTL |= DCTL_CGINAK;
    }
    if (st & GINT_USBSUSP)
        GINTSTS = GINT_USBSUSP;  /* bus powered at 100 mA: we keep running */
    while (GINTSTS & GINT_RXFLVL)
        on_rx();
    uint32_t daint = DAINT;
    for (uint8_t n = 0; n < N_EP; n++) {
        if (daint & (1u << (16 + n))) {
            uint32_t f = DOEPINT(n);
            DOEPINT(n) = f;
            if (n == 0 && (f & DOEPINT_STUP)) {
                psu_dcd_event_setup(dev, setup_pkt);
                continue;
            }
            if (f & EPINT_XFRC) {
                ep_state_t *e = &out_ep[n];
                uint16_t got = e->done;
                e->buf = NULL;
                if (n == 0)
                    ep0_arm_setup();
                psu_dcd_event_xfer_done(dev, n, got);
            }
        }
        if (daint & (1u << n)) {
            uint32_t f = DIEPINT(n);
            DIEPINT(n) = f;
            if (f & EPINT_XFRC) {
                uint16_t len = in_ep[n].len;
                in_ep[n].buf = NULL;
                psu_dcd_event_xfer_done(dev, (uint8_t)(0x80u | n), len);
            }
        }
        fill_tx(n);
    }
}
