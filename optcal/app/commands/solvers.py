"""optcal solvers: every registered solver (built-in and plugins) with its options and defaults, whether it
can run here, the wrapper prefixes that compose with any of them (``staged:bsas``, ``mcs:nafsa``), and the
families whose members are named in another library (``ng:NGOpt``: nevergrad's optimisers; ``mealpy:GWO``:
mealpy's, each of whose names is listed). ``optcal solvers mealpy:GWO`` describes one member: the class it
names, its paper line and its own settings with their defaults.

A command, so application layer (CONTRIBUTING.md, "Layers"): it imports the registry from ``solvers``
directly, inside :func:`listing` so that building the parser (``optcal --help``) does not load the solver
back-ends.
"""

from __future__ import annotations

import json

from optcal.core.errors import InputError

HELP = "list the registered solvers with their options, defaults and availability, and the wrappers"


def add_arguments(p):
    p.add_argument("names", nargs="*", metavar="NAME", help="only these solvers (default: all)")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def _plain(v):
    """A JSON-safe copy of an option default (numpy scalars and tuples included)."""
    import numpy as np

    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, tuple | list):
        return [_plain(x) for x in v]
    return v


def _member(reg, name: str) -> dict:
    """One member of a family (``mealpy:GWO``): checked by building it, described by its family if it can."""
    prefix, inner = name.split(":", 1)
    solver = reg.get(name)  # an unknown name or settings: the family's one-line error
    f = reg.family_factory(prefix)
    entry = {"name": name, "family": solver.family, "available": bool(solver.is_available()),
             "options": {k: {"default": _plain(o.default), "doc": o.doc} for k, o in solver.options.items()}}
    if not entry["available"]:
        entry["message"] = solver.unavailable_message()
    elif hasattr(f, "describe_member"):
        entry.update(f.describe_member(inner))
        entry["settings"] = {k: _plain(v) for k, v in entry["settings"].items()}
    return entry


def listing(names: list[str] | None = None) -> dict:
    """{"solvers": [...], "wrappers": [...], "families": [...]} as printed by ``optcal solvers --json``; with
    family members among ``names`` (``mealpy:GWO``) also {"members": [...]}."""
    from optcal.solvers import registry as reg

    known = reg.names()
    families = reg.family_prefixes()
    wanted_members = [n for n in names or [] if ":" in n and n.split(":", 1)[0] in families]
    unknown = [n for n in names or [] if n not in known and n not in wanted_members]
    if unknown:
        raise InputError(f"unknown solver(s) {', '.join(unknown)}; registered solvers: {', '.join(known)} "
                         f"(family members as PREFIX:NAME: {', '.join(p + ':' for p in families)})")
    out = []
    for d in reg.describe_all():
        if names and d["name"] not in names:
            continue
        cls, _ = reg.solver_class(d["name"])
        entry = {
            "name": d["name"], "family": d["family"], "available": bool(d["available"]),
            "module": cls.__module__,
            "options": {k: {"default": _plain(o["default"]), "doc": o.get("doc", ""),
                            **({"fixed": True} if o.get("fixed") else {})} for k, o in d["options"].items()},
        }
        if not entry["available"]:
            entry["message"] = cls.unavailable_message()
        out.append(entry)
    wrappers = []
    for prefix in reg.wrappers():
        f = reg.wrapper_factory(prefix)
        opts = getattr(f, "options", {}) or {}
        doc = (getattr(f, "__doc__", "") or "").strip().splitlines()
        wrappers.append({
            "prefix": prefix, "usage": f"{prefix}:<solver>", "doc": doc[0] if doc else "",
            "options": {k: {"default": _plain(o.default), "doc": o.doc} for k, o in opts.items()},
        })
    families = []
    for d in reg.describe_all(families=True):
        if "prefix" not in d:
            continue
        entry = {"prefix": d["prefix"], "usage": d["name"], "family": d["family"], "available": d["available"],
                 "doc": d["doc"], "list_hint": d["list_hint"],
                 "options": {k: {"default": _plain(o["default"]), "doc": o["doc"]} for k, o in d["options"].items()}}
        f = reg.family_factory(d["prefix"])
        if not d["available"]:
            entry["message"] = f.unavailable_message()
        elif hasattr(f, "members"):  # the library's own names, where the family can list them
            entry["members"] = list(f.members())
        families.append(entry)
    doc = {"solvers": out, "wrappers": wrappers, "families": families}
    if wanted_members:
        doc["members"] = [_member(reg, n) for n in wanted_members]
    return doc


def _option_lines(options: dict) -> list[str]:
    shown = {k: (repr(o["default"]) if isinstance(o["default"], str) else str(o["default"]))
             + (" (fixed)" if o.get("fixed") else "") for k, o in options.items()}
    kw = max((len(k) for k in shown), default=0)
    dw = max((len(v) for v in shown.values()), default=0)
    return [f"    {k:<{kw}} = {v:<{dw}}  {options[k]['doc']}".rstrip() for k, v in shown.items()]


def _member_lines(m: dict) -> list[str]:
    state = "available" if m["available"] else f"UNAVAILABLE: {m['message']}"
    lines = [f"{m['name']}  [{m['family']}]  {state}" + (f"  {m['class']} ({m['module']}): {m['doc']}"
                                                          if "class" in m else "")]
    lines.extend(_option_lines(m["options"]))
    if m.get("settings"):
        lines.append("    its own settings (--option KEY=VALUE), with their defaults:")
        lines.extend(f"    {k} = {v!r}" for k, v in m["settings"].items())
    return lines


def _wrapped(names: list[str], width: int = 116) -> list[str]:
    out, line = [], "   "
    for n in names:
        if len(line) + len(n) + 1 > width:
            out.append(line)
            line = "   "
        line += " " + n
    return out + ([line] if line.strip() else [])


def run(args) -> int:
    info = listing(args.names)
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    lines = []
    for m in info.get("members", []):
        lines.extend(_member_lines(m))
    for s in info["solvers"]:
        state = "available" if s["available"] else f"UNAVAILABLE: {s['message']}"
        lines.append(f"{s['name']}  [{s['family']}]  {state}")
        lines.extend(_option_lines(s["options"]) or ["    (no options)"])
    if not args.names:
        lines.append("")
        lines.append("wrappers (PREFIX:SOLVER composes with any solver; wrapper options as --option KEY=VALUE,")
        lines.append("the inner solver's as --option inner.KEY=VALUE):")
        for w in info["wrappers"]:
            lines.append(f"{w['usage']}  {w['doc']}")
            lines.extend(_option_lines(w["options"]))
        if info["families"]:
            lines.append("")
            lines.append("families (PREFIX:NAME, NAME from another library; its settings pass through --option):")
        for f in info["families"]:
            state = "available" if f["available"] else f"UNAVAILABLE: {f['message']}"
            lines.append(f"{f['usage']}  [{f['family']}]  {state}  {f['doc']}")
            lines.extend(_option_lines(f["options"]))
            if f.get("members"):
                lines.append(f"    names ({len(f['members'])}):")
                lines.extend(_wrapped(f["members"]))
            if f["list_hint"]:
                lines.append(f"    names: {f['list_hint']}")
    print("\n".join(lines))
    return 0
