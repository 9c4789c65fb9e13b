"""The host package's import graph: the command line sits on top. No library module
imports playscope.cli or playscope.commands (the commands call the library, never the other
way), and the modules import each other without a circle, counting the imports made inside
functions too (a deferred import hides a circle, it does not remove it). Read from the source
with ast, nothing imported."""

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
    return mod == "playscope.cli" or mod == "playscope.commands" or mod.startswith("playscope.commands.")


def test_graph_reads_the_package():
    g = import_graph()
    # The walk sees what is known to be there: a command importing the pipeline, the pipeline
    # importing the calibration (so an empty graph cannot pass the tests below).
    assert "playscope.pipeline" in g["playscope.commands.calibrate"]
    assert "playscope.calibration" in g["playscope.pipeline"]
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
