"""Generate :mod:`optcal.core.kernels._terms`, the compiled form of the model's term table.

The model's equations are written once, in :meth:`optcal.core.model.Model.components`. This module evaluates
that method on symbols (:mod:`optcal.core.kernels.symbolic`) for the model that holds every term, and prints
four numba functions of one position:

* ``forward_all``: the outputs N = F(A; q) (docs/design.md, "Terms and parameters"'s table), and ``forward_seed``, the
same
  for the terms of the named models only (see ``VARIANTS``),
* ``forward_dA``: ∂F/∂A, the 3×3 matrix the inverse and the implicit-function Jacobian need,
* ``forward_dq``: the non-zero entries of ∂F/∂q, the analytic Jacobian with respect to the parameters,
* ``linear_part``: F's linearisation at A = 0 with no temperature or time offset, M·A + c, whose
  inverse starts and steps the fixed-point inverse (for the linear terms it is diag(K)·T and K·b).

q is the *canonical* parameter vector: every parameter of every term, in term order (``SLOTS``). A model
with fewer terms puts its parameters into their slots and leaves the others at zero, where every term of
the table vanishes, so one compiled kernel serves every model.

Run ``python -m optcal.core.kernels.codegen`` after changing the term table; a test fails while the generated
file is out of date.
"""

from __future__ import annotations

import functools
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from optcal.core.kernels.symbolic import ZERO, SymbolicOps, diff, emit, substitute, sym
from optcal.core.model import AXES, TERMS, get_model

TARGET = Path(__file__).with_name("_terms.py")
A_NAMES = tuple(f"a{a}" for a in AXES)  # ax, ay, az
CTX_NAMES = ("dT", "dt")  # temperature offset (°C) and time offset (s) of the position


def slots() -> tuple[str, ...]:
    """Every parameter name of the term table, once, in term order."""
    out: list[str] = []
    for term in TERMS.values():
        out.extend(p for p in term.params if p not in out)
    return tuple(out)


@functools.cache
def _slot_of() -> dict[str, int]:
    return {n: k for k, n in enumerate(slots())}


# The parameters of user-defined terms (optcal.core.terms.user_term) are not in the table the kernel was generated
# from: each gets a slot past the canonical ones the first time a model with it is packed, and the kernel adds
# its feature to the outputs from a small table (optcal.core.kernels.evaluate, "user features"). The slots live as
# long as the process; they are never written anywhere.
_USER_SLOTS: dict[tuple, int] = {}
_USER_SPECS: list[tuple] = []


def slot_indices(model) -> np.ndarray:
    """Where each of ``model``'s parameters sits in the canonical vector q; a user-defined term's parameters in
    the slots after them (:func:`user_spec` gives their feature)."""
    where = _slot_of()
    user = {name: (axis, feature, kind) for _, axis, name, feature, kind in model._user}
    out = []
    for n in model.names:
        if n in where:
            out.append(where[n])
            continue
        key = (n, *user[n])
        if key not in _USER_SLOTS:
            _USER_SLOTS[key] = len(where) + len(_USER_SPECS)
            _USER_SPECS.append(user[n])
        out.append(_USER_SLOTS[key])
    return np.array(out, np.int64)


def user_spec(slot: int) -> tuple:
    """(output axis, :class:`optcal.core.terms.Feature`, kind) of a user-defined term's parameter slot."""
    return _USER_SPECS[slot - len(_slot_of())]


# The forward map is also generated for a smaller set of terms, which the fixed-point inverse (the
# inner loop of every cost) evaluates three times faster than the whole table. Its terms cover every
# named model (misalignment's three angles are slots of misalignment6); other models use "all".
VARIANTS: dict[str, tuple[str, ...]] = {
    "seed": ("scale", "bias", "misalignment6", "quadratic"),
    "all": tuple(t for t in TERMS if t != "misalignment"),  # misalignment6 holds every angle slot
}


def variant_of(model) -> int:
    """Index in VARIANTS of the first forward map whose terms hold every parameter of ``model``; a model with
    user-defined terms (the kernel's user features, outside the generated maps) takes the last, so that the
    kernel is compiled for them with one forward map only."""
    if model.user_terms:
        return len(VARIANTS) - 1
    names = set(model.names)
    for k, terms in enumerate(VARIANTS.values()):
        if names <= set(get_model("+".join(terms)).names):
            return k
    raise AssertionError("the last variant holds every term")


def traced(variant: str = "all") -> tuple[tuple[str, ...], list]:
    """The canonical slots and the three outputs of a variant's model as expressions."""
    names = slots()
    model = get_model("+".join(VARIANTS[variant]))
    if variant == "all":
        assert set(model.names) == set(names), "every slot must belong to the traced model"
    P = {n: sym(n) for n in model.names}
    A = tuple(sym(a) for a in A_NAMES)
    ctx = SimpleNamespace(dtemp=sym("dT"), dt=sym("dt"))
    return names, list(model.components(P, A, ctx, ops=SymbolicOps))


def _unpack(names: tuple[str, ...], used: set[str]) -> list[str]:
    return [f"    {n} = q[{k}]" for k, n in enumerate(names) if n in used]


def _symbols(exprs) -> set[str]:
    seen, out, stack = set(), set(), list(exprs)
    while stack:
        e = stack.pop()
        if e in seen:
            continue
        seen.add(e)
        if e.op == "sym":
            out.add(e.args[0])
        stack.extend(a for a in e.args if hasattr(a, "op"))
    return out


def source() -> str:
    names, F = traced()
    lines = [
        '"""The model\'s term table compiled with numba: GENERATED by ``python -m optcal.core.kernels.codegen`` from',
        "optcal.core.model.Model.components. Do not edit; change the term table and regenerate (see codegen.py).",
        '"""',
        "# ruff: noqa: E501",
        "",
        "from numba import njit",
        "",
        f"SLOTS = {names!r}",
        f"NQ = {len(names)}",
        f"VARIANTS = {tuple(VARIANTS)!r}",
        "",
        "",
    ]
    args = "q, ax, ay, az, dT, dt"

    def function(name: str, doc: str, outputs, signature: str = args, tail: list[str] | None = None):
        used = _symbols([e for _, e in outputs])
        lines.append('@njit(cache=True, error_model="numpy")')
        lines.append(f"def {name}({signature}):")
        lines.append(f'    """{doc}"""')
        lines.extend(_unpack(names, used))
        lines.extend(emit(outputs))
        lines.extend(tail or [])
        lines.extend(["", ""])

    for v, terms in VARIANTS.items():
        Fv = traced(v)[1]
        function(f"forward_{v}", f"Outputs (n0, n1, n2) of one position with specific force (ax, ay, az) in g,"
                 f"\n    for the terms {', '.join(terms)}.", [(f"n{i}", Fv[i]) for i in range(3)],
                 tail=["    return n0, n1, n2"])

    dA = [[diff(F[i], A_NAMES[j]) for j in range(3)] for i in range(3)]
    function("forward_dA", "∂N_i/∂A_j of one position, row-major (9 values).",
             [(f"d{i}{j}", dA[i][j]) for i in range(3) for j in range(3)],
             tail=["    return " + ", ".join(f"d{i}{j}" for i in range(3) for j in range(3))])

    dq = [(f"out[{i}, {k}]", diff(F[i], n)) for i in range(3) for k, n in enumerate(names)]
    dq = [(t, e) for t, e in dq if e is not ZERO]
    function("forward_dq", "The non-zero ∂N_i/∂q_k of one position into ``out`` (3, NQ); the other entries "
             "are zero\n    for every position, so the caller zeroes ``out`` once.", dq,
             signature=args + ", out")

    at0 = {**{a: 0.0 for a in A_NAMES}, **{c: 0.0 for c in CTX_NAMES}}
    lin = [(f"m{i}{j}", substitute(dA[i][j], at0)) for i in range(3) for j in range(3)]
    lin += [(f"c{i}", substitute(F[i], at0)) for i in range(3)]
    function("linear_part", "M (row-major) and c of N ≈ M·A + c, F's linearisation at A = 0, dT = dt = 0.",
             lin, signature="q",
             tail=["    return " + ", ".join([f"m{i}{j}" for i in range(3) for j in range(3)] +
                                          [f"c{i}" for i in range(3)])])
    return "\n".join(lines).rstrip() + "\n"


def main(argv: list[str] | None = None) -> int:
    text = source()
    if TARGET.exists() and TARGET.read_text() == text:
        print(f"{TARGET} is up to date")
        return 0
    TARGET.write_text(text)
    print(f"wrote {TARGET}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
