"""The solver registry: named, configured solvers; duplicate names refused (after nevergrad's registry).

Solvers register with :func:`register` (a class) or :func:`register_variant` (a class with fixed options,
e.g. ``nlopt-bobyqa``). Wrappers register a prefix (``staged:``, ``mcs:``) that takes any inner solver
name. Third-party solvers are found through the entry-point group ``optcal.solvers``: each entry point
names a Solver class (or a callable that registers several).
"""

from __future__ import annotations

from collections.abc import Callable
from importlib import metadata

from optcal.errors import InputError

from .base import Solver

_SOLVERS: dict[str, tuple[type[Solver], dict]] = {}
_WRAPPERS: dict[str, Callable[..., Solver]] = {}
_entry_points_loaded = False


def register(cls: type[Solver]) -> type[Solver]:
    """Class decorator: register a solver under ``cls.name``."""
    _add(cls.name, cls, {})
    return cls


def register_variant(name: str, cls: type[Solver], **options) -> None:
    """Register ``cls`` with fixed options under another name."""
    cls(**options)  # validate now, not at first use
    _add(name, cls, options)


def register_wrapper(prefix: str, factory: Callable[..., Solver]) -> None:
    """Register a wrapper prefix: ``prefix:inner`` builds ``factory(inner_solver, **options)``."""
    if prefix in _WRAPPERS:
        raise ValueError(f"wrapper prefix {prefix!r} is already registered")
    _WRAPPERS[prefix] = factory


def _add(name: str, cls: type[Solver], options: dict) -> None:
    if not name or ":" in name:
        raise ValueError(f"invalid solver name {name!r}")
    if name in _SOLVERS:
        raise ValueError(f"a solver named {name!r} is already registered ({_SOLVERS[name][0].__module__})")
    _SOLVERS[name] = (cls, options)


def load_entry_points() -> list[str]:
    """Load third-party solvers from the ``optcal.solvers`` entry-point group (once)."""
    global _entry_points_loaded
    if _entry_points_loaded:
        return []
    _entry_points_loaded = True
    loaded = []
    for ep in metadata.entry_points(group="optcal.solvers"):
        obj = ep.load()
        if isinstance(obj, type) and issubclass(obj, Solver):
            if obj.name not in _SOLVERS:
                register(obj)
                loaded.append(obj.name)
        elif callable(obj):
            obj()
            loaded.append(ep.name)
    return loaded


def names(include_variants: bool = True) -> list[str]:
    load_entry_points()
    return sorted(n for n, (_, opts) in _SOLVERS.items() if include_variants or not opts)


def wrappers() -> list[str]:
    return sorted(_WRAPPERS)


def wrapper_factory(prefix: str) -> Callable[..., Solver]:
    """The factory registered for ``prefix:`` (its ``options`` and docstring describe it)."""
    if prefix not in _WRAPPERS:
        raise InputError(f"unknown solver wrapper {prefix!r}; wrappers: {', '.join(wrappers()) or 'none'}")
    return _WRAPPERS[prefix]


def solver_class(name: str) -> tuple[type[Solver], dict]:
    load_entry_points()
    if name not in _SOLVERS:
        known = ", ".join(names())
        raise InputError(f"unknown solver {name!r}; registered solvers: {known} (wrappers: "
                         f"{', '.join(p + ':<solver>' for p in wrappers())})")
    return _SOLVERS[name]


def get(name: str, **options) -> Solver:
    """A configured solver by name; ``prefix:inner`` builds a wrapper around an inner solver.

    Options go to the outermost solver; inner options can be given as ``inner.KEY``.
    """
    name = name.strip()
    if ":" in name:
        prefix, inner_name = name.split(":", 1)
        if prefix not in _WRAPPERS:
            raise InputError(f"unknown solver wrapper {prefix!r}; wrappers: {', '.join(wrappers()) or 'none'}")
        inner_opts = {k.split(".", 1)[1]: v for k, v in options.items() if k.startswith("inner.")}
        outer_opts = {k: v for k, v in options.items() if not k.startswith("inner.")}
        return _WRAPPERS[prefix](get(inner_name, **inner_opts), **outer_opts)
    cls, fixed = solver_class(name)
    clash = sorted(set(fixed) & set(options))
    if clash:
        raise InputError(f"solver {name} fixes option(s) {', '.join(clash)}; use the base solver to change them")
    solver = cls(**{**fixed, **options})
    solver.name = name
    return solver


def describe_all() -> list[dict]:
    out = []
    for n in names():
        cls, fixed = _SOLVERS[n]
        d = cls.describe()
        d["name"] = n
        for k, v in fixed.items():
            d["options"][k]["default"] = v
            d["options"][k]["fixed"] = True
        out.append(d)
    return out
