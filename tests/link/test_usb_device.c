/* cmocka tests of the portable USB device core (firmware/link/usb) against a mock chip port. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "link/psl_link.h"
#include "storage/pss_flash_sim.h"
#include "link/usb/psu_dcd.h"
#include "link/usb/psu_device.h"

/* ---- mock chip port: records what the core asked of the controller ---- */

enum { MAX_XFERS = 64 };

typedef struct {
    uint8_t ep;
    uint16_t len;
    uint8_t data[PSU_TX_XFER_MAX_BYTES];
} xfer_t;

static struct {
    int init;
    int address;
    int opened[256];
    int closed[256];
    int stalled[256];
    int stall_calls;
    xfer_t xf[MAX_XFERS];
    int n_xf;
    uint8_t *out_buf;            /* the armed bulk OUT transfer */
    uint16_t out_len;
    int in_busy;
} M;

void psu_dcd_init(struct psu_dev *dev)
{
    (void)dev;
    M.init++;
}

void psu_dcd_set_address(uint8_t addr)
{
    M.address = addr;
}

void psu_dcd_ep_open(uint8_t ep, uint8_t type, uint16_t mps)
{
    assert_int_equal(type, PSU_EP_TYPE_BULK);
    assert_int_equal(mps, 64);
    M.opened[ep]++;
}

void psu_dcd_ep_close(uint8_t ep)
{
    M.closed[ep]++;
    if (ep == PSU_EP_OUT)
        M.out_buf = NULL;
    if (ep == PSU_EP_IN)
        M.in_busy = 0;
}

bool psu_dcd_ep_xfer(uint8_t ep, uint8_t *buf, uint16_t len)
{
    assert_true(M.n_xf < MAX_XFERS);
    if (ep == PSU_EP_OUT) {
        if (M.out_buf)
            return false;
        M.out_buf = buf;
        M.out_len = len;
    }
    if (ep == PSU_EP_IN) {
        if (M.in_busy)
            return false;
        M.in_busy = 1;
    }
    xfer_t *x = &M.xf[M.n_xf++];
    x->ep = ep;
    x->len = len;
    assert_true(len <= sizeof x->data);
    if (len)
        memcpy(x->data, buf, len);
    return true;
}

void psu_dcd_ep_stall(uint8_t ep)
{
    M.stalled[ep] = 1;
    M.stall_calls++;
}

void psu_dcd_ep_clear_stall(uint8_t ep)
{
    M.stalled[ep] = 0;
}

/* ---- helpers ---- */

static psu_dev_t D;
static uint8_t rx_got[4096];
static size_t rx_n;

static void rx(void *ctx, const uint8_t *data, size_t len)
{
    (void)ctx;
    assert_true(rx_n + len <= sizeof rx_got);
    memcpy(rx_got + rx_n, data, len);
    rx_n += len;
}

static int setup(void **state)
{
    (void)state;
    memset(&M, 0, sizeof M);
    rx_n = 0;
    psu_config_t cfg = {.board_id = {0x01234567u, 0x89ABCDEFu, 0x0000002Au}, .bcd_device = 0x0102,
                        .rx = rx};
    psu_init(&D, &cfg);
    psu_dcd_init(&D);
    psu_dcd_event_reset(&D);
    return 0;
}

static void send_setup(uint8_t rt, uint8_t req, uint16_t value, uint16_t index, uint16_t length)
{
    psu_setup_t s = {rt, req, value, index, length};
    uint8_t raw[8];
    memcpy(raw, &s, 8);
    psu_dcd_event_setup(&D, raw);
}

/* Run a control IN request through all stages; returns the data stage transfer. */
static const xfer_t *control_in(uint8_t rt, uint8_t req, uint16_t value, uint16_t index, uint16_t length)
{
    int first = M.n_xf;
    send_setup(rt, req, value, index, length);
    assert_int_equal(M.n_xf, first + 1);
    const xfer_t *data = &M.xf[first];
    assert_int_equal(data->ep, 0x80);
    psu_dcd_event_xfer_done(&D, 0x80, data->len);
    assert_int_equal(M.xf[M.n_xf - 1].ep, 0x00); /* status stage: host's zero-length OUT */
    assert_int_equal(M.xf[M.n_xf - 1].len, 0);
    psu_dcd_event_xfer_done(&D, 0x00, 0);
    return data;
}

/* A no-data request: the status stage is our zero-length IN. */
static void control_nodata(uint8_t rt, uint8_t req, uint16_t value, uint16_t index)
{
    int first = M.n_xf;
    send_setup(rt, req, value, index, 0);
    /* SET_CONFIGURATION also arms bulk OUT; the status ZLP is the last transfer. */
    assert_true(M.n_xf > first);
    assert_int_equal(M.xf[M.n_xf - 1].ep, 0x80);
    assert_int_equal(M.xf[M.n_xf - 1].len, 0);
    psu_dcd_event_xfer_done(&D, 0x80, 0);
}

static void enumerate(void)
{
    control_nodata(0x00, PSU_REQ_SET_ADDRESS, 7, 0);
    control_nodata(0x00, PSU_REQ_SET_CONFIGURATION, 1, 0);
}

/* ---- tests ---- */

static void device_descriptor(void **state)
{
    (void)state;
    const xfer_t *x = control_in(0x80, PSU_REQ_GET_DESCRIPTOR, PSU_DESC_DEVICE << 8, 0, 64);
    assert_int_equal(x->len, 18);
    psu_device_desc_t d;
    memcpy(&d, x->data, sizeof d);
    assert_int_equal(d.bLength, 18);
    assert_int_equal(d.bcdUSB, 0x0200);
    assert_int_equal(d.bMaxPacketSize0, 64);
    assert_int_equal(d.idVendor, 0x1209);
    assert_int_equal(d.idProduct, 0x0001);
    assert_int_equal(d.bcdDevice, 0x0102);
    assert_int_equal(d.bNumConfigurations, 1);
    /* The host's first read is often 8 bytes (bMaxPacketSize0): cut to wLength. */
    x = control_in(0x80, PSU_REQ_GET_DESCRIPTOR, PSU_DESC_DEVICE << 8, 0, 8);
    assert_int_equal(x->len, 8);
}

static void configuration_descriptor(void **state)
{
    (void)state;
    const xfer_t *x = control_in(0x80, PSU_REQ_GET_DESCRIPTOR, PSU_DESC_CONFIGURATION << 8, 0, 9);
    assert_int_equal(x->len, 9);
    x = control_in(0x80, PSU_REQ_GET_DESCRIPTOR, PSU_DESC_CONFIGURATION << 8, 0, 255);
    assert_int_equal(x->len, 32);
    psu_config_desc_t c;
    psu_iface_desc_t i;
    psu_ep_desc_t o, in;
    memcpy(&c, x->data, 9);
    memcpy(&i, x->data + 9, 9);
    memcpy(&o, x->data + 18, 7);
    memcpy(&in, x->data + 25, 7);
    assert_int_equal(c.wTotalLength, 32);
    assert_int_equal(c.bConfigurationValue, 1);
    assert_true(c.bmAttributes & 0x80);
    assert_int_equal(i.bInterfaceClass, 0xFF);
    assert_int_equal(i.bNumEndpoints, 2);
    assert_int_equal(o.bEndpointAddress, 0x01);
    assert_int_equal(in.bEndpointAddress, 0x81);
    assert_int_equal(o.bmAttributes, 2);
    assert_int_equal(in.wMaxPacketSize, 64);
}

static void strings(void **state)
{
    (void)state;
    const xfer_t *x = control_in(0x80, PSU_REQ_GET_DESCRIPTOR, PSU_DESC_STRING << 8, 0, 255);
    assert_int_equal(x->len, 4);
    assert_int_equal(x->data[2] | x->data[3] << 8, 0x0409);
    x = control_in(0x80, PSU_REQ_GET_DESCRIPTOR, PSU_DESC_STRING << 8 | 3, 0x0409, 255);
    assert_int_equal(x->len, 2 + 2 * 24);
    char s[25];
    for (int k = 0; k < 24; k++)
        s[k] = (char)x->data[2 + 2 * k];
    s[24] = 0;
    assert_string_equal(s, "0123456789ABCDEF0000002A");
    /* No string 5, no device qualifier (full speed only): STALL on both directions. */
    send_setup(0x80, PSU_REQ_GET_DESCRIPTOR, PSU_DESC_STRING << 8 | 5, 0x0409, 255);
    assert_true(M.stalled[0x80] && M.stalled[0x00]);
    M.stalled[0x80] = M.stalled[0x00] = 0;
    send_setup(0x80, PSU_REQ_GET_DESCRIPTOR, PSU_DESC_DEVICE_QUALIFIER << 8, 0, 10);
    assert_true(M.stalled[0x80]);
}

static void address_and_configuration(void **state)
{
    (void)state;
    /* SET_CONFIGURATION in the default state is a request error. */
    send_setup(0x00, PSU_REQ_SET_CONFIGURATION, 1, 0, 0);
    assert_true(M.stalled[0x80]);
    M.stalled[0x80] = M.stalled[0x00] = 0;
    control_nodata(0x00, PSU_REQ_SET_ADDRESS, 7, 0);
    assert_int_equal(M.address, 7);
    assert_int_equal(D.state, PSU_STATE_ADDRESS);
    const xfer_t *x = control_in(0x80, PSU_REQ_GET_CONFIGURATION, 0, 0, 1);
    assert_int_equal(x->data[0], 0);
    send_setup(0x00, PSU_REQ_SET_CONFIGURATION, 2, 0, 0); /* no configuration 2 */
    assert_true(M.stalled[0x80]);
    M.stalled[0x80] = M.stalled[0x00] = 0;
    control_nodata(0x00, PSU_REQ_SET_CONFIGURATION, 1, 0);
    assert_int_equal(D.state, PSU_STATE_CONFIGURED);
    assert_int_equal(M.opened[0x01], 1);
    assert_int_equal(M.opened[0x81], 1);
    assert_non_null(M.out_buf); /* bulk OUT armed for a packet */
    assert_int_equal(M.out_len, 64);
    x = control_in(0x80, PSU_REQ_GET_CONFIGURATION, 0, 0, 1);
    assert_int_equal(x->data[0], 1);
    x = control_in(0x81, PSU_REQ_GET_INTERFACE, 0, 0, 1);
    assert_int_equal(x->data[0], 0);
    send_setup(0x01, PSU_REQ_SET_INTERFACE, 1, 0, 0); /* no alternate setting 1 */
    assert_true(M.stalled[0x80]);
    M.stalled[0x80] = M.stalled[0x00] = 0;
    /* Deconfigure: endpoints closed, back to the address state. */
    control_nodata(0x00, PSU_REQ_SET_CONFIGURATION, 0, 0);
    assert_int_equal(D.state, PSU_STATE_ADDRESS);
    assert_int_equal(M.closed[0x01], 1);
    assert_int_equal(M.closed[0x81], 1);
    /* A bus reset forgets the address. */
    psu_dcd_event_reset(&D);
    assert_int_equal(D.state, PSU_STATE_DEFAULT);
    assert_int_equal(D.address, 0);
}

static void status_and_halt(void **state)
{
    (void)state;
    enumerate();
    const xfer_t *x = control_in(0x80, PSU_REQ_GET_STATUS, 0, 0, 2);
    assert_int_equal(x->len, 2);
    assert_int_equal(x->data[0], 0);
    control_nodata(0x02, PSU_REQ_SET_FEATURE, PSU_FEATURE_ENDPOINT_HALT, 0x81);
    assert_true(M.stalled[0x81]);
    x = control_in(0x82, PSU_REQ_GET_STATUS, 0, 0x81, 2);
    assert_int_equal(x->data[0], 1);
    /* While halted, queued bytes wait; CLEAR_FEATURE lets them go. */
    uint8_t b[10] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
    int before = M.n_xf;
    assert_true(psu_write(&D, b, sizeof b));
    assert_int_equal(M.n_xf, before);
    control_nodata(0x02, PSU_REQ_CLEAR_FEATURE, PSU_FEATURE_ENDPOINT_HALT, 0x81);
    assert_false(M.stalled[0x81]);
    assert_int_equal(M.xf[M.n_xf - 2].ep, 0x81); /* the bulk transfer, then the status ZLP */
    assert_int_equal(M.xf[M.n_xf - 2].len, 10);
    x = control_in(0x82, PSU_REQ_GET_STATUS, 0, 0x81, 2);
    assert_int_equal(x->data[0], 0);
    /* Unknown endpoint, remote wakeup (not offered), vendor requests, OUT data stages: STALL. */
    int stalls = M.stall_calls;
    send_setup(0x82, PSU_REQ_GET_STATUS, 0, 0x83, 2);
    send_setup(0x00, PSU_REQ_SET_FEATURE, PSU_FEATURE_DEVICE_REMOTE_WAKEUP, 0, 0);
    send_setup(0xC0, 0x01, 0, 0, 4);
    send_setup(0x00, PSU_REQ_SET_DESCRIPTOR, PSU_DESC_DEVICE << 8, 0, 18);
    assert_int_equal(M.stall_calls, stalls + 4 * 2);
}

static void bulk_out_to_rx(void **state)
{
    (void)state;
    enumerate();
    uint8_t *buf = M.out_buf;
    memset(buf, 0xAB, 64);
    M.out_buf = NULL;            /* the controller finished the armed transfer */
    psu_dcd_event_xfer_done(&D, PSU_EP_OUT, 64);
    assert_int_equal(rx_n, 64);
    assert_non_null(M.out_buf);  /* re-armed */
    M.out_buf[0] = 0x42;
    M.out_buf = NULL;
    psu_dcd_event_xfer_done(&D, PSU_EP_OUT, 1);
    assert_int_equal(rx_n, 65);
    assert_int_equal(rx_got[64], 0x42);
}

static void bulk_in_framing(void **state)
{
    (void)state;
    uint8_t b[1024];
    for (size_t k = 0; k < sizeof b; k++)
        b[k] = (uint8_t)k;
    /* Not configured: refused whole, counted. */
    assert_false(psu_write(&D, b, 10));
    assert_int_equal(D.tx_dropped_frames, 1);
    enumerate();
    int first = M.n_xf;
    /* A largest frame: one transfer ending in a short packet (260 = 4 x 64 + 4). */
    assert_true(psu_write(&D, b, 260));
    assert_int_equal(M.xf[first].ep, 0x81);
    assert_int_equal(M.xf[first].len, 260);
    assert_memory_equal(M.xf[first].data, b, 260);
    M.in_busy = 0;
    psu_dcd_event_xfer_done(&D, PSU_EP_IN, 260);
    assert_int_equal(M.n_xf, first + 1);
    /* 128 B = two full packets: the host learns the end from a zero-length packet. */
    assert_true(psu_write(&D, b, 128));
    M.in_busy = 0;
    psu_dcd_event_xfer_done(&D, PSU_EP_IN, 128);
    assert_int_equal(M.xf[first + 2].len, 0);
    M.in_busy = 0;
    psu_dcd_event_xfer_done(&D, PSU_EP_IN, 0);
    assert_int_equal(M.n_xf, first + 3);
    /* 700 B queued while busy go as 300 + 300 + 100, in order. */
    M.in_busy = 0;
    first = M.n_xf;
    assert_true(psu_write(&D, b, 700));
    uint8_t got[700];
    size_t n = 0;
    while (n < 700) {
        const xfer_t *x = &M.xf[M.n_xf - 1];
        memcpy(got + n, x->data, x->len);
        n += x->len;
        M.in_busy = 0;
        psu_dcd_event_xfer_done(&D, PSU_EP_IN, x->len);
    }
    assert_int_equal(M.n_xf - first, 3);
    assert_memory_equal(got, b, 700);
    /* A backlog that cannot take a whole frame drops that frame, never a part of it. */
    M.in_busy = 1;               /* the host stopped reading */
    D.tx_busy = true;
    assert_true(psu_write(&D, b, 1000));
    assert_false(psu_write(&D, b, 100));
    assert_int_equal(D.tx_head - D.tx_tail, 1000);
}

/* The link handler behind the USB core: an INFO request in 64 B packets, the answer on bulk IN. */
static void link_over_bulk(void **state)
{
    (void)state;
    static uint8_t mem[2 * 4096];
    static pss_sim_t sim;
    static psl_t L;
    pss_sim_init(&sim, mem, 4096, 1);
    psu_config_t cfg = {.bcd_device = 0x0100, .rx = (psu_rx_fn)psl_rx, .rx_ctx = &L};
    psu_init(&D, &cfg);
    psl_config_t lc = psl_default_config(1000);
    psl_init(&L, &lc, &sim.port, psu_write_frame, &D);
    psu_dcd_event_reset(&D);
    enumerate();
    uint8_t req[PSF_MAX_FRAME];
    size_t n = psf_encode(req, sizeof req, PSP_MSG_INFO, 1, NULL, 0);
    int first = M.n_xf;
    uint8_t *buf = M.out_buf;
    M.out_buf = NULL;
    memcpy(buf, req, n);
    psu_dcd_event_xfer_done(&D, PSU_EP_OUT, (uint16_t)n);
    assert_true(M.n_xf > first);
    const xfer_t *x = NULL;
    for (int k = first; k < M.n_xf; k++)
        if (M.xf[k].ep == 0x81)
            x = &M.xf[k];
    assert_non_null(x);
    psf_parser_t p;
    psf_result_t res;
    psf_parser_reset(&p);
    psf_parser_push(&p, x->data, x->len, &res);
    assert_int_equal(res, PSF_FRAME);
    assert_int_equal(p.hdr.type, PSP_MSG_INFO | PSP_RESPONSE);
    assert_int_equal(p.hdr.len, sizeof(psp_info_t));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(device_descriptor, setup),
        cmocka_unit_test_setup(configuration_descriptor, setup),
        cmocka_unit_test_setup(strings, setup),
        cmocka_unit_test_setup(address_and_configuration, setup),
        cmocka_unit_test_setup(status_and_halt, setup),
        cmocka_unit_test_setup(bulk_out_to_rx, setup),
        cmocka_unit_test_setup(bulk_in_framing, setup),
        cmocka_unit_test_setup(link_over_bulk, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
