"""The solver registry: named, configured solvers; duplicate names refused (after nevergrad's registry).

Solvers register with :func:`register` (a class) or :func:`register_variant` (a class with fixed options,
e.g. ``nlopt-bobyqa``). Wrappers register a prefix (``staged:``, ``mcs:``) that takes any inner solver
name. Families register a prefix (``ng:``) whose suffix is a name in another library (``ng:NGOpt``: the
optimiser nevergrad registers as ``NGOpt``); their members are not listed one by one (the other library
holds them, and may not be installed), so :func:`names` and :func:`describe_all` show a family as one
entry, ``ng:<NAME>``, only when asked (``families=True``): every name they return by default is one
:func:`solver_class` knows. Third-party solvers are found through the entry-point group ``optcal.solvers``:
each entry point names a Solver class (or a callable that registers several).

The package's own solver modules are imported when first needed (:func:`load_builtins`): a look-up of a name
that is one module's own (``lm``, in ``lm.py``) imports that module alone, anything else (another name, a
listing, a wrapper or family prefix, an entry point, a registration from outside the package) all of them
first, so that the answers are those of a registry holding every built-in solver.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
from collections.abc import Callable

from optcal.core.errors import InputError
from optcal.solvers.base import Solver

_SOLVERS: dict[str, tuple[type[Solver], dict]] = {}
_WRAPPERS: dict[str, Callable[..., Solver]] = {}
_FAMILIES: dict[str, Callable[..., Solver]] = {}
_entry_points_loaded = False
_builtins_loaded = False
_FOLDER = os.path.dirname(os.path.abspath(__file__))


def load_builtins() -> None:
    """Import every solver module of this package (once; each registers its solvers, wrappers and families): the
    modules of its own folder other than ``base``, ``registry`` and private ones, relative to the package, so
    that this discovery cannot reach another layer."""
    global _builtins_loaded
    if _builtins_loaded:
        return
    import pkgutil

    _builtins_loaded = True  # before the imports: their registrations must not load them again
    try:
        for m in sorted(i.name for i in pkgutil.iter_modules([_FOLDER])):
            if m not in ("base", "registry") and not m.startswith("_"):
                importlib.import_module(f".{m}", __package__)
    except BaseException:
        _builtins_loaded = False
        raise


def _load_module_of(name: str) -> None:
    """Import the solver module named ``name`` (``lm.py`` for ``lm``), when the package has one: a command that
    runs one solver imports no other."""
    if (name.isidentifier() and not name.startswith("_") and name not in ("base", "registry")
            and os.path.isfile(os.path.join(_FOLDER, f"{name}.py"))):
        importlib.import_module(f".{name}", __package__)


def _builtins_before(obj) -> None:
    """Load the built-in solvers before ``obj`` (a class or factory) is registered from outside the package, so
    that one taking a built-in's name is refused at its own registration."""
    if not str(getattr(obj, "__module__", "")).startswith(f"{__package__}."):
        load_builtins()


def register(cls: type[Solver]) -> type[Solver]:
    """Class decorator: register a solver under ``cls.name``."""
    _builtins_before(cls)
    _add(cls.name, cls, {})
    return cls


def register_variant(name: str, cls: type[Solver], **options) -> None:
    """Register ``cls`` with fixed options under another name."""
    _builtins_before(cls)
    cls(**options)  # validate now, not at first use
    _add(name, cls, options)


def register_wrapper(prefix: str, factory: Callable[..., Solver]) -> None:
    """Register a wrapper prefix: ``prefix:inner`` builds ``factory(inner_solver, **options)``."""
    _builtins_before(factory)
    _check_prefix(prefix, "wrapper")
    _WRAPPERS[prefix] = factory


def register_family(prefix: str, factory: Callable[..., Solver]) -> None:
    """Register a family prefix: ``prefix:NAME`` builds ``factory(NAME, **options)``, where NAME is a name in
    another library (``ng:NGOpt``). The factory checks NAME (an unknown one is an :class:`InputError`
    naming close names) and its options. For the listings it may carry ``family`` (the conformance family
    of its members), ``options`` (the Options every member takes), ``requires`` (packages), a docstring
    whose first line describes the family, and ``list_hint`` (how to list the library's names)."""
    _builtins_before(factory)
    _check_prefix(prefix, "family")
    _FAMILIES[prefix] = factory


def _check_prefix(prefix: str, kind: str) -> None:
    if not prefix or ":" in prefix:
        raise ValueError(f"invalid {kind} prefix {prefix!r}")
    if prefix in _WRAPPERS or prefix in _FAMILIES:
        taken = "wrapper" if prefix in _WRAPPERS else "family"
        raise ValueError(f"{kind} prefix {prefix!r} is already registered (as a {taken} prefix)")


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
    load_builtins()  # first: a plug-in cannot take a built-in solver's name
    _entry_points_loaded = True
    from importlib import metadata  # here: scanning the installed packages costs a command tens of ms

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


def names(include_variants: bool = True, families: bool = False) -> list[str]:
    """The registered solvers' names; with ``families=True`` also each family as ``prefix:<NAME>``."""
    load_entry_points()
    out = sorted(n for n, (_, opts) in _SOLVERS.items() if include_variants or not opts)
    return out + [f"{p}:<NAME>" for p in family_prefixes()] if families else out


def wrappers() -> list[str]:
    load_builtins()
    return sorted(_WRAPPERS)


def family_prefixes() -> list[str]:
    """The registered family prefixes (``ng``)."""
    load_builtins()
    return sorted(_FAMILIES)


def family_factory(prefix: str) -> Callable[..., Solver]:
    """The factory registered for the family ``prefix:`` (its attributes and docstring describe it)."""
    load_builtins()
    if prefix not in _FAMILIES:
        raise InputError(f"unknown solver family {prefix!r}; families: {', '.join(family_prefixes()) or 'none'}")
    return _FAMILIES[prefix]


def _prefixes() -> str:
    return ", ".join([p + ":<solver>" for p in wrappers()] + [p + ":<NAME>" for p in family_prefixes()]) or "none"


def wrapper_factory(prefix: str) -> Callable[..., Solver]:
    """The factory registered for ``prefix:`` (its ``options`` and docstring describe it)."""
    load_builtins()
    if prefix not in _WRAPPERS:
        raise InputError(f"unknown solver wrapper {prefix!r}; wrappers: {', '.join(wrappers()) or 'none'}")
    return _WRAPPERS[prefix]


def solver_class(name: str) -> tuple[type[Solver], dict]:
    if name not in _SOLVERS:
        _load_module_of(name)
    if name not in _SOLVERS:  # a plug-in cannot take a built-in solver's name: look further only for others
        load_entry_points()
    if name not in _SOLVERS:
        known = ", ".join(names())
        raise InputError(f"unknown solver {name!r}; registered solvers: {known} (wrappers and families: "
                         f"{_prefixes()})")
    return _SOLVERS[name]


def get(name: str, **options) -> Solver:
    """A configured solver by name; ``prefix:inner`` builds a wrapper around an inner solver, and
    ``family:NAME`` the member NAME of a family (``ng:NGOpt``).

    Options go to the outermost solver; inner options can be given as ``inner.KEY``.
    """
    name = name.strip()
    if ":" in name:
        load_builtins()
        prefix, inner_name = name.split(":", 1)
        if prefix in _FAMILIES:
            return _FAMILIES[prefix](inner_name, **options)
        if prefix not in _WRAPPERS:
            raise InputError(f"unknown solver prefix {prefix!r}; wrappers and families: {_prefixes()}")
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


def describe_all(families: bool = False) -> list[dict]:
    """:meth:`Solver.describe` of every registered solver; with ``families=True`` also one entry per family
    (``name`` ``prefix:<NAME>``, its members' family, availability and common options, ``doc`` and
    ``list_hint``)."""
    out = []
    for n in names():
        cls, fixed = _SOLVERS[n]
        d = cls.describe()
        d["name"] = n
        for k, v in fixed.items():
            d["options"][k]["default"] = v
            d["options"][k]["fixed"] = True
        out.append(d)
    if families:
        out += [_describe_family(p) for p in family_prefixes()]
    return out


def _describe_family(prefix: str) -> dict:
    f = _FAMILIES[prefix]
    requires = tuple(getattr(f, "requires", ()))
    doc = (getattr(f, "__doc__", "") or "").strip().splitlines()
    return {
        "name": f"{prefix}:<NAME>", "prefix": prefix, "family": getattr(f, "family", ""),
        "available": all(importlib.util.find_spec(r) is not None for r in requires),
        "options": {k: {"default": o.default, "doc": o.doc} for k, o in getattr(f, "options", {}).items()},
        "doc": doc[0] if doc else "", "list_hint": getattr(f, "list_hint", ""),
    }
