"""No issue numbers in code, comments or program output: a reader of the source (or of what a
command prints) should meet the behaviour, not a tracker's numbering. Docs that record
validation say what was measured, not which ticket asked for it."""

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
PATTERN = re.compile(r"\b[Ii]ssues? ?#?\d+")
FOLDERS = ("host", "firmware", "common", "bench", "tools", "tests", "fuzz", "cmake")
SUFFIXES = {".py", ".c", ".h", ".sh", ".cmake", ".txt", ".toml"}


def test_no_issue_numbers_in_source():
    files = subprocess.run(["git", "ls-files", *FOLDERS], cwd=ROOT, capture_output=True, text=True,
                           check=True).stdout.split()
    hits = []
    for f in files:
        p = ROOT / f
        if p.suffix not in SUFFIXES or p.name == Path(__file__).name or not p.is_file():
            continue
        for k, line in enumerate(p.read_text(errors="replace").splitlines(), 1):
            if PATTERN.search(line):
                hits.append(f"{f}:{k}: {line.strip()[:80]}")
    assert not hits, "issue numbers in the source:\n" + "\n".join(hits[:20])
