/* Board-side protocol handler, dispatch: every request is checked (version, type, length, seq) before its handler acts. */
#include "link/psl_internal.h"

#include <string.h>
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
    c.pace.tick_hz = tick_hz ? tick_hz : 1000u;
    c.onset = onset_default_config();
    c.upload_timeout_us = PSL_UPLOAD_TIMEOUT_US;
    c.limits = (pst_limits_t){.instrument_id = PST_INSTRUMENT_DEFAULT, .q_unit = PST_Q_UNIT_MM,
                              .q_min_q16 = -PSL_LIMIT_Q_ABS_Q16, .q_max_q16 = PSL_LIMIT_Q_ABS_Q16,
                              .c_min_q16 = -PSL_LIMIT_C_ABS_Q16, .c_max_q16 = PSL_LIMIT_C_ABS_Q16,
                              .b_max_q16 = PSL_LIMIT_B_MAX_Q16};
    c.recover = false;
    return c;
}

void psl_send(psl_t *l, uint8_t type, uint16_t seq, const void *payload, uint16_t len)
{
    size_t n = psf_encode(l->tx, sizeof(l->tx), type, seq, payload, len);
    if (n > 0 && l->write)
        l->write(l->write_ctx, l->tx, n);
}

static void send_error(psl_t *l, uint16_t seq, uint8_t ref_type, uint16_t code, uint8_t detail)
{
    psp_error_t e = {.code = code, .ref_type = ref_type, .detail = detail};
    psl_send(l, PSP_MSG_ERROR, seq, &e, sizeof(e));
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
    return calib_load_guarded(&l->cal[buf], psl_table_bytes(l, buf), size, &l->cfg.limits, NULL) == CALIB_OK;
}

void psl_init(psl_t *l, const psl_config_t *cfg, const pss_flash_t *flash, psl_write_fn write,
              void *write_ctx)
{
    memset(l, 0, sizeof(*l));
    l->cfg = *cfg;
    l->write = write;
    l->write_ctx = write_ctx;
    psf_parser_reset(&l->parser);
    psa_config_t lc = {.onset = l->cfg.onset, .exc = l->cfg.exc, .pace = l->cfg.pace, .smooth = false};
    psa_init(&l->loop, &lc);
    l->mode = PSP_MODE_IDLE;
    l->active_buf = PSS_NO_SLOT;
    if (l->cfg.recover) {
        /* Physical presence (docs/robustness.md): both slots erased, the generation counter
         * starts again; the board runs without a table until one is flashed. */
        (void)flash->erase(flash->ctx, 0);
        (void)flash->erase(flash->ctx, 1);
    }
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
    case PSP_MSG_BOARD: return 0;
    case PSP_MSG_TABLE_BEGIN: return (int)sizeof(psp_table_begin_t);
    case PSP_MSG_TABLE_CHUNK: return -2;
    case PSP_MSG_TABLE_COMMIT: return (int)sizeof(psp_table_commit_t);
    case PSP_MSG_TABLE_READ: return (int)sizeof(psp_table_read_t);
    case PSP_MSG_TABLE_ABORT: return (int)sizeof(psp_table_abort_t);
    case PSP_MSG_ENC_STREAM: return (int)sizeof(psp_stream_ctl_t);
    case PSP_MSG_REVERSAL: return (int)sizeof(psp_reversal_t);
    case PSP_MSG_MARKER_OBS: return (int)sizeof(psp_marker_obs_t);
    case PSP_MSG_EXC_CONFIG: return (int)sizeof(psp_exc_config_t);
    case PSP_MSG_COMP_STEP: return (int)sizeof(psp_comp_req_t);
    case PSP_MSG_LEARN: return (int)sizeof(psp_learn_ctl_t);
    default: return -1;
    }
}

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
    psl_send(l, PSP_MSG_MARKER_OBS | PSP_RESPONSE, 0, &b, sizeof(b));
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
    psl_send(l, PSP_MSG_SET_MODE | PSP_RESPONSE, seq, NULL, 0);
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
    psl_send(l, PSP_MSG_ENC_STREAM | PSP_RESPONSE, seq, NULL, 0);
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
        psl_send(l, PSP_MSG_REVERSAL | PSP_RESPONSE, seq, &b, sizeof(b));
    } else {
        psl_send(l, PSP_MSG_REVERSAL | PSP_RESPONSE, seq, NULL, 0);
    }
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
    l->last_obs_us = m.t_us;
    if (m.kind == 0)
        done = psa_observe_px(&l->loop, m.t_us, m.u_q16, m.v_q16, m.valid != 0, &ev);
    else
        done = psa_observe_deg(&l->loop, m.t_us, m.u_q16, m.valid != 0, &ev);
    if (done) {
        if (l->learn_on && (ev.reason == ONSET_OK || ev.reason == ONSET_OK_COARSE))
            psl_learn_enqueue(l, &ev);
        psp_b_sample_t b;
        b_sample_from(&ev, &b);
        psl_send(l, PSP_MSG_MARKER_OBS | PSP_RESPONSE, seq, &b, sizeof(b));
    } else {
        psl_send(l, PSP_MSG_MARKER_OBS | PSP_RESPONSE, seq, NULL, 0);
    }
    return PSP_OK;
}

/* The excitation (and its pacing to the camera) from the host: checked as psa_set_mode will
 * run it (exc_pace_config / exc_init on the given range), then kept in cfg and the loop's
 * config for the next excitation run. Configuration time: exc_pace_config's 64-bit divide. */
static uint16_t do_exc_config(psl_t *l, uint16_t seq, const uint8_t *pl, uint8_t *detail)
{
    psp_exc_config_t m;
    memcpy(&m, pl, sizeof(m));
    if (l->loop.mode == PSA_MODE_EXCITATION)
        return PSP_ERR_STATE; /* the running trajectory keeps its config */
    if (m.return_sweep > 1 || (m.v_q32 < 0))
        return PSP_ERR_RANGE;
    exc_config_t c = {.q_start_q16 = m.q_start_q16, .q_end_q16 = m.q_end_q16, .amplitude_q16 = m.amplitude_q16,
                      .advance_q16 = m.advance_q16, .v_q32 = m.v_q32, .return_sweep = m.return_sweep != 0};
    exc_pace_t pace = {.b_low_q16 = 0, .b_high_q16 = 0, .tick_hz = l->cfg.pace.tick_hz};
    uint32_t period_us = m.frame_period_us ? m.frame_period_us : l->loop.cfg.onset.frame_period_us;
    exc_status_t st;
    if (m.v_q32 == 0) {
        pace.b_low_q16 = m.b_low_q16;
        pace.b_high_q16 = m.b_high_q16;
        st = pace.b_high_q16 > 0 ? exc_pace_config(&c, pace.b_low_q16, pace.b_high_q16, period_us, pace.tick_hz)
                                 : EXC_ERR_PACE;
    } else {
        exc_t probe;
        st = exc_init(&probe, &c);
    }
    if (st != EXC_OK) {
        *detail = (uint8_t)st;
        return PSP_ERR_RANGE;
    }
    l->cfg.exc = c;
    l->cfg.pace = pace;
    l->cfg.onset.frame_period_us = period_us;
    l->loop.cfg.exc = c;
    l->loop.cfg.pace = pace;
    l->loop.cfg.onset.frame_period_us = period_us; /* the detector restarts with it on the next run */
    m.v_q32 = c.v_q32;
    m.frame_period_us = period_us;
    psl_send(l, PSP_MSG_EXC_CONFIG | PSP_RESPONSE, seq, &m, sizeof(m));
    return PSP_OK;
}

static uint16_t do_comp(psl_t *l, uint16_t seq, const uint8_t *pl)
{
    psp_comp_req_t r;
    psp_comp_resp_t a;
    memcpy(&r, pl, sizeof(r));
    if (!psl_have_table(l))
        return PSP_ERR_STATE;
    /* The step runs now, so the answer is what a host replaying comp_reset/comp_step
     * computes; the ticks after it hold this c*. */
    a.q_ref_q16 = psa_set_reference(&l->loop, r.c_ref_q16);
    if (a.q_ref_q16 == INT32_MIN)
        return PSP_ERR_STATE;
    psl_send(l, PSP_MSG_COMP_STEP | PSP_RESPONSE, seq, &a, sizeof(a));
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
    if (type == PSP_MSG_BOARD) {
        /* Read-only, like INFO: the board's own limits, for a host to check a table first. */
        psl_send(l, PSP_MSG_BOARD | PSP_RESPONSE, seq, &l->cfg.limits, sizeof(l->cfg.limits));
        return;
    }
    if (type == PSP_MSG_INFO) {
        /* Read-only, so exempt from the replay check: it is how a host learns last_seq. */
        psp_info_t info;
        psl_info(l, &info);
        psl_send(l, PSP_MSG_INFO | PSP_RESPONSE, seq, &info, sizeof(info));
        return;
    }
    if (seq == 0 || !seq_newer(seq, l->last_seq)) {
        send_error(l, seq, type, PSP_ERR_SEQ, 0);
        return;
    }
    switch (type) {
    case PSP_MSG_SET_MODE: err = do_set_mode(l, seq, payload, &detail); break;
    case PSP_MSG_TABLE_BEGIN: err = psl_do_table_begin(l, seq, payload, &detail); break;
    case PSP_MSG_TABLE_CHUNK: err = psl_do_table_chunk(l, seq, payload, hdr->len, &detail); break;
    case PSP_MSG_TABLE_COMMIT: err = psl_do_table_commit(l, seq, payload, &detail); break;
    case PSP_MSG_TABLE_READ: err = psl_do_table_read(l, seq, payload); break;
    case PSP_MSG_TABLE_ABORT: err = psl_do_table_abort(l, seq, payload, &detail); break;
    case PSP_MSG_ENC_STREAM: err = do_stream(l, seq, payload); break;
    case PSP_MSG_REVERSAL: err = do_reversal(l, seq, payload); break;
    case PSP_MSG_MARKER_OBS: err = do_marker(l, seq, payload); break;
    case PSP_MSG_EXC_CONFIG: err = do_exc_config(l, seq, payload, &detail); break;
    case PSP_MSG_COMP_STEP: err = do_comp(l, seq, payload); break;
    case PSP_MSG_LEARN: err = psl_do_learn(l, seq, payload); break;
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
            psl_send(l, PSP_MSG_ENC_STREAM | PSP_RESPONSE, 0, &l->batch,
                 (uint16_t)(4 + 8 * l->batch.count));
            l->batch.count = 0;
        }
    }
    return q_ref_q16;
}
