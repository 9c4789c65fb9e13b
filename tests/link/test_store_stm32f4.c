/* The STM32F405 flash-sector driver (firmware/boards/stm32f405/pss_flash_stm32f4.c), unchanged,
 * against a register-level model of the STM32F4 flash interface (support/stm32f4_flash_model.c,
 * from RM0090): the register sequences, then the A/B store's power-cut sweep through it. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "pss_flash_stm32f4.h"
#include "storage/pss_store.h"
#include "stm32f405_regs.h"
#include "stm32f4_flash_model.h"

enum { SECTOR = 1024, REC_MAX = SECTOR - PSS_DATA_OFFSET }; /* sectors shrunk for the sweep */

static uint8_t mem[2 * SECTOR], baseline[2 * SECTOR];
static stm32f4m_t fm;
static pss_t st;

static void fill(uint8_t *d, uint32_t n, uint32_t seed)
{
    for (uint32_t i = 0; i < n; i++)
        d[i] = (uint8_t)((i * 131u + seed * 17u) ^ (i >> 3));
}

/* Erase, program, read back through the driver: the model saw the manual's sequences
 * (one unlock per operation, relocked after, no access while busy, nothing outside the
 * table sectors), and the data landed. */
static void test_driver_sequences(void **state)
{
    (void)state;
    stm32f4m_init(&fm, mem, SECTOR, 0);
    memset(mem, 0x00, sizeof mem); /* a programmed sector: the erase must really happen */
    const pss_flash_t *f = pss_stm32f4_flash();
    assert_int_equal(f->slot_size, SECTOR);
    assert_int_equal(f->erase(f->ctx, 1), 0);
    for (uint32_t i = 0; i < SECTOR; i++)
        assert_int_equal(mem[SECTOR + i], 0xFF);
    assert_int_equal(mem[0], 0x00); /* sector 10 untouched */
    uint8_t d[100], got[100];
    fill(d, sizeof d, 1);
    assert_int_equal(f->program(f->ctx, 1, 40, d, sizeof d), 0);
    assert_int_equal(f->read(f->ctx, 1, 40, got, sizeof got), 0);
    assert_memory_equal(got, d, sizeof d);
    assert_int_equal(fm.n_sector_erases, 1);
    assert_int_equal(fm.n_program_bytes, sizeof d);
    assert_int_equal(fm.n_unlocks, 2);
    assert_true(fm.cr & FLASH_CR_LOCK);           /* relocked */
    assert_int_equal(fm.sr & FLASH_SR_ERRORS, 0);
    assert_int_equal(fm.violations, 0);
    /* Out of range: refused before any register is touched. */
    assert_int_equal(f->program(f->ctx, 1, SECTOR - 10, d, 11), -1);
    assert_int_equal(f->erase(f->ctx, 2), -1);
    assert_int_equal(fm.n_unlocks, 2);
}

/* The model enforces what the driver is checked against: a write of the wrong size for
 * PSIZE, a write without PG, a wrong key: each caught (else the test above proves little). */
static void test_model_catches_wrong_sequences(void **state)
{
    (void)state;
    stm32f4m_init(&fm, mem, SECTOR, 1);
    reg_write(&FLASH_CR, FLASH_CR_PG);            /* locked: ignored */
    assert_int_equal(fm.cr, FLASH_CR_LOCK);
    reg_write(&FLASH_KEYR, FLASH_KEY1);
    reg_write(&FLASH_KEYR, FLASH_KEY2);
    assert_int_equal(fm.cr & FLASH_CR_LOCK, 0);
    flash_write8((uintptr_t)mem + 5, 0x00);       /* no PG */
    assert_true(fm.sr & FLASH_SR_PGSERR);
    assert_int_equal(mem[5], 0xFF);
    reg_write(&FLASH_SR, FLASH_SR_ERRORS);
    reg_write(&FLASH_CR, FLASH_CR_PG | (2u << FLASH_CR_PSIZE_SHIFT)); /* x32 */
    flash_write8((uintptr_t)mem + 5, 0x00);       /* a byte access: wrong size */
    assert_true(fm.sr & FLASH_SR_PGPERR);
    assert_int_equal(mem[5], 0xFF);
    reg_write(&FLASH_SR, FLASH_SR_ERRORS);
    reg_write(&FLASH_CR, FLASH_CR_LOCK);
    reg_write(&FLASH_KEYR, FLASH_KEY2);           /* keys out of order: locked until reset */
    reg_write(&FLASH_KEYR, FLASH_KEY1);
    reg_write(&FLASH_KEYR, FLASH_KEY2);
    assert_true(fm.cr & FLASH_CR_LOCK);
    assert_true(fm.violations > 0);
    /* And so the driver fails cleanly on a write-protected sector. */
    stm32f4m_init(&fm, mem, SECTOR, 1);
    fm.wrp_sectors = 1u << 11;
    const pss_flash_t *f = pss_stm32f4_flash();
    uint8_t d[4] = {1, 2, 3, 4};
    assert_int_equal(f->erase(f->ctx, 1), -1);
    assert_int_equal(f->program(f->ctx, 1, 0, d, sizeof d), -1);
    assert_int_equal(mem[SECTOR], 0xFF);
    assert_int_equal(f->program(f->ctx, 0, 0, d, sizeof d), 0);
    assert_int_equal(mem[0], 1);
}

static uint32_t active(uint8_t *out)
{
    if (st.active == PSS_NO_SLOT)
        return 0;
    uint32_t n = st.slot[st.active].size;
    assert_int_equal(pss_read_active(&st, 0, out, n), PSS_OK);
    return n;
}

/* tests/link/test_store.c's sweep, through the real driver: power cut after every byte
 * erased or programmed during a commit; after the reboot the store holds exactly the old
 * or exactly the new record, and the next commit works. */
static void power_cut_sweep(const uint8_t *old, uint32_t old_n, const uint8_t *nw, uint32_t new_n,
                            uint32_t new_gen)
{
    uint8_t got[REC_MAX];
    const pss_flash_t *f = pss_stm32f4_flash();
    memcpy(mem, baseline, sizeof mem);
    stm32f4m_init(&fm, mem, SECTOR, 0);
    pss_mount(&st, f);
    assert_int_equal(pss_commit(&st, new_gen, nw, new_n), PSS_OK);
    int64_t total = (int64_t)fm.n_erase_bytes + fm.n_program_bytes;
    assert_int_equal(total, SECTOR + new_n + 20 + 4);
    assert_int_equal(fm.violations, 0);
    int n_old = 0, n_new = 0;
    for (int64_t cut = 0; cut <= total; cut++) {
        memcpy(mem, baseline, sizeof mem);
        stm32f4m_init(&fm, mem, SECTOR, 0);
        pss_mount(&st, f);
        stm32f4m_power_on(&fm, cut);
        pss_status_t r = pss_commit(&st, new_gen, nw, new_n);
        assert_true(cut == total ? r == PSS_OK : r != PSS_OK);
        stm32f4m_power_on(&fm, -1); /* reboot */
        pss_mount(&st, f);
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
        pss_mount(&st, f);
        assert_int_equal(st.slot[st.active].generation, new_gen + 1);
        assert_int_equal(fm.violations, 0);
    }
    assert_int_equal(n_new, 1);
    assert_int_equal(n_old, total);
}

static void test_power_cut_first_commit(void **state)
{
    (void)state;
    uint8_t b[200];
    fill(b, sizeof b, 7);
    memset(baseline, 0xFF, sizeof baseline);
    power_cut_sweep(NULL, 0, b, sizeof b, 1);
}

static void test_power_cut_over_older_slot(void **state)
{
    (void)state;
    uint8_t a[300], b[250], c[400];
    fill(a, sizeof a, 8);
    fill(b, sizeof b, 9);
    fill(c, sizeof c, 10);
    stm32f4m_init(&fm, mem, SECTOR, 1);
    pss_mount(&st, pss_stm32f4_flash());
    assert_int_equal(pss_commit(&st, 4, a, sizeof a), PSS_OK);
    assert_int_equal(pss_commit(&st, 5, b, sizeof b), PSS_OK);
    memcpy(baseline, mem, sizeof mem);
    power_cut_sweep(b, sizeof b, c, sizeof c, 6);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_driver_sequences),
        cmocka_unit_test(test_model_catches_wrong_sequences),
        cmocka_unit_test(test_power_cut_first_commit),
        cmocka_unit_test(test_power_cut_over_older_slot),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
