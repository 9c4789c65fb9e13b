/* Portable USB device core: descriptors, endpoint 0 state machine, standard requests, bulk framing. */
#include "link/usb/psu_device.h"

#include <string.h>
#include "link/usb/psu_dcd.h"

enum ep0_stage {
    EP0_IDLE = 0,
    EP0_DATA_IN,                 /* answer going to the host */
    EP0_STATUS_OUT,              /* waiting for the host's zero-length OUT */
    EP0_STATUS_IN,               /* our zero-length IN after a no-data request */
};

static const char *const str_ascii[PSU_STR_COUNT] = {
    NULL,                        /* index 0: language list, built below */
    "playscope",
    "playscope board",
    NULL,                        /* index 3: serial, from the board id */
    "playscope link v1",
};

static const psu_device_desc_t dev_desc_template = {
    .bLength = sizeof(psu_device_desc_t),
    .bDescriptorType = PSU_DESC_DEVICE,
    .bcdUSB = 0x0200,
    .bDeviceClass = 0,           /* class per interface */
    .bMaxPacketSize0 = PSU_EP0_MPS,
    .idVendor = PSU_VID,
    .idProduct = PSU_PID,
    .iManufacturer = 1,
    .iProduct = 2,
    .iSerialNumber = 3,
    .bNumConfigurations = 1,
};

/* Configuration, interface and both endpoint descriptors as the host reads them: one block. */
typedef struct PS_PACKED {
    psu_config_desc_t config;
    psu_iface_desc_t iface;
    psu_ep_desc_t ep_out;
    psu_ep_desc_t ep_in;
} config_block_t;
PS_STATIC_ASSERT(sizeof(config_block_t) == PSU_CONFIG_TOTAL_BYTES, "config block size");

static const config_block_t config_block = {
    .config = {
        .bLength = sizeof(psu_config_desc_t),
        .bDescriptorType = PSU_DESC_CONFIGURATION,
        .wTotalLength = PSU_CONFIG_TOTAL_BYTES,
        .bNumInterfaces = 1,
        .bConfigurationValue = PSU_CONFIG_VALUE,
        .iConfiguration = 0,
        .bmAttributes = 0x80,    /* bit 7 must be set; bus powered, no remote wakeup */
        .bMaxPower = 50,         /* 100 mA: the MCU and encoder; the motor has its own supply */
    },
    .iface = {
        .bLength = sizeof(psu_iface_desc_t),
        .bDescriptorType = PSU_DESC_INTERFACE,
        .bInterfaceNumber = 0,
        .bAlternateSetting = 0,
        .bNumEndpoints = 2,
        .bInterfaceClass = 0xFF, /* vendor: no kernel driver binds, libusb claims it */
        .bInterfaceSubClass = 0,
        .bInterfaceProtocol = 0,
        .iInterface = 4,
    },
    .ep_out = {
        .bLength = sizeof(psu_ep_desc_t),
        .bDescriptorType = PSU_DESC_ENDPOINT,
        .bEndpointAddress = PSU_EP_OUT,
        .bmAttributes = PSU_EP_TYPE_BULK,
        .wMaxPacketSize = PSU_BULK_MPS,
        .bInterval = 0,
    },
    .ep_in = {
        .bLength = sizeof(psu_ep_desc_t),
        .bDescriptorType = PSU_DESC_ENDPOINT,
        .bEndpointAddress = PSU_EP_IN,
        .bmAttributes = PSU_EP_TYPE_BULK,
        .wMaxPacketSize = PSU_BULK_MPS,
        .bInterval = 0,
    },
};

void psu_init(psu_dev_t *d, const psu_config_t *cfg)
{
    memset(d, 0, sizeof *d);
    d->cfg = *cfg;
}

/* String descriptor index idx (UTF-16LE of ASCII) into out; returns its length or 0. */
static uint16_t string_desc(const psu_dev_t *d, uint8_t idx, uint8_t *out, uint16_t cap)
{
    char serial[25];
    const char *s;
    if (idx == 0) {
        if (cap < 4)
            return 0;
        out[0] = 4;
        out[1] = PSU_DESC_STRING;
        out[2] = 0x09;           /* 0x0409 English (US), the only language */
        out[3] = 0x04;
        return 4;
    }
    if (idx >= PSU_STR_COUNT)
        return 0;
    if (idx == 3) {
        static const char hex[] = "0123456789ABCDEF";
        for (int w = 0; w < 3; w++)
            for (int k = 0; k < 8; k++)
                serial[w * 8 + k] = hex[(d->cfg.board_id[w] >> (28 - 4 * k)) & 0xF];
        serial[24] = 0;
        s = serial;
    } else {
        s = str_ascii[idx];
    }
    size_t n = strlen(s);
    uint16_t len = (uint16_t)(2 + 2 * n);
    if (len > cap)
        return 0;
    out[0] = (uint8_t)len;
    out[1] = PSU_DESC_STRING;
    for (size_t i = 0; i < n; i++) {
        out[2 + 2 * i] = (uint8_t)s[i];
        out[3 + 2 * i] = 0;
    }
    return len;
}

static bool bulk_ep(uint16_t ep)
{
    return ep == PSU_EP_OUT || ep == PSU_EP_IN;
}

static void arm_rx(psu_dev_t *d)
{
    if (d->state == PSU_STATE_CONFIGURED && !d->rx_armed && !d->halt_out)
        d->rx_armed = psu_dcd_ep_xfer(PSU_EP_OUT, d->rx_buf, sizeof d->rx_buf);
}

static void kick_tx(psu_dev_t *d)
{
    if (d->tx_busy || d->halt_in || d->state != PSU_STATE_CONFIGURED)
        return;
    uint32_t used = d->tx_head - d->tx_tail;
    if (used == 0 && !d->tx_zlp)
        return;
    uint16_t n = (uint16_t)(used < PSU_TX_XFER_MAX_BYTES ? used : PSU_TX_XFER_MAX_BYTES);
    for (uint16_t i = 0; i < n; i++)
        d->tx_xfer[i] = d->tx_ring[(d->tx_tail + i) % PSU_TX_RING_BYTES];
    /* A transfer that is a whole number of packets does not tell the host it has ended;
     * the host's read (512 B) would wait for more. A zero-length packet closes it. */
    if (!psu_dcd_ep_xfer(PSU_EP_IN, d->tx_xfer, n))
        return;
    d->tx_tail += n;
    d->tx_busy = true;
    d->tx_zlp = n > 0 && n % PSU_BULK_MPS == 0;
}

static void set_configured(psu_dev_t *d, uint8_t value)
{
    if (d->config != 0) {
        psu_dcd_ep_close(PSU_EP_OUT);
        psu_dcd_ep_close(PSU_EP_IN);
    }
    d->config = value;
    d->halt_in = d->halt_out = false;
    d->rx_armed = d->tx_busy = d->tx_zlp = false;
    d->tx_head = d->tx_tail = 0; /* a new configuration starts a new byte stream */
    if (value == 0) {
        d->state = PSU_STATE_ADDRESS;
        return;
    }
    d->state = PSU_STATE_CONFIGURED;
    psu_dcd_ep_open(PSU_EP_OUT, PSU_EP_TYPE_BULK, PSU_BULK_MPS);
    psu_dcd_ep_open(PSU_EP_IN, PSU_EP_TYPE_BULK, PSU_BULK_MPS);
    arm_rx(d);
}

static psu_ctrl_t get_descriptor(psu_dev_t *d, const psu_setup_t *s, uint8_t *out, uint16_t cap,
                                 uint16_t *len)
{
    uint8_t type = (uint8_t)(s->wValue >> 8), idx = (uint8_t)(s->wValue & 0xFF);
    switch (type) {
    case PSU_DESC_DEVICE: {
        if (cap < sizeof(psu_device_desc_t))
            return PSU_CTRL_STALL;
        psu_device_desc_t dd = dev_desc_template;
        dd.bcdDevice = d->cfg.bcd_device;
        memcpy(out, &dd, sizeof dd);
        *len = sizeof dd;
        return PSU_CTRL_ACK;
    }
    case PSU_DESC_CONFIGURATION:
        if (idx != 0 || cap < sizeof config_block)
            return PSU_CTRL_STALL;
        memcpy(out, &config_block, sizeof config_block);
        *len = sizeof config_block;
        return PSU_CTRL_ACK;
    case PSU_DESC_STRING:
        *len = string_desc(d, idx, out, cap);
        return *len ? PSU_CTRL_ACK : PSU_CTRL_STALL;
    default:                     /* device qualifier, other speed, BOS: full-speed USB 2.0 device */
        return PSU_CTRL_STALL;
    }
}

psu_ctrl_t psu_control(psu_dev_t *d, const psu_setup_t *s, uint8_t *out, uint16_t cap,
                       uint16_t *len)
{
    *len = 0;
    if ((s->bmRequestType & PSU_RT_TYPE_MASK) != PSU_RT_TYPE_STANDARD)
        return PSU_CTRL_STALL;   /* no class or vendor requests: the link runs on bulk */
    bool in = (s->bmRequestType & PSU_RT_DIR_IN) != 0;
    uint8_t recip = s->bmRequestType & PSU_RT_RECIP_MASK;
    bool configured = d->state == PSU_STATE_CONFIGURED;

    switch (s->bRequest) {
    case PSU_REQ_GET_DESCRIPTOR:
        if (!in || recip != PSU_RT_RECIP_DEVICE)
            return PSU_CTRL_STALL;
        return get_descriptor(d, s, out, cap, len);
    case PSU_REQ_SET_ADDRESS:
        if (in || recip != PSU_RT_RECIP_DEVICE || s->wValue > 127 || configured)
            return PSU_CTRL_STALL;
        d->address = (uint8_t)s->wValue;
        d->state = d->address ? PSU_STATE_ADDRESS : PSU_STATE_DEFAULT;
        psu_dcd_set_address(d->address);
        return PSU_CTRL_ACK;
    case PSU_REQ_GET_CONFIGURATION:
        if (!in || cap < 1 || d->state == PSU_STATE_DEFAULT)
            return PSU_CTRL_STALL;
        out[0] = d->config;
        *len = 1;
        return PSU_CTRL_ACK;
    case PSU_REQ_SET_CONFIGURATION:
        if (in || recip != PSU_RT_RECIP_DEVICE || d->state == PSU_STATE_DEFAULT ||
            (s->wValue != 0 && s->wValue != PSU_CONFIG_VALUE))
            return PSU_CTRL_STALL;
        set_configured(d, (uint8_t)s->wValue);
        return PSU_CTRL_ACK;
    case PSU_REQ_GET_STATUS:
        if (!in || cap < 2)
            return PSU_CTRL_STALL;
        out[0] = out[1] = 0;     /* device: bus powered, no remote wakeup; interface: 0 */
        if (recip == PSU_RT_RECIP_INTERFACE) {
            if (!configured || s->wIndex != 0)
                return PSU_CTRL_STALL;
        } else if (recip == PSU_RT_RECIP_ENDPOINT) {
            uint8_t ep = (uint8_t)s->wIndex;
            if (ep == PSU_EP_IN || ep == PSU_EP_OUT) {
                if (!configured)
                    return PSU_CTRL_STALL;
                out[0] = (ep == PSU_EP_IN ? d->halt_in : d->halt_out) ? 1 : 0;
            } else if ((ep & 0x7F) != 0) {
                return PSU_CTRL_STALL;
            }
        } else if (recip != PSU_RT_RECIP_DEVICE) {
            return PSU_CTRL_STALL;
        }
        *len = 2;
        return PSU_CTRL_ACK;
    case PSU_REQ_CLEAR_FEATURE:
    case PSU_REQ_SET_FEATURE: {
        bool set = s->bRequest == PSU_REQ_SET_FEATURE;
        if (in || recip != PSU_RT_RECIP_ENDPOINT || s->wValue != PSU_FEATURE_ENDPOINT_HALT ||
            !configured || !bulk_ep(s->wIndex))
            return PSU_CTRL_STALL; /* no remote wakeup, no test modes */
        uint8_t ep = (uint8_t)s->wIndex;
        if (set)
            psu_dcd_ep_stall(ep);
        else
            psu_dcd_ep_clear_stall(ep);
        if (ep == PSU_EP_IN) {
            d->halt_in = set;
            if (!set)
                kick_tx(d);
        } else {
            d->halt_out = set;
            if (!set)
                arm_rx(d);
        }
        return PSU_CTRL_ACK;
    }
    case PSU_REQ_GET_INTERFACE:
        if (!in || recip != PSU_RT_RECIP_INTERFACE || !configured || s->wIndex != 0 || cap < 1)
            return PSU_CTRL_STALL;
        out[0] = 0;
        *len = 1;
        return PSU_CTRL_ACK;
    case PSU_REQ_SET_INTERFACE:
        /* Only alternate setting 0 exists; selecting it resets the endpoints' halt state. */
        if (in || recip != PSU_RT_RECIP_INTERFACE || !configured || s->wIndex != 0 || s->wValue != 0)
            return PSU_CTRL_STALL;
        d->halt_in = d->halt_out = false;
        psu_dcd_ep_clear_stall(PSU_EP_OUT);
        psu_dcd_ep_clear_stall(PSU_EP_IN);
        arm_rx(d);
        kick_tx(d);
        return PSU_CTRL_ACK;
    default:                     /* SET_DESCRIPTOR, SYNCH_FRAME: not supported */
        return PSU_CTRL_STALL;
    }
}

void psu_dcd_event_reset(psu_dev_t *d)
{
    /* A bus reset returns to the default state; configuration and address are gone. */
    if (d->config != 0) {
        psu_dcd_ep_close(PSU_EP_OUT);
        psu_dcd_ep_close(PSU_EP_IN);
    }
    d->state = PSU_STATE_DEFAULT;
    d->address = d->config = 0;
    d->halt_in = d->halt_out = false;
    d->rx_armed = d->tx_busy = d->tx_zlp = false;
    d->tx_head = d->tx_tail = 0;
    d->ep0_stage = EP0_IDLE;
}

static void ep0_stall(void)
{
    psu_dcd_ep_stall(0x00);
    psu_dcd_ep_stall(0x80);
}

void psu_dcd_event_setup(psu_dev_t *d, const uint8_t raw[8])
{
    psu_setup_t s;
    memcpy(&s, raw, sizeof s);
    d->ep0_stage = EP0_IDLE;     /* a SETUP aborts whatever control transfer was running */
    d->ep0_zlp = false;
    bool in = (s.bmRequestType & PSU_RT_DIR_IN) != 0;
    if (!in && s.wLength > 0) {
        ep0_stall();             /* no supported request has an OUT data stage */
        return;
    }
    uint16_t n = 0;
    if (psu_control(d, &s, d->ep0_buf, sizeof d->ep0_buf, &n) != PSU_CTRL_ACK) {
        ep0_stall();
        return;
    }
    if (in && s.wLength > 0) {
        if (n > s.wLength)
            n = s.wLength;
        /* A short answer that fills whole packets needs a ZLP, or the host waits for more. */
        d->ep0_zlp = n < s.wLength && n % PSU_EP0_MPS == 0;
        d->ep0_stage = EP0_DATA_IN;
        psu_dcd_ep_xfer(0x80, d->ep0_buf, n);
    } else {
        d->ep0_stage = EP0_STATUS_IN;
        psu_dcd_ep_xfer(0x80, NULL, 0);
    }
}

void psu_dcd_event_xfer_done(psu_dev_t *d, uint8_t ep, uint16_t len)
{
    switch (ep) {
    case 0x80:
        if (d->ep0_stage == EP0_DATA_IN) {
            if (d->ep0_zlp) {
                d->ep0_zlp = false;
                psu_dcd_ep_xfer(0x80, NULL, 0);
                return;
            }
            d->ep0_stage = EP0_STATUS_OUT;
            psu_dcd_ep_xfer(0x00, NULL, 0);
        } else if (d->ep0_stage == EP0_STATUS_IN) {
            d->ep0_stage = EP0_IDLE;
        }
        return;
    case 0x00:
        if (d->ep0_stage == EP0_STATUS_OUT)
            d->ep0_stage = EP0_IDLE;
        return;
    case PSU_EP_OUT:
        d->rx_armed = false;
        if (len > sizeof d->rx_buf)
            len = sizeof d->rx_buf;
        if (len > 0 && d->cfg.rx)
            d->cfg.rx(d->cfg.rx_ctx, d->rx_buf, len);
        arm_rx(d);
        return;
    case PSU_EP_IN:
        d->tx_busy = false;
        kick_tx(d);
        return;
    default:
        return;
    }
}

bool psu_write(psu_dev_t *d, const uint8_t *data, size_t len)
{
    uint32_t used = d->tx_head - d->tx_tail;
    if (d->state != PSU_STATE_CONFIGURED || len > PSU_TX_RING_BYTES - used) {
        d->tx_dropped_frames++;  /* no host or it stopped reading: drop, as a UART would */
        return false;
    }
    for (size_t i = 0; i < len; i++)
        d->tx_ring[(d->tx_head + i) % PSU_TX_RING_BYTES] = data[i];
    d->tx_head += (uint32_t)len;
    kick_tx(d);
    return true;
}

void psu_write_frame(void *ctx, const uint8_t *frame, size_t len)
{
    (void)psu_write((psu_dev_t *)ctx, frame, len);
}
