"""bench/results_doc.py's writers on a small fake run: the README's summary never drops a row
(skipped parts say so), the in-situ ratios come from bench/insitu_real.py's JSON, and the docs'
figures blocks are filled from docs/results.md's rows and printed tables."""

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
_spec = importlib.util.spec_from_file_location("results_doc", ROOT / "bench" / "results_doc.py")
rd = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(rd)

# A fake run: two firmware rows, the main job, a failed part, no self-test.
TABLE = [
    ("M4 instructions per call: psa_tick, compensation, realistic: c* reversing", "117.3 avg, 302.1 worst",
     "avg <= 120 (met)", "", "bench/bench_firmware.sh"),
    ("USART image flash, everything", "16.27 KiB (16656 B)", "<= 24 KiB", "", "bench/bench_firmware.sh"),
    ("main job: B(q) error vs the simulator's centre width, mean / max", "0.1687 / 0.2966 mm", "", "",
     "playscope demo"),
    ("host", "not measured: bench/bench_host.py failed (1)", "", "", ""),
]

# bench/insitu_real.py's JSON and printed acceptance table, cut to what the writer reads.
INSITU_JSON = {"summary": {
    "catheter@0.5": {"development": {"geomean_ours_over_best_peer": 0.9141, "worst_ratio": 1.0462,
                                     "files": 5, "errors": []}},
    "catheter@0.75": {"development": {"geomean_ours_over_best_peer": 1.0109, "worst_ratio": 1.1951,
                                      "files": 5, "errors": []}},
    "endoscope@0.5": {"development": {"geomean_ours_over_best_peer": 1.3121, "worst_ratio": 1.5071,
                                      "files": 4, "errors": ["120"]}},
    "catheter@0.3": {"development": {"geomean_ours_over_best_peer": 9.0, "worst_ratio": 9.0,
                                     "files": 5, "errors": []}},
}}
INSITU_PRINTED = """\
| acceptance (development files) | measured | target | verdict |
|---|---|---|---|
| catheter, split 0.5 | ours <= every peer on 4 of 5; geomean ours / best peer 0.914 (worst 1.046) | every file; geomean <= 0.8 | FAIL |
| endoscope, split 0.5 | ours <= constant play + poly5 on 4 of 4; geomean 1.312 (worst 1.507) | every file; geomean <= 0.95 | FAIL |
"""


def _rows(block: str) -> dict[str, list[str]]:
    out = {}
    for ln in block.splitlines():
        if ln.startswith("| ") and not ln.startswith("| figure"):
            c = [x.strip() for x in ln.strip().strip("|").split("|")]
            out[c[0]] = c[1:]
    return out


def test_summary_keeps_every_row_and_says_why_one_is_missing():
    table = TABLE + rd.insitu_rows(INSITU_JSON, INSITU_PRINTED)
    block = rd.summary_block(table, "2026-01-01, commit abc1234", skipped=["diagnosis self-test"])
    assert block.startswith(rd.BEGIN) and block.endswith(rd.END)
    assert "2026-01-01, commit abc1234" in block
    rows = _rows(block)
    # one line per summary key, whatever the run made
    assert len(rows) == len(rd.SUMMARY)
    assert rows["USART image flash, everything"][0] == "16.27 KiB (16656 B)"
    assert rows["M4 instructions per call: psa_tick, compensation, realistic: c* reversing"][0] \
        == "117.3 avg, 302.1 worst"
    # skipped part: says it was not run; failed or absent part: says it was not measured
    assert rows["diagnosis blind self-test: top-1"] == [rd.NOT_RUN, ""]
    assert rows["calibrate a 3-min 25 Hz session"][0] == rd.NOT_MEASURED
    assert rows["start-up `playscope --version`"][0] == rd.NOT_MEASURED


def test_insitu_rows_geomean_and_worst_per_instrument_and_split():
    rows = {r[0]: r for r in rd.insitu_rows(INSITU_JSON, INSITU_PRINTED)}
    cat05 = rows["in situ, catheter (development files), split 0.5: ours / best peer, geometric mean (worst file)"]
    assert cat05[1] == "0.91 (1.05) on 5 files"
    assert cat05[2] == "every file; geomean <= 0.8 (FAIL)"
    cat075 = rows["in situ, catheter (development files), split 0.75: ours / best peer, geometric mean (worst file)"]
    assert cat075[1] == "1.01 (1.20) on 5 files" and cat075[2] == ""  # no acceptance line printed for it
    endo = rows["in situ, endoscope (development files), split 0.5: ours / best peer, geometric mean (worst file)"]
    assert endo[1] == "1.31 (1.51) on 4 files; errors: 120"
    # only the summary's splits; a split the bench did not run gives no row
    assert len(rows) == 3 and not any("split 0.3" in k for k in rows)
    block = rd.summary_block(list(rows.values()), "d", skipped=[])
    assert _rows(block)["in situ, endoscope (development files), split 0.75: ours / best peer"][0] == rd.NOT_MEASURED


def test_insitu_rows_refuse_a_non_finite_ratio():
    bad = {"summary": {"catheter@0.5": {"development": {"geomean_ours_over_best_peer": float("nan"),
                                                        "worst_ratio": 1.0, "files": 5, "errors": []}}}}
    with pytest.raises(ValueError, match="catheter at split 0.5"):
        rd.insitu_rows(bad, "")


FAKE_RESULTS = """# Results

- date and commit: 2026-01-01, commit abc1234

## Every figure

| figure | measured | target | paper / baseline | command |
|---|---|---|---|---|
| main job: B(q) error vs the simulator's centre width, mean / max | 0.1687 / 0.2966 mm |  |  | playscope demo |
| main job: Table I, mean |Qx| | 4.1 px |  | paper 17 px | playscope demo |
| USART image flash, everything | 16.27 KiB | <= 24 KiB |  | bench/bench_firmware.sh |

## Each bench as it printed

### `python bench/insitu_real.py`

**catheter, split 0.5: fit before, judged after (RMSE, deg)**

| model | a |
|---|---|
| ours | 0.192 |

development: geometric mean ours / best peer 0.914, worst 1.046

**catheter, split 0.75: fit before, judged after (RMSE, deg)**

| model | a |
|---|---|
| ours | 0.284 |
"""

PAGE = """# A page

Some prose.

<!-- figures:begin rows: main job: B(q) error; USART image; no such figure -->
stale text typed by hand: 9.99 mm
<!-- figures:end -->

More prose.

<!-- figures:begin printed: catheter, split 0.5 -->
<!-- figures:end -->
"""


def test_parse_figures_keeps_a_bar_inside_a_name():
    rows = rd.parse_figures(FAKE_RESULTS)
    assert [r[0] for r in rows][1] == "main job: Table I, mean|Qx|"
    assert all(len(r) == 5 for r in rows) and rows[2][1] == "16.27 KiB"


def test_fill_doc_blocks_rows_and_printed_tables():
    out = rd.fill_doc_blocks(PAGE, FAKE_RESULTS)
    assert "9.99 mm" not in out  # the stale block content is replaced
    assert out.startswith("# A page\n\nSome prose.") and "More prose." in out
    assert "| main job: B(q) error vs the simulator's centre width, mean / max | 0.1687 / 0.2966 mm |  |  |" in out
    assert "| USART image flash, everything | 16.27 KiB | <= 24 KiB |  |" in out
    assert f"| no such figure | {rd.MISSING_ROW} |" in out
    assert "(2026-01-01, commit abc1234)" in out
    page2 = rd.fill_doc_blocks("<!-- figures:begin rows: main job: Table I -->\n<!-- figures:end -->\n", FAKE_RESULTS)
    assert "| main job: Table I, mean\\|Qx\\| | 4.1 px |" in page2  # the bar escaped, the table intact
    assert "| ours | 0.192 |" in out and "geometric mean ours / best peer 0.914" in out
    assert "0.284" not in out  # the next printed table is not part of the block
    # filling twice changes nothing
    assert rd.fill_doc_blocks(out, FAKE_RESULTS) == out
    # strip_generated leaves only what a person wrote
    stripped = rd.strip_generated(out)
    assert "0.1687" not in stripped and "Some prose." in stripped


def test_fill_doc_blocks_names_the_page_on_an_unclosed_block():
    with pytest.raises(ValueError, match="docs/x.md"):
        rd.fill_doc_blocks("<!-- figures:begin rows: main job -->\nno end\n", FAKE_RESULTS, where="docs/x.md")


def test_run_all_help_says_how_long_each_part_takes():
    out = subprocess.run([sys.executable, str(ROOT / "bench" / "run_all.py"), "--help"], capture_output=True,
                         text=True, timeout=60, check=True).stdout
    for part in ("firmware", "in-situ real data", "diagnosis self-test", "--docs-only"):
        assert part in out, part
    assert "min" in out and "whole run" in out


def test_readme_stays_short_with_every_summary_row():
    """The README with the summary block of a run that made every SUMMARY row (one row each) is
    still at most 120 lines: the generated table cannot push it over."""
    readme = (ROOT / "README.md").read_text()
    i, j = readme.find(rd.BEGIN), readme.find(rd.END)
    assert 0 <= i < j
    full = rd.summary_block([(key, "1", "", "", "") for key, _ in rd.SUMMARY], "2026-01-01, commit abc1234")
    n = len((readme[:i] + full + readme[j + len(rd.END):]).splitlines())
    assert n <= 120, f"README would have {n} lines with a full summary"


def _score(top1, n, fd, nulls):
    return {"top1": top1, "n_planted": n, "n_false_discoveries": fd, "n_nulls": nulls,
            "false_discovery_ci95": [0.0, 0.139], "top1_identifiable": 1.0, "n_identifiable": n - 1,
            "ool_unexplained": 0.5, "shrink_within_25pct_identifiable": 0.79}


def test_selftest_rows_for_each_generator_that_ran():
    rows = rd.selftest_rows({"selftest": _score(17 / 18, 18, 0, 20), "selftest_second": _score(0.5, 18, 3, 20)},
                            "bench/diagnose_selftest.py --quick --second")
    assert len(rows) == 4
    assert rows[0][0].startswith("diagnosis blind self-test: top-1")
    assert rows[0][1] == "94 % of 18 / 0 of 20 (95 % CI 0-14 %)"
    assert rows[2][0].startswith("diagnosis blind self-test, second generator: top-1")
    assert rows[2][1] == "50 % of 18 / 3 of 20 (95 % CI 0-14 %)"
    block = rd.summary_block(rows, "d")
    got = _rows(block)
    assert got[rows[0][0]][0] == rows[0][1] and got[rows[2][0]][0] == rows[2][1]
    # only the first generator ran: the second's summary line says it was not measured
    only_first = rd.summary_block(rd.selftest_rows({"selftest": _score(1.0, 18, 0, 2)}, "c"), "d")
    assert _rows(only_first)["diagnosis blind self-test, second generator: top-1"][0] == rd.NOT_MEASURED


SWING_PRINTED = """group development: 9 renderings (bench/swing_render.py)
| category | rendering | shape, fps, noise px | true / cfg delay (s) | B error % | limit | x |
|---|---|---|---|---|---|---|
| swings | dev-swings25 | square, 25, 0.1 | 0.08 / 0.08 | 2.29 | <= 5 | a |

| category | renderings | B error % mean (worst) | |t_delay error| frames mean (worst) |
|---|---|---|---|
| swings | 2 | 1.50 (2.29) | 0.000 (0.000) |
| registration | 2 | 15.58 (15.87) | 0.010 (0.020) |
renderings failing (B over limit, |t_delay error| > 1/8 frame, or refused): 3 of 9
"""


def test_swing_rows_per_category_and_failures():
    rows = rd.swing_rows(SWING_PRINTED, "development", "bench/swing_bench.py --group development")
    assert len(rows) == 3
    assert rows[0][0].startswith("fast-swing onsets, development renderings, swings (2)")
    assert rows[0][1] == "1.50 % (2.29 %); 0.000 (0.000) frames"
    assert rows[1][1] == "15.58 % (15.87 %); 0.010 (0.020) frames"
    assert rows[2][1] == "3 of 9" and "/t_delay error/" in rows[2][0]  # no bar left in a name
    with pytest.raises(ValueError, match="renderings failing"):
        rd.swing_rows("| swings | 2 | 1.50 (2.29) | 0.000 (0.000) |\n", "development", "x")


def test_run_all_stamps_the_commit_and_only_a_changed_tracked_file_as_uncommitted(tmp_path, monkeypatch):
    # `run_all.commit()`, the stamp docs/results.md carries: HEAD's short hash, with "+ uncommitted
    # changes" when a tracked file differs from it, not for an untracked one (a run's own scratch). On
    # a throwaway repository. (That main() takes it before any part writes docs/img is not tested here.)
    spec = importlib.util.spec_from_file_location("run_all", ROOT / "bench" / "run_all.py")
    ra = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ra)

    def git(*args):
        return subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args], cwd=tmp_path,
                              capture_output=True, text=True, check=True).stdout.strip()

    git("init", "-q")
    (tmp_path / "a.txt").write_text("one\n")
    git("add", "a.txt")
    git("commit", "-q", "-m", "first")
    head = git("rev-parse", "--short", "HEAD")
    monkeypatch.setattr(ra, "ROOT", tmp_path)
    (tmp_path / "scratch.txt").write_text("untracked\n")
    assert ra.commit() == head
    (tmp_path / "a.txt").write_text("two\n")
    assert ra.commit() == f"{head} + uncommitted changes"
    monkeypatch.setattr(ra, "ROOT", tmp_path / "nowhere")
    assert ra.commit().startswith("unknown")
