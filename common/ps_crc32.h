/* CRC-32 (IEEE 802.3 polynomial, reflected, as zlib's crc32()) for tables and frames. */
#ifndef PS_CRC32_H
#define PS_CRC32_H

#include <stddef.h>
#include <stdint.h>

/* Continue a CRC-32 over len bytes. Same contract as zlib's crc32(crc, buf, len):
 * start with crc = 0 (or a seed such as a layout version), feed pieces in order.
 * Bitwise (no 1 KiB table) because it runs only on uploads and at boot, never per tick. */
uint32_t ps_crc32_update(uint32_t crc, const void *buf, size_t len);

#endif /* PS_CRC32_H */
