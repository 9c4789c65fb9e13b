"""The independent renderers that check the onset estimator (bench/marker_render.py for the
Fig. 7 replica and onset refinement, bench/swing_render.py for the fast swings) import nothing
from playscope, nor anything beyond numpy and the standard library: a generator that checks a
fitter shares no code with it. Read with ast, nothing imported."""

import ast
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[3] / "bench"


def _top_modules(path: Path) -> set[str]:
    mods = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            mods |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            mods.add((node.module or "").split(".")[0])
    return mods


@pytest.mark.parametrize("renderer", ["marker_render.py", "swing_render.py"])
def test_renderer_imports_nothing_from_playscope(renderer):
    mods = _top_modules(BENCH / renderer)
    assert mods <= {"__future__", "json", "dataclasses", "pathlib", "numpy"}, mods


def test_import_walk_sees_a_playscope_import(tmp_path):
    p = tmp_path / "r.py"
    p.write_text("import numpy as np\nfrom playscope.fit import onsets\n")
    assert "playscope" in _top_modules(p)
