#!/usr/bin/env python3
"""A red team of scripted cases over every `playscope` command and the board's link frames, as an
attacker and a careless user would try them: inputs that are pipes, devices, links, folders,
junk or the wrong kind of file; outputs aimed at inputs, at a user's files, at pipes, devices,
links and folders holding a user's file, with and without --force; option values out of range.

Each command case runs `python -m playscope ...` in a child process, in a fresh copy of a small
set of valid files, with a timeout (a hang is a failure) and the SHA-256 of every file before and
after (links, pipes and devices compared by what they are, never opened). A case fails on a
traceback, a hang, a pre-existing file changed or removed (other than a playscope output the
case names with --force), an exit status outside what the case expects, or a refusal that is
not one `playscope: error:` line. The link cases send frames to the virtual board (random
payloads of every message type, garbage, replays, implausible and damaged tables): the board
must answer or ignore each, stay alive, and keep its active table unless a valid one was sent.

    .venv/bin/python tools/redteam.py [--jobs 2] [--only SUBSTRING] [--keep DIR]

Prints one row per case (failures first) and the totals; exit status 1 when any case failed.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import hashlib
import json
import os
import random
import shutil
import stat
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PY = sys.executable
TIMEOUT_S = 90.0


@dataclass
class Case:
    name: str
    argv: list                      # playscope arguments; "{X}" is replaced by the case folder's X
    expect: tuple = (2,)            # exit statuses that pass
    setup: object = None            # callable(folder) run before the hashes are taken
    may_change: tuple = ()          # names (relative) a --force case may replace
    one_line: bool = True           # exit 2 must be exactly one `playscope: error:` line
    timeout: float = TIMEOUT_S


@dataclass
class Result:
    case: str
    ok: bool
    rc: object
    secs: float
    why: str = ""
    traceback: bool = False
    hang: bool = False
    changed: list = field(default_factory=list)


# --------------------------------------------------------------------------- the valid files
def build_base(root: Path) -> None:
    """Small valid inputs under root: A (angle session, 40 s), cal.json, t.pstb, V (image session
    with video, 3 s), rec.csv (catheter-like CSV), endo.csv (headerless, deg), board.flash, and a
    user's files: notes.txt, mine.json, photo.raw (an image's size), U/ (a folder of them)."""
    def pls(*a):
        r = subprocess.run([PY, "-m", "playscope", *map(str, a)], cwd=root, capture_output=True, text=True)
        if r.returncode:
            raise SystemExit(f"base set-up failed: playscope {' '.join(map(str, a))}\n{r.stderr}")

    pls("simulate", "A", "--kind", "angle", "--duration", "40", "--seed", "1", "-q")
    pls("calibrate", "A", "-o", "cal.json", "-q")
    pls("tables", "cal.json", "-o", "t.pstb", "-q")
    pls("simulate", "V", "--duration", "3", "--video", "-q")
    pls("flash", "t.pstb", "--flash-file", "board.flash", "--vectors", "5", "-q")
    enc = [r.split(",") for r in (root / "A" / "encoder.csv").read_text().splitlines()[1:]]
    dist = {r.split(",")[0]: r.split(",")[1] for r in (root / "A" / "distal.csv").read_text().splitlines()[1:]}
    rows = [(t, q, dist[t]) for t, q, *_ in enc if t in dist]
    (root / "rec.csv").write_text("Time,Tendon Disp.,Angle x\n" + "".join(f"{t},{q},{c}\n" for t, q, c in rows))
    (root / "endo.csv").write_text("".join(f"{t},{float(q) * 10:.4f},0,{c}\n" for t, q, c in rows))
    (root / "notes.txt").write_text("my notes\n")
    (root / "mine.json").write_text('{"mine": 1}\n')
    (root / "photo.raw").write_bytes(random.Random(1).randbytes(2 * 128 * 1024))
    (root / "U").mkdir()
    (root / "U" / "keep.txt").write_text("mine\n")


# --------------------------------------------------------------------------- hostile things
def fifo(name):
    return lambda d: os.mkfifo(d / name)


def devnode(name):
    def mk(d):
        if os.geteuid() == 0:
            os.mknod(d / name, 0o666 | stat.S_IFCHR, os.makedev(1, 3))  # a /dev/null of our own
        else:
            (d / name).symlink_to("/dev/null")
    return mk


def link(name, target):
    return lambda d: (d / name).symlink_to(target if target.startswith("/") else d / target)


def write(name, data):
    def mk(d):
        p = d / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data if isinstance(data, bytes) else data.encode())
    return mk


def seq(*fs):
    def mk(d):
        for f in fs:
            f(d)
    return mk


JUNK = bytes(random.Random(2).randrange(256) for _ in range(3000))

# Every kind of bad thing given where a file is read: (label, setup, path name).
BAD_INPUTS = [
    ("missing", None, "nothere"),
    ("folder", None, "U"),
    ("fifo", fifo("pipe"), "pipe"),
    ("device", devnode("node"), "node"),
    ("link to /dev/zero", link("zl", "/dev/zero"), "zl"),
    ("empty", write("empty.x", b""), "empty.x"),
    ("junk", write("junk.x", JUNK), "junk.x"),
    ("text", None, "notes.txt"),
    ("json of a user", None, "mine.json"),
    ("nul bytes", write("nul.x", b"\0" * 100), "nul.x"),
    ("dangling link", link("dl", "/nonexistent/x"), "dl"),
]

# Every kind of thing an output may be aimed at: (label, setup, name, with --force, may change).
BAD_OUTPUTS = [
    ("user text", None, "notes.txt"),
    ("user json", None, "mine.json"),
    ("user photo", None, "photo.raw"),
    ("fifo", fifo("opipe"), "opipe"),
    ("device", devnode("onode"), "onode"),
    ("link to user file", link("ol", "notes.txt"), "ol"),
    ("folder with user file", None, "U"),
    ("the table", None, "t.pstb"),
    ("the calibration", None, "cal.json"),
    ("session file", None, "A/encoder.csv"),
    ("session folder", None, "A"),
]


def command_cases() -> list[Case]:
    cases: list[Case] = []
    add = cases.append
    # Baselines: the undamaged set passes the cheap commands.
    add(Case("baseline tables", ["tables", "{cal.json}", "-o", "{new.pstb}"], (0,)))
    add(Case("baseline tables --force over its own", ["tables", "{cal.json}", "-o", "{t.pstb}", "--force",
                                                      "--generation", "3"], (0,), may_change=("t.pstb",)))
    add(Case("baseline import", ["import", "{rec.csv}", "-o", "{S2}"], (0,)))
    add(Case("baseline track", ["track", "{V}", "--force"], (0,), may_change=("V/marker.csv",)))
    add(Case("baseline flash", ["flash", "{t.pstb}", "--flash-file", "{board.flash}", "--vectors", "5",
                                "--generation", "9"] if False else
             ["flash", "{t.pstb}", "--flash-file", "{board.flash}", "--vectors", "5"], (0,),
             may_change=("board.flash",)))
    add(Case("baseline simulate", ["simulate", "{S3}", "--duration", "2", "--kind", "angle"], (0,)))
    add(Case("baseline evaluate-insitu", ["evaluate-insitu", "{A}", "--json", "{ei.json}"], (0,)))
    add(Case("baseline evaluate", ["evaluate", "{A}", "{cal.json}", "--comp-duration", "2"], (0,)))
    add(Case("baseline device info", ["device", "info"], (0,)))

    # Inputs: every reader, every bad thing.
    readers = {
        "tables cal": lambda p: ["tables", p, "-o", "{o.pstb}"],
        "calibrate session": lambda p: ["calibrate", p, "-o", "{o.json}"],
        "evaluate session": lambda p: ["evaluate", p, "{cal.json}"],
        "evaluate cal": lambda p: ["evaluate", "{A}", p],
        "evaluate --table": lambda p: ["evaluate", "{A}", "{cal.json}", "--table", p],
        "report cal": lambda p: ["report", p, "{A}", "-o", "{r.html}"],
        "report session": lambda p: ["report", "{cal.json}", p, "-o", "{r.html}"],
        "import csv": lambda p: ["import", p, "-o", "{S9}"],
        "track session": lambda p: ["track", p],
        "evaluate-insitu": lambda p: ["evaluate-insitu", p],
        "evaluate-transfer cal": lambda p: ["evaluate-transfer", p, "{rec.csv}"],
        "evaluate-transfer record": lambda p: ["evaluate-transfer", "{rec.csv}", p],
        "simulate --config": lambda p: ["simulate", "{S8}", "--config", p, "--duration", "2"],
        "simulate --reimage": lambda p: ["simulate", "{S8}", "--reimage", p, "--duration", "2"],
        "flash table": lambda p: ["flash", p, "--flash-file", "{nb.flash}"],
        "diagnose session": lambda p: ["diagnose", p],
        "run-insitu --geometry": lambda p: ["run-insitu", "--geometry", p, "--video", "{V}/video.avi", "--no-flash"],
        "evaluate-real folder": lambda p: ["evaluate-real", p],
    }
    for rname, mk in readers.items():
        for label, setup, name in BAD_INPUTS:
            if rname in ("evaluate-real folder",) and label == "folder":
                continue  # a folder is its input: U holds no records, refused below anyway
            add(Case(f"input {rname}: {label}", mk("{" + name + "}"), (2,), setup))
    # A session with a hostile file inside.
    for label, mk in (("video.avi a fifo", seq(lambda d: (d / "V" / "video.avi").unlink(), fifo("V/video.avi"))),
                      ("video.avi a device", seq(lambda d: (d / "V" / "video.avi").unlink(), devnode("V/video.avi"))),
                      ("video.avi a link to /dev/zero", seq(lambda d: (d / "V" / "video.avi").unlink(),
                                                            link("V/video.avi", "/dev/zero"))),
                      ("frames.csv a fifo", seq(lambda d: (d / "V" / "frames.csv").unlink(), fifo("V/frames.csv"))),
                      ("session.json a fifo", seq(lambda d: (d / "V" / "session.json").unlink(), fifo("V/session.json"))),
                      ("video.avi junk", write("V/video.avi", JUNK)),
                      ("video.avi empty", write("V/video.avi", b""))):
        add(Case(f"track: {label}", ["track", "{V}", "--force"], (2,), mk))
    for label, mk in (("encoder.csv a fifo", seq(lambda d: (d / "A" / "encoder.csv").unlink(), fifo("A/encoder.csv"))),
                      ("distal.csv a device", seq(lambda d: (d / "A" / "distal.csv").unlink(), devnode("A/distal.csv"))),
                      ("session.json junk", write("A/session.json", JUNK)),
                      ("session.json a list", write("A/session.json", "[1, 2]")),
                      ("encoder.csv junk", write("A/encoder.csv", JUNK))):
        for cmd in (["calibrate", "{A}", "-o", "{o.json}"], ["evaluate-insitu", "{A}"], ["evaluate", "{A}", "{cal.json}"]):
            add(Case(f"{cmd[0]}: {label}", cmd, (2,), mk))

    # Outputs: every writer, every target, with and without --force.
    writers = {
        "tables -o": lambda o: ["tables", "{cal.json}", "-o", o],
        "tables --json": lambda o: ["tables", "{cal.json}", "-o", "{o2.pstb}", "--json", o],
        "calibrate -o": lambda o: ["calibrate", "{A}", "-o", o],
        "import -o": lambda o: ["import", "{rec.csv}", "-o", o],
        "simulate out": lambda o: ["simulate", o, "--duration", "2", "--kind", "angle"],
        "track -o": lambda o: ["track", "{V}", "-o", o],
        "evaluate-insitu --json": lambda o: ["evaluate-insitu", "{A}", "--json", o],
        "report -o": lambda o: ["report", "{cal.json}", "{A}", "-o", o],
        "flash --flash-file": lambda o: ["flash", "{t.pstb}", "--flash-file", o, "--vectors", "5"],
        "evaluate-transfer --plot": lambda o: ["evaluate-transfer", "{rec.csv}", "{rec.csv}", "--plot", o],
        "diagnose --html": lambda o: ["diagnose", "{A}", "--html", o],
        "demo --json": lambda o: ["demo", "--out", "{D}", "--json", o],
        "run-insitu -o": lambda o: ["run-insitu", "--sim-plant", "--no-flash", "--seconds", "1", "-o", o],
    }
    # What each writer reads: those targets are refused even with --force; playscope's own
    # outputs that are not its inputs may be replaced with --force (exit 0 or 2, they may change).
    reads = {"tables -o": ("cal.json",), "tables --json": ("cal.json",), "calibrate -o": ("A",), "import -o": ("rec.csv",),
             "simulate out": (), "track -o": ("V",), "evaluate-insitu --json": ("A",),
             "report -o": ("cal.json", "A"), "flash --flash-file": ("t.pstb",), "evaluate-transfer --plot": ("rec.csv",),
             "diagnose --html": ("A",), "run-insitu -o": ()}
    own = {"t.pstb", "cal.json", "A", "A/encoder.csv"}
    for wname, mk in writers.items():
        for label, setup, name in BAD_OUTPUTS:
            if wname == "demo --json":
                continue  # demo --json is a work file of demo's own (cli.WORK_ARGS)
            for force in ([], ["--force"]):
                mine = force and name in own and not any(name == r or name.startswith(r + "/") for r in reads[wname])
                expect = (0, 1, 2) if mine else (2,)
                add(Case(f"output {wname}: {label}{' --force' if force else ''}", mk("{" + name + "}") + force, expect,
                         setup, may_change=(name,) if mine else ()))
    # Outputs into a folder that is a link, a file as a parent folder.
    add(Case("output under a file as folder", ["tables", "{cal.json}", "-o", "{notes.txt}/t.pstb"], (2,)))
    add(Case("simulate --overwrite over a session holding a user's sub-folder",
             ["simulate", "{A}", "--duration", "2", "--kind", "angle", "--overwrite"], (2,),
             write("A/session/notes.txt", "mine\n")))
    add(Case("import --overwrite over S/video.avi/ a folder", ["import", "{rec.csv}", "-o", "{V}", "--overwrite"], (2,),
             write("V/x/video.avi/clip.txt", "mine\n")))

    # Option values out of range.
    vals = ["nan", "inf", "-inf", "-1", "0", "1e309", "abc", "", "1e-300", "99999999999"]
    opts = [
        (["tables", "{cal.json}", "-o", "{o.pstb}", "--generation"], "tables --generation"),
        (["tables", "{cal.json}", "-o", "{o.pstb}", "--entries"], "tables --entries"),
        (["calibrate", "{A}", "-o", "{o.json}", "--fps"], "calibrate --fps"),
        (["calibrate", "{A}", "-o", "{o.json}", "-N"], "calibrate -N"),
        (["calibrate", "{A}", "-o", "{o.json}", "--t-delay"], "calibrate --t-delay"),
        (["evaluate-insitu", "{A}", "--split"], "evaluate-insitu --split"),
        (["simulate", "{S7}", "--duration"], "simulate --duration"),
        (["simulate", "{S7}", "--seed"], "simulate --seed"),
        (["evaluate", "{A}", "{cal.json}", "--comp-duration"], "evaluate --comp-duration"),
        (["flash", "{t.pstb}", "--flash-file", "{nb.flash}", "--vectors"], "flash --vectors"),
        (["evaluate-transfer", "{rec.csv}", "{rec.csv}", "--warmup"], "evaluate-transfer --warmup"),
        (["import", "{rec.csv}", "-o", "{S6}", "--time-scale"], "import --time-scale"),
        (["run-insitu", "--sim-plant", "--no-flash", "--seconds"], "run-insitu --seconds"),
    ]
    for base, label in opts:
        for v in vals:  # a number may be valid for an option (0 delay, seed 0): no traceback, no hang
            add(Case(f"option {label} {v!r}", base + [v], (2,) if v in ("nan", "inf", "-inf", "1e309", "abc", "") else (0, 2)))
    # Damaged tables and calibrations with every command that reads them.
    blob_damage = {"truncated": lambda b: b[: len(b) // 2], "flipped byte": lambda b: b[:40] + bytes([b[40] ^ 1]) + b[41:],
                   "zero CRC": lambda b: b[:12] + b"\0\0\0\0" + b[16:], "extra bytes": lambda b: b + b"\0" * 64}
    for label, dmg in blob_damage.items():
        def mk(d, dmg=dmg):
            (d / "bad.pstb").write_bytes(dmg((d / "t.pstb").read_bytes()))
        add(Case(f"flash: table {label}", ["flash", "{bad.pstb}", "--flash-file", "{board.flash}"], (2,), mk))
        add(Case(f"evaluate --table: {label}", ["evaluate", "{A}", "{cal.json}", "--table", "{bad.pstb}"], (2,), mk))
    cal_damage = [("q_range reversed", lambda d: d.__setitem__("q_range", d["q_range"][::-1])),
                  ("B a string", lambda d: d.__setitem__("B", "x")),
                  ("B.floor a dict", lambda d: d["B"].__setitem__("floor", {})),
                  ("transition a number", lambda d: d.__setitem__("transition", 3)),
                  ("model_family a list", lambda d: d.__setitem__("model_family", [1])),
                  ("format missing", lambda d: d.pop("format")),
                  ("f_coarse missing", lambda d: d.pop("f_coarse")),
                  ("actuator_unit um", lambda d: d.__setitem__("actuator_unit", "um"))]
    for label, dmg in cal_damage:
        def mk(d, dmg=dmg):
            doc = json.loads((d / "cal.json").read_text())
            dmg(doc)
            (d / "bad.json").write_text(json.dumps(doc))
        for cmd in (["tables", "{bad.json}", "-o", "{o.pstb}"], ["evaluate", "{A}", "{bad.json}"],
                    ["report", "{bad.json}", "{A}", "-o", "{r.html}"]):
            add(Case(f"{cmd[0]}: calibration {label}", cmd, (2,), mk))
    # Another calibration's table (warned), records of another unit (refused).
    add(Case("evaluate-transfer mm with deg", ["evaluate-transfer", "{rec.csv}", "{endo.csv}"], (2,)))
    return cases


# --------------------------------------------------------------------------- running a case
def snapshot(root: Path) -> dict:
    out = {}
    for dirpath, dirs, names in os.walk(root):
        for n in names + dirs:
            p = Path(dirpath) / n
            st = os.lstat(p)
            rel = p.relative_to(root).as_posix()
            if stat.S_ISREG(st.st_mode):
                h = hashlib.sha256()
                with open(p, "rb") as fh:
                    for b in iter(lambda: fh.read(1 << 20), b""):
                        h.update(b)
                out[rel] = h.hexdigest()
            elif stat.S_ISLNK(st.st_mode):
                out[rel] = "link:" + os.readlink(p)
            elif stat.S_ISDIR(st.st_mode):
                out[rel] = "dir"
            else:
                out[rel] = f"special:{stat.S_IFMT(st.st_mode)}:{st.st_rdev}"
    return out


def run_case(case: Case, base: Path, work: Path) -> Result:
    d = Path(tempfile.mkdtemp(prefix="case-", dir=work))
    shutil.copytree(base, d, symlinks=True, dirs_exist_ok=True)
    if case.setup:
        case.setup(d)
    argv = []
    for a in case.argv:
        while "{" in a:
            i, j = a.index("{"), a.index("}")
            a = a[:i] + str(d / a[i + 1:j]) + a[j + 1:]
        argv.append(a)
    before = snapshot(d)
    t0 = time.monotonic()
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", PYTHONWARNINGS="ignore")
    try:
        p = subprocess.Popen([PY, "-m", "playscope", *argv], cwd=d, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True, env=env, start_new_session=True)
        try:
            out, err = p.communicate(timeout=case.timeout)
            rc = p.returncode
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, 9)
            p.communicate()
            return Result(case.name, False, "hang", time.monotonic() - t0, f"no end within {case.timeout:.0f} s",
                          hang=True)
    finally:
        secs = time.monotonic() - t0
    after = snapshot(d)
    changed = [k for k, v in before.items() if after.get(k) != v
               and not any(k == m or k.startswith(m + "/") for m in case.may_change)]
    tb = "Traceback (most recent call last)" in err
    errs = [x for x in err.splitlines() if x.startswith("playscope: error:")]
    why = []
    if tb:
        why.append("traceback")
    if rc not in case.expect:
        why.append(f"exit {rc}, expected {'/'.join(map(str, case.expect))}")
    other = [x for x in err.strip().splitlines() if x and not x.startswith(("playscope: warning:", "playscope: error:",
                                                                             "SIMULATION:", "excitation"))]
    if rc == 2 and case.one_line and (len(errs) != 1 or other):
        why.append("not one error line")
    if changed:
        why.append("changed: " + ", ".join(changed[:4]))
    msg = "; ".join(why)
    if why:
        msg += " | " + (errs[0][:160] if errs else err.strip().splitlines()[-1][:160] if err.strip() else "")
    shutil.rmtree(d, ignore_errors=True)
    return Result(case.name, not why, rc, secs, msg, tb, False, changed)


# --------------------------------------------------------------------------- link frames
def link_cases(work: Path) -> list[Result]:
    """Frames straight to the virtual board: the board answers or ignores each, stays alive,
    and its active table changes only when a valid, plausible table is committed."""
    sys.path.insert(0, str(REPO / "host"))
    from playscope.board.link import DeviceError, Link
    from playscope.board.transport import TransportError, virtual_transport

    results = []
    flash_file = work / "link.flash"
    flash_file.unlink(missing_ok=True)  # a fresh board: its first table is generation 1
    base = work / "base"
    tr = virtual_transport(flash_file)
    lk = Link(tr, timeout_s=3.0)
    blob = (base / "t.pstb").read_bytes()
    lk.upload_table(blob)
    state = {"active": lk.read_table()}
    lib, ffi = lk.lib, lk.ffi
    mtypes = sorted({getattr(lib, n) for n in dir(lib) if n.startswith("PSP_MSG_") and isinstance(getattr(lib, n), int)
                     and getattr(lib, n) < 0x80})
    rng = random.Random(3)

    def alive() -> bool:
        try:
            lk.sync(attempts=3)
            return True
        except (DeviceError, TransportError):
            return False

    def record(name, fn, must_keep=True):
        t0 = time.monotonic()
        why = ""
        try:
            fn()
        except (DeviceError, TransportError, ValueError):
            pass  # a refusal is what is wanted; the checks below decide
        except Exception as e:  # noqa: BLE001 - anything else is a finding
            why = f"{type(e).__name__}: {e}"
        if not alive():
            why = (why + "; " if why else "") + "board no longer answers"
        elif must_keep:
            try:
                now = lk.read_table()
                if now != state["active"]:
                    why = (why + "; " if why else "") + "active table changed"
                    state["active"] = now  # judged once: the next cases compare with what is active now
            except (DeviceError, TransportError) as e:
                why = (why + "; " if why else "") + f"cannot read the table back: {e}"
        results.append(Result(name, not why, "-", time.monotonic() - t0, why))

    for m in mtypes:
        if m in (lib.PSP_MSG_TABLE_COMMIT,):
            pass
        for n in (0, 1, 7, 64, 200):
            pl = bytes(rng.randrange(256) for _ in range(n))
            record(f"link: type 0x{m:02x} random payload {n} B", lambda m=m, pl=pl: lk.request(m, pl, timeout_s=1.0))
    for k in range(10):
        junk = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 600)))
        record(f"link: garbage bytes #{k}", lambda junk=junk: tr.write(junk))
    record("link: replayed seq", lambda: lk.request(lib.PSP_MSG_INFO if hasattr(lib, "PSP_MSG_INFO") else mtypes[0],
                                                    b"", seq=1, timeout_s=1.0))
    for label, dmg in (("zero CRC", lambda b: b[:12] + b"\0\0\0\0" + b[16:]),
                       ("flipped data byte", lambda b: b[:-5] + bytes([b[-5] ^ 0x10]) + b[-4:]),
                       ("truncated", lambda b: b[:len(b) // 2]),
                       ("q_max flipped", lambda b: b[:24] + bytes([b[24] ^ 4]) + b[25:])):
        record(f"link: upload table {label}", lambda dmg=dmg: lk.upload_table(dmg(blob)))
    # Tables with a valid CRC and an intact structure whose physics no instrument has: refused
    # by the board's loader (ps_table.h PST_PLAUS_*), the active table kept.
    import numpy as np

    from playscope.fit.table_build import set_generation

    hd = ffi.new("pst_header_t *")
    ffi.memmove(hd, blob[:ffi.sizeof("pst_header_t")], ffi.sizeof("pst_header_t"))
    travel = hd.q_max_q16 - hd.q_min_q16
    b0 = np.frombuffer(blob[hd.b.offset:hd.b.offset + 4 * hd.b.n], "<i4").astype(np.int64)
    f0 = np.frombuffer(blob[hd.f.offset:hd.f.offset + 4 * hd.f.n], "<i4").astype(np.int64)

    def reseal(q_range=None, b=None, f=None, gen=None) -> bytes:
        out = bytearray(blob)
        if q_range is not None:
            at = ffi.offsetof("pst_header_t", "q_min_q16")
            out[at:at + 8] = np.array(q_range, "<i4").tobytes()
        for grid, v in ((hd.b, b), (hd.f, f)):
            if v is not None:
                out[grid.offset:grid.offset + 4 * grid.n] = np.clip(v, -2**31, 2**31 - 1).astype("<i4").tobytes()
        if gen is not None:
            at = ffi.offsetof("pst_header_t", "generation")
            out[at:at + 4] = int(gen).to_bytes(4, "little")
        crc = lib.calib_table_crc(ffi.from_buffer(out), hd.total_size)
        at = ffi.offsetof("pst_header_t", "crc32")
        out[at:at + 4] = int(crc).to_bytes(4, "little")
        return bytes(out)

    gen = [hd.generation + 10]

    def newer(**kw) -> bytes:
        gen[0] += 1
        return reseal(gen=gen[0], **kw)

    for label, kw in (("B twice the travel", {"b": np.full_like(b0, 2 * travel)}),
                      ("B the whole travel", {"b": np.full_like(b0, travel)}),
                      ("f scaled x100", {"f": f0 * 100}),
                      ("f flat", {"f": np.full_like(f0, int(f0[0])) + np.arange(f0.size)}),
                      ("travel of 1 raw", {"q_range": [hd.q_min_q16, hd.q_min_q16 + 1]}),
                      ("negative B", {"b": -b0})):
        record(f"link: implausible table, valid CRC: {label}", lambda kw=kw: lk.upload_table(newer(**kw)))
    record("link: the active table again (same generation)", lambda: lk.upload_table(state["active"]))
    record("link: an older generation", lambda: lk.upload_table(reseal(gen=max(hd.generation - 1, 0))))

    def take_newer():  # the control: a valid table of a newer generation is taken
        lk.upload_table(set_generation(blob, gen[0] + 1))
        if lk.read_table() == state["active"]:
            raise RuntimeError("a valid newer table was not taken")
        state["active"] = lk.read_table()
    record("link: control, a valid newer table is taken", take_newer, must_keep=False)
    record("link: begin upload, never commit", lambda: lk.begin_upload(len(blob), 0x1234))
    lk.close()
    tr.close()
    return results


# --------------------------------------------------------------------------- main
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", help="run only the cases whose name holds this")
    ap.add_argument("--keep", help="work folder to keep (default: a temporary one, removed)")
    ap.add_argument("--no-link", action="store_true", help="skip the link-frame cases")
    a = ap.parse_args(argv)
    work = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="playscope-redteam-"))
    work.mkdir(parents=True, exist_ok=True)
    base = work / "base"
    t0 = time.monotonic()
    if not (base / "t.pstb").exists():
        shutil.rmtree(base, ignore_errors=True)
        base.mkdir()
        build_base(base)
    cases = [c for c in command_cases() if not a.only or a.only in c.name]
    print(f"{len(cases)} command cases, base set in {time.monotonic() - t0:.0f} s", flush=True)
    results: list[Result] = []
    with cf.ThreadPoolExecutor(max_workers=max(1, a.jobs)) as ex:
        for r in ex.map(lambda c: run_case(c, base, work), cases):
            results.append(r)
            if not r.ok:
                print(f"FAIL {r.case}: {r.why}", flush=True)
    if not a.no_link and not a.only:
        results += link_cases(work)
    if not a.keep:
        shutil.rmtree(work, ignore_errors=True)
    results.sort(key=lambda r: (r.ok, r.case))
    print("\n| case | result | exit | s | why |\n|---|---|---|---|---|")
    for r in results:
        print(f"| {r.case} | {'ok' if r.ok else 'FAIL'} | {r.rc} | {r.secs:.1f} | {r.why} |")
    n_fail = sum(not r.ok for r in results)
    print(f"\nTOTAL cases {len(results)}, passed {len(results) - n_fail}, failed {n_fail}: "
          f"tracebacks {sum(r.traceback for r in results)}, hangs {sum(r.hang for r in results)}, "
          f"user files changed {sum(bool(r.changed) for r in results)}, "
          f"link cases {sum(r.case.startswith('link:') for r in results)}; {time.monotonic() - t0:.0f} s")
    return 1 if n_fail else 0


if __name__ == "__main__":
    sys.exit(main())
