"""A small symbolic algebra for tracing the model's term table into compiled code.

:meth:`optcal.core.model.Model.components` is written once, over an ``ops`` namespace, for NumPy arrays and
CasADi symbols. Evaluated on the :class:`Expr` symbols here it yields the model's equations as expression
graphs, which :mod:`optcal.core.kernels.codegen` differentiates and prints as Python source for numba. The
algebra only needs what the term table uses: sums, products, integer powers and ``min(a, 0)``.

Nodes are hash-consed (one object per distinct expression), so common subexpressions are shared and the
printer can name each once.
"""

from __future__ import annotations

from numbers import Real

_NODES: dict[tuple, Expr] = {}


class Expr:
    """An expression node: ``op`` is sym, const, add, mul, pow, neg_part or neg_step."""

    __slots__ = ("op", "args", "__weakref__")
    __array_priority__ = 1000  # so that float * Expr reaches Expr.__rmul__

    def __new__(cls, op: str, *args):
        key = (op, *args)
        node = _NODES.get(key)
        if node is None:
            node = super().__new__(cls)
            node.op, node.args = op, args
            _NODES[key] = node
        return node

    # -- construction with constant folding ---------------------------------------------------------
    def __add__(self, other):
        return add(self, lift(other))

    __radd__ = __add__

    def __mul__(self, other):
        return mul(self, lift(other))

    __rmul__ = __mul__

    def __pow__(self, n):
        if not isinstance(n, int) or n < 0:
            raise TypeError("only non-negative integer powers are supported")
        if n == 0:
            return const(1.0)
        if n == 1:
            return self
        if self.op == "const":
            return const(self.args[0] ** n)
        return Expr("pow", self, n)

    def __repr__(self) -> str:
        return f"Expr({self.op}, {self.args})"

    @property
    def is_zero(self) -> bool:
        return self.op == "const" and self.args[0] == 0.0


def sym(name: str) -> Expr:
    return Expr("sym", name)


def const(v: float) -> Expr:
    return Expr("const", float(v))


def lift(v) -> Expr:
    if isinstance(v, Expr):
        return v
    if isinstance(v, Real):
        return const(float(v))
    raise TypeError(f"cannot use {type(v).__name__} in a symbolic expression")


ZERO, ONE = const(0.0), const(1.0)


def add(a: Expr, b: Expr) -> Expr:
    if a.is_zero:
        return b
    if b.is_zero:
        return a
    if a.op == "const" and b.op == "const":
        return const(a.args[0] + b.args[0])
    return Expr("add", a, b)


def mul(a: Expr, b: Expr) -> Expr:
    if a.is_zero or b.is_zero:
        return ZERO
    if a is ONE:
        return b
    if b is ONE:
        return a
    if a.op == "const" and b.op == "const":
        return const(a.args[0] * b.args[0])
    if b.op == "const":  # constants first: reads as 2.0 * x
        a, b = b, a
    return Expr("mul", a, b)


def neg_part(a: Expr) -> Expr:
    """min(a, 0)."""
    if a.op == "const":
        return const(min(a.args[0], 0.0))
    return Expr("neg_part", a)


def neg_step(a: Expr) -> Expr:
    """d min(a, 0) / da: 1 where a < 0, else 0 (the NumPy path's complex step sees the same)."""
    if a.op == "const":
        return const(1.0 if a.args[0] < 0 else 0.0)
    return Expr("neg_step", a)


class SymbolicOps:
    """The ``ops`` namespace of :meth:`optcal.core.model.Model.components` for :class:`Expr` inputs."""

    neg_part = staticmethod(neg_part)


# -- calculus ------------------------------------------------------------------------------------------
def diff(e: Expr, name: str, memo: dict | None = None) -> Expr:
    """∂e/∂name."""
    memo = {} if memo is None else memo
    got = memo.get(e)
    if got is not None:
        return got
    op, a = e.op, e.args
    if op == "sym":
        d = ONE if a[0] == name else ZERO
    elif op in ("const", "neg_step"):
        d = ZERO
    elif op == "add":
        d = add(diff(a[0], name, memo), diff(a[1], name, memo))
    elif op == "mul":
        d = add(mul(diff(a[0], name, memo), a[1]), mul(a[0], diff(a[1], name, memo)))
    elif op == "pow":
        base, n = a
        d = mul(mul(const(n), base ** (n - 1)), diff(base, name, memo))
    elif op == "neg_part":
        d = mul(neg_step(a[0]), diff(a[0], name, memo))
    else:  # pragma: no cover - every op is handled above
        raise ValueError(op)
    memo[e] = d
    return d


def substitute(e: Expr, values: dict[str, float], memo: dict | None = None) -> Expr:
    """e with the named symbols replaced by constants (and folded)."""
    memo = {} if memo is None else memo
    got = memo.get(e)
    if got is not None:
        return got
    op, a = e.op, e.args
    if op == "sym":
        out = const(values[a[0]]) if a[0] in values else e
    elif op == "const":
        out = e
    elif op == "add":
        out = add(substitute(a[0], values, memo), substitute(a[1], values, memo))
    elif op == "mul":
        out = mul(substitute(a[0], values, memo), substitute(a[1], values, memo))
    elif op == "pow":
        out = substitute(a[0], values, memo) ** a[1]
    elif op == "neg_part":
        out = neg_part(substitute(a[0], values, memo))
    else:
        out = neg_step(substitute(a[0], values, memo))
    memo[e] = out
    return out


# -- printing ------------------------------------------------------------------------------------------
def _children(e: Expr) -> tuple[Expr, ...]:
    return tuple(x for x in e.args if isinstance(x, Expr))


def emit(outputs: list[tuple[str, Expr]], indent: str = "    ", prefix: str = "t") -> list[str]:
    """Python statements assigning each ``(target, expr)``, with every subexpression used more than once
    computed once into a temporary (in dependency order)."""
    uses: dict[Expr, int] = {}
    order: list[Expr] = []

    def visit(e: Expr):
        uses[e] = uses.get(e, 0) + 1
        if uses[e] == 1:
            for c in _children(e):
                visit(c)
            order.append(e)

    for _, e in outputs:
        visit(e)
    names: dict[Expr, str] = {}
    lines: list[str] = []

    def text(e: Expr) -> str:
        if e in names:
            return names[e]
        op, a = e.op, e.args
        if op == "sym":
            return a[0]
        if op == "const":
            return repr(a[0])
        if op == "add":
            return f"({text(a[0])} + {text(a[1])})"
        if op == "mul":
            return f"({text(a[0])} * {text(a[1])})"
        if op == "pow":
            b = text(a[0])
            return f"({' * '.join([b] * a[1])})" if a[1] <= 3 else f"{b} ** {a[1]}"
        if op == "neg_part":
            return f"min({text(a[0])}, 0.0)"
        return f"(1.0 if {text(a[0])} < 0.0 else 0.0)"

    for e in order:
        if uses[e] > 1 and e.op not in ("sym", "const"):
            name = f"{prefix}{len(names)}"
            lines.append(f"{indent}{name} = {text(e)}")
            names[e] = name
    for target, e in outputs:
        lines.append(f"{indent}{target} = {text(e)}")
    return lines
