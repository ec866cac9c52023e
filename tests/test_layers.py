"""The layers (CONTRIBUTING.md, "Layers"; docs/design.md §1): core ← solvers ← studies ← application, and no
import cycles. The layers are named once, in pyproject.toml's [tool.importlinter] contracts; this file reads
them from there and checks

- that every module of optcal and studies is in exactly one layer (a new module must be placed);
- at run time, that importing any core module leaves ``solvers`` and ``studies`` out of ``sys.modules``,
  however it reaches them (a fresh interpreter imports the core modules one at a time);
- statically, that no core module names ``solvers``, ``studies`` or an application-layer module in an
  import statement or in a string given to ``importlib.import_module`` / ``__import__``, and that no module
  at all imports one of the project's modules by a fixed string (which would hide the edge from the
  contracts);
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

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("optcal", "solvers", "studies")
CONTRACTS = {c["id"]: c for c in tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
             ["contracts"]}

CORE = tuple(CONTRACTS["core"]["source_modules"])
SOLVERS = tuple(CONTRACTS["solvers"]["source_modules"])
STUDIES_LIBRARY = tuple(CONTRACTS["studies"]["source_modules"])
# The application layer: what the core may not import, less the lower layers themselves.
APPLICATION = tuple(sorted({m for c in ("core", "studies") for m in CONTRACTS[c]["forbidden_modules"]}
                           - {"solvers", "studies"}))
# Package __init__ files that re-export names of two layers, the application layer's at first use (PEP 562).
# Importing them imports no solver (checked below for optcal; tests/test_startup.py checks `import optcal`).
FACADES = {
    "optcal": "the package's public names; the application layer's (discover, and optcal.api's) at first use",
    "optcal.discovery": "re-exports discovery's core names, and discover/fit_model/score from its workflow",
    "optcal.recording": "re-exports the recording path's core names, and choose_threshold/fit_score/"
                        "positions_from_raw from its workflow",
    # packages whose modules sit in two layers; their __init__ imports only the core ones
    "optcal.gyro": "the gyroscope's core names (data, model, problem, simulation); optcal.gyro.workflow, which runs "
                   "a solver, is imported by name",
    "optcal.plan": "imports nothing; optcal.plan.solve, which runs a registry solver, is imported by name",
}


def _within(module: str, layer) -> bool:
    return any(module == m or module.startswith(m + ".") for m in layer)


def _modules(package: str) -> list[str]:
    """Every module of a package in the source tree (packages by their __init__), by file, without importing."""
    out = []
    for path in sorted((ROOT / package).rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        out.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return out


def _layer_of(module: str) -> list[str]:
    layers = {"core": CORE, "solvers": SOLVERS, "studies": STUDIES_LIBRARY, "application": APPLICATION}
    found = [name for name, layer in layers.items() if _within(module, layer)]
    return found + (["facade"] if module in FACADES else [])


def _path(module: str) -> Path:
    base = ROOT.joinpath(*module.split("."))
    return base / "__init__.py" if base.is_dir() else base.with_suffix(".py")


def test_every_module_is_in_exactly_one_layer():
    mods = [m for p in PACKAGES for m in _modules(p) if m != "studies"]  # studies/__init__.py is empty
    assert len(mods) > 60, mods  # the walk found the tree
    misplaced = {m: _layer_of(m) for m in mods if len(_layer_of(m)) != 1}
    assert misplaced == {}, ("name each module in one layer of pyproject.toml's [tool.importlinter] contracts "
                             f"(or, for a facade, in tests/test_layers.py): {misplaced}")
    assert {"optcal.fit", "optcal.cli", "optcal.commands", "optcal.discovery.workflow", "studies.command"} <= set(
        APPLICATION)
    assert {"optcal.problem", "optcal.analysis", "optcal.model", "optcal.discovery.statistics"} <= set(CORE)


# -- at run time ---------------------------------------------------------------------------------------

_IMPORT_EACH = """
import importlib, json, sys
found = []
for name in sys.argv[1:]:
    importlib.import_module(name)
    found.append([name, sorted({m.split(".")[0] for m in sys.modules} & {"solvers", "studies"})])
print(json.dumps(found))
"""


def _import_each(modules: list[str]) -> dict[str, list[str]]:
    """Import ``modules`` one after another in a fresh interpreter: {module: [solvers/studies imported by then]}."""
    proc = subprocess.run([sys.executable, "-c", _IMPORT_EACH, *modules], capture_output=True, text=True,
                          timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    return dict(json.loads(proc.stdout.strip().splitlines()[-1]))


def test_importing_core_modules_imports_neither_solvers_nor_studies():
    core = [m for m in _modules("optcal") if _within(m, CORE)]
    found = _import_each(core)
    assert list(found) == core
    assert {m: got for m, got in found.items() if got} == {}
    print(f"{len(core)} core modules imported; solvers and studies stayed out")


def test_the_run_time_check_sees_an_import_of_solvers():
    """The check above can fail: the discovery workflow, application layer, does import solvers; and the
    facade optcal.discovery does too, but only when one of the workflow's names is first used."""
    assert _import_each(["optcal.discovery", "optcal.discovery.workflow"]) == {
        "optcal.discovery": [], "optcal.discovery.workflow": ["solvers"]}


def test_importing_solvers_imports_no_study():
    found = _import_each(_modules("solvers"))
    assert {m: got for m, got in found.items() if got != ["solvers"]} == {}


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
        importlib.import_module("solvers")
        import_module(f"studies.{name}")
        __import__("optcal.fit")
        importlib.import_module("..commands.calibrate", __package__)
        importlib.import_module(f".{name}", __package__)
        importlib.import_module(name)
        importlib.import_module("optcal.model")
    """)
    found = dynamic_imports(src, "optcal.discovery.statistics")
    assert found == [(4, "solvers"), (5, "studies.{}"), (6, "optcal.fit"), (7, "optcal.commands.calibrate"),
                     (8, "optcal.discovery.{}"), (9, None), (10, "optcal.model")]
    forbidden = ("solvers", "studies", *APPLICATION)
    assert [_names(t, forbidden) for _, t in found] == [["solvers"], ["studies"], ["optcal.fit"],
                                                        ["optcal.commands"], [], [], []]


def _production_modules():
    for package in PACKAGES:
        for module in _modules(package):
            yield module, _path(module).read_text()


def test_core_modules_name_no_other_layer_in_imports_or_strings():
    """The rule tests/test_cli_core.py checked for all of optcal, now for its core (the application layer in
    optcal imports solvers on purpose), and with imports by string."""
    forbidden = ("solvers", "studies", *APPLICATION)
    static, dynamic = [], []
    for module, source in _production_modules():
        if not _within(module, CORE):
            continue
        for node in ast.walk(ast.parse(source)):
            mods = ([a.name for a in node.names] if isinstance(node, ast.Import)
                    else [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
            static += [f"{module}: {m}" for m in mods if m.split(".")[0] in ("solvers", "studies")]
        dynamic += [f"{module}:{line}: {t}" for line, t in dynamic_imports(source, module) if _names(t, forbidden)]
    assert static == []
    assert dynamic == []


def test_no_module_imports_one_of_the_projects_modules_by_a_fixed_string():
    """``importlib.import_module("optcal.x")`` is ``import optcal.x`` hidden from the contracts: write the
    import. Plugin discovery (optcal.cli over optcal/commands, solvers/__init__.py over its folder) builds
    the name from what it finds in its own package, relative to it, and is not a fixed string."""
    hidden = [f"{module}:{line}: {t}" for module, source in _production_modules()
              for line, t in dynamic_imports(source, module)
              if t is not None and "{}" not in t and t.split(".")[0] in PACKAGES]
    assert hidden == []


def test_no_import_cycles():
    """No module reaches itself through imports (function-level imports included): Tarjan's strongly
    connected components of grimp's graph, each printed with the imports that close it."""
    graph = grimp.build_graph(*PACKAGES, cache_dir=None)
    edges = {m: sorted(graph.find_modules_directly_imported_by(m)) for m in sorted(graph.modules)}
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(v):  # iterative would be longer; the graph is ~100 modules deep at most
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while not comp or comp[-1] != v:
                comp.append(stack.pop())
                on_stack.discard(comp[-1])
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for m in edges:
        if m not in index:
            visit(m)
    def lines(a, b):
        return ", ".join(str(d["line_number"]) for d in graph.get_import_details(importer=a, imported=b))

    detail = [[f"{a} -> {b} (line {lines(a, b)})" for a in c for b in edges[a] if b in c] for c in cycles]
    assert cycles == [], detail
    assert len(edges) > 80 and sum(map(len, edges.values())) > 200  # the graph was built


def test_lint_imports_keeps_every_contract():
    exe = Path(sys.executable).with_name("lint-imports")
    if not exe.exists():
        pytest.fail(f"{exe} not found: install the test extra (pip install -e '.[test]')")
    proc = subprocess.run([str(exe), "--no-cache"], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert f"Contracts: {len(CONTRACTS)} kept, 0 broken." in proc.stdout
