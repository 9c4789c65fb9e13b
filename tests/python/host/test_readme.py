"""The README is the front door: short, its links resolve, and its test command is CI's."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
README = ROOT / "README.md"


def test_readme_is_short():
    n = len(README.read_text().splitlines())
    assert n <= 120, f"README.md has {n} lines (at most 120: details belong in docs/)"


def test_readme_links_resolve():
    text = README.read_text()
    links = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    assert len(links) >= 5
    broken = [ln for ln in links if not ln.startswith(("http://", "https://")) and not (ROOT / ln).exists()]
    assert not broken, f"README links to missing files: {broken}"


def test_readme_commands_are_the_ones_ci_runs():
    text = README.read_text()
    first = re.search(r"```sh\n(.*?)```", text, re.S)
    assert first, "README: no sh block with the two commands"
    cmds = [ln.split("#")[0].strip() for ln in first[1].splitlines() if ln.strip()]
    assert cmds == ["./tools/run-main.sh", "./tools/run-tests.sh"], cmds
    ci = (ROOT / ".ci" / "run").read_text()
    assert "./tools/run-tests.sh" in ci
    for c in cmds:
        assert (ROOT / c).is_file(), c


def test_no_release_diary_in_readme():
    text = README.read_text().lower()
    for phrase in ("previous release", "issue ", "seed "):
        assert phrase not in text, f"README mentions '{phrase.strip()}': release history goes to CHANGELOG.md"
