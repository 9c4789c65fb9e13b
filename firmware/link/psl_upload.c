/* Table upload session: one owner per upload (token, timeout), chunks, commit with read-back, table read. */
#include <string.h>
#include "link/psl_internal.h"
#include "ps_crc32.h"

static uint32_t table_size(const psl_t *l)
{
    if (l->active_buf == PSS_NO_SLOT)
        return 0;
    return l->store.slot[l->store.active].size;
}

enum { CHUNK_HDR = 12 }; /* psp_table_chunk_t bytes before data[] */

static uint8_t upload_buf(const psl_t *l)
{
    return l->active_buf == 0 ? 1 : 0;
}

/* True while an upload session is open and its owner has not been silent for the timeout. */
static bool session_live(const psl_t *l)
{
    return l->up_open && (uint32_t)(l->now_us - l->up_last_us) < l->cfg.upload_timeout_us;
}

/* Check a request's session token: PSP_OK for the live owner, else BUSY (someone else's
 * session is live, detail = whole seconds left) or STATE (no live session). */
static uint16_t session_check(psl_t *l, uint16_t session, uint8_t *detail)
{
    if (!session_live(l)) {
        l->up_open = false;
        return PSP_ERR_STATE;
    }
    if (session != l->up_session) {
        uint32_t left_s = (l->cfg.upload_timeout_us - (uint32_t)(l->now_us - l->up_last_us) + 999999u) / 1000000u;
        *detail = (uint8_t)(left_s > 255u ? 255u : left_s);
        return PSP_ERR_BUSY;
    }
    l->up_last_us = l->now_us;
    return PSP_OK;
}

uint16_t psl_do_table_begin(psl_t *l, uint16_t seq, const uint8_t *pl, uint8_t *detail)
{
    psp_table_begin_t b;
    memcpy(&b, pl, sizeof(b));
    if (b.total_size < sizeof(pst_header_t) || b.total_size > PST_MAX_TABLE_SIZE)
        return PSP_ERR_RANGE;
    if (session_live(l))
        return session_check(l, 0, detail); /* 0 is never a token: BUSY */
    /* Tokens differ from one session to the next and between boots that saw different
     * timing, so a late request of a previous owner is not taken for the current one. */
    l->up_sessions++;
    uint16_t tok = (uint16_t)((l->up_sessions * 0x9E37u) ^ (l->now_us >> 4) ^ (l->last_seq << 3));
    l->up_session = tok ? tok : 1;
    l->up_open = true;
    l->up_last_us = l->now_us;
    l->up_size = b.total_size;
    l->up_crc32 = b.crc32;
    l->up_have = 0;
    psp_table_session_t r = {.session = l->up_session, .timeout_ms = l->cfg.upload_timeout_us / 1000u};
    psl_send(l, PSP_MSG_TABLE_BEGIN | PSP_RESPONSE, seq, &r, sizeof(r));
    return PSP_OK;
}

uint16_t psl_do_table_abort(psl_t *l, uint16_t seq, const uint8_t *pl, uint8_t *detail)
{
    psp_table_abort_t a;
    memcpy(&a, pl, sizeof(a));
    uint16_t err = session_check(l, a.session, detail);
    if (err != PSP_OK)
        return err;
    l->up_open = false;
    psl_send(l, PSP_MSG_TABLE_ABORT | PSP_RESPONSE, seq, NULL, 0);
    return PSP_OK;
}

uint16_t psl_do_table_chunk(psl_t *l, uint16_t seq, const uint8_t *pl, uint16_t len, uint8_t *detail)
{
    if (len < CHUNK_HDR)
        return PSP_ERR_LENGTH;
    uint32_t off = psf_get_u32(&pl[0]);
    uint16_t n = psf_get_u16(&pl[4]);
    uint16_t session = psf_get_u16(&pl[6]);
    uint32_t crc = psf_get_u32(&pl[8]);
    if (n > PSP_CHUNK_MAX || len != CHUNK_HDR + n)
        return PSP_ERR_LENGTH;
    uint16_t err = session_check(l, session, detail);
    if (err != PSP_OK)
        return err;
    /* Chunks may repeat or overlap what came before but must not leave a hole. */
    if (off > l->up_have || off > l->up_size || n > l->up_size - off)
        return PSP_ERR_RANGE;
    if (ps_crc32_update(0, &pl[CHUNK_HDR], n) != crc)
        return PSP_ERR_CRC;
    memcpy((uint8_t *)l->tables[upload_buf(l)] + off, &pl[CHUNK_HDR], n);
    if (off + n > l->up_have)
        l->up_have = off + n;
    psl_send(l, PSP_MSG_TABLE_CHUNK | PSP_RESPONSE, seq, NULL, 0);
    return PSP_OK;
}

/* Read the just-committed slot back over the upload buffer and check the table CRC on what
 * the board will boot (the store's own CRC covers the record; this one is the table's,
 * end to end from the host's file). calib_load already read this buffer, so on success
 * cal[nb] stays valid over identical bytes. */
static bool slot_holds_upload(psl_t *l, uint8_t nb)
{
    uint8_t *buf = (uint8_t *)l->tables[nb];
    if (pss_read_active(&l->store, 0, buf, l->up_size) != PSS_OK)
        return false;
    return calib_table_crc(buf, l->up_size) == l->up_crc32 && psf_get_u32(buf + offsetof(pst_header_t, crc32)) == l->up_crc32;
}

uint16_t psl_do_table_commit(psl_t *l, uint16_t seq, const uint8_t *pl, uint8_t *detail)
{
    psp_table_commit_t c;
    memcpy(&c, pl, sizeof(c));
    uint16_t err = session_check(l, c.session, detail);
    if (err != PSP_OK)
        return err;
    /* Not during an excitation (its trajectory spans the running table's range); during
     * compensation the loop swaps tables without stopping (psa_set_table: a host refresh of
     * f_remain, an offset or B during use). */
    if (l->mode == PSP_MODE_EXCITATION || l->up_have != l->up_size)
        return PSP_ERR_STATE;
    /* From here the upload is consumed, taken or refused: the session closes, and a host
     * that wants to try again uploads anew (a STATE refusal above keeps it, to commit later). */
    l->up_open = false;
    uint8_t nb = upload_buf(l);
    const uint8_t *blob = psl_table_bytes(l, nb);
    if (c.crc32 != l->up_crc32 || calib_table_crc(blob, l->up_size) != l->up_crc32)
        return PSP_ERR_CRC;
    /* The board's own limits bind every table (psl_config_t.limits): its instrument, unit,
     * travel, angle range and largest play, whatever the table says. */
    calib_status_t st = calib_load_guarded(&l->cal[nb], blob, l->up_size, &l->cfg.limits, NULL);
    if (st != CALIB_OK) {
        *detail = (uint8_t)st;
        return PSP_ERR_TABLE;
    }
    uint32_t gen = l->cal[nb].generation;
    if (!pst_generation_ok(psl_have_table(l), psl_have_table(l) ? l->cal[l->active_buf].generation : 0u, gen)) {
        *detail = PSL_DETAIL_GENERATION;
        return PSP_ERR_TABLE;
    }
    uint8_t prev_slot = l->store.active;
    pss_status_t ps = pss_commit(&l->store, gen, blob, l->up_size);
    if (ps != PSS_OK) {
        *detail = (uint8_t)ps;
        return PSP_ERR_FLASH;
    }
    if (!slot_holds_upload(l, nb)) {
        /* What flash holds is not the table that was checked: unmake the commit so neither
         * this session nor the next boot runs it, and keep the previous table. */
        uint8_t bad = l->store.active;
        (void)l->store.flash->erase(l->store.flash->ctx, bad);
        pss_scan_slot(&l->store, bad);
        if (prev_slot == PSS_NO_SLOT || !pss_select(&l->store, prev_slot))
            l->store.active = PSS_NO_SLOT;
        *detail = PSL_DETAIL_READBACK;
        return PSP_ERR_FLASH;
    }
    /* Learning carries over to the new table (psl_learn.c). */
    psl_learn_rebind(l, nb);
    l->active_buf = nb;
    (void)psa_set_table(&l->loop, &l->cal[nb]); /* not in excitation (checked above): always taken */
    psp_info_t info;
    psl_info(l, &info);
    psl_send(l, PSP_MSG_TABLE_COMMIT | PSP_RESPONSE, seq, &info, sizeof(info));
    return PSP_OK;
}

uint16_t psl_do_table_read(psl_t *l, uint16_t seq, const uint8_t *pl)
{
    psp_table_read_t r;
    memcpy(&r, pl, sizeof(r));
    if (!psl_have_table(l))
        return PSP_ERR_STATE;
    uint32_t size = table_size(l);
    if (r.len > PSP_CHUNK_MAX || r.offset > size)
        return PSP_ERR_RANGE;
    uint16_t n = (uint16_t)(size - r.offset < r.len ? size - r.offset : r.len);
    psp_table_chunk_t ch;
    ch.offset = r.offset;
    ch.len = n;
    ch.session = 0;
    /* Read back from flash, not from RAM: the host checks what the board will boot. */
    if (pss_read_active(&l->store, r.offset, ch.data, n) != PSS_OK)
        return PSP_ERR_FLASH;
    ch.chunk_crc32 = ps_crc32_update(0, ch.data, n);
    psl_send(l, PSP_MSG_TABLE_READ | PSP_RESPONSE, seq, &ch, (uint16_t)(CHUNK_HDR + n));
    return PSP_OK;
}

