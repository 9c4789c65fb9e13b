/* Emulated USB board: umockdev testbed device 1209:0001 whose usbdevfs URBs go through the portable USB core to ps_vboard. */
/*
 * Usage: ps_usbemu [--vboard PATH] [--flash FILE] [--trace] -- COMMAND [ARGS...]
 *
 * Builds a umockdev testbed with one USB device (sysfs attributes, and the `descriptors`
 * file filled with what the device core answers to GET_DESCRIPTOR), attaches an ioctl
 * handler to its node /dev/bus/usb/001/002, starts ps_vboard --stdio behind it, and runs
 * COMMAND with LD_PRELOAD=libumockdev-preload.so.0 and UMOCKDEV_DIR set, so the command's
 * unmodified libusb (pyusb) finds and opens the device as if it were plugged in.
 *
 * The handler plays the kernel's usbdevfs and the device controller at once:
 *   control URBs      -> psu_control() of firmware/link/usb (the firmware's own answers)
 *   bulk OUT URBs     -> cut into 64 B packets, each completing the core's armed OUT
 *                        transfer; the core hands the bytes to ps_vboard's stdin
 *   ps_vboard stdout  -> psu_write() (the firmware's bulk IN framing: 300 B transfers,
 *                        ZLP after a whole number of packets) -> pending bulk IN URBs
 *   REAPURB(NDELAY)   -> finished URBs, discarded first; EAGAIN when none
 * What it does not emulate: the packet-level bus (no NAKs, toggles or timing), hub
 * events, suspend. Exit status: COMMAND's.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <linux/usbdevice_fs.h>
#include <pthread.h>
#include <signal.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <umockdev.h>

#include "link/usb/psu_dcd.h"
#include "link/usb/psu_device.h"

/* The emulator links glib, whose caches live until exit; LeakSanitizer (desktop preset)
 * would turn them into a failing exit status that is not the command's. */
const char *__asan_default_options(void);
const char *__asan_default_options(void)
{
    return "detect_leaks=0";
}

#ifndef USBDEVFS_GET_SPEED
#define USBDEVFS_GET_SPEED _IO('U', 31)
#endif

enum {
    EMU_BUS = 1,
    EMU_DEVNUM = 2,
    EMU_MAX_URBS = 64,           /* in flight at once; libusb uses a handful */
    EMU_RX_QUEUE_BYTES = 1 << 16, /* vboard output not yet taken by the device core */
    EMU_USB_SPEED_FULL = 2,      /* enum usb_device_speed */
};

typedef struct {
    UMockdevIoctlData *urb;      /* the client's struct usbdevfs_urb (resolved copy) */
    UMockdevIoctlData *buf;      /* its buffer (resolved copy), NULL when length 0 */
    UMockdevIoctlClient *client;
} urb_t;

typedef struct {
    urb_t v[EMU_MAX_URBS];
    int n;
} urb_list_t;

static struct {
    psu_dev_t dev;
    int trace;
    int vb_in, vb_out;           /* pipes to / from ps_vboard */
    pid_t vb_pid;
    /* Bytes from ps_vboard, filled by the reader thread, drained by the ioctl thread. */
    pthread_mutex_t mu;
    uint8_t rxq[EMU_RX_QUEUE_BYTES];
    size_t rxq_len;
    int vb_eof;
    /* The device controller the core drives (psu_dcd.h), as seen by the ioctl thread. */
    uint8_t *out_buf;            /* armed bulk OUT transfer */
    uint16_t out_len;
    uint8_t *in_buf;             /* armed bulk IN transfer */
    uint16_t in_len;
    int in_armed;
    int stalled_in, stalled_out;
    urb_list_t done, in_pending, discarded;
    uint64_t n_urbs;
} E;

#define TRACE(...) do { if (E.trace) fprintf(stderr, "usbemu: " __VA_ARGS__); } while (0)

/* ---- chip port for the emulator (psu_dcd.h) ---- */

void psu_dcd_init(struct psu_dev *dev)
{
    (void)dev;
}

void psu_dcd_set_address(uint8_t addr)
{
    TRACE("set address %u\n", addr);
}

void psu_dcd_ep_open(uint8_t ep, uint8_t type, uint16_t mps)
{
    TRACE("open ep %02x type %u mps %u\n", ep, type, mps);
}

void psu_dcd_ep_close(uint8_t ep)
{
    if (ep == PSU_EP_IN)
        E.in_armed = 0;
    else if (ep == PSU_EP_OUT)
        E.out_buf = NULL;
}

bool psu_dcd_ep_xfer(uint8_t ep, uint8_t *buf, uint16_t len)
{
    if (ep == PSU_EP_OUT) {
        if (E.out_buf)
            return false;
        E.out_buf = buf;
        E.out_len = len;
    } else if (ep == PSU_EP_IN) {
        if (E.in_armed)
            return false;
        E.in_buf = buf;
        E.in_len = len;
        E.in_armed = 1;
    }
    /* Endpoint 0 stages are not replayed: control URBs go to psu_control() whole. */
    return true;
}

void psu_dcd_ep_stall(uint8_t ep)
{
    if (ep == PSU_EP_IN)
        E.stalled_in = 1;
    else if (ep == PSU_EP_OUT)
        E.stalled_out = 1;
}

void psu_dcd_ep_clear_stall(uint8_t ep)
{
    if (ep == PSU_EP_IN)
        E.stalled_in = 0;
    else if (ep == PSU_EP_OUT)
        E.stalled_out = 0;
}

/* ---- ps_vboard ---- */

static void to_vboard(void *ctx, const uint8_t *data, size_t len)
{
    (void)ctx;
    while (len > 0) {
        ssize_t n = write(E.vb_in, data, len);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            return;              /* board gone: the next reap reports nothing more */
        data += n;
        len -= (size_t)n;
    }
}

static void *vboard_reader(void *arg)
{
    (void)arg;
    uint8_t buf[4096];
    for (;;) {
        ssize_t n = read(E.vb_out, buf, sizeof buf);
        if (n < 0 && errno == EINTR)
            continue;
        pthread_mutex_lock(&E.mu);
        if (n <= 0) {
            E.vb_eof = 1;
            pthread_mutex_unlock(&E.mu);
            return NULL;
        }
        size_t k = (size_t)n;
        if (k > sizeof E.rxq - E.rxq_len)
            k = sizeof E.rxq - E.rxq_len; /* host stopped reading for 64 KiB: drop */
        memcpy(E.rxq + E.rxq_len, buf, k);
        E.rxq_len += k;
        pthread_mutex_unlock(&E.mu);
    }
}

static pid_t spawn(char *const argv[], int *in_fd, int *out_fd)
{
    int pin[2], pout[2];
    if (pipe2(pin, O_CLOEXEC) != 0 || pipe2(pout, O_CLOEXEC) != 0)
        return -1;
    pid_t pid = fork();
    if (pid == 0) {
        dup2(pin[0], 0);
        dup2(pout[1], 1);
        execv(argv[0], argv);
        perror(argv[0]);
        _exit(127);
    }
    close(pin[0]);
    close(pout[1]);
    *in_fd = pin[1];
    *out_fd = pout[0];
    return pid;
}

/* ---- URB bookkeeping (ioctl thread only) ---- */

static struct usbdevfs_urb *urb_of(const urb_t *u)
{
    return (struct usbdevfs_urb *)u->urb->data;
}

static void list_push(urb_list_t *l, urb_t u)
{
    if (l->n < EMU_MAX_URBS)
        l->v[l->n++] = u;
}

static urb_t list_pop(urb_list_t *l, int i)
{
    urb_t u = l->v[i];
    memmove(&l->v[i], &l->v[i + 1], (size_t)(l->n - i - 1) * sizeof(urb_t));
    l->n--;
    return u;
}

/* Write status/length (and IN data) into the client's copies; umockdev syncs them back
 * when the reap completes. */
static void finish(urb_t *u, int status, int actual, const uint8_t *data, size_t off)
{
    struct usbdevfs_urb r = *urb_of(u);
    r.status = status;
    r.actual_length = actual;
    if (data && actual > 0 && u->buf)
        umockdev_ioctl_data_update(u->buf, off, (guint8 *)data, actual);
    /* The buffer pointer in the local copy points at our copy; update() keeps the
     * bytes, and umockdev rewrites the pointer to the client's address on sync. */
    umockdev_ioctl_data_update(u->urb, 0, (guint8 *)&r, sizeof r);
}

/* Move ps_vboard output into the device core, and finished IN transfers into URBs. */
static void pump_in(void)
{
    pthread_mutex_lock(&E.mu);
    size_t used = 0;
    while (used < E.rxq_len) {
        /* psu_write is all or nothing; offer what fits in its backlog. */
        size_t k = E.rxq_len - used;
        uint32_t room = PSU_TX_RING_BYTES - (E.dev.tx_head - E.dev.tx_tail);
        if (k > room)
            k = room;
        if (k == 0 || !psu_write(&E.dev, E.rxq + used, k))
            break;
        used += k;
    }
    memmove(E.rxq, E.rxq + used, E.rxq_len - used);
    E.rxq_len -= used;
    pthread_mutex_unlock(&E.mu);

    while (E.in_armed && E.in_pending.n > 0 && !E.stalled_in) {
        urb_t u = list_pop(&E.in_pending, 0);
        struct usbdevfs_urb *r = urb_of(&u);
        uint16_t n = E.in_len;
        E.in_armed = 0;
        if (n > r->buffer_length) {
            finish(&u, -EOVERFLOW, r->buffer_length, E.in_buf, 0); /* babble, as the HCD reports it */
        } else {
            finish(&u, 0, n, E.in_buf, 0);
        }
        TRACE("bulk IN %u B\n", n);
        list_push(&E.done, u);
        psu_dcd_event_xfer_done(&E.dev, PSU_EP_IN, n);
    }
}

static void submit(UMockdevIoctlClient *c, UMockdevIoctlData *arg)
{
    GError *err = NULL;
    urb_t u = {.client = c};
    u.urb = umockdev_ioctl_data_resolve(arg, 0, sizeof(struct usbdevfs_urb), &err);
    if (!u.urb) {
        umockdev_ioctl_client_complete(c, -1, EFAULT);
        g_clear_error(&err);
        return;
    }
    struct usbdevfs_urb *r = urb_of(&u);
    if (r->buffer_length > 0) {
        u.buf = umockdev_ioctl_data_resolve(u.urb, offsetof(struct usbdevfs_urb, buffer),
                                            (gsize)r->buffer_length, &err);
        if (!u.buf) {
            umockdev_ioctl_client_complete(c, -1, EFAULT);
            g_clear_error(&err);
            return;
        }
        r = urb_of(&u);
    }
    E.n_urbs++;
    const uint8_t *b = u.buf ? u.buf->data : NULL;
    if (r->type == USBDEVFS_URB_TYPE_CONTROL) {
        psu_setup_t s;
        if (!b || r->buffer_length < (int)sizeof s) {
            umockdev_ioctl_client_complete(c, -1, EINVAL);
            return;
        }
        memcpy(&s, b, sizeof s);
        uint8_t ans[PSU_EP0_BUF_BYTES];
        uint16_t n = 0;
        psu_ctrl_t res = psu_control(&E.dev, &s, ans, sizeof ans, &n);
        if (n > s.wLength)
            n = s.wLength;
        if (n > r->buffer_length - sizeof s)
            n = (uint16_t)(r->buffer_length - sizeof s);
        TRACE("control %02x %02x %04x %04x %u -> %s %u B\n", s.bmRequestType, s.bRequest, s.wValue,
              s.wIndex, s.wLength, res == PSU_CTRL_ACK ? "ack" : "STALL", n);
        if (res == PSU_CTRL_ACK)
            finish(&u, 0, (s.bmRequestType & PSU_RT_DIR_IN) ? n : 0, ans, sizeof s);
        else
            finish(&u, -EPIPE, 0, NULL, 0);
        list_push(&E.done, u);
    } else if (r->type == USBDEVFS_URB_TYPE_BULK && r->endpoint == PSU_EP_OUT) {
        if (E.stalled_out || E.dev.state != PSU_STATE_CONFIGURED) {
            finish(&u, -EPIPE, 0, NULL, 0);
        } else {
            /* Packets of at most 64 B, each ending the core's armed transfer, as the OTG
             * core reports an OUT transfer that a short or full packet ended. */
            int off = 0;
            while (off < r->buffer_length && E.out_buf) {
                uint16_t k = (uint16_t)(r->buffer_length - off);
                if (k > PSU_BULK_MPS)
                    k = PSU_BULK_MPS;
                if (k > E.out_len)
                    k = E.out_len;
                memcpy(E.out_buf, b + off, k);
                E.out_buf = NULL;
                off += k;
                psu_dcd_event_xfer_done(&E.dev, PSU_EP_OUT, k);
            }
            TRACE("bulk OUT %d B\n", off);
            finish(&u, 0, off, NULL, 0);
        }
        list_push(&E.done, u);
    } else if (r->type == USBDEVFS_URB_TYPE_BULK && r->endpoint == PSU_EP_IN) {
        list_push(&E.in_pending, u);
    } else {
        umockdev_ioctl_client_complete(c, -1, EINVAL); /* no such endpoint */
        return;
    }
    umockdev_ioctl_client_complete(c, 0, 0);
}

static void reap(UMockdevIoctlClient *c, UMockdevIoctlData *arg)
{
    GError *err = NULL;
    pump_in();
    urb_list_t *from = E.discarded.n ? &E.discarded : E.done.n ? &E.done : NULL;
    int i = 0;
    if (from) {
        /* Only this client's URBs (a closed client's were dropped in client-vanished). */
        while (i < from->n && from->v[i].client != c)
            i++;
        if (i == from->n)
            from = NULL;
    }
    if (!from) {
        pthread_mutex_lock(&E.mu);
        int eof = E.vb_eof && E.rxq_len == 0;
        pthread_mutex_unlock(&E.mu);
        umockdev_ioctl_client_complete(c, -1, eof && E.in_pending.n == 0 ? ENODEV : EAGAIN);
        return;
    }
    /* REAPURB's argument points at the client's `void *` slot that receives the URB's address. */
    UMockdevIoctlData *slot = umockdev_ioctl_data_resolve(arg, 0, sizeof(void *), &err);
    if (!slot) {
        g_clear_error(&err);
        umockdev_ioctl_client_complete(c, -1, EFAULT);
        return;
    }
    urb_t u = list_pop(from, i);
    umockdev_ioctl_data_set_ptr(slot, 0, u.urb); /* synced back as the client's own address */
    umockdev_ioctl_client_complete(c, 0, 0);
    g_object_unref(slot);
    if (u.buf)
        g_object_unref(u.buf);
    g_object_unref(u.urb);
}

static void discard(UMockdevIoctlClient *c, UMockdevIoctlData *arg)
{
    gulong addr = *(gulong *)arg->data; /* DISCARDURB passes the URB's address itself */
    for (int i = 0; i < E.in_pending.n; i++) {
        if (E.in_pending.v[i].urb->client_addr == addr) {
            urb_t u = list_pop(&E.in_pending, i);
            finish(&u, -ENOENT, 0, NULL, 0);
            list_push(&E.discarded, u);
            umockdev_ioctl_client_complete(c, 0, 0);
            return;
        }
    }
    umockdev_ioctl_client_complete(c, -1, EINVAL); /* already finished: libusb then reaps it */
}

static unsigned uint_arg(UMockdevIoctlData *arg, UMockdevIoctlData **res)
{
    GError *err = NULL;
    *res = umockdev_ioctl_data_resolve(arg, 0, sizeof(unsigned), &err);
    g_clear_error(&err);
    return *res ? *(unsigned *)(*res)->data : ~0u;
}

static void control_sync(UMockdevIoctlClient *c, uint8_t rt, uint8_t req, uint16_t value, uint16_t index)
{
    psu_setup_t s = {.bmRequestType = rt, .bRequest = req, .wValue = value, .wIndex = index};
    uint8_t ans[8];
    uint16_t n;
    psu_ctrl_t r = psu_control(&E.dev, &s, ans, sizeof ans, &n);
    umockdev_ioctl_client_complete(c, r == PSU_CTRL_ACK ? 0 : -1, r == PSU_CTRL_ACK ? 0 : EPIPE);
}

static gboolean on_ioctl(UMockdevIoctlBase *h, UMockdevIoctlClient *c, gpointer ud)
{
    (void)h;
    (void)ud;
    gulong req = umockdev_ioctl_client_get_request(c);
    UMockdevIoctlData *arg = umockdev_ioctl_client_get_arg(c), *d = NULL;
    GError *err = NULL;
    if (req != USBDEVFS_REAPURBNDELAY && req != USBDEVFS_REAPURB && req != USBDEVFS_SUBMITURB)
        TRACE("ioctl %08lx\n", req);
    switch (req) {
    case USBDEVFS_SUBMITURB:
        submit(c, arg);
        return TRUE;
    case USBDEVFS_REAPURB:       /* blocking reap: the client polls again on EAGAIN */
    case USBDEVFS_REAPURBNDELAY:
        reap(c, arg);
        return TRUE;
    case USBDEVFS_DISCARDURB:
        discard(c, arg);
        return TRUE;
    case USBDEVFS_GET_CAPABILITIES: {
        /* One URB per transfer (no 16 KiB split) and ZLP flag support, as a modern xHCI. */
        guint32 caps = USBDEVFS_CAP_ZERO_PACKET | USBDEVFS_CAP_NO_PACKET_SIZE_LIM |
                       USBDEVFS_CAP_BULK_CONTINUATION;
        d = umockdev_ioctl_data_resolve(arg, 0, sizeof caps, &err);
        if (d)
            umockdev_ioctl_data_update(d, 0, (guint8 *)&caps, sizeof caps);
        umockdev_ioctl_client_complete(c, d ? 0 : -1, d ? 0 : EFAULT);
        break;
    }
    case USBDEVFS_CLAIMINTERFACE:
    case USBDEVFS_RELEASEINTERFACE: {
        unsigned iface = uint_arg(arg, &d);
        umockdev_ioctl_client_complete(c, iface == 0 ? 0 : -1, iface == 0 ? 0 : EINVAL);
        break;
    }
    case USBDEVFS_GETDRIVER:     /* vendor interface: no kernel driver bound */
        umockdev_ioctl_client_complete(c, -1, ENODATA);
        break;
    case USBDEVFS_SETCONFIGURATION: {
        unsigned v = uint_arg(arg, &d);
        control_sync(c, 0x00, PSU_REQ_SET_CONFIGURATION, (uint16_t)v, 0);
        break;
    }
    case USBDEVFS_SETINTERFACE: {
        d = umockdev_ioctl_data_resolve(arg, 0, sizeof(struct usbdevfs_setinterface), &err);
        struct usbdevfs_setinterface si = {0};
        if (d)
            memcpy(&si, d->data, sizeof si);
        control_sync(c, 0x01, PSU_REQ_SET_INTERFACE, (uint16_t)si.altsetting, (uint16_t)si.interface);
        break;
    }
    case USBDEVFS_CLEAR_HALT: {
        unsigned ep = uint_arg(arg, &d);
        control_sync(c, 0x02, PSU_REQ_CLEAR_FEATURE, 0, (uint16_t)ep);
        break;
    }
    case USBDEVFS_RESETEP:
        umockdev_ioctl_client_complete(c, 0, 0);
        break;
    case USBDEVFS_RESET:         /* the device keeps its configuration: reset re-enumerates it */
        umockdev_ioctl_client_complete(c, 0, 0);
        break;
    case USBDEVFS_CONNECTINFO: {
        struct usbdevfs_connectinfo ci = {.devnum = EMU_DEVNUM, .slow = 0};
        d = umockdev_ioctl_data_resolve(arg, 0, sizeof ci, &err);
        if (d)
            umockdev_ioctl_data_update(d, 0, (guint8 *)&ci, sizeof ci);
        umockdev_ioctl_client_complete(c, d ? 0 : -1, d ? 0 : EFAULT);
        break;
    }
    case USBDEVFS_GET_SPEED:
        umockdev_ioctl_client_complete(c, EMU_USB_SPEED_FULL, 0);
        break;
    default:
        TRACE("unsupported ioctl %08lx\n", req);
        umockdev_ioctl_client_complete(c, -1, ENOTTY);
        break;
    }
    g_clear_error(&err);
    if (d)
        g_object_unref(d);
    return TRUE;
}

static void drop_client(urb_list_t *l, UMockdevIoctlClient *c)
{
    for (int i = 0; i < l->n;)
        if (l->v[i].client == c)
            (void)list_pop(l, i);
        else
            i++;
}

static void on_vanished(UMockdevIoctlBase *h, UMockdevIoctlClient *c, gpointer ud)
{
    (void)h;
    (void)ud;
    drop_client(&E.done, c);
    drop_client(&E.in_pending, c);
    drop_client(&E.discarded, c);
    TRACE("client closed the device (%llu URBs so far)\n", (unsigned long long)E.n_urbs);
}

/* Enumerate the core as the kernel's hub driver would: reset, address, read the device and
 * configuration descriptors (they become the sysfs `descriptors` file), configure. */
static size_t enumerate(uint8_t *desc, size_t cap)
{
    uint16_t n = 0;
    size_t len = 0;
    psu_dcd_event_reset(&E.dev);
    psu_setup_t s = {0x00, PSU_REQ_SET_ADDRESS, EMU_DEVNUM, 0, 0};
    if (psu_control(&E.dev, &s, desc, 0, &n) != PSU_CTRL_ACK)
        return 0;
    s = (psu_setup_t){0x80, PSU_REQ_GET_DESCRIPTOR, PSU_DESC_DEVICE << 8, 0, 18};
    if (psu_control(&E.dev, &s, desc, (uint16_t)cap, &n) != PSU_CTRL_ACK)
        return 0;
    len = n;
    s = (psu_setup_t){0x80, PSU_REQ_GET_DESCRIPTOR, PSU_DESC_CONFIGURATION << 8, 0, 255};
    if (psu_control(&E.dev, &s, desc + len, (uint16_t)(cap - len), &n) != PSU_CTRL_ACK)
        return 0;
    len += n;
    s = (psu_setup_t){0x00, PSU_REQ_SET_CONFIGURATION, PSU_CONFIG_VALUE, 0, 0};
    if (psu_control(&E.dev, &s, desc, 0, &n) != PSU_CTRL_ACK)
        return 0;
    return len;
}

static void string_attr(UMockdevTestbed *tb, const char *sys, const char *name, uint8_t idx)
{
    uint8_t b[PSU_EP0_BUF_BYTES];
    uint16_t n = 0;
    char s[64];
    psu_setup_t q = {0x80, PSU_REQ_GET_DESCRIPTOR, (uint16_t)(PSU_DESC_STRING << 8 | idx), 0x0409, 255};
    if (psu_control(&E.dev, &q, b, sizeof b, &n) != PSU_CTRL_ACK || n < 2)
        return;
    size_t k = 0;
    for (size_t i = 2; i + 1 < n && k + 1 < sizeof s; i += 2)
        s[k++] = (char)b[i];
    s[k] = 0;
    umockdev_testbed_set_attribute(tb, sys, name, s);
}

static void usage(void)
{
    fprintf(stderr, "usage: ps_usbemu [--vboard PATH] [--flash FILE] [--trace] -- COMMAND [ARGS...]\n"
                    "  runs COMMAND with an emulated USB board 1209:0001 (umockdev), backed by ps_vboard\n");
}

int main(int argc, char **argv)
{
    const char *vboard = NULL, *flash = NULL;
    int i = 1;
    for (; i < argc; i++) {
        if (!strcmp(argv[i], "--vboard") && i + 1 < argc)
            vboard = argv[++i];
        else if (!strcmp(argv[i], "--flash") && i + 1 < argc)
            flash = argv[++i];
        else if (!strcmp(argv[i], "--trace"))
            E.trace = 1;
        else if (!strcmp(argv[i], "--")) {
            i++;
            break;
        } else {
            usage();
            return 2;
        }
    }
    if (i >= argc) {
        usage();
        return 2;
    }
    char vb_default[4096];
    if (!vboard) {
        /* ps_vboard is built next to ps_usbemu */
        ssize_t n = readlink("/proc/self/exe", vb_default, sizeof vb_default - 16);
        if (n <= 0)
            return 2;
        vb_default[n] = 0;
        char *slash = strrchr(vb_default, '/');
        strcpy(slash + 1, "ps_vboard");
        vboard = vb_default;
    }
    signal(SIGPIPE, SIG_IGN);

    /* The board process first: it must not inherit the testbed environment. */
    char *vb_argv[] = {(char *)vboard, "--stdio", flash ? "--flash" : NULL, (char *)flash, NULL};
    E.vb_pid = spawn(vb_argv, &E.vb_in, &E.vb_out);
    if (E.vb_pid < 0) {
        perror("ps_vboard");
        return 1;
    }
    pthread_mutex_init(&E.mu, NULL);
    pthread_t reader;
    pthread_create(&reader, NULL, vboard_reader, NULL);

    psu_config_t cfg = {.board_id = {0x454D5520u /* "EMU " */, 0, (uint32_t)E.vb_pid},
                        .bcd_device = 0x0100, .rx = to_vboard};
    psu_init(&E.dev, &cfg);
    psu_dcd_init(&E.dev);
    uint8_t desc[PSU_EP0_BUF_BYTES];
    size_t desc_len = enumerate(desc, sizeof desc);
    if (desc_len == 0) {
        fprintf(stderr, "ps_usbemu: the device core refused enumeration\n");
        return 1;
    }

    UMockdevTestbed *tb = umockdev_testbed_new();
    char devnode[64];
    snprintf(devnode, sizeof devnode, "/dev/bus/usb/%03d/%03d", EMU_BUS, EMU_DEVNUM);
    char busnum[8], devnum[8], product[32];
    snprintf(busnum, sizeof busnum, "%03d", EMU_BUS);
    snprintf(devnum, sizeof devnum, "%03d", EMU_DEVNUM);
    snprintf(product, sizeof product, "%x/%x/%x", PSU_VID, PSU_PID, cfg.bcd_device);
    gchar *sys = umockdev_testbed_add_device(
        tb, "usb", "1-1", NULL,
        /* attributes */
        "busnum", "1\n", "devnum", "2\n", "idVendor", "1209\n", "idProduct", "0001\n", "bcdDevice", "0100\n",
        "bConfigurationValue", "1\n", "bNumConfigurations", "1\n", "bNumInterfaces", " 1\n",
        "bDeviceClass", "00\n", "bMaxPacketSize0", "64\n", "speed", "12\n", "version", " 2.00\n", NULL,
        /* udev properties */
        "DEVNAME", devnode, "DEVTYPE", "usb_device", "BUSNUM", busnum, "DEVNUM", devnum,
        "PRODUCT", product, "ID_VENDOR_ID", "1209", "ID_MODEL_ID", "0001", NULL);
    if (!sys) {
        fprintf(stderr, "ps_usbemu: umockdev could not add the device\n");
        return 1;
    }
    umockdev_testbed_set_attribute_binary(tb, sys, "descriptors", desc, (gint)desc_len);
    /* add_device() records DEVNAME but makes no node (umockdev's text format does, with a
     * plain file for USB); libusb opens the node, so make that file here. */
    gchar *root = umockdev_testbed_get_root_dir(tb);
    gchar *node = g_strconcat(root, devnode, NULL);
    gchar *dir = g_path_get_dirname(node);
    if (g_mkdir_with_parents(dir, 0755) != 0 || !g_file_set_contents(node, "", 0, NULL)) {
        fprintf(stderr, "ps_usbemu: cannot create %s\n", node);
        return 1;
    }
    g_free(dir);
    g_free(node);
    g_free(root);
    string_attr(tb, sys, "manufacturer", 1);
    string_attr(tb, sys, "product", 2);
    string_attr(tb, sys, "serial", 3);

    UMockdevIoctlBase *handler = g_object_new(UMOCKDEV_TYPE_IOCTL_BASE, NULL);
    g_signal_connect(handler, "handle-ioctl", G_CALLBACK(on_ioctl), NULL);
    g_signal_connect(handler, "client-vanished", G_CALLBACK(on_vanished), NULL);
    GError *err = NULL;
    if (!umockdev_testbed_attach_ioctl(tb, devnode, handler, &err)) {
        fprintf(stderr, "ps_usbemu: attach_ioctl: %s\n", err ? err->message : "?");
        return 1;
    }
    TRACE("device %s at %s, testbed %s\n", sys, devnode, umockdev_testbed_get_root_dir(tb));

    /* The command: the testbed already exported UMOCKDEV_DIR into our environment. */
    pid_t child = fork();
    if (child == 0) {
        const char *old = getenv("LD_PRELOAD");
        char pre[1024];
        snprintf(pre, sizeof pre, "libumockdev-preload.so.0%s%s", old ? ":" : "", old ? old : "");
        setenv("LD_PRELOAD", pre, 1);
        execvp(argv[i], &argv[i]);
        perror(argv[i]);
        _exit(127);
    }
    int status = 0;
    while (waitpid(child, &status, 0) < 0 && errno == EINTR)
        ;
    TRACE("command exited, %llu URBs\n", (unsigned long long)E.n_urbs);

    close(E.vb_in);              /* EOF: the board exits and flushes its flash file */
    int vst;
    waitpid(E.vb_pid, &vst, 0);
    pthread_join(reader, NULL);
    umockdev_testbed_detach_ioctl(tb, devnode, NULL);
    g_object_unref(handler);
    g_object_unref(tb);          /* removes the testbed directory */
    g_free(sys);
    if (WIFEXITED(status))
        return WEXITSTATUS(status);
    return 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
}
