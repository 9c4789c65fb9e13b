"""The host package's import graph: the command line sits on top. No library module
imports playscope.cli or playscope.commands (the commands call the library, never the other
way), the modules import each other without a circle, counting the imports made inside
functions too (a deferred import hides a circle, it does not remove it), and the folders follow
the data's path in one order (LAYERS): a folder imports only folders before it. No two modules
share a file name. Read from the source with ast, nothing imported."""

from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[3] / "host" / "playscope"


def _module_name(path: Path) -> str:
    rel = path.relative_to(PKG.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def import_graph() -> dict[str, set[str]]:
    """{module: playscope modules it imports anywhere in its source}. `from X import name` counts
    X.name when that is a module of the package, else X."""
    files = {_module_name(p): p for p in PKG.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for mod, path in files.items():
        is_pkg = path.name == "__init__.py"
        base = mod.split(".") if is_pkg else mod.split(".")[:-1]
        deps = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    stem = ".".join(base[:len(base) - node.level + 1] + ([node.module] if node.module else []))
                else:
                    stem = node.module or ""
                targets = [f"{stem}.{a.name}" if f"{stem}.{a.name}" in files else stem for a in node.names]
            else:
                continue
            deps |= {t for t in targets if t in files and t != mod}
        graph[mod] = deps
    return graph


def _is_cli(mod: str) -> bool:
    return mod in ("playscope.cli", "playscope.__main__", "playscope.commands") or mod.startswith("playscope.commands.")


# The folders in the data's path order; a module may import its own layer and the layers before
# it, never one after. base: shared basics (errors, atomic writes, JSON, the native C core and
# its constants); io: recordings in (sessions, import, ROS bags, marker tracking); fit: onsets to
# the calibration (and the fixed-point tables the fit scores its candidates through); board:
# table files, link, flashing, on-line update, the board side of run-insitu; sim: the simulated
# instrument (runs the fit's models, writes sessions); evaluate: the benches judging a
# calibration (may simulate); diagnose: the sim-to-real gap (simulates, calibrates); pipeline:
# the workflows with typed results (pipeline.py, the main job); cli: argument parsing and
# printing only.
LAYERS = [
    ("base", ("playscope", "playscope.base")),
    ("io", ("playscope.io",)),
    ("fit", ("playscope.fit",)),
    ("board", ("playscope.board",)),
    ("sim", ("playscope.sim",)),
    ("evaluate", ("playscope.evaluate",)),
    ("diagnose", ("playscope.diagnose",)),
    ("pipeline", ("playscope.pipeline", "playscope.mainjob")),
    ("cli", ("playscope.cli", "playscope.__main__", "playscope.commands")),
]


def layer_of(mod: str) -> int:
    """Index in LAYERS of the longest prefix naming mod (the package itself counts as base)."""
    best, best_len = None, -1
    for i, (_, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            if (mod == p or mod.startswith(p + ".")) and len(p) > best_len and (p != "playscope" or mod == p):
                best, best_len = i, len(p)
    assert best is not None, f"{mod}: in no layer of LAYERS (place it in a folder)"
    return best


def test_every_module_has_a_layer():
    g = import_graph()
    for mod in g:
        layer_of(mod)
    assert layer_of("playscope.fit.calibration") < layer_of("playscope.board.flash") < layer_of("playscope.pipeline")
    assert layer_of("playscope.commands.calibrate") == len(LAYERS) - 1


def test_folders_follow_the_data_path():
    g = import_graph()
    bad = sorted(f"{m} ({LAYERS[layer_of(m)][0]}) -> {d} ({LAYERS[layer_of(d)][0]})"
                 for m, deps in g.items() for d in deps if layer_of(d) > layer_of(m))
    assert not bad, "imports against the folders' order: " + ", ".join(bad)


def test_no_two_modules_share_a_file_name():
    names: dict[str, list[str]] = {}
    for p in PKG.rglob("*.py"):
        if p.name not in ("__init__.py", "__main__.py"):
            names.setdefault(p.name, []).append(str(p.relative_to(PKG)))
    same = {n: sorted(ps) for n, ps in names.items() if len(ps) > 1}
    assert not same, f"modules sharing a file name: {same}"
    assert len(names) > 60


def test_graph_reads_the_package():
    g = import_graph()
    # The walk sees what is known to be there: a command importing the pipeline, the pipeline
    # importing the calibration (so an empty graph cannot pass the tests below).
    assert "playscope.pipeline" in g["playscope.commands.calibrate"]
    assert "playscope.fit.calibration" in g["playscope.pipeline"]
    assert "playscope.base.native" in g["playscope.io.session"]
    assert len(g) > 60


def test_no_library_module_imports_the_command_line():
    g = import_graph()
    bad = sorted(f"{m} -> {d}" for m, deps in g.items() if not _is_cli(m) for d in deps if _is_cli(d))
    assert not bad, "library modules importing the CLI: " + ", ".join(bad)


def _cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in g.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(g):
        if v not in index:
            visit(v)
    return out


def test_cycle_finder_finds_a_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_circle():
    cycles = _cycles(import_graph())
    assert not cycles, "import circles: " + "; ".join(" <-> ".join(c) for c in cycles)
