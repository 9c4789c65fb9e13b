"""docs/ is a user guide plus a validation report, not a diary: every page is listed in the
index (docs/README.md), every link in README.md and docs/ resolves (files and #anchors), and no
page tells release history (that is CHANGELOG.md's)."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
DOCS = ROOT / "docs"
PAGES = [ROOT / "README.md"] + sorted(DOCS.glob("*.md"))

# Phrases of a release diary, with why each is one.
DIARY = (
    (r"\bissue \d+", "issue numbers belong to the tracker"),
    (r"\bthis release\b|\bprevious release\b|\brelease before\b|\bthe release after\b", "release history"),
    (r"\bon (this )?branch\b|\bbranch `?[a-z0-9]+(-[a-z0-9]+)+", "branch names are history"),
    (r"\bstop \d+\b", "work-session numbers"),
    (r"\bbefore this (change|branch|release)\b", "a before/after comparison is history"),
)


def _anchor(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    h = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return h.replace(" ", "-")


def _anchors(page: Path) -> set[str]:
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
    return {_anchor(m[1]) for m in re.finditer(r"^#+ (.+)$", text, re.M)}


def _prose(page: Path) -> str:
    text = page.read_text()
    text = re.sub(r"<!-- (results|mainjob):begin -->.*?<!-- \1:end -->", "", text, flags=re.S)
    return re.sub(r"<!-- figures:begin [^>]*-->.*?<!-- figures:end -->", "", text, flags=re.S)


def test_every_link_resolves():
    broken = []
    for page in PAGES:
        text = page.read_text()
        if page.name == "results.md":  # its summary block is the README's copy, links relative to the README
            text = re.sub(r"<!-- results:begin -->.*?<!-- results:end -->", "", text, flags=re.S)
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if target.startswith(("http://", "https://", "mailto:")):
                continue
            path, _, anchor = target.partition("#")
            dest = (page.parent / path).resolve() if path else page
            if not dest.exists():
                broken.append(f"{page.name}: {target}")
            elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
                broken.append(f"{page.name}: {target} (no such heading)")
    assert not broken, broken


def test_index_lists_every_page():
    index = (DOCS / "README.md").read_text()
    missing = [p.name for p in DOCS.glob("*.md") if p.name != "README.md" and f"]({p.name})" not in index]
    assert not missing, f"docs/README.md does not list {missing}"


def test_guide_and_validation_parts():
    """The pages with a validation report have both parts, guide first."""
    for name in ("method.md", "insitu.md", "diagnosis.md", "online.md"):
        text = (DOCS / name).read_text()
        i, j = text.find("# Part 1:"), text.find("# Part 2: validation report")
        assert 0 <= i < j, f"{name}: needs '# Part 1: ...' then '# Part 2: validation report'"
        assert "<!-- figures:begin" in text[j:], f"{name}: its validation report shows no generated figures"


def test_no_release_diary_in_docs():
    found = []
    for page in PAGES:
        if page.name == "results.md":
            continue
        text = _prose(page)
        for pat, why in DIARY:
            for m in re.finditer(pat, text, re.I):
                found.append(f"{page.name}: '{m[0]}' ({why})")
    assert not found, found


def test_diary_check_fires_on_a_planted_line(tmp_path):
    page = tmp_path / "x.md"
    page.write_text("Since " + "issue" + " 27 this release reads B faster (on this branch).\n")  # split: no number in the source
    hits = [pat for pat, _ in DIARY if re.search(pat, _prose(page), re.I)]
    assert len(hits) == 3


def test_every_file_a_page_names_exists():
    """A path a page names (`host/playscope/fit/onset_model.py`, `firmware/core/relax.c`,
    `bench/insitu_real.py`, or a package folder-relative `fit/backlash.py`) is a file of the tree:
    a moved module cannot leave a page pointing at nothing."""
    roots = ("host/", "firmware/", "common/", "bench/", "tests/", "tools/", "fuzz/")
    pkg = ("base/", "io/", "fit/", "board/", "evaluate/", "diagnose/", "sim/", "commands/")
    missing = set()
    for page in PAGES:
        if page.name == "results.md":
            continue
        for m in re.finditer(r"(?<![\w/.-])((?:[\w.-]+/)+[\w.-]+\.(?:py|c|h|sh|txt))\b", _prose(page)):
            path = m[1]
            if path.startswith(roots):
                ok = (ROOT / path).exists()
            elif path.startswith(pkg):
                ok = (ROOT / "host" / "playscope" / path).exists()
            elif path.startswith("playscope/"):
                ok = (ROOT / "host" / path).exists()
            else:
                continue
            if not ok:
                missing.add(f"{page.name}: {path}")
    assert not missing, sorted(missing)
