"""Never overwrite inputs: every write goes through atomic.atomic_path, whose guard
(armed by the CLI per command) refuses a file of the input session, an input itself or a
folder holding one, and an existing output without --force; writes stay atomic."""

from __future__ import annotations

import hashlib
import os

import pytest

from playscope.base.atomic import check_output, output_guard, write_text_atomic
from playscope.cli import main
from playscope.base.errors import InputError

from .goodfiles import copy_good


def _digest(root) -> dict:
    out = {}
    for dirpath, _, names in os.walk(root):
        for n in names:
            p = os.path.join(dirpath, n)
            out[p] = hashlib.sha256(open(p, "rb").read()).hexdigest()
    return out


def test_guard_rules(tmp_path, good):
    g = copy_good(good, tmp_path / "in")
    s = g["session"]
    with output_guard([s, g["cal"]], force=True):
        for f in ("encoder.csv", "distal.csv", "session.json"):
            with pytest.raises(InputError, match="is a file of the input"):
                check_output(s / f)
        with pytest.raises(InputError, match="is an input"):
            check_output(g["cal"])
        with pytest.raises(InputError, match="folder holding the input"):
            check_output(tmp_path / "in")
        check_output(s / "new.json")              # a new file beside the recording is fine
        check_output(tmp_path / "in" / "table.pstb")  # not an input here: replaced with force
    with output_guard([s], force=False):
        with pytest.raises(InputError, match="exists; pass --force"):
            check_output(g["table"])
    check_output(s / "encoder.csv")  # unarmed (library use): no rule


def test_atomic_write_failure_leaves_dest(tmp_path):
    dest = tmp_path / "out.json"
    dest.write_text("old\n")
    from playscope.base.atomic import atomic_path

    with pytest.raises(RuntimeError):
        with atomic_path(dest) as tmp:
            tmp.write_text("half")
            raise RuntimeError("killed")
    assert dest.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]


@pytest.mark.parametrize("argv", [
    ["calibrate", "{session}", "-o", "{session}/encoder.csv", "--fps", "25"],
    ["calibrate", "{session}", "-o", "{session}/session.json", "--fps", "25", "--force"],
    ["calibrate", "{session}", "-o", "{session}", "--fps", "25", "--force"],
    ["calibrate", "{session}", "-o", "{cal}", "--fps", "25"],                 # exists, no --force
    ["calibrate", "{session}", "-o", "{tmp}/c.json", "--json", "{session}/distal.csv", "--fps", "25"],
    ["tables", "{cal}", "-o", "{cal}", "--force"],
    ["tables", "{cal}", "-o", "{table}"],                                     # exists, no --force
    ["evaluate", "{session}", "{cal}", "--json", "{cal}", "--force"],
    ["report", "{cal}", "{session}", "-o", "{session}/encoder.csv", "--force"],
    ["import", "{csv}", "-o", "{tmp}", "--overwrite"],                        # folder holding the CSV
    ["import", "{csv}", "-o", "{session}"],                                   # exists, no --overwrite
])
def test_cli_refuses_and_changes_nothing(argv, tmp_path, good, capsys):
    g = copy_good(good, tmp_path)
    names = {k: str(v) for k, v in g.items()} | {"tmp": str(tmp_path)}
    before = _digest(tmp_path)
    assert main([a.format(**names) for a in argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("playscope: error: ") and "\n" not in err
    assert "elsewhere" in err or "--force" in err or "is a folder" in err
    assert _digest(tmp_path) == before


def test_cli_force_replaces_an_output(tmp_path, good, capsys):
    g = copy_good(good, tmp_path)
    out = tmp_path / "t2.pstb"
    assert main(["tables", str(g["cal"]), "-o", str(out)]) == 0
    first = out.read_bytes()
    assert main(["tables", str(g["cal"]), "-o", str(out), "--generation", "2"]) == 2
    assert out.read_bytes() == first
    assert main(["tables", str(g["cal"]), "-o", str(out), "--generation", "2", "--force"]) == 0
    assert out.read_bytes() != first
    write_text_atomic(tmp_path / "x", "y")  # library writes stay unguarded outside a command


def test_unreadable_files_are_one_line(tmp_path, good, capsys, monkeypatch):
    """Permission errors (tests run as root here, so chmod cannot make one: the read is made
    to fail as the kernel would)."""
    from pathlib import Path

    g = copy_good(good, tmp_path)
    real = Path.read_bytes

    def denied(self):
        if self.name in ("session.json", "cal.json"):
            raise PermissionError(13, "Permission denied", str(self))
        return real(self)

    monkeypatch.setattr(Path, "read_bytes", denied)
    for argv in (["calibrate", str(g["session"]), "-o", str(tmp_path / "o.json")],
                 ["tables", str(g["cal"]), "-o", str(tmp_path / "o.pstb")]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and "cannot read: Permission denied; check the permissions" in err
    assert not (tmp_path / "o.json").exists() and not (tmp_path / "o.pstb").exists()


def test_work_folders_are_neither_inputs_nor_outputs(tmp_path, good):
    """`demo --out` and `evaluate-real --reimage` manage their folder themselves (a rerun
    replaces its own outputs); `simulate --reimage SRC` reads SRC, so SRC is an input."""
    from playscope.cli import _paths, build_parser

    g = copy_good(good, tmp_path)
    p = build_parser()
    assert _paths(p.parse_args(["demo", "--out", str(tmp_path), "--json", str(g["cal"])])) == ([], [])
    ins, outs = _paths(p.parse_args(["evaluate-real", str(tmp_path), "--reimage", str(g["session"])]))
    assert ins == [str(tmp_path)] and outs == []
    ins, outs = _paths(p.parse_args(["simulate", str(tmp_path / "new"), "--reimage", str(g["session"])]))
    assert ins == [str(g["session"])] and outs == [str(tmp_path / "new")]


@pytest.mark.parametrize("target", ["{table}", "{cal}", "{session}/encoder.csv", "{session}/session.json",
                                    "{session}"])
def test_flash_file_never_replaces_a_user_file(target, tmp_path, good, capsys):
    """--flash-file goes through the guard: an input, or anything that is not a board flash
    image (2 x 128 KiB), is refused before the board starts, with or without --force."""
    g = copy_good(good, tmp_path)
    names = {k: str(v) for k, v in g.items()}
    before = _digest(tmp_path)
    for force in ([], ["--force"]):
        assert main(["flash", names["table"], "--flash-file", target.format(**names)] + force) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("playscope: error: ") and "\n" not in err, err
        assert "is an input" in err or "not a board flash image" in err or "is a folder" in err, err
    assert _digest(tmp_path) == before


def test_flash_file_locked_by_its_board(tmp_path, good, capsys):
    """One board process per flash file: while another holds it (flock), a second is refused
    with the board's reason, and the image is left as it was."""
    import fcntl

    g = copy_good(good, tmp_path)
    img = tmp_path / "board.flash"
    assert main(["flash", str(g["table"]), "--flash-file", str(img), "--vectors", "5"]) == 0
    capsys.readouterr()
    first = img.read_bytes()
    with open(img, "r+b") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        assert main(["flash", str(g["table"]), "--flash-file", str(img), "--vectors", "5"]) == 2
    err = capsys.readouterr().err.strip()
    assert "in use by another board process" in err and "\n" not in err, err
    assert img.read_bytes() == first
    assert main(["flash", str(g["table"]), "--flash-file", str(img), "--vectors", "5"]) == 0  # lock released
    assert "generation 2" in capsys.readouterr().out


@pytest.mark.parametrize("opt", ["--force", "--overwrite"])
def test_replacing_a_folder_keeps_unrelated_files(opt, tmp_path, good, capsys):
    """--force and --overwrite are one option; a folder is replaced only when it holds nothing
    but files playscope writes, so a user's own file in it is never deleted."""
    g = copy_good(good, tmp_path)
    out = tmp_path / "d"
    assert main(["import", str(g["csv"]), "-o", str(out)]) == 0
    assert main(["import", str(g["csv"]), "-o", str(out), opt]) == 0          # a session folder: replaced
    (out / "notes.txt").write_text("mine\n")
    before = _digest(tmp_path)
    assert main(["import", str(g["csv"]), "-o", str(out), opt]) == 2
    assert "notes.txt" in capsys.readouterr().err
    assert main(["simulate", str(out), "--duration", "5", opt]) == 2
    assert _digest(tmp_path) == before


def test_force_replaces_only_the_same_kind(tmp_path, good, capsys):
    """A playscope calibration is not replaced by a table, nor a user's JSON by anything."""
    g = copy_good(good, tmp_path)
    other = tmp_path / "other.json"
    other.write_text('{"mine": 1}\n')
    before = _digest(tmp_path)
    assert main(["tables", str(g["cal"]), "-o", str(other), "--force"]) == 2
    assert "playscope did not write" in capsys.readouterr().err
    cal2 = tmp_path / "cal2.json"
    cal2.write_bytes(g["cal"].read_bytes())
    before = _digest(tmp_path)
    assert main(["tables", str(g["cal"]), "-o", str(cal2), "--force"]) == 2
    assert "holds JSON and this command writes a table" in capsys.readouterr().err
    assert _digest(tmp_path) == before


def test_unwritable_output_folder_named_before_work(tmp_path, good, capsys, monkeypatch):
    """A read-only output folder is refused before any work, naming the output the user gave
    (tests run as root, so the folder's refusal is simulated as os.access would report it);
    a failure at the write itself names the output too, never the temporary beside it."""
    import tempfile

    g = copy_good(good, tmp_path)
    ro = tmp_path / "ro"
    ro.mkdir()
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, m: False if os.fspath(p) == str(ro) else real(p, m))
    assert main(["calibrate", str(g["session"]), "-o", str(ro / "c.json"), "--fps", "25"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"playscope: error: {ro / 'c.json'}: cannot write into {ro}: permission denied; choose another folder"
    monkeypatch.setattr(os, "access", real)

    def denied(*a, **k):
        raise PermissionError(13, "Permission denied", str(ro / ".c.json.x.tmp"))

    monkeypatch.setattr(tempfile, "mkstemp", denied)
    assert main(["tables", str(g["cal"]), "-o", str(ro / "t.pstb")]) == 2
    err = capsys.readouterr().err.strip()
    assert ".tmp" not in err and f"{ro / 't.pstb'}: cannot write here: Permission denied" in err, err
