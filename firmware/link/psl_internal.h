/* Link internals shared by dispatch, upload session and learning queue; not for callers of psl_link.h. */
#ifndef PSL_INTERNAL_H
#define PSL_INTERNAL_H

#include "link/psl_link.h"

/* Each request handler returns a psp_error_code; on PSP_OK its answer has been sent, otherwise
 * the dispatcher sends the error with *detail (0 unless the handler set it). */

/* Encode and send one frame (psl_link.c). */
void psl_send(psl_t *l, uint8_t type, uint16_t seq, const void *payload, uint16_t len);

static inline const uint8_t *psl_table_bytes(const psl_t *l, uint8_t buf)
{
    return (const uint8_t *)l->tables[buf];
}

static inline bool psl_have_table(const psl_t *l)
{
    return l->active_buf != PSS_NO_SLOT;
}

/* Upload session and table read-back (psl_upload.c). */
uint16_t psl_do_table_begin(psl_t *l, uint16_t seq, const uint8_t *pl, uint8_t *detail);
uint16_t psl_do_table_chunk(psl_t *l, uint16_t seq, const uint8_t *pl, uint16_t len, uint8_t *detail);
uint16_t psl_do_table_commit(psl_t *l, uint16_t seq, const uint8_t *pl, uint8_t *detail);
uint16_t psl_do_table_abort(psl_t *l, uint16_t seq, const uint8_t *pl, uint8_t *detail);
uint16_t psl_do_table_read(psl_t *l, uint16_t seq, const uint8_t *pl);

/* Learning queue (psl_learn.c). */
uint16_t psl_do_learn(psl_t *l, uint16_t seq, const uint8_t *pl);
/* Queue a completed B sample for psl_background (counted, dropped when the queue is full). */
void psl_learn_enqueue(psl_t *l, const onset_event_t *ev);
/* A newly committed table cal[buf] becomes the learner's prior (or learning restarts on its grid,
 * or stops if the learner cannot take it). No-op while learning is off. */
void psl_learn_rebind(psl_t *l, uint8_t buf);

#endif /* PSL_INTERNAL_H */
