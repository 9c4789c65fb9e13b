/* Wire protocol v1: framed, checksummed request/response with sequence numbers.
 *
 * One frame on any byte stream (USART, TCP to QEMU) or USB bulk endpoint:
 *   [psp_frame_header_t (8 B)][payload, len bytes][crc32 (4 B, little-endian)]
 * The CRC-32 (common/ps_crc32.h, zlib's) covers header and payload. The host numbers
 * its requests with seq; the board answers with the same seq and type | PSP_RESPONSE,
 * or PSP_MSG_ERROR. A request whose seq is not newer than the last one accepted is a
 * replay and is refused (PSP_ERR_SEQ) without effect. Payloads are the packed structs
 * below; every struct's size is pinned. Direction: H->B host to board, B->H back. */
#ifndef PS_PROTO_H
#define PS_PROTO_H

#include <stdint.h>
#include "ps_defs.h"

enum {
    PSP_SYNC0 = 0x50,            /* 'P' */
    PSP_SYNC1 = 0x53,            /* 'S' */
    PSP_VERSION = 1,
    PSP_MAX_PAYLOAD = 248,       /* bytes; a frame never exceeds 8 + 248 + 4 = 260 */
    PSP_CHUNK_MAX = 224,         /* table bytes per PSP_MSG_TABLE_CHUNK / _DATA */
    PSP_ENC_SAMPLES_MAX = 30,    /* encoder samples per PSP_MSG_ENC_STREAM */
    PSP_RESPONSE = 0x80,         /* OR-ed into type in responses */
};

enum psp_msg_type {
    PSP_MSG_INFO = 0x01,         /* H->B empty; B->H psp_info_t */
    PSP_MSG_SET_MODE = 0x02,     /* H->B psp_set_mode_t; B->H empty */
    PSP_MSG_BOARD = 0x03,        /* H->B empty; B->H pst_limits_t (ps_table.h, 28 B): the board's own limits; read-only */
    PSP_MSG_TABLE_BEGIN = 0x10,  /* H->B psp_table_begin_t; B->H psp_table_session_t (the upload's owner token) */
    PSP_MSG_TABLE_CHUNK = 0x11,  /* H->B psp_table_chunk_t (with the session); B->H empty */
    PSP_MSG_TABLE_COMMIT = 0x12, /* H->B psp_table_commit_t (with the session); B->H psp_info_t (new state) */
    PSP_MSG_TABLE_READ = 0x13,   /* H->B psp_table_read_t; B->H psp_table_chunk_t of the active table */
    PSP_MSG_TABLE_ABORT = 0x14,  /* H->B psp_table_abort_t: give the upload session up; B->H empty */
    PSP_MSG_ENC_STREAM = 0x20,   /* H->B psp_stream_ctl_t; B->H psp_enc_samples_t batches */
    PSP_MSG_REVERSAL = 0x21,     /* H->B psp_reversal_t: a commanded direction change (t1, q1) */
    PSP_MSG_MARKER_OBS = 0x22,   /* H->B psp_marker_obs_t; B->H empty, or psp_b_sample_t on an onset */
    PSP_MSG_EXC_CONFIG = 0x23,   /* H->B psp_exc_config_t: the excitation (paced to the camera or not); B->H
                                    psp_exc_config_t as the board will run it (speed filled in) */
    PSP_MSG_COMP_STEP = 0x30,    /* H->B psp_comp_req_t; B->H psp_comp_resp_t */
    PSP_MSG_LEARN = 0x31,        /* H->B psp_learn_ctl_t: on-line B update on/off/query; B->H psp_learn_state_t */
    PSP_MSG_ERROR = 0x7F,        /* B->H psp_error_t */
};

enum psp_error_code {
    PSP_OK = 0,
    PSP_ERR_CRC = 1,             /* frame or chunk CRC mismatch */
    PSP_ERR_LENGTH = 2,          /* payload length wrong for the type, or oversized */
    PSP_ERR_TYPE = 3,            /* unknown message type */
    PSP_ERR_SEQ = 4,             /* out-of-order or replayed sequence number */
    PSP_ERR_VERSION = 5,         /* protocol version not supported */
    PSP_ERR_STATE = 6,           /* not allowed now (e.g. commit while not idle) */
    PSP_ERR_RANGE = 7,           /* offset/size outside the table being uploaded */
    PSP_ERR_TABLE = 8,           /* table refused by the loader (see calib_status) */
    PSP_ERR_FLASH = 9,           /* storage write or verify failed; old table kept */
    PSP_ERR_BUSY = 10,           /* another host holds the upload session; detail = s until it expires (<= 255) */
};

enum psp_mode {
    PSP_MODE_IDLE = 0,
    PSP_MODE_EXCITATION = 1,     /* board runs the excitation trajectory (section III-B) */
    PSP_MODE_COMPENSATION = 2,   /* board runs the inverse model (eqs. 4, 5/9) */
    PSP_MODE_PASSTHROUGH = 3,    /* q* = f_coarse^-1(c*), no backlash model */
};

typedef struct PS_PACKED psp_frame_header {
    uint8_t sync0;               /* PSP_SYNC0 */
    uint8_t sync1;               /* PSP_SYNC1 */
    uint8_t version;             /* PSP_VERSION */
    uint8_t type;                /* enum psp_msg_type, | PSP_RESPONSE in answers */
    uint16_t seq;                /* request number; echoed in the answer */
    uint16_t len;                /* payload bytes, <= PSP_MAX_PAYLOAD */
} psp_frame_header_t;
PS_STATIC_ASSERT(sizeof(psp_frame_header_t) == 8, "psp_frame_header_t must be 8 bytes");

typedef struct PS_PACKED psp_info {
    uint32_t fw_version;         /* major << 16 | minor << 8 | patch */
    uint16_t proto_version;      /* PSP_VERSION */
    uint16_t table_layout_version; /* PST_LAYOUT_VERSION */
    uint32_t board_id[3];        /* unique id (STM32 UID; desktop: fixed) */
    uint32_t active_generation;  /* generation of the running table, 0 if none */
    uint32_t active_crc32;       /* its CRC */
    uint8_t mode;                /* enum psp_mode */
    uint8_t active_slot;         /* 0 = A, 1 = B, 0xFF = none */
    uint16_t last_seq;           /* last accepted request seq: a reconnecting host continues above it */
} psp_info_t;
PS_STATIC_ASSERT(sizeof(psp_info_t) == 32, "psp_info_t must be 32 bytes");

typedef struct PS_PACKED psp_set_mode {
    uint8_t mode;                /* enum psp_mode */
    uint8_t reserved[3];
} psp_set_mode_t;
PS_STATIC_ASSERT(sizeof(psp_set_mode_t) == 4, "psp_set_mode_t must be 4 bytes");

typedef struct PS_PACKED psp_table_begin {
    uint32_t total_size;         /* bytes of the table to come, <= PST_MAX_TABLE_SIZE */
    uint32_t crc32;              /* whole-table CRC as in pst_header_t.crc32 */
} psp_table_begin_t;
PS_STATIC_ASSERT(sizeof(psp_table_begin_t) == 8, "psp_table_begin_t must be 8 bytes");

/* One owner per upload: BEGIN opens a session and answers its token; CHUNK, COMMIT and
 * ABORT must carry it. While a session is open, another BEGIN (another host) gets
 * PSP_ERR_BUSY until the owner commits, aborts, or sends nothing for timeout_ms. */
typedef struct PS_PACKED psp_table_session {
    uint16_t session;            /* token, never 0 */
    uint16_t reserved;
    uint32_t timeout_ms;         /* the session expires after this long without an upload request */
} psp_table_session_t;
PS_STATIC_ASSERT(sizeof(psp_table_session_t) == 8, "psp_table_session_t must be 8 bytes");

typedef struct PS_PACKED psp_table_chunk {
    uint32_t offset;             /* byte offset into the table */
    uint16_t len;                /* bytes used in data, <= PSP_CHUNK_MAX */
    uint16_t session;            /* upload: psp_table_session_t.session; read-back answers: 0 */
    uint32_t chunk_crc32;        /* ps_crc32_update(0, data, len) */
    uint8_t data[PSP_CHUNK_MAX];
} psp_table_chunk_t;
PS_STATIC_ASSERT(sizeof(psp_table_chunk_t) == 236, "psp_table_chunk_t must be 236 bytes");

typedef struct PS_PACKED psp_table_commit {
    uint32_t crc32;              /* must equal the announced whole-table CRC */
    uint16_t session;            /* psp_table_session_t.session */
    uint16_t reserved;
} psp_table_commit_t;
PS_STATIC_ASSERT(sizeof(psp_table_commit_t) == 8, "psp_table_commit_t must be 8 bytes");

typedef struct PS_PACKED psp_table_abort {
    uint16_t session;            /* psp_table_session_t.session */
    uint16_t reserved;
} psp_table_abort_t;
PS_STATIC_ASSERT(sizeof(psp_table_abort_t) == 4, "psp_table_abort_t must be 4 bytes");

typedef struct PS_PACKED psp_table_read {
    uint32_t offset;             /* byte offset into the active table */
    uint16_t len;                /* <= PSP_CHUNK_MAX */
    uint16_t reserved;
} psp_table_read_t;
PS_STATIC_ASSERT(sizeof(psp_table_read_t) == 8, "psp_table_read_t must be 8 bytes");

typedef struct PS_PACKED psp_stream_ctl {
    uint8_t enable;              /* 1: stream encoder samples, 0: stop */
    uint8_t decimation;          /* send one sample every N control ticks (>= 1) */
    uint16_t reserved;
} psp_stream_ctl_t;
PS_STATIC_ASSERT(sizeof(psp_stream_ctl_t) == 4, "psp_stream_ctl_t must be 4 bytes");

typedef struct PS_PACKED psp_enc_sample {
    uint32_t t_us;               /* board clock */
    int32_t q_q16;               /* actuator position */
} psp_enc_sample_t;
PS_STATIC_ASSERT(sizeof(psp_enc_sample_t) == 8, "psp_enc_sample_t must be 8 bytes");

typedef struct PS_PACKED psp_enc_samples {
    uint16_t count;              /* samples used, <= PSP_ENC_SAMPLES_MAX */
    uint16_t reserved;
    psp_enc_sample_t s[PSP_ENC_SAMPLES_MAX];
} psp_enc_samples_t;
PS_STATIC_ASSERT(sizeof(psp_enc_samples_t) == 244, "psp_enc_samples_t must be 244 bytes");

typedef struct PS_PACKED psp_reversal {
    uint32_t t1_us;              /* when the direction change was commanded */
    int32_t q1_q16;              /* actuator position then */
} psp_reversal_t;
PS_STATIC_ASSERT(sizeof(psp_reversal_t) == 8, "psp_reversal_t must be 8 bytes");

typedef struct PS_PACKED psp_marker_obs {
    uint32_t t_us;               /* frame time on the board clock (acquisition delay not removed) */
    int32_t u_q16;               /* px, or deg for an angle sensor */
    int32_t v_q16;               /* px; 0 for an angle sensor */
    uint8_t valid;               /* 0: marker lost in this frame */
    uint8_t kind;                /* 0: image point (px), 1: angle (deg) */
    uint16_t reserved;
} psp_marker_obs_t;
PS_STATIC_ASSERT(sizeof(psp_marker_obs_t) == 16, "psp_marker_obs_t must be 16 bytes");

typedef struct PS_PACKED psp_b_sample {
    uint8_t reason;              /* enum onset_reason (firmware/core/onset.h) */
    uint8_t reserved[3];
    uint32_t t1_us;              /* commanded reversal */
    uint32_t t2_us;              /* refined image onset */
    int32_t q1_q16;
    int32_t q2_q16;              /* q(t2 - t_delay) */
    int32_t q_mean_q16;          /* (q1 + q2) / 2 */
    int32_t b_q16;               /* |q2 - q1|, eq. 1 */
} psp_b_sample_t;
PS_STATIC_ASSERT(sizeof(psp_b_sample_t) == 28, "psp_b_sample_t must be 28 bytes");

typedef struct PS_PACKED psp_comp_req {
    int32_t c_ref_q16;           /* c*[k], deg */
} psp_comp_req_t;
PS_STATIC_ASSERT(sizeof(psp_comp_req_t) == 4, "psp_comp_req_t must be 4 bytes");

typedef struct PS_PACKED psp_comp_resp {
    int32_t q_ref_q16;           /* q*[k], actuator units */
} psp_comp_resp_t;
PS_STATIC_ASSERT(sizeof(psp_comp_resp_t) == 4, "psp_comp_resp_t must be 4 bytes");

/* The excitation the board runs in PSP_MODE_EXCITATION (firmware/core/exc.h), set from the
 * host (run-insitu) on any image. v_q32 > 0: that speed; v_q32 == 0: paced to the camera
 * (exc_pace_config: the smallest play b_low taken up over EXC_PACE_FRAMES frames of
 * frame_period_us), which needs 0 < b_low <= b_high. frame_period_us != 0 also becomes the
 * onset detector's frame period. Refused in excitation mode (PSP_ERR_STATE); an invalid one
 * (PSP_ERR_RANGE, detail = exc_status_t) changes nothing. With a table loaded the trajectory
 * spans the table's q range (q_start, q_end are then checked, not used). */
typedef struct PS_PACKED psp_exc_config {
    int32_t q_start_q16;         /* actuator units */
    int32_t q_end_q16;
    int32_t amplitude_q16;
    int32_t advance_q16;
    int64_t v_q32;               /* actuator units per tick, Q32.32; 0: paced */
    int32_t b_low_q16;           /* expected play range, actuator units (pacing) */
    int32_t b_high_q16;
    uint32_t frame_period_us;    /* camera frame period; 0: keep the board's */
    uint8_t return_sweep;        /* 0 or 1 */
    uint8_t reserved[3];
} psp_exc_config_t;
PS_STATIC_ASSERT(sizeof(psp_exc_config_t) == 40, "psp_exc_config_t must be 40 bytes");

/* On-line B update during use (docs/online.md): the B samples the onset
 * detector completes are queued and learnt outside the tick (firmware/core/b_online.h). */
enum psp_learn_op {
    PSP_LEARN_QUERY = 0,         /* report the state, change nothing */
    PSP_LEARN_START = 1,         /* start on the running table's B (restart: theta 0, P = p0 I) */
    PSP_LEARN_STOP = 2,          /* stop; the running table's flashed B is used again */
};

typedef struct PS_PACKED psp_learn_ctl {
    uint8_t op;                  /* enum psp_learn_op */
    uint8_t reserved[3];
} psp_learn_ctl_t;
PS_STATIC_ASSERT(sizeof(psp_learn_ctl_t) == 4, "psp_learn_ctl_t must be 4 bytes");

typedef struct PS_PACKED psp_learn_state {
    uint32_t samples;            /* B samples learnt since the start (b_online_t.samples) */
    uint32_t queued;             /* B samples completed since the start, learnt or waiting */
    uint32_t dropped;            /* of those, lost because the queue was full */
    uint32_t b_crc32;            /* CRC-32 (ps_crc32) of the n_grid B entries the loop runs, int32 LE;
                                    0 when stopped: a host mirror (b_online through cffi) checks it */
    uint16_t n_grid;             /* B grid entries (0 when stopped) */
    uint8_t n_nodes;             /* coefficients learnt */
    uint8_t on;                  /* 1 while learning */
} psp_learn_state_t;
PS_STATIC_ASSERT(sizeof(psp_learn_state_t) == 20, "psp_learn_state_t must be 20 bytes");

typedef struct PS_PACKED psp_error {
    uint16_t code;               /* enum psp_error_code */
    uint8_t ref_type;            /* type of the refused request */
    uint8_t detail;              /* module-specific reason (e.g. calib_status) */
} psp_error_t;
PS_STATIC_ASSERT(sizeof(psp_error_t) == 4, "psp_error_t must be 4 bytes");

#endif /* PS_PROTO_H */
