"""The blind self-test is blind: the generator of withheld effects (playscope.sim.withheld) and the
diagnosis' fitted forms (playscope.diagnose: fitmodel, attribute, geometry, localise, split) share no
module, function or constant. Walks the imports with ast, transitively inside the playscope package,
and compares the names each side defines."""

from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[3] / "host" / "playscope"
FORMS = ["diagnose/fitmodel.py", "diagnose/attribute.py", "diagnose/geometry.py", "diagnose/localise.py",
         "diagnose/split.py"]
GENERATOR = sorted(str(p.relative_to(PKG)) for p in (PKG / "sim" / "withheld").glob("*.py"))


def _module_path(mod: str) -> Path | None:
    """playscope.a.b -> host/playscope/a/b.py (or its package __init__)."""
    if not mod.startswith("playscope"):
        return None
    parts = mod.split(".")[1:]
    p = PKG.joinpath(*parts)
    if p.with_suffix(".py").is_file():
        return p.with_suffix(".py")
    if (p / "__init__.py").is_file():
        return p / "__init__.py"
    return None


def _imports(path: Path) -> set[str]:
    """Absolute playscope module names imported by a file (relative imports resolved; each
    package on the way counted too, since importing a.b runs a/__init__)."""
    rel = path.relative_to(PKG.parent).with_suffix("")
    pkg = list(rel.parts[:-1]) if rel.name != "__init__" else list(rel.parts[:-1])
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = pkg[: len(pkg) - node.level + 1] if node.level else []
            mod = ".".join(base + ([node.module] if node.module else [])) if node.level else node.module
            names = [mod] + [f"{mod}.{a.name}" for a in node.names]
        for n in names:
            if n and n.startswith("playscope"):
                parts = n.split(".")
                for i in range(1, len(parts) + 1):
                    if _module_path(".".join(parts[:i])):
                        out.add(".".join(parts[:i]))
    return out


def _closure(files: list[str]) -> set[str]:
    seen, todo = set(), [PKG / f for f in files if (PKG / f).is_file()]
    mods = set()
    while todo:
        p = todo.pop()
        if p in seen:
            continue
        seen.add(p)
        for m in _imports(p):
            mods.add(m)
            mp = _module_path(m)
            if mp and mp not in seen:
                todo.append(mp)
    return mods


def _defined(files: list[str]) -> set[str]:
    """Top-level function, class and constant names defined in the files."""
    out = set()
    for f in files:
        p = PKG / f
        if not p.is_file():
            continue
        for node in ast.parse(p.read_text()).body:
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                out.add(node.name)
            elif isinstance(node, ast.Assign):
                out |= {t.id for t in node.targets if isinstance(t, ast.Name)}
    return out


def test_diagnosis_forms_import_nothing_from_the_simulators():
    mods = _closure(FORMS)
    bad = sorted(m for m in mods if m.startswith("playscope.sim"))
    assert not bad, f"the diagnosis' fitted forms import simulator code: {bad}"


def test_generator_imports_no_diagnosis_or_effect_forms():
    assert len(GENERATOR) >= 3
    mods = _closure(GENERATOR)
    forbidden = ("playscope.diagnose", "playscope.fit", "playscope.sim.core", "playscope.sim.effects")
    bad = sorted(m for m in mods if m.startswith(forbidden))
    assert not bad, f"the withheld-effect generator imports fitted forms: {bad}"
    # What it may use: the session container and the excitation trajectory (no model form).
    # playscope.base.native, playscope.io.inputfile and playscope.io.csvtable (its CSV reader) come in
    # through the session container's loader
    # (the Q format's |q| limit, regular-file checks): never called while a record is generated,
    # which test_generators_never_run_the_native_core checks at run time.
    assert mods <= {"playscope", "playscope.base", "playscope.io", "playscope.io.session", "playscope.base.atomic", "playscope.base.errors", "playscope.sim",
                    "playscope.base.native", "playscope.io.inputfile", "playscope.io.csvtable",
                    "playscope.sim.withheld", "playscope.sim.withheld.hidden_plant",
                    "playscope.sim.withheld.variants", "playscope.sim.withheld.oracle",
                    "playscope.sim.withheld.recover"}, mods


def test_the_recoverability_oracle_is_on_the_generator_side():
    # recover.py knows the planted effect's form (the generator's own hooks): it is walked with the
    # generator, and nothing in the diagnosis, the harness aside, may import it.
    assert "sim/withheld/recover.py" in GENERATOR
    diagnosis = sorted(str(p.relative_to(PKG)) for p in (PKG / "diagnose").glob("*.py") if p.name != "selftest.py")
    bad = sorted(f for f in diagnosis if "playscope.sim.withheld.recover" in _closure([f]))
    assert not bad, f"the diagnosis imports the recoverability oracle: {bad}"


def test_no_name_defined_on_both_sides():
    common = (_defined(FORMS) & _defined(GENERATOR)) - {"__all__"}
    assert not common, f"defined on both sides: {sorted(common)}"


def test_the_walker_sees_a_forbidden_import(tmp_path):
    # The check can fail: selftest.py (the harness) imports both sides on purpose.
    mods = _closure(["diagnose/selftest.py"])
    assert any(m.startswith("playscope.sim.withheld") for m in mods)
    assert any(m.startswith("playscope.diagnose.fitmodel") for m in mods)


SECOND = sorted(str(p.relative_to(PKG)) for p in (PKG / "sim" / "withheld_b").glob("*.py"))


def test_second_generator_shares_no_code_with_the_first_or_the_fitter():
    assert "sim/withheld_b/generator.py" in SECOND
    mods = _closure(SECOND)
    assert mods <= {"playscope", "playscope.base", "playscope.io", "playscope.io.session", "playscope.base.atomic", "playscope.base.errors", "playscope.sim",
                    "playscope.base.native", "playscope.io.inputfile", "playscope.io.csvtable",  # the session loader's, see above
                    "playscope.sim.withheld_b", "playscope.sim.withheld_b.generator"}, mods
    common = (_defined(SECOND) & (_defined(FORMS) | _defined(GENERATOR))) - {"__all__"}
    assert not common, f"defined in the second generator and elsewhere: {sorted(common)}"


def test_generators_never_run_the_native_core(monkeypatch):
    """The firmware's C (play operator, tables) reaches the generators' import closure only
    through the session loader: generating a record of either generator never runs it."""
    import playscope.base.native as native

    def refuse(*a, **k):
        raise AssertionError("a generator ran the native core (the fitted forms' code)")

    monkeypatch.setattr(native, "core", refuse)
    monkeypatch.setattr(native, "_cached", None, raising=False)
    from playscope.diagnose.selftest import cases as cases_a
    from playscope.diagnose.selftest import make_session
    from playscope.sim.withheld_b.generator import cases as cases_b
    from playscope.sim.withheld_b.generator import session as session_b

    s_a = make_session(cases_a(nulls=1)[0], 20.0)
    s_b = session_b(cases_b(0, nulls=1)[0], 20.0)
    assert s_a.encoder["q"].size > 100 and s_b.encoder["q"].size > 100
