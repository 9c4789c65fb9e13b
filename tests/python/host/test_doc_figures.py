"""No measured figure is typed by hand in README.md or docs/*.md: every number with a unit in
their prose is either inside a block bench/run_all.py generates (results, main-job excerpt,
figures blocks) or appears in docs/results.md, the page one run wrote. A figure copied by hand
drifts from the next run; this fails as soon as it does.

Not scanned: generated blocks, fenced and indented code (commands, example sessions), code
spans (options and source constants a user types or reads in the code, e.g. `--split 0.5`,
`EXC_PACE_FRAMES`), link targets. Settings of the method or of a recording (not measurements) are allowed by ALLOWED
below, each with its reason.
"""

import importlib.util
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
_spec = importlib.util.spec_from_file_location("results_doc", ROOT / "bench" / "results_doc.py")
rd = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(rd)

UNITS = (r"(?:deg|°|rad|mm/s|mm|um|µm|ms|us|µs|s|min|h|KiB|MiB|kB|bytes|%|x|px|Hz|kHz|MHz|fps|frames/s|"
         r"ticks/s|instructions|cycles)")
# a number, possibly a range or a list ("0.19 / 0.24", "24-89"), then its unit
FIGURE = re.compile(r"(?<![\w.\-/])\d+(?:\.\d+)?(?:\s?(?:-|–|/|to)\s?\d+(?:\.\d+)?)*\s?" + UNITS + r"(?![\w/])")

# Settings, not measurements: (pattern of the figure, why it is not a measured figure).
ALLOWED = (
    (r"(25|30|60) (fps|Hz)", "camera frame rates of the recordings and of the simulator's presets (settings)"),
    (r"(20|1|5) kHz|(500|100) Hz", "the control loop's tick rate and the encoder and sensor log rates (settings)"),
    (r"(168|48) MHz", "the STM32F405's core and USB clocks (hardware constants)"),
    (r"(24|64|128|192) KiB", "flash and RAM budgets and the board's memory sizes (targets, not measurements)"),
    (r"(0\.3|3|20|30) s", "time targets of the project (start-up < 0.3 s, calibrate < 3 s, diagnose <= 20 s, "
                          "main job < 30 s): targets, stated beside the measured row they judge"),
    (r"(80|40|200) ms", "acquisition delays configured in the simulator and the swing renderer (settings)"),
    (r"(2|1\.5|0\.5|3) deg", "registration errors planted in the simulator and in the Fig. 7 replica (settings)"),
    (r"(5|10|95|25|90) %", "acceptance limits and confidence levels (5 % and 10 % B error, 95 % intervals, "
                           "25 % shrink band, 90 % top-1): targets, not measurements"),
)
ALLOWED_RE = [re.compile(p + r"$") for p, _ in ALLOWED]


def _prose(text: str) -> str:
    """What a person wrote: generated blocks, fenced code, code spans and link targets removed."""
    text = rd.strip_generated(text)
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    # indented code blocks (example sessions): 4 spaces after a blank line, and what follows them
    kept, in_code = [], False
    for line in text.split("\n"):
        in_code = line.startswith("    ") and (in_code or not kept or not kept[-1].strip())
        kept.append("" if in_code else line)
    text = "\n".join(kept)
    text = re.sub(r"`[^`\n]*`", "", text)
    return re.sub(r"\]\([^)]*\)", "]", text)


def typed_figures(text: str, results: str) -> list[str]:
    """The measured figures in text's prose that docs/results.md does not hold."""
    res = re.sub(r"\s+", " ", results)
    bad = []
    for m in FIGURE.finditer(_prose(text)):
        fig = re.sub(r"\s+", " ", m[0])
        if fig in res or any(a.match(fig) for a in ALLOWED_RE):
            continue
        bad.append(fig)
    return bad


def _pages():
    return [ROOT / "README.md"] + [p for p in sorted((ROOT / "docs").glob("*.md")) if p.name != "results.md"]


def test_no_figure_typed_by_hand_in_readme_or_docs():
    results = (ROOT / "docs" / "results.md").read_text()
    found = {p.relative_to(ROOT).as_posix(): typed_figures(p.read_text(), results) for p in _pages()}
    found = {k: v for k, v in found.items() if v}
    assert not found, ("figures typed by hand (link to docs/results.md or use a figures block; "
                       f"see bench/results_doc.py): {found}")


RESULTS_FAKE = "| calibrate | 13.14 / 13.23 s | < 3 s |\n| B error | 1.84 % | <= 5 % |\n"


def test_a_planted_typed_figure_fails():
    page = "The calibration takes 12.5 s on the bench session, the B error is 1.84 % and 0.31 deg.\n"
    assert typed_figures(page, RESULTS_FAKE) == ["12.5 s", "0.31 deg"]
    # ranges and lists count as one figure, and must be in the results whole
    assert typed_figures("worst 24-89 %, files 0.19 / 0.24 deg", RESULTS_FAKE) == ["24-89 %", "0.19 / 0.24 deg"]
    assert typed_figures("it took 13.14 / 13.23 s", RESULTS_FAKE) == []


def test_generated_blocks_code_and_settings_are_not_typed_figures():
    page = ("Recorded at 25 fps with a 80 ms delay; run `playscope evaluate-insitu S --split 0.5 --tol 0.7 deg`.\n"
            "```\nTable I ... 4.1 px\n```\n"
            "<!-- figures:begin rows: calibrate -->\n| calibrate | 9.9 s |\n<!-- figures:end -->\n"
            "See [the row](results.md#0.7-deg).\n\n    $ playscope calibrate S\n    CV RMSE 0.0227 deg\n")
    assert typed_figures(page, RESULTS_FAKE) == []
    # the same figure outside the block is caught
    assert typed_figures(page + "It takes 9.9 s.\n", RESULTS_FAKE) == ["9.9 s"]


def test_every_allowed_setting_says_why():
    assert all(len(reason) > 20 for _, reason in ALLOWED)
