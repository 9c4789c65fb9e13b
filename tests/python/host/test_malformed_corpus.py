"""No tracebacks, no hangs, nothing of the user's changed: a corpus of malformed, hostile or
implausible inputs, generated here from one set of valid files (goodfiles.make_good), each
damaged one way: command-line values, session folders, calibration JSON, table blobs
(structural damage and valid-CRC tables with impossible physics), foreign CSVs, outputs aimed
at inputs or at a user's files (the board's flash file, --force over other kinds, folders
holding a user's file), named pipes and devices as inputs, simulate --config files. Every
case must end within CASE_TIMEOUT_S with exit status 2, exactly one stderr line
``playscope: error: ...``, and no file created, changed or removed (SHA-256 of every file
before and after)."""

from __future__ import annotations

import hashlib
import json
import os
import warnings

import pytest

from playscope.cli import main

from .goodfiles import copy_good

JUNK = bytes(range(256)) * 3


# --------------------------------------------------------------------------- damage helpers
def _write(rel: str, data: bytes | str):
    def f(g):
        p = g["root"] / rel
        if p.is_dir():
            import shutil
            shutil.rmtree(p)
        p.write_bytes(data if isinstance(data, bytes) else data.encode())
    return f


def _delete(rel: str):
    def f(g):
        (g["root"] / rel).unlink()
    return f


def _to_folder(rel: str):
    def f(g):
        p = g["root"] / rel
        p.unlink()
        p.mkdir()
    return f


def _json_edit(rel: str, fn):
    def f(g):
        p = g["root"] / rel
        d = json.loads(p.read_text())
        fn(d)
        p.write_text(json.dumps(d))
    return f


def _csv_edit(rel: str, fn):
    def f(g):
        p = g["root"] / rel
        lines = p.read_text().splitlines()
        fn(lines)
        p.write_text("\n".join(lines) + "\n")
    return f


def _clock_reset(first: int, back_s: float = 1000.0):
    """Lines from ``first`` on moved back by back_s seconds: a clock reset (or two joined logs),
    refused; one stray backward row is dropped with a warning by design."""
    def fn(lines):
        for i in range(first, len(lines)):
            t, rest = lines[i].split(",", 1)
            lines[i] = f"{float(t) - back_s!r},{rest}"
    return fn


def _set(path: str, value):
    """Edit of a nested key "a.b.c" (value DELETE removes it)."""
    def fn(d):
        keys = path.split(".")
        for k in keys[:-1]:
            d = d[k]
        if value is DELETE:
            del d[keys[-1]]
        else:
            d[keys[-1]] = value
    return fn


def _fifo(rel: str):
    """rel replaced by a named pipe nobody writes: opening it for reading would block forever."""
    def f(g):
        p = g["root"] / rel
        if p.is_dir():
            import shutil
            shutil.rmtree(p)
        elif p.exists():
            p.unlink()
        os.mkfifo(p)
    return f


def _link(rel: str, target: str):
    """rel replaced by a symlink to target (a device such as /dev/urandom never ends)."""
    def f(g):
        p = g["root"] / rel
        if p.exists():
            p.unlink()
        os.symlink(target, p)
    return f


def _user_folder(rel: str, own: str = "notes.txt"):
    """A folder rel holding a session and a user's own file (which nothing may delete)."""
    def f(g):
        import shutil
        d = g["root"] / rel
        shutil.copytree(g["session"], d)
        (d / own).write_text("my notes\n")
    return f


def _both(*fs):
    def f(g):
        for x in fs:
            x(g)
    return f


DELETE = object()
S = "session/"
CAL = ["calibrate", "{session}", "-o", "{root}/out.json", "--fps", "25"]
TAB = ["tables", "{cal}", "-o", "{root}/out.pstb"]
FLASH = ["flash", "{table}", "--flash-file", "{root}/board.bin"]
IMPORT = ["import", "{csv}", "-o", "{root}/imported"]


def cases() -> list[tuple[str, list[str], object]]:
    """(id, argv template, damage or None)."""
    out = []

    def add(name, argv, damage=None):
        out.append((name, argv, damage))

    # ---- command-line values (argparse types): 92 cases
    values = {
        ("calibrate", "-N"): ["0", "2", "3", "65", "100000", "abc", "1.5", "-1"],
        ("calibrate", "--fps"): ["0", "-1", "nan", "inf", "1e-9", "abc", "1e9"],
        ("calibrate", "--t-delay"): ["-1", "nan", "inf", "11", "x"],
        ("calibrate", "--hysteresis"): ["0", "-1", "nan", "1e9"],
        ("calibrate", "--threshold"): ["0", "-1", "nan", "1e9", "inf"],
        ("calibrate", "--f-method"): ["bogus"],
        ("tables", "--entries"): ["0", "1", "257", "-5", "x"],
        ("tables", "--generation"): ["0", "-1", "4294967296", "1e3", "x"],
        ("evaluate", "--comp-duration"): ["0", "-1", "nan", "1e9"],
        ("import", "--time-scale"): ["0", "-1", "nan"],
        ("import", "--q-scale"): ["0", "nan", "inf"],
        ("import", "--q-per-rad"): ["0", "nan"],
        ("import", "--unit"): ["furlong"],
        ("track", "--s-min"): ["256", "-1"],
        ("track", "--v-min"): ["300"],
        ("track", "--circ-min"): ["2", "-0.1"],
        ("track", "--roi"): ["0", "100000"],
        ("flash", "--vectors"): ["0", "-1", "x", "1000000000"],
        ("flash", "--address"): ["nocolon", "host:0", "host:99999"],
        ("run-insitu", "--time-scale"): ["0", "1000"],
        ("run-insitu", "--seconds"): ["0", "-5", "nan"],
        ("run-insitu", "--exc"): ["1:2:3", "a:b:c:d:e"],
        ("run-insitu", "-N"): ["1"],
        ("run-insitu", "--seed"): ["-1"],
        ("simulate", "--duration"): ["0", "-1", "nan"],
        ("simulate", "--seed"): ["-1"],
        ("diagnose", "--split"): ["0", "1", "1.5"],
        ("diagnose", "--workers"): ["0", "1000"],
    }
    base = {"calibrate": CAL, "tables": TAB, "evaluate": ["evaluate", "{session}", "{cal}"], "import": IMPORT,
            "track": ["track", "{session}"], "flash": FLASH, "run-insitu": ["run-insitu", "--no-flash"],
            "simulate": ["simulate", "{root}/sim"], "diagnose": ["diagnose", "{session}"]}
    for (cmd, opt), vals in values.items():
        for v in vals:
            add(f"arg {cmd} {opt} {v}", base[cmd] + [opt, v])
    add("arg track --hue 0 180", ["track", "{session}", "--hue", "0", "180"])
    add("arg track --area nan 5", ["track", "{session}", "--area", "nan", "5"])
    add("arg flash --flash-file folder", ["flash", "{table}", "--flash-file", "{session}"])
    add("arg flash --elf missing", ["flash", "{table}", "--device", "qemu", "--elf", "{root}/nope.elf"])
    add("arg calibrate -o folder", ["calibrate", "{session}", "-o", "{root}"])
    add("arg unknown command", ["frobnicate"])
    add("arg calibrate missing -o", ["calibrate", "{session}"])

    # ---- session folders: 49 cases
    sj = S + "session.json"
    for name, dmg in [
        ("missing", _delete(sj)), ("empty", _write(sj, "")), ("truncated", _write(sj, '{"format": "playscope-se')),
        ("binary", _write(sj, JUNK)), ("invalid utf-8", _write(sj, b'{"format": "\xff\xfe"}')),
        ("nested", _write(sj, "[" * 100000 + "]" * 100000)), ("list", _write(sj, "[]")), ("null", _write(sj, "null")),
        ("NUL bytes", _write(sj, b"\x00" * 64)), ("a folder", _to_folder(sj)),
        ("format", _json_edit(sj, _set("format", "playscope-session/9"))),
        ("no actuator", _json_edit(sj, _set("actuator", DELETE))),
        ("unit", _json_edit(sj, _set("actuator.unit", "furlong"))),
        ("kind", _json_edit(sj, _set("distal.kind", "smell"))),
        ("no robot", _json_edit(sj, _set("robot", DELETE))),
        ("robot model", _json_edit(sj, _set("robot.model", "snake"))),
        ("q_per_rad 0", _json_edit(sj, _set("robot.q_per_rad", 0))),
        ("bend length", _json_edit(sj, _set("robot.bend_length_mm", -1))),
        ("bend length NaN", _json_edit(sj, _set("robot.bend_length_mm", float("nan")))),
        ("bend length str", _json_edit(sj, _set("robot.bend_length_mm", "20"))),
        ("t_delay negative", _json_edit(sj, _set("t_delay_s", -1))),
        ("t_delay str", _json_edit(sj, _set("t_delay_s", "x"))),
        ("camera K singular", _json_edit(sj, _set("camera", {"width": 720, "height": 576, "fps": 25,
                                                             "K": [[0, 0, 360], [0, 380, 288], [0, 0, 1]]}))),
        ("camera K inf", _json_edit(sj, _set("camera", {"width": 720, "height": 576, "fps": 25,
                                                        "K": [[float("inf"), 0, 360], [0, 380, 288], [0, 0, 1]]}))),
        ("camera folds", _json_edit(sj, _set("camera", {"width": 720, "height": 576, "fps": 25,
                                                        "K": [[380, 0, 360], [0, 380, 288], [0, 0, 1]],
                                                        "dist": [-1.0, 0, 0, 0, 0]}))),
        ("camera width 0", _json_edit(sj, _set("camera", {"width": 0, "height": 576, "fps": 25,
                                                          "K": [[380, 0, 360], [0, 380, 288], [0, 0, 1]]}))),
        ("camera fps 0", _json_edit(sj, _set("camera", {"width": 720, "height": 576, "fps": 0,
                                                        "K": [[380, 0, 360], [0, 380, 288], [0, 0, 1]]}))),
        ("hand_eye not rotation", _json_edit(sj, _set("hand_eye", {"R": [[2, 0, 0], [0, 1, 0], [0, 0, 1]],
                                                                   "t_mm": [0, 0, 50]}))),
    ]:
        add(f"session.json {name}", CAL, dmg)
    enc = S + "encoder.csv"
    for name, dmg in [
        ("missing", _delete(enc)), ("empty", _write(enc, "")), ("header only", _write(enc, "t_s,q\n")),
        ("wrong header", _csv_edit(enc, lambda L: L.__setitem__(0, "time,pos"))),
        ("text cell", _csv_edit(enc, lambda L: L.__setitem__(50, "0.5,abc"))),
        ("NaN cell", _csv_edit(enc, lambda L: L.__setitem__(50, "0.5,nan"))),
        ("inf cell", _csv_edit(enc, lambda L: L.__setitem__(50, "0.5,inf"))),
        ("short row", _csv_edit(enc, lambda L: L.__setitem__(50, "0.5"))),
        ("time backwards (clock reset)", _csv_edit(enc, _clock_reset(50))),
        ("binary", _write(enc, JUNK)), ("NUL bytes", _write(enc, b"t_s,q\n0,\x00\x00\n")),
        ("invalid utf-8", _write(enc, b"t_s,q\n0,1\n\xff\xfe,2\n")), ("a folder", _to_folder(enc)),
        ("one row", _write(enc, "t_s,q\n0,1\n")),
        ("never moves", _write(enc, "t_s,q\n" + "".join(f"{k * 0.01},1.0\n" for k in range(500)))),
    ]:
        add(f"encoder.csv {name}", CAL, dmg)
    dis = S + "distal.csv"
    for name, dmg in [("missing", _delete(dis)), ("text cell", _csv_edit(dis, lambda L: L.__setitem__(9, "1,x"))),
                      ("time backwards (clock reset)", _csv_edit(dis, _clock_reset(9))),
                      ("invalid utf-8", _write(dis, b"t_s,c_deg\n\xff\n"))]:
        add(f"distal.csv {name}", CAL, dmg)
    add("session folder missing", ["calibrate", "{root}/nope", "-o", "{root}/out.json"])
    add("session is a file", ["calibrate", "{cal}", "-o", "{root}/out.json"])

    # ---- calibration JSON: 30 cases
    for name, dmg in [
        ("missing", _delete("cal.json")), ("empty", _write("cal.json", "")), ("not JSON", _write("cal.json", "B = 1")),
        ("invalid utf-8", _write("cal.json", b'{"\xff": 1}')), ("binary", _write("cal.json", JUNK)),
        ("list", _write("cal.json", "[1, 2]")), ("nested", _write("cal.json", '{"a":' * 50000 + "1" + "}" * 50000)),
        ("a folder", _to_folder("cal.json")),
        ("format", _json_edit("cal.json", _set("format", "other/1"))),
        ("q_range missing", _json_edit("cal.json", _set("q_range", DELETE))),
        ("q_range NaN", _json_edit("cal.json", _set("q_range", [float("nan"), 1.0]))),
        ("q_range reversed", _json_edit("cal.json", _set("q_range", [2.0, -2.0]))),
        ("q_range beyond Q16.16", _json_edit("cal.json", _set("q_range", [0.0, 1e6]))),
        ("q_range strings", _json_edit("cal.json", _set("q_range", ["a", "b"]))),
        ("q_range one", _json_edit("cal.json", _set("q_range", [1.0]))),
        ("B missing", _json_edit("cal.json", _set("B", DELETE))),
        ("B garbage", _json_edit("cal.json", _set("B", "spline"))),
        ("f_remain missing", _json_edit("cal.json", _set("f_remain", DELETE))),
        ("f_remain sign", _json_edit("cal.json", _set("f_remain.sign", "up"))),
        ("B degree 7", _json_edit("cal.json", _set("B.degree", 7))),
        ("B coef NaN", _json_edit("cal.json", lambda d: d["B"].__setitem__("coef", [float("nan")] * len(d["B"]["coef"])))),
        ("B coef 1e30", _json_edit("cal.json", lambda d: d["B"].__setitem__("coef", [1e30] * len(d["B"]["coef"])))),
        ("B range reversed", _json_edit("cal.json", _set("B.range", [2.0, -2.0]))),
        ("f_remain sign 0", _json_edit("cal.json", _set("f_remain.sign", 0))),
        ("q_per_rad 0", _json_edit("cal.json", _set("f_coarse.q_per_rad", 0))),
        ("actuator unit", _json_edit("cal.json", _set("actuator_unit", "furlong"))),
        # Physically impossible models: refused by tables.check_physical.
        ("B negative", _json_edit("cal.json", lambda d: d["B"].__setitem__("coef", [-0.3] * len(d["B"]["coef"])))),
        ("B all zero", _json_edit("cal.json", lambda d: d["B"].__setitem__("coef", [0.0] * len(d["B"]["coef"])))),
        ("f_remain all zero", _json_edit("cal.json", lambda d: d["f_remain"].__setitem__(
            "coef", [0.0] * len(d["f_remain"]["coef"])))),
        ("f_remain not monotone", _json_edit("cal.json", lambda d: d["f_remain"].__setitem__(
            "coef", [(-1) ** k * 20.0 for k in range(len(d["f_remain"]["coef"]))]))),
        # A play of 2 raw units: the table's own rounding would exceed it (CALIB_ERR_PRECISION).
        ("B tiny", _json_edit("cal.json", lambda d: d["B"].__setitem__("coef", [3e-5] * len(d["B"]["coef"])))),
        # Implausible for the travel (PST_PLAUS_*): a play of 100 mm, f scaled x500.
        ("B 100 mm", _json_edit("cal.json", lambda d: d["B"].__setitem__("coef", [100.0] * len(d["B"]["coef"])))),
        ("f_remain x500", _json_edit("cal.json", lambda d: d["f_remain"].__setitem__(
            "coef", [500.0 * c for c in d["f_remain"]["coef"]]))),
    ]:
        add(f"cal.json {name}", TAB, dmg)
    for name, dmg in [("missing", _delete("cal.json")), ("list", _write("cal.json", "[]")),
                      ("invalid utf-8", _write("cal.json", b"\xff"))]:
        add(f"evaluate cal.json {name}", ["evaluate", "{session}", "{cal}"], dmg)

    # ---- table blobs for flash: 14 cases (refused before the board is started)
    from .goodfiles import table_damages

    for name, dmg in table_damages():
        add(f"table {name}", FLASH, dmg)
    # Valid CRC, intact structure, impossible physics (ps_table.h PST_PLAUS_*): refused by rule.
    from .goodfiles import table_nonsense

    for name, _code, dmg in table_nonsense():
        add(f"table {name}", FLASH, dmg)
    add("table missing", FLASH, _delete("table.pstb"))
    add("table empty", FLASH, _write("table.pstb", b""))
    add("table a folder", FLASH, _to_folder("table.pstb"))
    add("table random", FLASH, _write("table.pstb", JUNK[:600]))
    add("table too large", FLASH, _write("table.pstb", JUNK * 10))

    # ---- foreign CSV for import: 8 cases
    for name, dmg in [("missing", _delete("rec.csv")), ("empty", _write("rec.csv", "")),
                      ("header only", _write("rec.csv", "Time,Tendon Disp.,Angle x\n")),
                      ("wrong columns", _csv_edit("rec.csv", lambda L: L.__setitem__(0, "a,b,c"))),
                      ("text cell", _csv_edit("rec.csv", lambda L: L.__setitem__(20, "0.2,x,1"))),
                      ("invalid utf-8", _write("rec.csv", b"Time,Tendon Disp.,Angle x\n\xff,1,2\n")),
                      ("binary", _write("rec.csv", JUNK)), ("a folder", _to_folder("rec.csv"))]:
        add(f"import {name}", IMPORT, dmg)

    # ---- outputs aimed at inputs, or existing without --force: 8 cases
    add("out onto encoder.csv", ["calibrate", "{session}", "-o", "{session}/encoder.csv", "--force"])
    add("out onto session.json", ["calibrate", "{session}", "-o", "{session}/session.json"])
    add("out onto the calibration", ["tables", "{cal}", "-o", "{cal}", "--force"])
    add("json onto distal.csv", CAL + ["--json", "{session}/distal.csv", "--force"])
    add("existing table no --force", ["tables", "{cal}", "-o", "{table}"])
    add("import over its own folder", ["import", "{csv}", "-o", "{root}", "--overwrite"])
    add("report onto the session", ["report", "{cal}", "{session}", "-o", "{session}/session.json", "--force"])
    add("simulate over its --reimage source", ["simulate", "{session}", "--reimage", "{session}", "--overwrite"])

    # ---- nothing of the user's overwritten: the board's flash file and --force's limits
    for target in ("{table}", "{cal}", "{csv}", "{session}/session.json", "{session}/encoder.csv",
                   "{session}/distal.csv", "{session}/truth.csv", "{session}"):
        for force in ([], ["--force"]):
            add(f"flash-file onto {target}{' ' + force[0] if force else ''}",
                ["flash", "{table}", "--flash-file", target] + force)
    add("flash-file a FIFO", ["flash", "{table}", "--flash-file", "{root}/pipe"], _fifo("pipe"))
    add("flash-file a device", ["flash", "{table}", "--flash-file", "{root}/dev"], _link("dev", "/dev/zero"))
    for opt in ("--overwrite", "--force"):
        add(f"simulate {opt} over a folder with a user's file",
            ["simulate", "{root}/d", "--duration", "2", opt], _user_folder("d"))
        add(f"import {opt} over a folder with a user's file", IMPORT[:-1] + ["{root}/d", opt], _user_folder("d"))
        add(f"import {opt} over a folder with a user's CSV", IMPORT[:-1] + ["{root}/d", opt],
            _user_folder("d", "my_log.csv"))
    add("tables --force onto a JSON", ["tables", "{cal}", "-o", "{root}/other.json", "--force"],
        _write("other.json", '{"mine": 1}\n'))
    add("calibrate --force onto a table", CAL[:3] + ["{root}/other.pstb", "--fps", "25", "--force"],
        lambda g: (g["root"] / "other.pstb").write_bytes(g["table"].read_bytes()))
    add("calibrate --force onto a CSV", CAL[:3] + ["{csv}", "--fps", "25", "--force"])
    add("tables --force onto a folder", ["tables", "{cal}", "-o", "{root}/d", "--force"], _user_folder("d"))

    # ---- non-regular inputs: refused, never opened (a FIFO would hang, a device never ends)
    add("evaluate cal.json a FIFO", ["evaluate", "{session}", "{cal}"], _fifo("cal.json"))
    add("tables cal.json a FIFO", TAB, _fifo("cal.json"))
    add("tables cal.json -> /dev/urandom", TAB, _link("cal.json", "/dev/urandom"))
    add("tables cal.json -> /dev/zero", TAB, _link("cal.json", "/dev/zero"))
    add("flash table a FIFO", FLASH, _fifo("table.pstb"))
    add("flash table -> /dev/urandom", FLASH, _link("table.pstb", "/dev/urandom"))
    add("calibrate encoder.csv a FIFO", CAL, _fifo(S + "encoder.csv"))
    add("calibrate encoder.csv -> /dev/urandom", CAL, _link(S + "encoder.csv", "/dev/urandom"))
    add("calibrate distal.csv a FIFO", CAL, _fifo(S + "distal.csv"))
    add("calibrate session.json a FIFO", CAL, _fifo(S + "session.json"))
    add("calibrate session.json -> /dev/zero", CAL, _link(S + "session.json", "/dev/zero"))
    add("calibrate session a FIFO", CAL, _fifo("session"))
    add("import CSV a FIFO", IMPORT, _fifo("rec.csv"))
    add("import CSV -> /dev/urandom", IMPORT, _link("rec.csv", "/dev/urandom"))
    add("evaluate session.json a FIFO", ["evaluate", "{session}", "{cal}"], _fifo(S + "session.json"))

    # ---- simulate --config: a JSON object of known keys with the preset's types
    SIM = ["simulate", "{root}/sim", "--duration", "2", "--config", "{root}/c.json"]
    for name, text in [("unknown key", '{"bogus": 1}'), ("a string", '"stras"'), ("a list", "[1, 2]"),
                       ("null", "null"), ("seed a string", '{"seed": "x"}'), ("K a number", '{"K": 5}'),
                       ("trajectory a list", '{"trajectory": [1]}'), ("fps a string", '{"fps": "25"}'),
                       ("not JSON", "fps = 25"), ("empty", ""), ("binary", JUNK)]:
        add(f"simulate --config {name}", SIM, _write("c.json", text))
    add("simulate --config missing", SIM)
    add("simulate --config a FIFO", SIM, _fifo("c.json"))
    for v in ("nan", "inf", "x", ""):
        add(f"simulate --effect drift rate {v!r}", ["simulate", "{root}/sim", "--duration", "2", "--effect",
                                                    f"drift:rate_deg_per_min={v}"])

    # ---- values that gave unclear messages: now named by file and row or option
    add("encoder.csv one t_s = 1e9 (last row)", CAL, _csv_edit(S + "encoder.csv", lambda L: L.__setitem__(
        -1, "1000000000," + L[-1].split(",", 1)[1])))
    add("encoder.csv one t_s = 1e9 (mid row)", CAL, _csv_edit(S + "encoder.csv", lambda L: L.__setitem__(
        500, "1000000000," + L[500].split(",", 1)[1])))
    add("encoder.csv q = 1e300", CAL, _csv_edit(S + "encoder.csv", lambda L: L.__setitem__(
        50, L[50].split(",")[0] + ",1e300")))
    add("encoder.csv q = -40000", CAL, _csv_edit(S + "encoder.csv", lambda L: L.__setitem__(
        50, L[50].split(",")[0] + ",-40000")))
    add("encoder.csv header t_s,q,q", CAL, _csv_edit(S + "encoder.csv", lambda L: [
        L.__setitem__(i, f"{L[i]},{L[i].split(',')[1]}" if i else "t_s,q,q") for i in range(len(L))]))
    add("distal.csv c_deg = 1e6", CAL, _csv_edit(S + "distal.csv", lambda L: L.__setitem__(
        9, L[9].split(",")[0] + ",1e6")))
    for v in (1e6, 11.0, -0.5, float("inf")):
        add(f"session.json t_delay_s {v}", CAL, _json_edit(S + "session.json", _set("t_delay_s", v)))
    for fx in (1e-9, 0.5, -380.0):
        add(f"session.json camera fx {fx}", CAL, _json_edit(S + "session.json", _set("camera", {
            "width": 720, "height": 576, "fps": 25, "K": [[fx, 0, 360], [0, 380, 288], [0, 0, 1]]})))
    add("flash --elf not an ELF", ["flash", "{table}", "--device", "qemu", "--elf", "{root}/fake.elf"],
        _write("fake.elf", "root:x:0:0:root:/root:/bin/bash\n"))
    add("flash --elf empty", ["flash", "{table}", "--device", "qemu", "--elf", "{root}/fake.elf"],
        _write("fake.elf", b""))
    for v in ("nan", "nans", "1.5", "0", "-3s", "infs", "x", ""):
        add(f"evaluate-insitu --split {v!r}", ["evaluate-insitu", "{session}", f"--split={v}"])

    # ---- a user's own CSV: options applied or refused, never ignored
    add("import all stamps 0", IMPORT, _write("rec.csv", "Time,Tendon Disp.,Angle x\n" +
                                               "".join(f"0,{k * 0.1},{k}\n" for k in range(50))))
    add("import header Time,q,q", ["import", "{csv}", "-o", "{root}/imported", "--t-col", "Time", "--q-col", "q",
                                   "--c-col", "3"], _write("rec.csv", "Time,q,q\n0,1,2\n1,2,3\n2,3,4\n"))
    for opt, v in (("--t-col", "9"), ("--t-col", "0"), ("--q-col", "nope"), ("--c-col", "Time")):
        add(f"import {opt} {v}", IMPORT + [opt, v])
    add("import headerless by name", IMPORT + ["--t-col", "Time"],
        _csv_edit("rec.csv", lambda L: L.pop(0)))
    add("import headerless text row", IMPORT, _csv_edit("rec.csv", lambda L: [L.pop(0), L.__setitem__(30, "1,x,2")]))
    add("import bag option on a CSV", IMPORT + ["--q-topic", "/joint_states"])
    add("import --geometry on a CSV", IMPORT + ["--geometry", "{session}/session.json"])
    add("import --q-source bogus", IMPORT + ["--q-source", "bogus"])
    add("import --c-scale nan", IMPORT + ["--c-scale", "nan"])
    add("import --c-scale 0", IMPORT + ["--c-scale", "0"])
    add("import --t-delay 1e6", IMPORT + ["--t-delay", "1e6"])
    add("import --t-delay -1", IMPORT + ["--t-delay", "-1"])
    add("import --q-per-rad inf", IMPORT + ["--q-per-rad", "inf"])
    add("import q = 1e300", IMPORT, _csv_edit("rec.csv", lambda L: L.__setitem__(40, L[40].split(",")[0] + ",1e300,1")))
    return out


CASES = cases()


def test_corpus_size():
    assert len(CASES) >= 300, len(CASES)
    assert len({c[0] for c in CASES}) == len(CASES)  # ids unique


def _digest(root) -> dict:
    """SHA-256 of every regular file under root; links and pipes by what they are (never
    opened: a FIFO would block, /dev/urandom never ends)."""
    import stat

    out = {}
    for dirpath, dirs, names in os.walk(root):
        for n in dirs:
            out[os.path.join(dirpath, n)] = "dir"
        for n in names:
            p = os.path.join(dirpath, n)
            m = os.lstat(p).st_mode
            if stat.S_ISLNK(m):
                out[p] = "link " + os.readlink(p)
            elif not stat.S_ISREG(m):
                out[p] = f"special {stat.S_IFMT(m)}"
            else:
                with open(p, "rb") as fh:
                    out[p] = hashlib.sha256(fh.read()).hexdigest()
    return out


CASE_TIMEOUT_S = 120  # a case still running after this is a hang (the slowest case takes ~3 s)


class _Hang(Exception):
    pass


def test_undamaged_inputs_pass(good, tmp_path, capsys):
    """The baseline every case damages works, so each refusal is due to its one damage."""
    g = copy_good(good, tmp_path)
    names = {k: str(v) for k, v in g.items()} | {"root": str(tmp_path)}
    for argv in (CAL, TAB, IMPORT, FLASH + ["--vectors", "5"], ["evaluate", "{session}", "{cal}"]):
        assert main([a.format(**names) for a in argv]) == 0, capsys.readouterr().err


@pytest.mark.parametrize("name,argv,damage", CASES, ids=[c[0] for c in CASES])
def test_malformed_input(name, argv, damage, good, tmp_path, capsys):
    g = copy_good(good, tmp_path)
    g["root"] = tmp_path
    if damage is not None:
        damage(g)
    names = {k: str(v) for k, v in g.items()}
    before = _digest(tmp_path)
    import signal

    def hang(*_):
        raise _Hang(f"case still running after {CASE_TIMEOUT_S} s")

    old = signal.signal(signal.SIGALRM, hang)
    signal.alarm(CASE_TIMEOUT_S)
    try:
        with warnings.catch_warnings(record=True) as caught:  # a warning would be a second stderr line
            warnings.simplefilter("always")
            rc = main([a.format(**names) for a in argv])
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    err = capsys.readouterr().err
    shown = [str(w.message) for w in caught if issubclass(w.category, (UserWarning, RuntimeWarning))]
    assert not shown, shown
    lines = err.strip().splitlines()
    assert rc == 2, err
    assert len(lines) == 1 and lines[0].startswith("playscope: error: "), err
    assert "Traceback" not in err
    assert _digest(tmp_path) == before, "a file was created, changed or removed"
