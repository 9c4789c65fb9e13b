/* Frame codec: encoder and resynchronising byte-stream parser for ps_proto.h frames. */
#include "ps_frame.h"

#include <string.h>
#include "ps_crc32.h"

void psf_parser_reset(psf_parser_t *p)
{
    memset(p, 0, sizeof(*p));
}

const uint8_t *psf_parser_payload(const psf_parser_t *p)
{
    return &p->buf[PSF_HEADER_SIZE];
}

/* Drop the first byte of buf and rescan the rest for a sync pair, so a frame that
 * starts inside a corrupted one is not lost. */
static void resync(psf_parser_t *p)
{
    uint16_t i = 1;
    while (i < p->have) {
        if (p->buf[i] == PSP_SYNC0 && (i + 1 == p->have || p->buf[i + 1] == PSP_SYNC1))
            break;
        i++;
    }
    p->n_dropped_bytes += i;
    memmove(p->buf, &p->buf[i], (size_t)(p->have - i));
    p->have = (uint16_t)(p->have - i);
    p->need = 0;
}

/* Examine what is buffered; returns a result other than PSF_NEED_MORE when a frame
 * completes or fails. Rescanned bytes may complete further headers, hence the loop. */
static psf_result_t scan(psf_parser_t *p)
{
    for (;;) {
        if (p->have >= 1 && p->buf[0] != PSP_SYNC0) {
            resync(p);
            continue;
        }
        if (p->have >= 2 && p->buf[1] != PSP_SYNC1) {
            resync(p);
            continue;
        }
        if (p->need == 0) {
            if (p->have < PSF_HEADER_SIZE)
                return PSF_NEED_MORE;
            uint16_t len = psf_get_u16(&p->buf[6]);
            if (len > PSP_MAX_PAYLOAD) {
                p->n_bad_length++;
                p->hdr.type = p->buf[3];
                p->hdr.seq = psf_get_u16(&p->buf[4]);
                p->hdr.len = len;
                resync(p);
                return PSF_BAD_LENGTH;
            }
            p->need = (uint16_t)(PSF_HEADER_SIZE + len + PSF_CRC_SIZE);
        }
        if (p->have < p->need)
            return PSF_NEED_MORE;
        uint16_t body = (uint16_t)(p->need - PSF_CRC_SIZE);
        uint32_t crc = ps_crc32_update(0, p->buf, body);
        p->hdr.sync0 = p->buf[0];
        p->hdr.sync1 = p->buf[1];
        p->hdr.version = p->buf[2];
        p->hdr.type = p->buf[3];
        p->hdr.seq = psf_get_u16(&p->buf[4]);
        p->hdr.len = psf_get_u16(&p->buf[6]);
        if (crc != psf_get_u32(&p->buf[body])) {
            p->n_bad_crc++;
            resync(p);
            return PSF_BAD_CRC;
        }
        p->n_frames++;
        /* Leave the frame in buf for the caller; the next push starts a new one. */
        p->need = 0;
        p->have = 0;
        return PSF_FRAME;
    }
}

size_t psf_parser_push(psf_parser_t *p, const uint8_t *data, size_t len, psf_result_t *res)
{
    size_t used = 0;
    *res = PSF_NEED_MORE;
    /* Bytes left over by a resync may already hold a complete frame. */
    if (p->have > 0) {
        *res = scan(p);
        if (*res != PSF_NEED_MORE)
            return 0;
    }
    while (used < len) {
        /* Copy as much as the current frame can still take, then scan once. */
        size_t room = (p->need ? p->need : PSF_HEADER_SIZE) - p->have;
        if (p->have < 2)
            room = 1;            /* byte by byte while hunting, so garbage costs no copy of a frame */
        if (room > len - used)
            room = len - used;
        memcpy(&p->buf[p->have], &data[used], room);
        p->have = (uint16_t)(p->have + room);
        used += room;
        *res = scan(p);
        if (*res != PSF_NEED_MORE)
            return used;
    }
    return used;
}

size_t psf_encode(uint8_t *out, size_t cap, uint8_t type, uint16_t seq, const void *payload,
                  uint16_t len)
{
    size_t total = (size_t)PSF_HEADER_SIZE + len + PSF_CRC_SIZE;
    if (len > PSP_MAX_PAYLOAD || cap < total || (len > 0 && payload == NULL))
        return 0;
    out[0] = PSP_SYNC0;
    out[1] = PSP_SYNC1;
    out[2] = PSP_VERSION;
    out[3] = type;
    psf_put_u16(&out[4], seq);
    psf_put_u16(&out[6], len);
    if (len > 0)
        memmove(&out[PSF_HEADER_SIZE], payload, len);
    psf_put_u32(&out[PSF_HEADER_SIZE + len], ps_crc32_update(0, out, (size_t)PSF_HEADER_SIZE + len));
    return total;
}
