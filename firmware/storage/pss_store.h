/* A/B table store: two flash slots, generation counter and CRC; a commit never harms the running table. */
#ifndef PSS_STORE_H
#define PSS_STORE_H

#include <stdbool.h>
#include <stdint.h>
#include "ps_defs.h"

/* Flash port, one per board (STM32F405 sectors 10/11, a file on the desktop, RAM in
 * tests). Slots are erased to 0xFF; program only clears bits, as NOR flash does.
 * Every function returns 0 on success, non-zero when the operation did not complete
 * (the store then treats the slot as garbage). */
typedef struct pss_flash {
    uint32_t slot_size;          /* bytes per slot (erase unit), >= PSS_DATA_OFFSET + the largest record */
    int (*erase)(void *ctx, uint8_t slot);
    int (*program)(void *ctx, uint8_t slot, uint32_t off, const uint8_t *data, uint32_t len);
    int (*read)(void *ctx, uint8_t slot, uint32_t off, uint8_t *out, uint32_t len);
    void *ctx;
} pss_flash_t;

enum {
    PSS_MAGIC = 0x4C535350,      /* bytes "PSSL" */
    PSS_COMMITTED = 0xC0DEC0DE,  /* written last: a slot without it is never used */
    PSS_LAYOUT_VERSION = 1,      /* seeds the record CRC so a store of another layout fails its check */
    PSS_DATA_OFFSET = 32,        /* record data start in a slot; 4-aligned for in-place use */
    PSS_NO_SLOT = 0xFF,
};

/* Slot record header at offset 0; the commit word follows at offset 20. */
typedef struct PS_PACKED pss_record {
    uint32_t magic;              /* PSS_MAGIC */
    uint32_t generation;         /* newer wins at boot; strictly increasing per commit */
    uint32_t size;               /* data bytes at PSS_DATA_OFFSET */
    uint32_t data_crc32;         /* ps_crc32_update(PSS_LAYOUT_VERSION, data, size) */
    uint32_t header_crc32;       /* ps_crc32_update(PSS_LAYOUT_VERSION, the 16 bytes above) */
} pss_record_t;
PS_STATIC_ASSERT(sizeof(pss_record_t) == 20, "pss_record_t must be 20 bytes");
enum { PSS_COMMIT_OFFSET = 20 };

typedef enum {
    PSS_OK = 0,
    PSS_ERR_SIZE,                /* record larger than a slot allows, or empty */
    PSS_ERR_GENERATION,          /* generation not newer than the active one */
    PSS_ERR_ERASE,               /* erase reported failure */
    PSS_ERR_PROGRAM,             /* program reported failure */
    PSS_ERR_VERIFY,              /* read-back differs from what was written */
    PSS_ERR_NO_SLOT,             /* nothing valid to read */
} pss_status_t;

typedef struct {
    bool valid;
    uint32_t generation;
    uint32_t size;
    uint32_t data_crc32;
} pss_slot_info_t;

typedef struct {
    const pss_flash_t *flash;
    pss_slot_info_t slot[2];
    uint8_t active;              /* 0 = A, 1 = B, PSS_NO_SLOT */
} pss_t;

/* Scan both slots and make the newest valid one active. Cost: reads each record once
 * (CRC over its data). Boot time only. */
void pss_mount(pss_t *s, const pss_flash_t *flash);

/* Re-check one slot on flash (header, commit word, data CRC) into s->slot[slot]. */
void pss_scan_slot(pss_t *s, uint8_t slot);

/* Make a valid slot the active one (used when the newest valid record is refused by a
 * higher layer and the board falls back to the other). Returns false if not valid. */
bool pss_select(pss_t *s, uint8_t slot);

/* Write data[0..size) as a record of this generation into the slot that is not active:
 * erase, program data, program header, verify the data CRC on flash, then program the
 * commit word and verify it. Only then does the new slot become active. Any failure
 * leaves the active slot untouched and the written slot unusable. */
pss_status_t pss_commit(pss_t *s, uint32_t generation, const uint8_t *data, uint32_t size);

/* Read size bytes at offset off of the active record's data. */
pss_status_t pss_read_active(const pss_t *s, uint32_t off, uint8_t *out, uint32_t size);

/* Read a record's data from any valid slot. */
pss_status_t pss_read_slot(const pss_t *s, uint8_t slot, uint32_t off, uint8_t *out, uint32_t size);

#endif /* PSS_STORE_H */
