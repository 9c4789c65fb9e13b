/* Learning queue: B samples the observations complete, learnt by psl_background outside the tick. */
#include <string.h>
#include "link/psl_internal.h"
#include "ps_crc32.h"

/* A completed B sample waits for psl_background; the oldest is kept when the queue is full
 * (the learner sees the samples in the order the host was told them). */
void psl_learn_enqueue(psl_t *l, const onset_event_t *ev)
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

static void learn_f_stop(psl_t *l)
{
    if (l->learn_f_on) {
        psa_set_f_learning(&l->loop, NULL);
        f_online_stop(&l->learn_f);
        psa_f_changed(&l->loop);
    }
    l->learn_f_on = false;
}

static void learn_stop(psl_t *l)
{
    if (l->learn_on) {
        b_online_stop(&l->learn);
        psa_b_changed(&l->loop);
    }
    learn_f_stop(l);
    l->learn_on = false;
    l->learn_count = 0;
}

/* The offset and gain of f start with the B update on the running table (a = 0, g = 1: the
 * loader's f^-1 keeps running until the first publish). A table the learner cannot take
 * leaves B learning alone. */
static void learn_f_start(psl_t *l, uint8_t buf)
{
    f_online_config_t fc = f_online_default_config();
    l->learn_f_on = f_online_init(&l->learn_f, &fc, &l->cal[buf].f, &l->cal[buf].f_inv) == F_ONLINE_OK;
    psa_set_f_learning(&l->loop, l->learn_f_on ? &l->learn_f : NULL);
}

/* Start on the running table's B (already running it: the published copy equals the flashed
 * entries, so the compensator sees no change). */
static bool learn_start(psl_t *l)
{
    learn_stop(l);
    b_online_config_t c = b_online_default_config();
    if (!psl_have_table(l) || b_online_init(&l->learn, &c, &l->cal[l->active_buf].b) != B_ONLINE_OK)
        return false;
    psa_b_changed(&l->loop);
    learn_f_start(l, l->active_buf);
    l->learn_on = true;
    l->learn_head = 0;
    l->learn_queued = 0;
    l->learn_dropped = 0;
    return true;
}

/* Learning carries over: the new table's B becomes the learner's prior (the host flashes
 * what the board learnt, docs/online.md), or, on another grid, learning restarts on it. */
void psl_learn_rebind(psl_t *l, uint8_t buf)
{
    if (l->learn_on && b_online_rebind(&l->learn, &l->cal[buf].b) != B_ONLINE_OK) {
        b_online_config_t lc = b_online_default_config();
        if (b_online_init(&l->learn, &lc, &l->cal[buf].b) != B_ONLINE_OK) {
            l->learn_on = false;
            l->learn_count = 0;
        }
    }
    /* The offset and gain carry over when the new table keeps f (a commit of B), else
     * restart on its f; they stop with the B update (the new table then runs its loader's
     * f^-1: nothing is published into it). */
    if (l->learn_f_on &&
        (!l->learn_on || f_online_rebind(&l->learn_f, &l->cal[buf].f, &l->cal[buf].f_inv) != F_ONLINE_OK)) {
        psa_set_f_learning(&l->loop, NULL);
        l->learn_f_on = false;
    }
}

bool psl_background(psl_t *l)
{
    if (!l->learn_on)
        return false;
    if (l->learn_count == 0)
        return psa_background(&l->loop);
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

uint16_t psl_do_learn(psl_t *l, uint16_t seq, const uint8_t *pl)
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
    psl_send(l, PSP_MSG_LEARN | PSP_RESPONSE, seq, &st, sizeof(st));
    return PSP_OK;
}

