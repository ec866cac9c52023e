"""Facts of optcal's import graph (issue #30's closing note, CONTRIBUTING.md "Layers"): the number of modules,
the floors (the longest chain of module imports, a module counted once), the import cycles between modules and
between the sibling subpackages of a package, and the upward arrows: imports from a lower layer into a higher
one, the layers being the folders optcal/core ← optcal/solvers ← optcal/studies ← optcal/app.

    .venv/bin/python docs/scripts/import_graph.py

grimp (import-linter's own graph builder) reads the imports statically, as the contracts see them.
"""

from __future__ import annotations

import sys

import grimp

LAYER = {"core": 0, "solvers": 1, "studies": 2, "app": 3}


def layer_of(module: str) -> str:
    """A module's layer is its folder; the package's own __init__ (the front door, which imports only the
    core's errors and loads the rest by name at first use) counts as the top."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in LAYER else "app"


def strongly_connected(nodes: list[str], deps: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components, iteratively (no recursion limit)."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], 0
    for root in nodes:
        if root in index:
            continue
        work = [(root, iter(sorted(deps[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(deps[w]))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    out.append(sorted(comp))
    return out


def facts(graph) -> dict:
    mods = sorted(graph.modules)
    deps = {m: set(graph.find_modules_directly_imported_by(m)) & set(mods) for m in mods}
    sccs = strongly_connected(mods, deps)
    comp = {m: k for k, c in enumerate(sccs) for m in c}
    # Tarjan emits components in reverse topological order: a component's imports come before it
    depth = [0] * len(sccs)
    for k, c in enumerate(sccs):
        depth[k] = 1 + max((depth[comp[w]] for m in c for w in deps[m] if comp[w] != k), default=0)
    upward = sorted((a, b) for a in mods for b in deps[a] if LAYER[layer_of(b)] > LAYER[layer_of(a)])
    # cycles between the sibling subpackages (or modules) of each package, as import-linter's acyclic contract
    sibling_cycles = []
    for parent in sorted({m.rsplit(".", 1)[0] for m in mods if "." in m}):
        kids = sorted(m for m in mods if "." in m and m.rsplit(".", 1)[0] == parent)
        top = {m: next((k for k in kids if m == k or m.startswith(k + ".")), None) for m in mods}
        kdeps = {k: set() for k in kids}
        for a in mods:
            for b in deps[a]:
                ka, kb = top[a], top[b]
                if ka and kb and ka != kb:
                    kdeps[ka].add(kb)
        sibling_cycles += [c for c in strongly_connected(kids, kdeps) if len(c) > 1]
    return {"modules": len(mods), "floors": max(depth, default=0),
            "module_cycles": [c for c in sccs if len(c) > 1], "sibling_cycles": sibling_cycles, "upward": upward}


def main() -> None:
    f = facts(grimp.build_graph("optcal", cache_dir=None))
    print(f"modules: {f['modules']}")
    print(f"floors (longest chain of module imports): {f['floors']}")
    print(f"cycles between modules: {len(f['module_cycles'])}; between sibling packages: "
          f"{len(f['sibling_cycles'])} {f['sibling_cycles']}")
    print(f"upward arrows (a lower layer importing a higher one): {len(f['upward'])}")
    for a, b in f["upward"]:
        print(f"  {a} ({layer_of(a)}) -> {b} ({layer_of(b)})")


if __name__ == "__main__":
    sys.exit(main())
