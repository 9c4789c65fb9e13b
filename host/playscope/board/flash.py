"""Flashing a table: upload, commit, read back, and the board's compensator checked bit for bit
against the host's run of the same C. Library code (used by `playscope flash`, run-insitu and
the main job); it never imports the command line."""

from __future__ import annotations

import time


def flash(link, blob: bytes, n_vectors: int = 200, log=print) -> dict:
    """Upload with generation = active + 1, commit, read back, then run the test vector
    through the board's compensator and compare with the host's run of the same C code.
    Returns timings and the check results; raises RuntimeError when a check fails."""
    from .table_check import check_blob
    from ..fit.table_build import CalibTable, set_generation, test_vector

    check_blob(blob)  # names the damaged field; nothing is sent, nothing resealed
    # The board's own limits (instrument, unit, travel, angle, play), checked here by the same C
    # the board runs, so a refusal names its numbers and nothing is sent.
    check_blob(blob, limits=link.board_limits())
    before = link.info()
    if before["active_generation"] >= 0xFFFFFFFF:  # pst_header_t.generation is a uint32
        raise RuntimeError("the board's table generation counter is at its end (2^32 - 1): it takes no table "
                           "until recovered by its physical path (STM32: hold the recovery pin PA0 high at reset; "
                           "virtual board: --recover; or erase sectors 10-11 on the programming port; "
                           "docs/robustness.md), which erases its tables")
    blob = set_generation(blob, before["active_generation"] + 1)
    host = CalibTable(blob)  # refuses a bad table before anything is sent
    t0 = time.perf_counter()
    after = link.upload_table(blob)
    t_upload = time.perf_counter() - t0
    back = link.read_table()
    t_read = time.perf_counter() - t0 - t_upload
    if back != blob:
        raise RuntimeError("read-back differs from the uploaded table")
    c = test_vector(host, n_vectors)
    link.set_mode("compensation")
    t1 = time.perf_counter()
    q_board = [link.comp_step(x) for x in c]
    t_vec = time.perf_counter() - t1
    link.set_mode("idle")
    q_host = host.comp_run(c)
    bad = [k for k in range(len(c)) if q_board[k] != q_host[k]]
    if bad:
        k = bad[0]
        raise RuntimeError(f"compensator mismatch at step {k}: board {q_board[k]}, host {q_host[k]} "
                           f"({len(bad)} of {len(c)} differ)")
    r = {"generation": after["active_generation"], "slot": after["active_slot"], "bytes": len(blob),
         "crc32": f"{after['active_crc32']:08x}", "upload_s": t_upload, "readback_s": t_read,
         "vectors": len(c), "round_trip_us": t_vec / len(c) * 1e6}
    log(flash_line(r))
    return r


def flash_line(r: dict) -> str:
    """The one line `playscope flash` prints for flash()'s result r."""
    return (f"flashed {r['bytes']} B as generation {r['generation']} into slot {r['slot']} "
            f"(crc {r['crc32']}) in {r['upload_s'] * 1e3:.1f} ms; read back identical in {r['readback_s'] * 1e3:.1f} ms; "
            f"{r['vectors']} compensator steps bit-identical to the host ({r['round_trip_us']:.0f} us per round trip)")


def _usb_child(argv: list[str]) -> int:
    """`python -m playscope.board.flash TABLE [--vectors N]`: flash over --device usb in a
    process started under the emulated USB device (pipeline.flash_tables), the result as one
    JSON line on stdout; a failure is one line on stderr, exit 1. Not a user command."""
    import json
    import sys

    from .link import Link
    from .transport import open_transport
    from .table_check import read_table_file

    n = int(argv[argv.index("--vectors") + 1]) if "--vectors" in argv else 200
    try:
        blob = read_table_file(argv[0])
        link = Link(open_transport("usb"))
        try:
            r = flash(link, blob, n, log=lambda s: None)
        finally:
            link.close()
    except (OSError, RuntimeError, ValueError) as e:
        print(f"playscope: flash failed: {' '.join(str(e).split())}", file=sys.stderr)
        return 1
    print(json.dumps(r))
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(_usb_child(sys.argv[1:]))
