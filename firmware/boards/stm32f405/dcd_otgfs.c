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

#include "link/usb/psu_dcd.h"
#include "link/usb/psu_device.h"
#include "stm32f405_regs.h"


enum {
    PKTSTS_OUT_DATA = 2,         /* OUT data packet received: BCNT bytes in the RX OTG_FS_FIFO */
    PKTSTS_OUT_DONE = 3,         /* OUT transfer completed (XFRC follows) */
    PKTSTS_SETUP_DONE = 4,       /* SETUP stage done (STUP follows) */
    PKTSTS_SETUP_DATA = 6,       /* 8 setup bytes in the RX OTG_FS_FIFO */
    N_EP = 2,                    /* endpoint 0 and 1 are used */
    /* OTG_FS_FIFO RAM is 1.25 KB (320 words). RX: 128 words covers a setup burst plus two 64 B
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
    OTG_FS_GRSTCTL = OTG_FS_GRSTCTL_TXFFLSH | OTG_FS_GRSTCTL_TXFNUM_ALL;
    while (OTG_FS_GRSTCTL & OTG_FS_GRSTCTL_TXFFLSH)
        ;
    OTG_FS_GRSTCTL = OTG_FS_GRSTCTL_RXFFLSH;
    while (OTG_FS_GRSTCTL & OTG_FS_GRSTCTL_RXFFLSH)
        ;
}

/* Endpoint 0 waits for up to three back-to-back SETUP packets (RM0090: STUPCNT = 3). */
static void ep0_arm_setup(void)
{
    OTG_FS_DOEPTSIZ(0) = OTG_FS_DOEPTSIZ0_STUPCNT3 | OTG_FS_TSIZ_PKTCNT(1) | 3u * 8u;
    OTG_FS_DOEPCTL(0) |= OTG_FS_EPCTL_EPENA | OTG_FS_EPCTL_CNAK;
}

void psu_dcd_init(struct psu_dev *d)
{
    dev = d;
    memset(in_ep, 0, sizeof in_ep);
    memset(out_ep, 0, sizeof out_ep);
    in_ep[0].mps = out_ep[0].mps = PSU_EP0_MPS;
    RCC_AHB1ENR |= RCC_AHB1ENR_GPIOAEN;
    RCC_AHB2ENR |= RCC_AHB2ENR_OTGFSEN;
    /* PA11 = DM, PA12 = DP: alternate function 10, very high speed. */
    GPIOA_MODER = (GPIOA_MODER & ~(0xFu << 22)) | (0xAu << 22);
    GPIOA_OSPEEDR |= 0xFu << 22;
    GPIOA_AFRH = (GPIOA_AFRH & ~(0xFFu << 12)) | (0xAAu << 12);

    OTG_FS_GUSBCFG |= OTG_FS_GUSBCFG_PHYSEL;   /* read-only 1 on OTG_FS; set for clarity */
    while (!(OTG_FS_GRSTCTL & OTG_FS_GRSTCTL_AHBIDL))
        ;
    OTG_FS_GRSTCTL |= OTG_FS_GRSTCTL_CSRST;    /* core soft reset, clears in a few PHY clocks */
    while (OTG_FS_GRSTCTL & OTG_FS_GRSTCTL_CSRST)
        ;
    while (!(OTG_FS_GRSTCTL & OTG_FS_GRSTCTL_AHBIDL))
        ;
    OTG_FS_GCCFG = OTG_FS_GCCFG_PWRDWN | OTG_FS_GCCFG_NOVBUSSENS;
    OTG_FS_GUSBCFG = (OTG_FS_GUSBCFG & ~(0xFu << 10)) | OTG_FS_GUSBCFG_FDMOD | OTG_FS_GUSBCFG_TRDT(TRDT_AHB_GE_32MHZ);
    delay_cycles(168000u * 25u / 4u); /* >= 25 ms for the forced device mode to take effect */
    OTG_FS_PCGCCTL = 0;                 /* PHY clock not gated */
    OTG_FS_DCFG = (OTG_FS_DCFG & ~(OTG_FS_DCFG_DAD_MASK | 3u)) | OTG_FS_DCFG_DSPD_FS;

    OTG_FS_GRXFSIZ = RX_FIFO_WORDS;
    OTG_FS_DIEPTXF0 = ((uint32_t)TX0_FIFO_WORDS << 16) | RX_FIFO_WORDS;
    OTG_FS_DIEPTXF(1) = ((uint32_t)TX1_FIFO_WORDS << 16) | (RX_FIFO_WORDS + TX0_FIFO_WORDS);
    flush_fifos();

    OTG_FS_DIEPMSK = OTG_FS_EPINT_XFRC;
    OTG_FS_DOEPMSK = OTG_FS_EPINT_XFRC | OTG_FS_DOEPINT_STUP;
    OTG_FS_GINTSTS = 0xFFFFFFFFu;       /* write-1-to-clear what a previous run left */
    /* Polled: the mask only selects what the OTG_FS_BASE interrupt line would report; the status
     * bits are read in psu_stm32_otgfs_poll() either way. */
    OTG_FS_GINTMSK = OTG_FS_GINT_USBRST | OTG_FS_GINT_ENUMDNE | OTG_FS_GINT_RXFLVL | OTG_FS_GINT_IEPINT | OTG_FS_GINT_OEPINT | OTG_FS_GINT_USBSUSP;
    OTG_FS_GAHBCFG = 0;                 /* global interrupt off */
    (void)OTG_FS_GOTGCTL;
    OTG_FS_DCTL &= ~OTG_FS_DCTL_SDIS;          /* connect: pull-up on DP */
}

void psu_dcd_set_address(uint8_t addr)
{
    /* The Synopsys core wants DAD programmed before the status stage (RM0090 34.17.5). */
    OTG_FS_DCFG = (OTG_FS_DCFG & ~OTG_FS_DCFG_DAD_MASK) | ((uint32_t)addr << 4);
}

void psu_dcd_ep_open(uint8_t ep_addr, uint8_t type, uint16_t mps)
{
    uint8_t n = ep_addr & 0x7Fu;
    uint32_t ctl = (mps & 0x7FFu) | OTG_FS_EPCTL_USBAEP | ((uint32_t)type << 18) | OTG_FS_EPCTL_SD0PID | OTG_FS_EPCTL_SNAK;
    if (n == 0 || n >= N_EP)
        return;
    if (ep_addr & PSU_EP_DIR_IN) {
        in_ep[n].mps = mps;
        OTG_FS_DIEPCTL(n) = ctl | OTG_FS_EPCTL_TXFNUM(n);
        OTG_FS_DAINTMSK |= 1u << n;
    } else {
        out_ep[n].mps = mps;
        OTG_FS_DOEPCTL(n) = ctl;
        OTG_FS_DAINTMSK |= 1u << (16 + n);
    }
}

void psu_dcd_ep_close(uint8_t ep_addr)
{
    uint8_t n = ep_addr & 0x7Fu;
    if (n == 0 || n >= N_EP)
        return;
    if (ep_addr & PSU_EP_DIR_IN) {
        if (OTG_FS_DIEPCTL(n) & OTG_FS_EPCTL_EPENA)
            OTG_FS_DIEPCTL(n) |= OTG_FS_EPCTL_EPDIS | OTG_FS_EPCTL_SNAK;
        OTG_FS_DIEPCTL(n) &= ~OTG_FS_EPCTL_USBAEP;
        OTG_FS_DAINTMSK &= ~(1u << n);
        in_ep[n].buf = NULL;
    } else {
        if (OTG_FS_DOEPCTL(n) & OTG_FS_EPCTL_EPENA)
            OTG_FS_DOEPCTL(n) |= OTG_FS_EPCTL_EPDIS | OTG_FS_EPCTL_SNAK;
        OTG_FS_DOEPCTL(n) &= ~OTG_FS_EPCTL_USBAEP;
        OTG_FS_DAINTMSK &= ~(1u << (16 + n));
        out_ep[n].buf = NULL;
    }
}

/* Push the next whole packets of an IN transfer while the TX OTG_FS_FIFO has room for them. */
static void fill_tx(uint8_t n)
{
    ep_state_t *e = &in_ep[n];
    while (e->buf && e->done < e->len) {
        uint16_t k = (uint16_t)(e->len - e->done);
        if (k > e->mps)
            k = e->mps;
        uint32_t words = (k + 3u) / 4u;
        if ((OTG_FS_DTXFSTS(n) & 0xFFFFu) < words)
            return;
        for (uint32_t w = 0; w < words; w++) {
            uint32_t v = 0;
            for (uint32_t b = 0; b < 4 && w * 4 + b < k; b++)
                v |= (uint32_t)e->buf[e->done + w * 4 + b] << (8 * b);
            OTG_FS_FIFO(n) = v;
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
        if (OTG_FS_DIEPCTL(n) & OTG_FS_EPCTL_EPENA)
            return false;
        uint32_t pkts = len == 0 ? 1u : (len + e->mps - 1u) / e->mps;
        /* EP0: XFRSIZ is 7 bits and PKTCNT 2 bits; the core's answers are <= 66 B. */
        e->buf = buf;
        e->len = len;
        e->done = 0;
        OTG_FS_DIEPTSIZ(n) = OTG_FS_TSIZ_PKTCNT(pkts) | len;
        OTG_FS_DIEPCTL(n) |= OTG_FS_EPCTL_EPENA | OTG_FS_EPCTL_CNAK;
        if (len == 0)
            e->buf = NULL;
        fill_tx(n);
    } else {
        ep_state_t *e = &out_ep[n];
        if (n != 0 && (OTG_FS_DOEPCTL(n) & OTG_FS_EPCTL_EPENA))
            return false;
        uint32_t pkts = len == 0 ? 1u : (len + e->mps - 1u) / e->mps;
        e->buf = buf;
        e->len = len;
        e->done = 0;
        if (n == 0)
            OTG_FS_DOEPTSIZ(0) = OTG_FS_DOEPTSIZ0_STUPCNT3 | OTG_FS_TSIZ_PKTCNT(1) | e->mps;
        else
            OTG_FS_DOEPTSIZ(n) = OTG_FS_TSIZ_PKTCNT(pkts) | (pkts * e->mps);
        OTG_FS_DOEPCTL(n) |= OTG_FS_EPCTL_EPENA | OTG_FS_EPCTL_CNAK;
    }
    return true;
}

void psu_dcd_ep_stall(uint8_t ep_addr)
{
    uint8_t n = ep_addr & 0x7Fu;
    if (n >= N_EP)
        return;
    if (ep_addr & PSU_EP_DIR_IN)
        OTG_FS_DIEPCTL(n) |= OTG_FS_EPCTL_STALL;
    else
        OTG_FS_DOEPCTL(n) |= OTG_FS_EPCTL_STALL;
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
        OTG_FS_DIEPCTL(n) = (OTG_FS_DIEPCTL(n) & ~OTG_FS_EPCTL_STALL) | OTG_FS_EPCTL_SD0PID;
    else
        OTG_FS_DOEPCTL(n) = (OTG_FS_DOEPCTL(n) & ~OTG_FS_EPCTL_STALL) | OTG_FS_EPCTL_SD0PID;
}

static void on_bus_reset(void)
{
    for (uint8_t n = 0; n < N_EP; n++)
        OTG_FS_DOEPCTL(n) |= OTG_FS_EPCTL_SNAK;
    OTG_FS_DAINTMSK = (1u << 0) | (1u << 16);
    flush_fifos();
    OTG_FS_DCFG &= ~OTG_FS_DCFG_DAD_MASK;
    in_ep[1].buf = out_ep[1].buf = NULL;
    psu_dcd_event_reset(dev);
    ep0_arm_setup();
}

/* Drain one RX OTG_FS_FIFO entry: setup bytes or OUT data into the armed transfer's buffer. */
static void on_rx(void)
{
    uint32_t sts = OTG_FS_GRXSTSP;
    uint8_t n = (uint8_t)OTG_FS_RXSTS_EPNUM(sts);
    uint16_t bcnt = (uint16_t)OTG_FS_RXSTS_BCNT(sts);
    uint32_t words = (bcnt + 3u) / 4u;
    switch (OTG_FS_RXSTS_PKTSTS(sts)) {
    case PKTSTS_SETUP_DATA:
        for (uint32_t w = 0; w < words; w++) {
            uint32_t v = OTG_FS_FIFO(0);
            if (w < 2)
                memcpy(&setup_pkt[4 * w], &v, 4);
        }
        break;
    case PKTSTS_OUT_DATA: {
        ep_state_t *e = n < N_EP ? &out_ep[n] : NULL;
        for (uint32_t w = 0; w < words; w++) {
            uint32_t v = OTG_FS_FIFO(0);
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
    uint32_t st = OTG_FS_GINTSTS & OTG_FS_GINTMSK;
    if (st & OTG_FS_GINT_USBRST) {
        OTG_FS_GINTSTS = OTG_FS_GINT_USBRST;
        on_bus_reset();
    }
    if (st & OTG_FS_GINT_ENUMDNE) {
        OTG_FS_GINTSTS = OTG_FS_GINT_ENUMDNE;
        OTG_FS_DIEPCTL(0) &= ~3u;       /* MPSIZ 00 = 64 bytes */
        OTG_FS_DCTL |= OTG_FS_DCTL_CGINAK;
    }
    if (st & OTG_FS_GINT_USBSUSP)
        OTG_FS_GINTSTS = OTG_FS_GINT_USBSUSP;  /* bus powered at 100 mA: we keep running */
    while (OTG_FS_GINTSTS & OTG_FS_GINT_RXFLVL)
        on_rx();
    uint32_t daint = OTG_FS_DAINT;
    for (uint8_t n = 0; n < N_EP; n++) {
        if (daint & (1u << (16 + n))) {
            uint32_t f = OTG_FS_DOEPINT(n);
            OTG_FS_DOEPINT(n) = f;
            if (n == 0 && (f & OTG_FS_DOEPINT_STUP)) {
                psu_dcd_event_setup(dev, setup_pkt);
                continue;
            }
            if (f & OTG_FS_EPINT_XFRC) {
                ep_state_t *e = &out_ep[n];
                uint16_t got = e->done;
                e->buf = NULL;
                if (n == 0)
                    ep0_arm_setup();
                psu_dcd_event_xfer_done(dev, n, got);
            }
        }
        if (daint & (1u << n)) {
            uint32_t f = OTG_FS_DIEPINT(n);
            OTG_FS_DIEPINT(n) = f;
            if (f & OTG_FS_EPINT_XFRC) {
                uint16_t len = in_ep[n].len;
                in_ep[n].buf = NULL;
                psu_dcd_event_xfer_done(dev, (uint8_t)(0x80u | n), len);
            }
        }
        fill_tx(n);
    }
}
