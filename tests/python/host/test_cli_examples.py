"""Every `playscope` command's --help ends with examples that parse, and the common
options mean the same everywhere: --json PATH writes the result to PATH, --json - to stdout in
place of the summary, --quiet prints no summary (docs/host.md, "Common options")."""

from __future__ import annotations

import argparse
import json
import shlex

import pytest

from playscope import cli
from playscope.commands.argtypes import existing_file



def _subparsers(p: argparse.ArgumentParser, path=()):
    """(command words, parser) of every command that runs (has func), nested ones included."""
    for a in p._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sp in a.choices.items():
                if sp.get_default("func") is not None:
                    yield path + (name,), sp
                yield from _subparsers(sp, path + (name,))


def _examples(sp: argparse.ArgumentParser) -> list[list[str]]:
    """The command lines of the epilog's "examples:" block (a trailing backslash continues)."""
    lines, out, cur = (sp.epilog or "").splitlines(), [], ""
    for ln in lines:
        if ln.startswith("  playscope ") or cur:
            cur += ln.strip().rstrip("\\") + " "
            if not ln.rstrip().endswith("\\"):
                text = cur.split("  (")[0]  # an explanation in brackets after two spaces ends it
                out.append(shlex.split(text)[1:])
                cur = ""
    return out


def test_example_reader_reads_continued_lines():
    sp = argparse.ArgumentParser(epilog="examples:\n  playscope a b \\\n      --c d   (why)\n  playscope e\nnotes")
    assert _examples(sp) == [["a", "b", "--c", "d"], ["e"]]


def test_every_command_has_examples_and_they_parse(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    parser = cli.build_parser()
    commands = list(_subparsers(parser))
    assert len(commands) >= 14  # import ... demo, flash, device info, run-insitu
    for words, sp in commands:
        exs = _examples(sp)
        assert exs, f"`playscope {' '.join(words)} --help` shows no example"
        for argv in exs:
            assert argv[:len(words)] == list(words), (words, argv)
            # Inputs that must exist (existing_file) are made empty here: the example parses.
            for i, tok in enumerate(argv[:-1]):
                act = sp._option_string_actions.get(tok)
                if act is not None and act.type is existing_file:
                    (tmp_path / argv[i + 1]).parent.mkdir(parents=True, exist_ok=True)
                    (tmp_path / argv[i + 1]).touch()
            try:
                args = parser.parse_args(argv)
            except SystemExit:
                pytest.fail(f"example does not parse: playscope {' '.join(argv)}")
            assert args.func is sp.get_default("func")


def test_every_command_takes_quiet_and_json_path():
    for words, sp in _subparsers(cli.build_parser()):
        opts = sp._option_string_actions
        assert "--quiet" in opts, words
        if "--json" in opts:
            # --json is a path everywhere (never a bare flag)
            assert opts["--json"].nargs is None and opts["--json"].const is None, words


def _csv(path):
    """A small recording in the catheter CSV layout (playscope import's defaults)."""
    rows = ["Time,Tendon Disp.,Angle x"] + [f"{k / 100:.2f},{(k % 50) / 10:.2f},{(k % 50) * 2.0:.1f}" for k in range(200)]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_json_dash_goes_to_stdout_in_place_of_the_summary(tmp_path, capsys):
    src = _csv(tmp_path / "rec.csv")
    assert cli.main(["import", str(src), "-o", str(tmp_path / "s1"), "--json", "-"]) == 0
    doc = json.loads(capsys.readouterr().out)  # stdout holds the JSON document alone
    assert doc["session"] == str(tmp_path / "s1") and doc["rows"] == 200


def test_quiet_prints_no_summary_and_json_path_writes_the_file(tmp_path, capsys):
    src = _csv(tmp_path / "rec.csv")
    assert cli.main(["import", str(src), "-o", str(tmp_path / "s2"), "--quiet", "--json", str(tmp_path / "s2.json")]) == 0
    assert capsys.readouterr().out == ""
    assert json.loads((tmp_path / "s2.json").read_text())["rows"] == 200
    assert cli.main(["import", str(src), "-o", str(tmp_path / "s3")]) == 0
    assert capsys.readouterr().out == f"{tmp_path / 's3'}: 200 rows, 2.0 s\n"


def test_lazy_parser_names_every_command_with_its_modules_help():
    """cli.COMMANDS (what `playscope --help` shows without importing a command module) says
    what each module declares, and lists every command the full parser has."""
    full = {}
    for a in cli.build_parser()._actions:
        if isinstance(a, argparse._SubParsersAction):
            full = {c.dest: c.help for c in a._choices_actions}
    assert full == {k: v[1] for k, v in cli.COMMANDS.items()}
    # ...and every command module is reachable: the parser is built from COMMANDS alone, so a
    # module listed only in COMMAND_MODULES would be refused as an unknown command.
    reachable = {m for m, _ in cli.COMMANDS.values()}
    assert {m for m, _ in cli.COMMAND_MODULES} <= reachable


@pytest.mark.parametrize("argv", [["--version"], ["--help"], ["frobnicate"]])
def test_help_and_version_import_no_command_module(argv):
    """Start-up: --help, --version and an unknown command import neither numpy nor a command
    module (bench/bench_startup.py measures the time)."""
    import subprocess
    import sys

    code = ("import sys; from playscope.cli import main\n"
            f"rc = main({argv!r})\n"
            "print(sorted(m for m in sys.modules if m == 'numpy' or m.startswith('playscope.commands.')))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.stdout.strip().splitlines()[-1] == "[]", r.stdout + r.stderr
