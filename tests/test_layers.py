"""The layers (CONTRIBUTING.md, "Layers"; docs/design.md, "Scope, layout and the direction of imports"), one folder
each: optcal.core ← optcal.solvers ←
optcal.studies ← optcal.app, and no import cycles. pyproject.toml states them in two contracts (a ``layers``
contract over the folders and an acyclic one with no exception); this file checks

- that the contracts are that short, and that every module lives in one of the four folders;
- at run time, that importing any module of a layer leaves every higher layer out of ``sys.modules``,
  however it reaches them (a fresh interpreter imports the layer's modules one at a time);
- statically, that no module imports one of the project's modules by a fixed string (which would hide the
  edge from the contracts);
- that no two modules import each other, directly or through others (grimp's graph, function-level imports
  included);
- and that ``lint-imports`` (the contracts themselves) passes, so that pytest alone checks them too.
"""

from __future__ import annotations

import ast
import json
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import grimp
import pytest
from conftest import doc_script

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("optcal",)
LINTER = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
CONTRACTS = {c["id"]: c for c in LINTER["contracts"]}
# lowest first: a layer may import those before it, never those after it
LAYERS = tuple(f"optcal.{name}" for name in reversed(CONTRACTS["layers"]["layers"]))


def _within(module: str, layer) -> bool:
    return any(module == m or module.startswith(m + ".") for m in layer)


def _modules(package: str) -> list[str]:
    """Every module of a package in the source tree (packages by their __init__), by file, without importing."""
    out = []
    for path in sorted((ROOT.joinpath(*package.split("."))).rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        out.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return out


def _path(module: str) -> Path:
    base = ROOT.joinpath(*module.split("."))
    return base / "__init__.py" if base.is_dir() else base.with_suffix(".py")


def test_the_contracts_are_the_folders():
    """Two contracts, no exception, no module named by hand: the layers are the folders."""
    assert list(CONTRACTS) == ["layers", "acyclic"]
    assert LINTER["root_packages"] == ["optcal"]
    assert CONTRACTS["layers"]["containers"] == ["optcal"] and CONTRACTS["layers"]["exhaustive"] is True
    assert LAYERS == ("optcal.core", "optcal.solvers", "optcal.studies", "optcal.app")
    assert CONTRACTS["acyclic"]["ancestors"] == ["optcal"] and "ignore_imports" not in CONTRACTS["acyclic"]
    text = (ROOT / "pyproject.toml").read_text()
    section = text[text.index("[tool.importlinter]"):]
    section = re.split(r"\n\[tool\.(?!importlinter)", section)[0]
    assert len([ln for ln in section.splitlines() if ln.strip() and not ln.startswith("#")]) <= 16, section


def test_every_module_lives_in_one_layer_folder():
    mods = _modules("optcal")
    assert len(mods) > 150, mods  # the walk found the tree
    # optcal.__main__ is where `python -m optcal` must find it, and imports optcal.app.cli alone
    outside = [m for m in mods if m not in ("optcal", "optcal.__main__") and not _within(m, LAYERS)]
    assert (ROOT / "optcal" / "__main__.py").read_text().count("import") == 2  # sys, and the CLI
    assert outside == [], f"put each module in one layer's folder (optcal/core, solvers, studies or app): {outside}"
    assert sorted(p.name for p in (ROOT / "optcal").iterdir() if p.is_dir() and p.name != "__pycache__") == [
        "app", "core", "solvers", "studies"]


# -- at run time ---------------------------------------------------------------------------------------

_IMPORT_EACH = """
import importlib, json, sys
above = sys.argv[1].split(",")
found = []
for name in sys.argv[2:]:
    importlib.import_module(name)
    found.append([name, sorted({a for a in above for m in sys.modules if m == a or m.startswith(a + ".")})])
print(json.dumps(found))
"""


def _import_each(modules: list[str], above) -> dict[str, list[str]]:
    """Import ``modules`` one after another in a fresh interpreter: {module: [the layers of ``above`` imported by
    then]}."""
    proc = subprocess.run([sys.executable, "-c", _IMPORT_EACH, ",".join(above), *modules], capture_output=True,
                          text=True, timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    return dict(json.loads(proc.stdout.strip().splitlines()[-1]))


@pytest.mark.parametrize("level", range(3))
def test_importing_a_layer_imports_no_higher_layer(level):
    layer, above = LAYERS[level], LAYERS[level + 1:]
    mods = _modules(layer)
    found = _import_each(mods, above)
    assert list(found) == mods
    assert {m: got for m, got in found.items() if got} == {}


def test_the_run_time_check_sees_an_import_of_solvers():
    """The check above can fail: the discovery workflow (application) imports the solvers; the core's
    discovery package does not."""
    assert _import_each(["optcal.core.discovery", "optcal.app.workflows.discovery"], LAYERS[1:3]) == {
        "optcal.core.discovery": [], "optcal.app.workflows.discovery": ["optcal.solvers"]}


# -- statically ------------------------------------------------------------------------------------------

def _is_dynamic_import(call: ast.Call) -> bool:
    f = call.func
    name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
    return name in ("import_module", "__import__")


def _text(node) -> str | None:
    """A string argument as text, each f-string placeholder as {}; None when it is not written out."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        return "".join(v.value if isinstance(v, ast.Constant) else "{}" for v in node.values)
    return None


def dynamic_imports(source: str, module: str) -> list[tuple[int, str | None]]:
    """(line, target) of every ``importlib.import_module(...)`` / ``__import__(...)`` call in ``source``: the
    target written out (placeholders as {}), made absolute when it is relative to the module's own package,
    or None when it is not a string or f-string."""
    package = module if _path(module).name == "__init__.py" else module.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(source)):
        if not (isinstance(node, ast.Call) and _is_dynamic_import(node) and node.args):
            continue
        target = _text(node.args[0])
        anchor = node.args[1] if len(node.args) > 1 else next((k.value for k in node.keywords if k.arg == "package"),
                                                                None)
        if target and target.startswith(".") and isinstance(anchor, ast.Name) and anchor.id in ("__name__",
                                                                                                 "__package__"):
            base = (module if anchor.id == "__name__" else package).split(".")
            level = len(target) - len(target.lstrip("."))
            target = ".".join(base[: len(base) - level + 1] + [target.lstrip(".")])
        found.append((node.lineno, target))
    return found


def _names(target: str | None, modules) -> list[str]:
    """The modules of ``modules`` that ``target`` names (as a whole dotted name or a prefix of one)."""
    if target is None:
        return []
    return [m for m in modules if re.search(rf"(?<![\w.]){re.escape(m)}(?![\w])", target)]


def test_the_dynamic_import_scan_finds_string_imports():
    src = textwrap.dedent("""
        import importlib
        from importlib import import_module
        importlib.import_module("optcal.solvers")
        import_module(f"optcal.studies.{name}")
        __import__("optcal.app.fit")
        importlib.import_module("..commands.calibrate", __package__)
        importlib.import_module(f".{name}", __package__)
        importlib.import_module(name)
        importlib.import_module("optcal.core.model")
    """)
    found = dynamic_imports(src, "optcal.core.discovery.statistics")
    assert found == [(4, "optcal.solvers"), (5, "optcal.studies.{}"), (6, "optcal.app.fit"),
                     (7, "optcal.core.commands.calibrate"),
                     (8, "optcal.core.discovery.{}"), (9, None), (10, "optcal.core.model")]
    forbidden = LAYERS[1:]
    assert [_names(t, forbidden) for _, t in found] == [["optcal.solvers"], ["optcal.studies"], ["optcal.app"],
                                                        [], [], [], []]


def _production_modules():
    for package in PACKAGES:
        for module in _modules(package):
            yield module, _path(module).read_text()


def test_no_module_imports_a_higher_layer_by_a_built_string():
    """An import whose target is built at run time (an f-string) is invisible to the contracts: none of a lower
    layer's may name a higher layer."""
    bad = []
    for level, layer in enumerate(LAYERS[:-1]):
        for module in _modules(layer):
            bad += [f"{module}:{line}: {t}" for line, t in dynamic_imports(_path(module).read_text(), module)
                    if _names(t, LAYERS[level + 1:])]
    assert bad == []


def test_no_module_imports_one_of_the_projects_modules_by_a_fixed_string():
    """``importlib.import_module("optcal.x")`` is ``import optcal.x`` hidden from the contracts: write the
    import. Plugin discovery (optcal.app.cli over optcal/app/commands, optcal/solvers/registry.py over its folder)
    builds
    the name from what it finds in its own package, relative to it, and is not a fixed string."""
    hidden = [f"{module}:{line}: {t}" for module, source in _production_modules()
              for line, t in dynamic_imports(source, module)
              if t is not None and "{}" not in t and t.split(".")[0] in PACKAGES]
    assert hidden == []


def _import_graph_script():
    """docs/scripts/import_graph.py, whose facts (floors, cycles, upward arrows) the closing notes quote."""
    return doc_script("import_graph")


def test_no_import_cycles_and_no_upward_arrow():
    """No module reaches itself through imports (function-level imports included), no two sibling packages
    import each other, and no module imports a higher layer: the strongly connected components of grimp's
    graph (docs/scripts/import_graph.py), each cycle printed with the imports that close it."""
    graph = grimp.build_graph(*PACKAGES, cache_dir=None)
    facts = _import_graph_script().facts(graph)
    edges = {m: sorted(graph.find_modules_directly_imported_by(m)) for m in sorted(graph.modules)}

    def lines(a, b):
        return ", ".join(str(d["line_number"]) for d in graph.get_import_details(importer=a, imported=b))

    cycles = facts["module_cycles"]
    detail = [[f"{a} -> {b} (line {lines(a, b)})" for a in c for b in edges[a] if b in c] for c in cycles]
    assert cycles == [], detail
    assert facts["sibling_cycles"] == [] and facts["upward"] == []
    assert facts["modules"] > 150 and sum(map(len, edges.values())) > 200  # the graph was built


def test_lint_imports_keeps_every_contract():
    exe = Path(sys.executable).with_name("lint-imports")
    if not exe.exists():
        pytest.fail(f"{exe} not found: install the test extra (pip install -e '.[test]')")
    proc = subprocess.run([str(exe), "--no-cache"], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert f"Contracts: {len(CONTRACTS)} kept, 0 broken." in proc.stdout
