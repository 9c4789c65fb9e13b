/* Tests of the A/B store: commit, boot choice, and a power cut after every byte of a commit. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "storage/pss_flash_sim.h"
#include "storage/pss_store.h"

enum { SLOT = 1024, REC_MAX = SLOT - PSS_DATA_OFFSET };

static uint8_t mem[2 * SLOT], baseline[2 * SLOT];
static pss_sim_t sim;
static pss_t st;

static void fill(uint8_t *d, uint32_t n, uint32_t seed)
{
    for (uint32_t i = 0; i < n; i++)
        d[i] = (uint8_t)((i * 131u + seed * 17u) ^ (i >> 3));
}

/* The active record, read back; returns its size (0 with none). */
static uint32_t active(uint8_t *out)
{
    if (st.active == PSS_NO_SLOT)
        return 0;
    uint32_t n = st.slot[st.active].size;
    assert_int_equal(pss_read_active(&st, 0, out, n), PSS_OK);
    return n;
}

static void test_commit_and_boot(void **state)
{
    (void)state;
    uint8_t a[300], b[500], got[REC_MAX];
    fill(a, sizeof a, 1);
    fill(b, sizeof b, 2);
    pss_sim_init(&sim, mem, SLOT, 1);
    pss_mount(&st, &sim.port);
    assert_int_equal(st.active, PSS_NO_SLOT);
    assert_int_equal(pss_read_active(&st, 0, got, 1), PSS_ERR_NO_SLOT);
    assert_int_equal(pss_commit(&st, 1, a, sizeof a), PSS_OK);
    assert_int_equal(st.active, 0);
    assert_int_equal(pss_commit(&st, 2, b, sizeof b), PSS_OK);
    assert_int_equal(st.active, 1);
    assert_int_equal(pss_commit(&st, 2, a, sizeof a), PSS_ERR_GENERATION);
    assert_int_equal(pss_commit(&st, 3, a, REC_MAX + 1), PSS_ERR_SIZE);
    assert_int_equal(pss_commit(&st, 3, a, 0), PSS_ERR_SIZE);
    pss_mount(&st, &sim.port); /* reboot */
    assert_int_equal(st.active, 1);
    assert_int_equal(active(got), sizeof b);
    assert_memory_equal(got, b, sizeof b);
    /* The third commit goes to A, the older slot, never over the running B. */
    assert_int_equal(pss_commit(&st, 3, a, sizeof a), PSS_OK);
    assert_int_equal(st.active, 0);
    assert_true(st.slot[1].valid);
}

static void test_corrupt_newest_falls_back(void **state)
{
    (void)state;
    uint8_t a[100], b[100], got[REC_MAX];
    fill(a, sizeof a, 3);
    fill(b, sizeof b, 4);
    pss_sim_init(&sim, mem, SLOT, 1);
    pss_mount(&st, &sim.port);
    assert_int_equal(pss_commit(&st, 10, a, sizeof a), PSS_OK);
    assert_int_equal(pss_commit(&st, 11, b, sizeof b), PSS_OK);
    mem[SLOT + PSS_DATA_OFFSET + 50] ^= 0x01; /* bit rot in B */
    pss_mount(&st, &sim.port);
    assert_int_equal(st.active, 0);
    assert_int_equal(active(got), sizeof a);
    assert_memory_equal(got, a, sizeof a);
    assert_false(pss_select(&st, 1));
}

/* Flash with one stuck bit in the data area: read-back differs, so the commit must not switch. */
static int bad_program(void *ctx, uint8_t slot, uint32_t off, const uint8_t *data, uint32_t len)
{
    pss_sim_t *s = ctx;
    uint8_t *m = s->mem + (uint32_t)slot * s->slot_size + off;
    for (uint32_t i = 0; i < len; i++)
        m[i] &= (uint8_t)(data[i] & (off >= PSS_DATA_OFFSET && i == 7 ? 0xFE : 0xFF));
    return 0;
}

static void test_verify_failure_keeps_old(void **state)
{
    (void)state;
    uint8_t a[64], b[64], got[REC_MAX];
    fill(a, sizeof a, 5);
    fill(b, sizeof b, 6);
    b[7] |= 1; /* so the stuck bit matters */
    pss_sim_init(&sim, mem, SLOT, 1);
    pss_mount(&st, &sim.port);
    assert_int_equal(pss_commit(&st, 1, a, sizeof a), PSS_OK);
    pss_flash_t broken = sim.port;
    broken.program = bad_program;
    st.flash = &broken;
    assert_int_equal(pss_commit(&st, 2, b, sizeof b), PSS_ERR_VERIFY);
    assert_int_equal(st.active, 0);
    pss_mount(&st, &sim.port);
    assert_int_equal(active(got), sizeof a);
    assert_memory_equal(got, a, sizeof a);
}

/* Power cut after every byte erased or programmed during a commit: after the reboot the
 * store holds exactly the old or exactly the new record, and the next commit works. */
static void power_cut_sweep(const uint8_t *old, uint32_t old_n, const uint8_t *nw, uint32_t new_n,
                            uint32_t new_gen)
{
    uint8_t got[REC_MAX];
    /* Bytes a full commit touches: measured with unlimited power. */
    memcpy(mem, baseline, sizeof mem);
    pss_sim_init(&sim, mem, SLOT, 0);
    pss_mount(&st, &sim.port);
    assert_int_equal(pss_commit(&st, new_gen, nw, new_n), PSS_OK);
    int64_t total = (int64_t)sim.n_erase_bytes + sim.n_program_bytes;
    assert_int_equal(total, SLOT + new_n + 20 + 4);
    int n_old = 0, n_new = 0;
    for (int64_t cut = 0; cut <= total; cut++) {
        memcpy(mem, baseline, sizeof mem);
        pss_sim_init(&sim, mem, SLOT, 0);
        pss_mount(&st, &sim.port);
        pss_sim_power_on(&sim, cut);
        pss_status_t r = pss_commit(&st, new_gen, nw, new_n);
        assert_true(cut == total ? r == PSS_OK : r != PSS_OK);
        pss_sim_power_on(&sim, -1);
        pss_mount(&st, &sim.port); /* reboot */
        uint32_t n = active(got);
        if (n == new_n && memcmp(got, nw, new_n) == 0 && st.slot[st.active].generation == new_gen) {
            n_new++;
        } else {
            assert_int_equal(n, old_n);
            if (old_n)
                assert_memory_equal(got, old, old_n);
            n_old++;
        }
        assert_int_equal(pss_commit(&st, new_gen + 1, nw, new_n), PSS_OK);
        pss_mount(&st, &sim.port);
        assert_int_equal(st.slot[st.active].generation, new_gen + 1);
    }
    /* Only the very last byte (the commit word's last) switches to the new record. */
    assert_int_equal(n_new, 1);
    assert_int_equal(n_old, total);
}

static void test_power_cut_first_commit(void **state)
{
    (void)state;
    uint8_t b[200];
    fill(b, sizeof b, 7);
    pss_sim_init(&sim, mem, SLOT, 1);
    memcpy(baseline, mem, sizeof mem);
    power_cut_sweep(NULL, 0, b, sizeof b, 1);
}

static void test_power_cut_over_older_slot(void **state)
{
    (void)state;
    uint8_t a[300], b[250], c[400];
    fill(a, sizeof a, 8);
    fill(b, sizeof b, 9);
    fill(c, sizeof c, 10);
    pss_sim_init(&sim, mem, SLOT, 1);
    pss_mount(&st, &sim.port);
    assert_int_equal(pss_commit(&st, 4, a, sizeof a), PSS_OK);
    assert_int_equal(pss_commit(&st, 5, b, sizeof b), PSS_OK);
    memcpy(baseline, mem, sizeof mem);
    /* Running b in slot B; c overwrites a in slot A. */
    power_cut_sweep(b, sizeof b, c, sizeof c, 6);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_commit_and_boot),
        cmocka_unit_test(test_corrupt_newest_falls_back),
        cmocka_unit_test(test_verify_failure_keeps_old),
        cmocka_unit_test(test_power_cut_first_commit),
        cmocka_unit_test(test_power_cut_over_older_slot),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
