/* Portable USB device core: descriptors, standard control requests, bulk byte pipe for the link frames. */
#ifndef PSU_DEVICE_H
#define PSU_DEVICE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include "link/usb/psu_usb.h"

/* pid.codes VID 0x1209 with PID 0x0001, the first of pid.codes' *test* PIDs
 * (https://pid.codes/1209/0001/): fine on a bench, not for a released board, which needs
 * its own PID from pid.codes. The host (host/playscope/device/transport.py) and the udev
 * rule (tools/udev/99-playscope.rules) use the same pair. */
enum {
    PSU_VID = 0x1209,
    PSU_PID = 0x0001,
    PSU_EP0_MPS = 64,            /* bytes, full speed control */
    PSU_BULK_MPS = 64,           /* bytes, the full-speed bulk maximum */
    PSU_EP_OUT = 0x01,           /* host -> board frames */
    PSU_EP_IN = 0x81,            /* board -> host frames */
    PSU_CONFIG_VALUE = 1,
    PSU_CONFIG_TOTAL_BYTES = 9 + 9 + 7 + 7,
    PSU_STR_COUNT = 5,           /* 0 languages, 1 manufacturer, 2 product, 3 serial, 4 interface */
    PSU_EP0_BUF_BYTES = 128,     /* longest answer: the 66 B product/serial strings, 32 B config */
    PSU_TX_RING_BYTES = 1024,    /* board -> host backlog, about 4 largest frames */
    /* Bytes per bulk IN transfer: one largest frame (260 B) fits, and it is not a multiple
     * of 64, so a full transfer ends in a short packet and needs no zero-length packet. */
    PSU_TX_XFER_MAX_BYTES = 300,
};

enum psu_state {
    PSU_STATE_DEFAULT = 0,       /* after bus reset, address 0 */
    PSU_STATE_ADDRESS = 1,
    PSU_STATE_CONFIGURED = 2,
};

typedef enum {
    PSU_CTRL_ACK = 0,            /* request done; data (if any) in the answer buffer */
    PSU_CTRL_STALL = 1,          /* request error: the control pipe answers STALL */
} psu_ctrl_t;

/* Bytes that arrived on bulk OUT (a piece of the frame stream, not a whole frame). */
typedef void (*psu_rx_fn)(void *ctx, const uint8_t *data, size_t len);

typedef struct {
    uint32_t board_id[3];        /* serial number string = 24 hex digits of this */
    uint16_t bcd_device;         /* device release, e.g. 0x0100 */
    psu_rx_fn rx;
    void *rx_ctx;
} psu_config_t;

typedef struct psu_dev {
    psu_config_t cfg;
    uint8_t state;               /* enum psu_state */
    uint8_t address;
    uint8_t config;              /* bConfigurationValue, 0 = not configured */
    bool halt_in, halt_out;      /* ENDPOINT_HALT feature of the bulk endpoints */
    uint8_t ep0_stage;           /* control transfer stage, psu_device.c */
    bool ep0_zlp;                /* IN data stage must end with a zero-length packet */
    uint8_t ep0_buf[PSU_EP0_BUF_BYTES];
    uint8_t rx_buf[PSU_BULK_MPS];
    bool rx_armed;
    uint8_t tx_ring[PSU_TX_RING_BYTES];
    uint32_t tx_head, tx_tail;   /* free-running byte counts; used = head - tail */
    uint8_t tx_xfer[PSU_TX_XFER_MAX_BYTES];
    bool tx_busy;                /* a bulk IN transfer is with the controller */
    bool tx_zlp;                 /* the last transfer was a multiple of 64: send a ZLP next */
    uint32_t tx_dropped_frames;  /* frames refused: not configured or backlog full */
} psu_dev_t;

/* Reset the core to the default state. Does not touch the controller (psu_dcd_init does). */
void psu_init(psu_dev_t *d, const psu_config_t *cfg);

/* Answer one standard control request. For IN requests the answer (at most in_cap bytes,
 * not yet cut to wLength) goes to in_buf and its length to *in_len. Side effects of
 * SET_ADDRESS / SET_CONFIGURATION / features go to the chip port. Used by the endpoint 0
 * state machine below and directly by the emulated device (firmware/boards/desktop). */
psu_ctrl_t psu_control(psu_dev_t *d, const psu_setup_t *s, uint8_t *in_buf, uint16_t in_cap,
                       uint16_t *in_len);

/* Events from the chip port (psu_dcd.h). Not re-entrant: call from one context. */
void psu_dcd_event_reset(psu_dev_t *d);
void psu_dcd_event_setup(psu_dev_t *d, const uint8_t setup[8]);
void psu_dcd_event_xfer_done(psu_dev_t *d, uint8_t ep_addr, uint16_t len_bytes);

/* Queue bytes for bulk IN. All or nothing: returns false (and counts a dropped frame) when
 * not configured or when the backlog cannot take all len bytes, so a frame is never cut. */
bool psu_write(psu_dev_t *d, const uint8_t *data, size_t len);

/* psl_write_fn-compatible wrapper (ctx = psu_dev_t *) for psl_init. */
void psu_write_frame(void *ctx, const uint8_t *frame, size_t len);

#endif /* PSU_DEVICE_H */
