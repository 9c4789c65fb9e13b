/* Frame codec for the wire protocol (ps_proto.h): encoder and byte-stream parser, shared by board and host. */
#ifndef PS_FRAME_H
#define PS_FRAME_H

#include <stddef.h>
#include <stdint.h>
#include "ps_proto.h"

enum {
    PSF_HEADER_SIZE = 8,                                   /* sizeof(psp_frame_header_t) */
    PSF_CRC_SIZE = 4,
    PSF_MAX_FRAME = PSF_HEADER_SIZE + PSP_MAX_PAYLOAD + PSF_CRC_SIZE, /* 260 bytes */
};

/* What the parser reports after consuming input. */
typedef enum {
    PSF_NEED_MORE = 0,           /* no complete frame yet */
    PSF_FRAME = 1,               /* a frame with a valid CRC is in the parser (see psf_parser_t) */
    PSF_BAD_CRC = 2,             /* a whole frame arrived but its CRC is wrong; header fields untrusted */
    PSF_BAD_LENGTH = 3,          /* header announced len > PSP_MAX_PAYLOAD; frame skipped */
} psf_result_t;

/* Parser state. No allocation: one frame buffer inside. After PSF_FRAME the decoded
 * header is in hdr and the payload in buf[PSF_HEADER_SIZE ..]; it stays valid until the
 * next call to psf_parser_push(). The version byte is not checked here: the handler
 * answers PSP_ERR_VERSION with the frame's seq, which needs the frame. */
typedef struct {
    uint8_t buf[PSF_MAX_FRAME];
    uint16_t have;               /* bytes of the current frame in buf */
    uint16_t need;               /* total bytes of the current frame, 0 while the header is incomplete */
    psp_frame_header_t hdr;      /* decoded (little-endian) header of the last frame */
    uint32_t n_frames;           /* good frames seen */
    uint32_t n_dropped_bytes;    /* bytes skipped while hunting for sync */
    uint32_t n_bad_crc;
    uint32_t n_bad_length;
} psf_parser_t;

/* Start hunting for a sync pair; counters are zeroed. */
void psf_parser_reset(psf_parser_t *p);

/* Consume bytes from data[0..len) until a frame completes, an error is found, or the
 * input ends. Returns the number of bytes consumed and stores the outcome in *res;
 * call again with the rest of the input. Resynchronises on the next 'P' 'S' pair
 * after garbage, an oversized length or a CRC error. O(len), no allocation. */
size_t psf_parser_push(psf_parser_t *p, const uint8_t *data, size_t len, psf_result_t *res);

/* Payload of the frame just reported as PSF_FRAME (p->hdr.len bytes). */
const uint8_t *psf_parser_payload(const psf_parser_t *p);

/* Write one frame into out[0..cap): header (sync, PSP_VERSION, type, seq, len), payload,
 * CRC-32 of both. Returns the frame size, or 0 if len > PSP_MAX_PAYLOAD or cap is short. */
size_t psf_encode(uint8_t *out, size_t cap, uint8_t type, uint16_t seq, const void *payload,
                  uint16_t len);

/* Little-endian field helpers: the wire is little-endian whatever the CPU. Hidden from
 * cffi's cdef, which cannot parse function bodies. */
#ifndef PS_CDEF
static inline uint16_t psf_get_u16(const uint8_t *b) { return (uint16_t)(b[0] | (b[1] << 8)); }
static inline uint32_t psf_get_u32(const uint8_t *b)
{
    return (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) | ((uint32_t)b[3] << 24);
}
static inline void psf_put_u16(uint8_t *b, uint16_t v)
{
    b[0] = (uint8_t)v;
    b[1] = (uint8_t)(v >> 8);
}
static inline void psf_put_u32(uint8_t *b, uint32_t v)
{
    b[0] = (uint8_t)v;
    b[1] = (uint8_t)(v >> 8);
    b[2] = (uint8_t)(v >> 16);
    b[3] = (uint8_t)(v >> 24);
}
#endif /* PS_CDEF */

#endif /* PS_FRAME_H */
