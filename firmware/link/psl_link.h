/* Board-side protocol handler API: requests in (frames), answers and events out, the tick and the background learner. */
#ifndef PSL_LINK_H
#define PSL_LINK_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include "calib.h"
#include "psa_loop.h"
#include "ps_frame.h"
#include "ps_proto.h"
#include "ps_table.h"
#include "storage/pss_store.h"

/* psp_error_t.detail for PSP_ERR_TABLE when calib_load accepted the table but its
 * generation is not one the board takes next (pst_generation_ok: above the running one by 1 to
 * PST_GENERATION_STEP_MAX; calib_status_t values stay below it). */
enum { PSL_DETAIL_GENERATION = 0x80 };

/* psp_error_t.detail for PSP_ERR_FLASH when the slot was written and verified by the store
 * but the table read back from it fails the table CRC: the commit is undone (slot erased),
 * the previous table stays active (pss_status_t values stay below it). */
enum { PSL_DETAIL_READBACK = 0x81 };

/* Sends one complete frame (on a UART, a USB bulk IN pipe, stdout...). Must take the
 * whole frame; the handler keeps no transmit queue. */
typedef void (*psl_write_fn)(void *ctx, const uint8_t *frame, size_t len);

typedef struct {
    uint32_t fw_version;         /* major << 16 | minor << 8 | patch */
    uint32_t board_id[3];        /* unique id reported by PSP_MSG_INFO */
    exc_config_t exc;            /* excitation used when no table is loaded (with a table: its q range) */
    exc_pace_t pace;             /* pacing of exc to the camera (b_high 0: off) and the tick rate;
                                  * both set at run time by PSP_MSG_EXC_CONFIG */
    onset_config_t onset;        /* on-board onset detector */
    uint32_t upload_timeout_us;  /* an upload session with no request for this long is free again (board clock) */
    pst_limits_t limits;         /* the board's own instrument, unit, travel, angle and play limits
                                  * (firmware/boards/<board>/psb_config.h): every table is held to them */
    bool recover;                /* physical presence at boot (a pin, a flag): psl_init erases both table
                                  * slots first, the one way out of an exhausted generation counter */
} psl_config_t;

#ifndef PSL_LIMIT_Q_ABS_Q16
/* PSL_LIMIT_Q_ABS_Q16: psl_default_config's travel limit +-this (Q16.16 actuator units). Default 100 units. */
#define PSL_LIMIT_Q_ABS_Q16 (100 * 65536)
#endif
#ifndef PSL_LIMIT_C_ABS_Q16
/* PSL_LIMIT_C_ABS_Q16: psl_default_config's angle limit +-this (Q16.16 deg). Default 180 deg. */
#define PSL_LIMIT_C_ABS_Q16 (180 * 65536)
#endif
#ifndef PSL_LIMIT_B_MAX_Q16
/* PSL_LIMIT_B_MAX_Q16: psl_default_config's largest play (Q16.16 actuator units). Default 10 units. */
#define PSL_LIMIT_B_MAX_Q16 (10 * 65536)
#endif

#ifndef PSL_UPLOAD_TIMEOUT_US
/* PSL_UPLOAD_TIMEOUT_US: default psl_config_t.upload_timeout_us. Default 5 s: longer than a
 * host's request timeout, short enough that a killed host does not lock the board out. */
#define PSL_UPLOAD_TIMEOUT_US 5000000u
#endif

#ifndef PSL_LEARN_QUEUE
/* PSL_LEARN_QUEUE: B samples waiting for psl_background. Default 4: onsets complete about
 * once per reversal (a few per second at most), the main loop runs every tick. */
#define PSL_LEARN_QUEUE 4
#endif

typedef struct {
    psl_config_t cfg;
    psf_parser_t parser;
    psl_write_fn write;
    void *write_ctx;
    pss_t store;
    uint8_t mode;                /* enum psp_mode */
    uint16_t last_seq;           /* last accepted request; 0 = none since boot */
    /* Table upload into tables[1 - active_buf] (or tables[0] with none active), owned by
     * the host that holds session up_session (one owner per upload, docs/protocol.md). */
    bool up_open;
    uint32_t up_size, up_crc32, up_have;
    uint16_t up_session;         /* token of the open session; never 0 */
    uint16_t up_sessions;        /* sessions opened since boot: the next token derives from it */
    uint32_t up_last_us;         /* board time of the owner's last upload request */
    uint32_t now_us;             /* board time of the last tick (psl_tick) */
    uint8_t active_buf;          /* index of the running table, PSS_NO_SLOT if none */
    uint32_t tables[2][(PST_MAX_TABLE_SIZE + 3) / 4]; /* uint32_t: calib_load reads entries in place, 4-aligned */
    calib_t cal[2];
    psa_loop_t loop;             /* the control loop (firmware/app/psa_loop.h) runs cal[active_buf] */
    bool stream_on;
    uint8_t stream_decim, stream_left;
    psp_enc_samples_t batch;
    uint32_t n_b_events;         /* B samples (or failures) sent unsolicited */
    uint32_t last_obs_us;        /* board time stamp of the last MARKER_OBS (0 before any): a
                                    desktop board in lock-step waits for the host (vboard --lockstep-ms) */
    /* On-line B update (PSP_MSG_LEARN): B samples the observations complete are queued by the
     * request handler and learnt by psl_background, outside the tick. */
    bool learn_on;
    uint8_t learn_head, learn_count;
    int32_t learn_q[PSL_LEARN_QUEUE][2]; /* (q_mean, b) Q16, oldest at learn_head */
    uint32_t learn_queued, learn_dropped;
    b_online_t learn;
    /* On-line offset and gain of f, on with the B update: the angle readings are learnt on the
     * observation call (O(1)), each publish runs in psl_background. */
    bool learn_f_on;
    f_online_t learn_f;
    uint8_t tx[PSF_MAX_FRAME];
} psl_t;

/* Defaults: version 0.1.0, board id 0, limits for instrument PST_INSTRUMENT_DEFAULT in mm within
 * PSL_LIMIT_* (a board's main replaces them with its psb_config.h's), no recovery,
 * onset_default_config(), an excitation over
 * [0, 10] actuator units with amplitude 1 and advance 0.25 at 10 units/s for tick_hz (pacing
 * off, pace.tick_hz = tick_hz),
 * upload sessions expiring after PSL_UPLOAD_TIMEOUT_US. */
psl_config_t psl_default_config(uint32_t tick_hz);

/* Mount the store, load the newest table the loader accepts (falling back to the
 * other slot), start idle. flash must outlive l. Boot time. */
void psl_init(psl_t *l, const psl_config_t *cfg, const pss_flash_t *flash, psl_write_fn write,
              void *write_ctx);

/* Feed received bytes; every complete frame is handled and answered through write. */
void psl_rx(psl_t *l, const uint8_t *data, size_t len);

/* Handle one decoded frame (header fields already checked by the CRC). */
void psl_handle(psl_t *l, const psp_frame_header_t *hdr, const uint8_t *payload);

/* One control tick at t_us with the measured actuator position q_meas_q16: psa_tick() with
 * the last c* the host sent (excitation, compensation or passthrough by mode; the encoder
 * sample into the onset history), then streaming. Returns the set-point q* for the motor.
 * O(1) except when a batch or event is sent. */
int32_t psl_tick(psl_t *l, uint32_t t_us, int32_t q_meas_q16);

/* Work that must not delay a tick, run from the main loop between ticks (or at the lowest
 * priority): learns the oldest queued B sample (b_online_sample: its RLS step, the grid
 * rewritten into the copy the loop does not read, then published by one pointer store) and
 * drops the compensator's cached B cell; with no B sample waiting, a due publish of the
 * learnt offset and gain of f (psa_background: f^-1 rewritten into its spare copy, one
 * pointer store). True if it did either. bench/bench_firmware.sh gives the costs. */
bool psl_background(psl_t *l);

/* The on-line B state as PSP_MSG_LEARN reports it. */
void psl_learn_state(const psl_t *l, psp_learn_state_t *st);

/* Fill an info record of the current state. */
void psl_info(const psl_t *l, psp_info_t *info);

#endif /* PSL_LINK_H */
