/* CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320), bit-at-a-time. */
#include "ps_crc32.h"

uint32_t ps_crc32_update(uint32_t crc, const void *buf, size_t len)
{
    const uint8_t *p = (const uint8_t *)buf;
    crc = ~crc;
    while (len--) {
        crc ^= *p++;
        for (int k = 0; k < 8; k++)
            crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}
