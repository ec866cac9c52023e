"""Every solver a study can name from this tree ("all" in a spec expands to them) has its section in
docs/algorithms.md (CONTRIBUTING.md, "Adding a solver"): a solver module added to optcal/solvers/ without one fails
here, naming the section to write. A plugin outside the tree (entry point optcal.solvers) documents itself
and is not checked."""

from __future__ import annotations

import re
from pathlib import Path

from optcal import solvers  # noqa: F401 - registers the in-tree solvers
from optcal.solvers import registry

DOC = Path(__file__).resolve().parents[1] / "docs" / "algorithms.md"


def _headings() -> list[str]:
    return re.findall(r"^## \d+\. (.*)$", DOC.read_text(), re.M)


def test_every_in_tree_solver_has_a_section_in_algorithms_md():
    heads = _headings()
    named = {n for h in heads for n in re.findall(r"`([^`]+)`", h)}
    missing = []
    for name in registry.names(include_variants=False):
        cls, _ = registry.solver_class(name)
        if cls.__module__.startswith("solvers.") and name not in named:
            missing.append(f"{name} ({cls.__module__})")
    for prefix in registry.wrappers() + registry.family_prefixes():
        if not any(n.startswith(f"{prefix}:") for n in named):
            missing.append(f"{prefix}:")
    assert not missing, ("docs/algorithms.md has no '## N. ... (`name`)' section for: " + ", ".join(missing))


def test_a_variant_is_covered_by_its_base_solver_section():
    named = {n for h in _headings() for n in re.findall(r"`([^`]+)`", h)}
    for name in registry.names(include_variants=True):
        cls, options = registry.solver_class(name)
        if options:  # a registered variant (register_variant): fixed options of a documented class
            assert cls.name in named, name
