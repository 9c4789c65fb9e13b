"""One owner per upload: two hosts on one virtual board (ps_vboard --listen, one TCP
port each, shared tables and upload session). The second host is told "busy" until the first
commits, aborts or times out; concurrent flashes never leave a table nobody committed."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from playscope.board.flash import flash
from playscope.board.link import DeviceError, Link
from playscope.fit.table_build import builtin_table
from playscope.board.transport import TcpTransport
from playscope.base.native import executable

GUARD_CLIENT = Path(__file__).with_name("usb_guard_client.py")
TIMEOUT_MS = 1500  # the board's upload session timeout for these tests (default 5000)


@pytest.fixture
def board(tmp_path):
    proc = subprocess.Popen([str(executable("ps_vboard")), "--listen", "0", "--flash", str(tmp_path / "flash.bin"),
                             "--upload-timeout-ms", str(TIMEOUT_MS)], stdout=subprocess.PIPE, text=True)
    port = int(proc.stdout.readline().split()[1])
    links = []

    def connect() -> Link:
        links.append(Link(TcpTransport("127.0.0.1", port)))
        return links[-1]

    yield connect
    for link in links:
        link.close()
    proc.terminate()
    proc.wait(timeout=5)


def _chunk(link: Link, blob: bytes, session: int, off: int = 0) -> None:
    ffi, lib = link.ffi, link.lib
    data = blob[off:off + lib.PSP_CHUNK_MAX]
    c = ffi.new("psp_table_chunk_t *")
    c.offset, c.len, c.session = off, len(data), session
    c.chunk_crc32 = lib.ps_crc32_update(0, data, len(data))
    ffi.memmove(c.data, data, len(data))
    link.request(lib.PSP_MSG_TABLE_CHUNK, bytes(ffi.buffer(c, ffi.offsetof("psp_table_chunk_t", "data") + len(data))))


def _crc(blob: bytes) -> int:
    return int.from_bytes(blob[12:16], "little")


def test_second_host_busy_until_abort(board):
    a, b = board(), board()
    t1, t2 = builtin_table(generation=1), builtin_table(generation=2)
    s = a.begin_upload(len(t1), _crc(t1))
    _chunk(a, t1, s)
    with pytest.raises(DeviceError) as e:
        b.upload_table(t2)
    assert e.value.busy and "board busy" in str(e.value) and "\n" not in str(e.value)
    assert 1 <= e.value.detail <= 2  # whole seconds left of the 1.5 s session
    with pytest.raises(DeviceError) as e:  # B cannot take A's session over by guessing 0 or a neighbour
        _chunk(b, t2, s ^ 1)
    assert e.value.busy
    a.abort_upload(s)
    info = b.upload_table(t2)
    assert info["active_generation"] == 2
    assert b.read_table() == t2
    assert a.info()["active_generation"] == 2  # both hosts see the same board


def test_second_host_busy_until_commit(board):
    a, b = board(), board()
    t1 = builtin_table(generation=1)
    s = a.begin_upload(len(t1), _crc(t1))
    for off in range(0, len(t1), a.lib.PSP_CHUNK_MAX):
        _chunk(a, t1, s, off)
        with pytest.raises(DeviceError) as e:
            b.begin_upload(len(t1), _crc(t1))
        assert e.value.busy
    a.request(a.lib.PSP_MSG_TABLE_COMMIT, bytes(a.ffi.buffer(a.ffi.new("psp_table_commit_t *",
                                                                        {"crc32": _crc(t1), "session": s}))))
    assert b.upload_table(builtin_table(generation=2))["active_generation"] == 2


def test_silent_owner_times_out(board):
    a, b = board(), board()
    t1 = builtin_table(generation=1)
    s = a.begin_upload(len(t1), _crc(t1))  # then host A goes silent (killed, unplugged)
    with pytest.raises(DeviceError) as e:
        b.upload_table(builtin_table(generation=3))
    assert e.value.busy
    time.sleep(TIMEOUT_MS / 1000 + 0.3)
    assert b.upload_table(builtin_table(generation=3))["active_generation"] == 3
    with pytest.raises(DeviceError) as e:  # A's token died with its session
        _chunk(a, t1, s)
    assert e.value.code == a.lib.PSP_ERR_STATE


def test_overlapping_uploads_from_threads(board):
    """A's upload pauses after its first chunk until B has tried: B is busy, A commits."""
    a, b = board(), board()
    tried = threading.Event()
    got = {}

    def host_b():
        try:
            b.upload_table(builtin_table(generation=7))
            got["b"] = "ok"
        except DeviceError as e:
            got["b"] = "busy" if e.busy else str(e)
        tried.set()

    def progress(done, total):
        if done <= a.lib.PSP_CHUNK_MAX:
            threading.Thread(target=host_b).start()
            assert tried.wait(5)

    assert a.upload_table(builtin_table(generation=5), progress=progress)["active_generation"] == 5
    assert got["b"] == "busy"
    assert b.read_table() == builtin_table(generation=5)


def test_concurrent_flashes_consistent(board):
    """Two hosts flash in a loop at once: each flash succeeds or fails with a one-line reason;
    the board ends on the newest generation some host was told it committed, byte for byte."""
    links = [board(), board()]
    results = [[], []]

    def run(k):
        for _ in range(6):
            try:
                r = flash(links[k], builtin_table(), 5, log=lambda *_: None)
                results[k].append(("ok", r["generation"]))
            except (DeviceError, RuntimeError) as e:
                assert "\n" not in str(e)
                results[k].append(("refused", str(e)))

    threads = [threading.Thread(target=run, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    committed = [g for res in results for kind, g in res if kind == "ok"]
    assert committed, results
    info = links[0].info()
    back = links[0].read_table()
    assert info["active_generation"] >= max(committed)
    assert back[60:] == builtin_table()[60:]
    assert int.from_bytes(back[16:20], "little") == info["active_generation"]


def test_usb_emulated_second_host_busy_until_timeout(tmp_path):
    """Host A opens an upload over USB and vanishes; host B is told busy until the board's
    session times out (PSL_UPLOAD_TIMEOUT_US, 5 s), then flashes."""
    from .test_usb_umockdev import _emu_or_skip

    usbemu = _emu_or_skip()
    r = usbemu.run([sys.executable, str(GUARD_CLIENT), "session"], flash_file=tmp_path / "flash.bin")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["busy_messages"] and all(m.startswith("board busy") for m in out["busy_messages"])
    assert 4.5 <= out["waited_s"] <= 7.0, out
    assert out["generation"] == 1
