/* A/B table store: commit writes the inactive slot, verifies it, then commits it with a final word. */
#include "storage/pss_store.h"

#include <string.h>
#include "ps_crc32.h"

enum { PSS_IO_CHUNK = 64 }; /* bytes read per step when checking a CRC: bounded stack, no heap */

static void put_u32(uint8_t *b, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        b[i] = (uint8_t)(v >> (8 * i));
}

static uint32_t get_u32(const uint8_t *b)
{
    return (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) | ((uint32_t)b[3] << 24);
}

/* CRC of size data bytes of a slot, read from flash in pieces; false on a read error. */
static bool flash_crc(const pss_t *s, uint8_t slot, uint32_t size, uint32_t *crc)
{
    uint8_t tmp[PSS_IO_CHUNK];
    uint32_t c = PSS_LAYOUT_VERSION;
    for (uint32_t off = 0; off < size;) {
        uint32_t n = size - off < PSS_IO_CHUNK ? size - off : PSS_IO_CHUNK;
        if (s->flash->read(s->flash->ctx, slot, PSS_DATA_OFFSET + off, tmp, n) != 0)
            return false;
        c = ps_crc32_update(c, tmp, n);
        off += n;
    }
    *crc = c;
    return true;
}

void pss_scan_slot(pss_t *s, uint8_t slot)
{
    pss_slot_info_t *si = &s->slot[slot];
    uint8_t hdr[PSS_DATA_OFFSET];
    memset(si, 0, sizeof(*si));
    if (s->flash->read(s->flash->ctx, slot, 0, hdr, sizeof(hdr)) != 0)
        return;
    if (get_u32(&hdr[0]) != PSS_MAGIC || get_u32(&hdr[PSS_COMMIT_OFFSET]) != PSS_COMMITTED)
        return;
    if (ps_crc32_update(PSS_LAYOUT_VERSION, hdr, 16) != get_u32(&hdr[16]))
        return;
    uint32_t size = get_u32(&hdr[8]);
    if (size == 0 || size > s->flash->slot_size - PSS_DATA_OFFSET)
        return;
    uint32_t crc;
    if (!flash_crc(s, slot, size, &crc) || crc != get_u32(&hdr[12]))
        return;
    si->valid = true;
    si->generation = get_u32(&hdr[4]);
    si->size = size;
    si->data_crc32 = crc;
}

void pss_mount(pss_t *s, const pss_flash_t *flash)
{
    memset(s, 0, sizeof(*s));
    s->flash = flash;
    s->active = PSS_NO_SLOT;
    pss_scan_slot(s, 0);
    pss_scan_slot(s, 1);
    if (s->slot[0].valid && (!s->slot[1].valid || s->slot[0].generation >= s->slot[1].generation))
        s->active = 0;
    else if (s->slot[1].valid)
        s->active = 1;
}

bool pss_select(pss_t *s, uint8_t slot)
{
    if (slot > 1 || !s->slot[slot].valid)
        return false;
    s->active = slot;
    return true;
}

pss_status_t pss_commit(pss_t *s, uint32_t generation, const uint8_t *data, uint32_t size)
{
    const pss_flash_t *f = s->flash;
    if (size == 0 || size > f->slot_size - PSS_DATA_OFFSET)
        return PSS_ERR_SIZE;
    if (s->active != PSS_NO_SLOT && generation <= s->slot[s->active].generation)
        return PSS_ERR_GENERATION;
    /* The slot that is not running; with none running, A. */
    uint8_t dst = s->active == 0 ? 1 : 0;
    /* From here on dst is garbage until the commit word lands. */
    s->slot[dst].valid = false;
    if (f->erase(f->ctx, dst) != 0)
        return PSS_ERR_ERASE;
    if (f->program(f->ctx, dst, PSS_DATA_OFFSET, data, size) != 0)
        return PSS_ERR_PROGRAM;
    uint8_t hdr[20];
    uint32_t data_crc = ps_crc32_update(PSS_LAYOUT_VERSION, data, size);
    put_u32(&hdr[0], PSS_MAGIC);
    put_u32(&hdr[4], generation);
    put_u32(&hdr[8], size);
    put_u32(&hdr[12], data_crc);
    put_u32(&hdr[16], ps_crc32_update(PSS_LAYOUT_VERSION, hdr, 16));
    if (f->program(f->ctx, dst, 0, hdr, sizeof(hdr)) != 0)
        return PSS_ERR_PROGRAM;
    /* Verify what flash holds, not what we meant to write, before committing. */
    uint32_t crc;
    if (!flash_crc(s, dst, size, &crc) || crc != data_crc)
        return PSS_ERR_VERIFY;
    uint8_t word[4];
    put_u32(word, PSS_COMMITTED);
    if (f->program(f->ctx, dst, PSS_COMMIT_OFFSET, word, sizeof(word)) != 0)
        return PSS_ERR_PROGRAM;
    pss_scan_slot(s, dst);
    if (!s->slot[dst].valid || s->slot[dst].generation != generation)
        return PSS_ERR_VERIFY;
    s->active = dst;
    return PSS_OK;
}

pss_status_t pss_read_slot(const pss_t *s, uint8_t slot, uint32_t off, uint8_t *out, uint32_t size)
{
    if (slot > 1 || !s->slot[slot].valid)
        return PSS_ERR_NO_SLOT;
    if (off > s->slot[slot].size || size > s->slot[slot].size - off)
        return PSS_ERR_SIZE;
    if (s->flash->read(s->flash->ctx, slot, PSS_DATA_OFFSET + off, out, size) != 0)
        return PSS_ERR_VERIFY;
    return PSS_OK;
}

pss_status_t pss_read_active(const pss_t *s, uint32_t off, uint8_t *out, uint32_t size)
{
    if (s->active == PSS_NO_SLOT)
        return PSS_ERR_NO_SLOT;
    return pss_read_slot(s, s->active, off, out, size);
}
