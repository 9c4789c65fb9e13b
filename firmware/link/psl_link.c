/* Board-side protocol handler: every request is checked (version, type, length, seq) before it acts. */
#include "psl_link.h"

#include <string.h>
#include "lut.h"
#include "ps_fixed.h"
#include "ps_crc32.h"

PS_STATIC_ASSERT((int)PSA_MODE_IDLE == (int)PSP_MODE_IDLE && (int)PSA_MODE_EXCITATION == (int)PSP_MODE_EXCITATION &&
                     (int)PSA_MODE_COMPENSATION == (int)PSP_MODE_COMPENSATION &&
                     (int)PSA_MODE_PASSTHROUGH == (int)PSP_MODE_PASSTHROUGH,
                 "psa_mode_t carries the wire's mode values");

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "payload structs are copied as-is: the wire is little-endian"
#endif

psl_config_t psl_default_config(uint32_t tick_hz)
{
    psl_config_t c;
    memset(&c, 0, sizeof(c));
    c.fw_version = (0u << 16) | (1u << 8) | 0u;
    c.exc.q_start_q16 = 0;
    c.exc.q_end_q16 = 10 * PS_Q16_ONE;
    c.exc.amplitude_q16 = PS_Q16_ONE;
    c.exc.advance_q16 = PS_Q16_ONE / 4;
    /* 10 units/s as Q32.32 per tick; init time, so the divide is fine. */
    c.exc.v_q32 = (int64_t)(((uint64_t)10 << 32) / (tick_hz ? tick_hz : 1000u));
    c.exc.return_sweep = true;
    c.onset = onset_default_config();
    c.upload_timeout_us = PSL_UPLOAD_TIMEOUT_US;
    return c;
}

static void send(psl_t *l, uint8_t type, uint16_t seq, const void *payload, uint16_t len)
{
    size_t n = psf_encode(l->tx, sizeof(l->tx), type, seq, payload, len);
    if (n > 0 && l->write)
        l->write(l->write_ctx, l->tx, n);
}

static void send_error(psl_t *l, uint16_t seq, uint8_t ref_type, uint16_t code, uint8_t detail)
{
    psp_error_t e = {.code = code, .ref_type = ref_type, .detail = detail};
    send(l, PSP_MSG_ERROR, seq, &e, sizeof(e));
}

static const uint8_t *table_bytes(const psl_t *l, uint8_t buf)
{
    return (const uint8_t *)l->tables[buf];
}

static uint32_t table_size(const psl_t *l)
{
    if (l->active_buf == PSS_NO_SLOT)
        return 0;
    return l->store.slot[l->store.active].size;
}

void psl_info(const psl_t *l, psp_info_t *info)
{
    memset(info, 0, sizeof(*info));
    info->fw_version = l->cfg.fw_version;
    info->proto_version = PSP_VERSION;
    info->table_layout_version = PST_LAYOUT_VERSION;
    memcpy(info->board_id, l->cfg.board_id, sizeof(info->board_id));
    if (l->active_buf != PSS_NO_SLOT) {
        info->active_generation = l->cal[l->active_buf].generation;
        info->active_crc32 = l->cal[l->active_buf].crc32;
        info->active_slot = l->store.active;
    } else {
        info->active_slot = PSS_NO_SLOT;
    }
    info->mode = l->mode;
    /* last_seq carries the last accepted seq so a host that (re)connects can continue
     * above it without being refused as a replay (docs/protocol.md). */
    info->last_seq = l->last_seq;
}

/* Load slot into tables[buf] and cal[buf]; true if the loader accepted it. */
static bool load_slot(psl_t *l, uint8_t slot, uint8_t buf)
{
    uint32_t size = l->store.slot[slot].size;
    if (size > PST_MAX_TABLE_SIZE)
        return false;
    if (pss_read_slot(&l->store, slot, 0, (uint8_t *)l->tables[buf], size) != PSS_OK)
        return false;
    return calib_load(&l->cal[buf], table_bytes(l, buf), size) == CALIB_OK;
}

void psl_init(psl_t *l, const psl_config_t *cfg, const pss_flash_t *flash, psl_write_fn write,
              void *write_ctx)
{
    memset(l, 0, sizeof(*l));
    l->cfg = *cfg;
    l->write = write;
    l->write_ctx = write_ctx;
    psf_parser_reset(&l->parser);
    psa_config_t lc = {.onset = l->cfg.onset, .exc = l->cfg.exc, .smooth = false};
    psa_init(&l->loop, &lc);
    l->mode = PSP_MODE_IDLE;
    l->active_buf = PSS_NO_SLOT;
    pss_mount(&l->store, flash);
    if (l->store.active != PSS_NO_SLOT) {
        uint8_t first = l->store.active;
        if (load_slot(l, first, 0)) {
            l->active_buf = 0;
        } else if (pss_select(&l->store, (uint8_t)(1 - first)) && load_slot(l, l->store.active, 0)) {
            /* The newest record is intact but refused by this firmware's loader: run the older. */
            l->active_buf = 0;
        } else {
            l->store.active = PSS_NO_SLOT;
        }
    }
    if (l->active_buf != PSS_NO_SLOT)
        (void)psa_set_table(&l->loop, &l->cal[l->active_buf]);
}

/* Expected payload length for a request type, or -1 if the type is unknown.
 * TABLE_CHUNK is variable (12 + data bytes) and checked by its handler. */
static int expected_len(uint8_t type)
{
    switch (type) {
    case PSP_MSG_INFO: return 0;
    case PSP_MSG_SET_MODE: return (int)sizeof(psp_set_mode_t);
    case PSP_MSG_TABLE_BEGIN: return (int)sizeof(psp_table_begin_t);
    case PSP_MSG_TABLE_CHUNK: return -2;
    case PSP_MSG_TABLE_COMMIT: return (int)sizeof(psp_table_commit_t);
    case PSP_MSG_TABLE_READ: return (int)sizeof(psp_table_read_t);
    case PSP_MSG_TABLE_ABORT: return (int)sizeof(psp_table_abort_t);
    case PSP_MSG_ENC_STREAM: return (int)sizeof(psp_stream_ctl_t);
    case PSP_MSG_REVERSAL: return (int)sizeof(psp_reversal_t);
    case PSP_MSG_MARKER_OBS: return (int)sizeof(psp_marker_obs_t);
    case PSP_MSG_COMP_STEP: return (int)sizeof(psp_comp_req_t);
    case PSP_MSG_LEARN: return (int)sizeof(psp_learn_ctl_t);
    default: return -1;
    }
}

enum { CHUNK_HDR = 12 }; /* psp_table_chunk_t bytes before data[] */

static void b_sample_from(const onset_event_t *ev, psp_b_sample_t *b)
{
    memset(b, 0, sizeof(*b));
    b->reason = (uint8_t)ev->reason;
    b->t1_us = ev->t1_us;
    b->t2_us = ev->t2_us;
    b->q1_q16 = ev->q1_q16;
    b->q2_q16 = ev->q2_q16;
    b->q_mean_q16 = ev->q_mean_q16;
    b->b_q16 = ev->b_q16;
}

/* An onset outcome not tied to a request: sent with seq 0, which requests never use. */
static void send_event(psl_t *l, const onset_event_t *ev)
{
    psp_b_sample_t b;
    b_sample_from(ev, &b);
    l->n_b_events++;
    send(l, PSP_MSG_MARKER_OBS | PSP_RESPONSE, 0, &b, sizeof(b));
}

static bool have_table(const psl_t *l)
{
    return l->active_buf != PSS_NO_SLOT;
}

/* Returns a psp_error_code; on PSP_OK the answer has been sent. */
static uint16_t do_set_mode(psl_t *l, uint16_t seq, const uint8_t *pl, uint8_t *detail)
{
    psp_set_mode_t m;
    memcpy(&m, pl, sizeof(m));
    (void)detail;
    if (m.mode > PSP_MODE_PASSTHROUGH)
        return PSP_ERR_RANGE;
    if (!psa_set_mode(&l->loop, (psa_mode_t)m.mode))
        return PSP_ERR_STATE;
    l->mode = m.mode;
    send(l, PSP_MSG_SET_MODE | PSP_RESPONSE, seq, NULL, 0);
    return PSP_OK;
}

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

static uint16_t do_table_begin(psl_t *l, uint16_t seq, const uint8_t *pl, uint8_t *detail)
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
    send(l, PSP_MSG_TABLE_BEGIN | PSP_RESPONSE, seq, &r, sizeof(r));
    return PSP_OK;
}

static uint16_t do_table_abort(psl_t *l, uint16_t seq, const uint8_t *pl, uint8_t *detail)
{
    psp_table_abort_t a;
    memcpy(&a, pl, sizeof(a));
    uint16_t err = session_check(l, a.session, detail);
    if (err != PSP_OK)
        return err;
    l->up_open = false;
    send(l, PSP_MSG_TABLE_ABORT | PSP_RESPONSE, seq, NULL, 0);
    return PSP_OK;
}

static uint16_t do_table_chunk(psl_t *l, uint16_t seq, const uint8_t *pl, uint16_t len, uint8_t *detail)
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
    send(l, PSP_MSG_TABLE_CHUNK | PSP_RESPONSE, seq, NULL, 0);
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

static uint16_t do_table_commit(psl_t *l, uint16_t seq, const uint8_t *pl, uint8_t *detail)
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
    const uint8_t *blob = table_bytes(l, nb);
    if (c.crc32 != l->up_crc32 || calib_table_crc(blob, l->up_size) != l->up_crc32)
        return PSP_ERR_CRC;
    calib_status_t st = calib_load(&l->cal[nb], blob, l->up_size);
    if (st != CALIB_OK) {
        *detail = (uint8_t)st;
        return PSP_ERR_TABLE;
    }
    uint32_t gen = l->cal[nb].generation;
    if (have_table(l) && gen <= l->cal[l->active_buf].generation) {
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
    /* Learning carries over: the new table's B becomes the learner's prior (the host flashes
     * what the board learnt, docs/online.md), or, on another grid, learning restarts on it. */
    if (l->learn_on && b_online_rebind(&l->learn, &l->cal[nb].b) != B_ONLINE_OK) {
        b_online_config_t lc = b_online_default_config();
        if (b_online_init(&l->learn, &lc, &l->cal[nb].b) != B_ONLINE_OK) {
            l->learn_on = false;
            l->learn_count = 0;
        }
    }
    l->active_buf = nb;
    (void)psa_set_table(&l->loop, &l->cal[nb]); /* not in excitation (checked above): always taken */
    psp_info_t info;
    psl_info(l, &info);
    send(l, PSP_MSG_TABLE_COMMIT | PSP_RESPONSE, seq, &info, sizeof(info));
    return PSP_OK;
}

static uint16_t do_table_read(psl_t *l, uint16_t seq, const uint8_t *pl)
{
    psp_table_read_t r;
    memcpy(&r, pl, sizeof(r));
    if (!have_table(l))
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
    send(l, PSP_MSG_TABLE_READ | PSP_RESPONSE, seq, &ch, (uint16_t)(CHUNK_HDR + n));
    return PSP_OK;
}

static uint16_t do_stream(psl_t *l, uint16_t seq, const uint8_t *pl)
{
    psp_stream_ctl_t s;
    memcpy(&s, pl, sizeof(s));
    if (s.enable > 1 || (s.enable && s.decimation == 0))
        return PSP_ERR_RANGE;
    l->stream_on = s.enable != 0;
    l->stream_decim = s.decimation;
    l->stream_left = 1;
    l->batch.count = 0;
    send(l, PSP_MSG_ENC_STREAM | PSP_RESPONSE, seq, NULL, 0);
    return PSP_OK;
}

static uint16_t do_reversal(psl_t *l, uint16_t seq, const uint8_t *pl)
{
    psp_reversal_t r;
    onset_event_t ev;
    memcpy(&r, pl, sizeof(r));
    if (psa_reversal(&l->loop, r.t1_us, r.q1_q16, &ev)) {
        psp_b_sample_t b;
        b_sample_from(&ev, &b);
        send(l, PSP_MSG_REVERSAL | PSP_RESPONSE, seq, &b, sizeof(b));
    } else {
        send(l, PSP_MSG_REVERSAL | PSP_RESPONSE, seq, NULL, 0);
    }
    return PSP_OK;
}

/* ------------------------------------------------------------------ on-line B update */
/* A completed B sample waits for psl_background; the oldest is kept when the queue is full
 * (the learner sees the samples in the order the host was told them). */
static void learn_enqueue(psl_t *l, const onset_event_t *ev)
{
    l->learn_queued++;
    if (l->learn_count == PSL_LEARN_QUEUE) {
        l->learn_dropped++;
        return;
    }
    uint8_t i = (uint8_t)((l->learn_head + l->learn_count) % PSL_LEARN_QUEUE);
    l->learn_q[i][0] = ev->q_mean_q16;
    l->learn_q[i][1] = ev->b_q16;
    l->learn_count++;
}

static void learn_stop(psl_t *l)
{
    if (l->learn_on) {
        b_online_stop(&l->learn);
        psa_b_changed(&l->loop);
    }
    l->learn_on = false;
    l->learn_count = 0;
}

/* Start on the running table's B (already running it: the published copy equals the flashed
 * entries, so the compensator sees no change). */
static bool learn_start(psl_t *l)
{
    learn_stop(l);
    b_online_config_t c = b_online_default_config();
    if (!have_table(l) || b_online_init(&l->learn, &c, &l->cal[l->active_buf].b) != B_ONLINE_OK)
        return false;
    psa_b_changed(&l->loop);
    l->learn_on = true;
    l->learn_head = 0;
    l->learn_queued = 0;
    l->learn_dropped = 0;
    return true;
}

bool psl_background(psl_t *l)
{
    if (!l->learn_on || l->learn_count == 0)
        return false;
    const int32_t *s = l->learn_q[l->learn_head];
    b_online_sample(&l->learn, s[0], s[1]);
    psa_b_changed(&l->loop);
    l->learn_head = (uint8_t)((l->learn_head + 1u) % PSL_LEARN_QUEUE);
    l->learn_count--;
    return true;
}

void psl_learn_state(const psl_t *l, psp_learn_state_t *st)
{
    memset(st, 0, sizeof(*st));
    st->queued = l->learn_queued;
    st->dropped = l->learn_dropped;
    st->on = l->learn_on ? 1u : 0u;
    if (l->learn_on) {
        st->samples = l->learn.samples;
        st->n_grid = l->learn.n_grid;
        st->n_nodes = l->learn.n_nodes;
        st->b_crc32 = ps_crc32_update(0, (const uint8_t *)b_online_entries(&l->learn),
                                      (size_t)l->learn.n_grid * sizeof(int32_t));
    }
}

static uint16_t do_learn(psl_t *l, uint16_t seq, const uint8_t *pl)
{
    psp_learn_ctl_t c;
    memcpy(&c, pl, sizeof(c));
    if (c.op > PSP_LEARN_STOP)
        return PSP_ERR_RANGE;
    if (c.op == PSP_LEARN_START && !learn_start(l))
        return PSP_ERR_STATE; /* no table (or a grid the learner cannot take) */
    if (c.op == PSP_LEARN_STOP)
        learn_stop(l);
    psp_learn_state_t st;
    psl_learn_state(l, &st);
    send(l, PSP_MSG_LEARN | PSP_RESPONSE, seq, &st, sizeof(st));
    return PSP_OK;
}

static uint16_t do_marker(psl_t *l, uint16_t seq, const uint8_t *pl)
{
    psp_marker_obs_t m;
    onset_event_t ev;
    bool done;
    memcpy(&m, pl, sizeof(m));
    if (m.kind > 1 || m.valid > 1)
        return PSP_ERR_RANGE;
    if (m.kind == 0)
        done = psa_observe_px(&l->loop, m.t_us, m.u_q16, m.v_q16, m.valid != 0, &ev);
    else
        done = psa_observe_deg(&l->loop, m.t_us, m.u_q16, m.valid != 0, &ev);
    if (done) {
        if (l->learn_on && (ev.reason == ONSET_OK || ev.reason == ONSET_OK_COARSE))
            learn_enqueue(l, &ev);
        psp_b_sample_t b;
        b_sample_from(&ev, &b);
        send(l, PSP_MSG_MARKER_OBS | PSP_RESPONSE, seq, &b, sizeof(b));
    } else {
        send(l, PSP_MSG_MARKER_OBS | PSP_RESPONSE, seq, NULL, 0);
    }
    return PSP_OK;
}

static uint16_t do_comp(psl_t *l, uint16_t seq, const uint8_t *pl)
{
    psp_comp_req_t r;
    psp_comp_resp_t a;
    memcpy(&r, pl, sizeof(r));
    if (!have_table(l))
        return PSP_ERR_STATE;
    /* The step runs now, so the answer is what a host replaying comp_reset/comp_step
     * computes; the ticks after it hold this c*. */
    a.q_ref_q16 = psa_set_reference(&l->loop, r.c_ref_q16);
    if (a.q_ref_q16 == INT32_MIN)
        return PSP_ERR_STATE;
    send(l, PSP_MSG_COMP_STEP | PSP_RESPONSE, seq, &a, sizeof(a));
    return PSP_OK;
}

/* Serial-number comparison (RFC 1982 style): seq is newer than last within half the space. */
static bool seq_newer(uint16_t seq, uint16_t last)
{
    uint16_t d = (uint16_t)(seq - last);
    return d != 0 && d < 0x8000u;
}

void psl_handle(psl_t *l, const psp_frame_header_t *hdr, const uint8_t *payload)
{
    uint8_t type = hdr->type;
    uint16_t seq = hdr->seq;
    uint8_t detail = 0;
    uint16_t err;
    if (hdr->version != PSP_VERSION) {
        send_error(l, seq, type, PSP_ERR_VERSION, PSP_VERSION);
        return;
    }
    int want = expected_len(type);
    if (want == -1) {
        send_error(l, seq, type, PSP_ERR_TYPE, 0);
        return;
    }
    if (want >= 0 && hdr->len != (uint16_t)want) {
        send_error(l, seq, type, PSP_ERR_LENGTH, 0);
        return;
    }
    if (type == PSP_MSG_INFO) {
        /* Read-only, so exempt from the replay check: it is how a host learns last_seq. */
        psp_info_t info;
        psl_info(l, &info);
        send(l, PSP_MSG_INFO | PSP_RESPONSE, seq, &info, sizeof(info));
        return;
    }
    if (seq == 0 || !seq_newer(seq, l->last_seq)) {
        send_error(l, seq, type, PSP_ERR_SEQ, 0);
        return;
    }
    switch (type) {
    case PSP_MSG_SET_MODE: err = do_set_mode(l, seq, payload, &detail); break;
    case PSP_MSG_TABLE_BEGIN: err = do_table_begin(l, seq, payload, &detail); break;
    case PSP_MSG_TABLE_CHUNK: err = do_table_chunk(l, seq, payload, hdr->len, &detail); break;
    case PSP_MSG_TABLE_COMMIT: err = do_table_commit(l, seq, payload, &detail); break;
    case PSP_MSG_TABLE_READ: err = do_table_read(l, seq, payload); break;
    case PSP_MSG_TABLE_ABORT: err = do_table_abort(l, seq, payload, &detail); break;
    case PSP_MSG_ENC_STREAM: err = do_stream(l, seq, payload); break;
    case PSP_MSG_REVERSAL: err = do_reversal(l, seq, payload); break;
    case PSP_MSG_MARKER_OBS: err = do_marker(l, seq, payload); break;
    case PSP_MSG_COMP_STEP: err = do_comp(l, seq, payload); break;
    case PSP_MSG_LEARN: err = do_learn(l, seq, payload); break;
    default: err = PSP_ERR_TYPE; break;
    }
    if (err != PSP_OK) {
        send_error(l, seq, type, err, detail);
        return;
    }
    /* Only a request that took effect moves the window: a refused one changes nothing. */
    l->last_seq = seq;
}

void psl_rx(psl_t *l, const uint8_t *data, size_t len)
{
    while (len > 0) {
        psf_result_t res;
        size_t used = psf_parser_push(&l->parser, data, len, &res);
        data += used;
        len -= used;
        if (res == PSF_FRAME)
            psl_handle(l, &l->parser.hdr, psf_parser_payload(&l->parser));
        else if (res == PSF_BAD_CRC)
            send_error(l, l->parser.hdr.seq, l->parser.hdr.type, PSP_ERR_CRC, 0);
        else if (res == PSF_BAD_LENGTH)
            send_error(l, l->parser.hdr.seq, l->parser.hdr.type, PSP_ERR_LENGTH, 0);
        else if (used == 0)
            break;
    }
}

int32_t psl_tick(psl_t *l, uint32_t t_us, int32_t q_meas_q16)
{
    onset_event_t ev;
    bool ev_ready;
    l->now_us = t_us;
    int32_t q_ref_q16 = psa_tick(&l->loop, t_us, l->loop.c_ref_q16, q_meas_q16, &ev, &ev_ready);
    if (ev_ready)
        send_event(l, &ev);
    l->mode = (uint8_t)l->loop.mode; /* the excitation ends by itself */
    if (l->stream_on && --l->stream_left == 0) {
        l->stream_left = l->stream_decim;
        psp_enc_sample_t *s = &l->batch.s[l->batch.count++];
        s->t_us = t_us;
        s->q_q16 = q_meas_q16;
        if (l->batch.count == PSP_ENC_SAMPLES_MAX) {
            send(l, PSP_MSG_ENC_STREAM | PSP_RESPONSE, 0, &l->batch,
                 (uint16_t)(4 + 8 * l->batch.count));
            l->batch.count = 0;
        }
    }
    return q_ref_q16;
}
