/* Test fixture: calibration-table blobs from double functions, written field by field. */
#include "table_fixture.h"

#include <math.h>
#include <string.h>
#include "calib.h"
#include "table_write.h"

static int32_t to_q16(double x)
{
    return (int32_t)llround(x * 65536.0);
}

size_t fixture_build(fixture_blob_t *blob, const fixture_grid_t *g, fixture_fn b, const void *b_ctx,
                     fixture_fn f, const void *f_ctx)
{
    return fixture_build_pi(blob, g, b, b_ctx, f, f_ctx, 0, 0, NULL, NULL);
}

size_t fixture_build_pi(fixture_blob_t *blob, const fixture_grid_t *g, fixture_fn b, const void *b_ctx,
                        fixture_fn f, const void *f_ctx, uint16_t version, uint16_t n_ops,
                        const int32_t *r_q16, const int32_t *w_q16)
{
    static int32_t bb[PST_MAX_ENTRIES], ff[PST_MAX_ENTRIES];
    pst_header_t hd;
    memset(&hd, 0, sizeof hd);
    memset(blob, 0, sizeof *blob);
    hd.generation = g->generation;
    hd.q_unit = PST_Q_UNIT_MM;
    hd.f_kind = g->f_kind;
    hd.q_min_q16 = to_q16(g->q_min);
    hd.q_max_q16 = to_q16(g->q_max);
    int32_t x0 = to_q16(g->q0);
    int32_t step = (int32_t)1 << g->step_log2;
    hd.b = (pst_grid_t){.x0_q16 = x0, .step_q16 = step, .n = g->n};
    hd.f = hd.b;
    hd.layout_version = version;
    hd.pi.n = n_ops;
    for (int i = 0; i < g->n; i++) {
        double q = (x0 + (double)i * step) / 65536.0;
        bb[i] = to_q16(b(q, b_ctx));
        ff[i] = to_q16(f(q, f_ctx));
    }
    return table_write(blob->bytes, sizeof blob->bytes, &hd, bb, ff, r_q16, w_q16);
}

size_t fixture_with_ops(fixture_blob_t *blob, uint16_t version, uint16_t n_ops, const int32_t *r_q16,
                        const int32_t *w_q16)
{
    static int32_t bb[PST_MAX_ENTRIES], ff[PST_MAX_ENTRIES];
    pst_header_t hd;
    memcpy(&hd, blob->bytes, sizeof hd);
    memcpy(bb, blob->bytes + hd.b.offset, 4u * hd.b.n);
    memcpy(ff, blob->bytes + hd.f.offset, 4u * hd.f.n);
    hd.layout_version = version;
    hd.pi.n = n_ops;
    memset(blob, 0, sizeof *blob);
    return table_write(blob->bytes, sizeof blob->bytes, &hd, bb, ff, r_q16, w_q16);
}

/* A table's parts copied out of its blob, to be written again in another layout. */
typedef struct {
    pst_header_t hd;
    pst_grid_t tm;                      /* the threshold map's grid (n = 0: none) */
    pst_relax_t rx;                     /* the relaxation (0, 0: none) */
    int32_t bb[PST_MAX_ENTRIES], ff[PST_MAX_ENTRIES], rr[PST_MAX_OPS], ww[PST_MAX_OPS], gg[PST_MAX_ENTRIES];
} parts_t;

static parts_t *unpack(const fixture_blob_t *blob)
{
    static parts_t u;                   /* one at a time: the fixtures are single-threaded */
    memset(&u, 0, sizeof u);
    memcpy(&u.hd, blob->bytes, sizeof u.hd);
    if (u.hd.layout_version >= 3)
        memcpy(&u.tm, blob->bytes + offsetof(pst_header_v3_t, tmap), sizeof u.tm);
    if (u.hd.layout_version >= 4)
        memcpy(&u.rx, blob->bytes + offsetof(pst_header_v4_t, relax), sizeof u.rx);
    memcpy(u.bb, blob->bytes + u.hd.b.offset, 4u * u.hd.b.n);
    memcpy(u.ff, blob->bytes + u.hd.f.offset, 4u * u.hd.f.n);
    if (u.hd.pi.n) {
        memcpy(u.rr, blob->bytes + u.hd.pi.offset, 4u * u.hd.pi.n);
        memcpy(u.ww, blob->bytes + u.hd.pi.offset + 4u * u.hd.pi.n, 4u * u.hd.pi.n);
    }
    if (u.tm.n)
        memcpy(u.gg, blob->bytes + u.tm.offset, 4u * u.tm.n);
    u.tm.offset = 0;                    /* the writer places it again */
    return &u;
}

size_t fixture_with_tmap(fixture_blob_t *blob, int32_t x0_q16, int32_t step_q16, uint16_t n,
                         const int32_t *u_q16)
{
    parts_t *u = unpack(blob);
    u->hd.layout_version = 3;
    pst_grid_t tm = {.x0_q16 = x0_q16, .step_q16 = step_q16, .n = n, .offset = 0};
    memset(blob, 0, sizeof *blob);
    return table_write_map(blob->bytes, sizeof blob->bytes, &u->hd, u->bb, u->ff, u->hd.pi.n ? u->rr : NULL,
                           u->hd.pi.n ? u->ww : NULL, &tm, u_q16);
}

size_t fixture_with_relax(fixture_blob_t *blob, int32_t kappa_q16, int32_t lambda_q16)
{
    parts_t *u = unpack(blob);
    u->hd.layout_version = 4;
    pst_relax_t rx = {.kappa_q16 = kappa_q16, .lambda_q16 = lambda_q16};
    memset(blob, 0, sizeof *blob);
    return table_write_relax(blob->bytes, sizeof blob->bytes, &u->hd, u->bb, u->ff, u->hd.pi.n ? u->rr : NULL,
                             u->hd.pi.n ? u->ww : NULL, &u->tm, u->tm.n ? u->gg : NULL, &rx);
}

size_t fixture_with_instrument(fixture_blob_t *blob, uint32_t id, const pst_instrument_t *inst)
{
    parts_t *u = unpack(blob);
    pst_instrument_t in;
    if (inst != NULL)
        in = *inst;
    else
        pst_instrument_derive(&u->hd, u->bb, u->ff, id, &in);
    in.id = id;
    u->hd.layout_version = 5;
    memset(blob, 0, sizeof *blob);
    return table_write_inst(blob->bytes, sizeof blob->bytes, &u->hd, u->bb, u->ff, u->hd.pi.n ? u->rr : NULL,
                            u->hd.pi.n ? u->ww : NULL, &u->tm, u->tm.n ? u->gg : NULL, &u->rx, &in);
}

void fixture_reseal(fixture_blob_t *blob)
{
    pst_header_t hd;
    memcpy(&hd, blob->bytes, sizeof hd);
    uint32_t size = hd.total_size <= sizeof blob->bytes ? hd.total_size : (uint32_t)sizeof blob->bytes;
    hd.crc32 = calib_table_crc(blob->bytes, size);
    memcpy(blob->bytes, &hd, sizeof hd);
}

static double entry(const fixture_blob_t *blob, const pst_grid_t *gr, int i)
{
    int32_t v;
    memcpy(&v, blob->bytes + gr->offset + 4 * i, 4);
    return v / 65536.0;
}

double fixture_b(const fixture_blob_t *blob, int i)
{
    pst_header_t hd;
    memcpy(&hd, blob->bytes, sizeof hd);
    return entry(blob, &hd.b, i);
}

double fixture_f(const fixture_blob_t *blob, int i)
{
    pst_header_t hd;
    memcpy(&hd, blob->bytes, sizeof hd);
    return entry(blob, &hd.f, i);
}
