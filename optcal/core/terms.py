"""The terms of the sensor model, their parameters and units, the named models and the cell map of the
installation matrix (docs/design.md, "Terms and parameters" to "Named models and parameter order"): the table every
numeric back end reads. The equations the
terms stand for are written once, in :meth:`optcal.core.model.Model.components`.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass

AXES = ("x", "y", "z")


@dataclass(frozen=True)
class Term:
    """One named effect of the model: its parameters, its group and the data columns it needs."""

    name: str
    params: tuple[str, ...]
    group: str
    needs: tuple[str, ...] = ()
    description: str = ""
    # A typical magnitude of each parameter relative to the scale factor (for normalised search boxes
    # and for the natural scaling used in observability analysis).
    unit: float = 1.0
    # The term's output is affine in the specific force and needs no data column: a model made only of
    # such terms is inverted in closed form.
    affine: bool = False
    # The unit of each parameter (docs/design.md, "Terms and parameters" "unit"), "{out}" standing for the output units.
    param_unit: str = "1"
    # A user-defined term (:func:`user_term`): its feature, and the output axes it adds to (0, 1, 2).
    feature: Feature | None = None
    axes: tuple[int, ...] = ()

    @property
    def user(self) -> bool:
        """True for a term the table lacks, defined by its name (docs/discovery.md, "Terms the list lacks")."""
        return self.feature is not None


def _axes(prefix: str) -> tuple[str, ...]:
    return tuple(f"{prefix}_{a}" for a in AXES)


class TermTable(dict):
    """The built-in terms by name; a user-defined term (:func:`user_term`) is looked up by its name as well.

    Iterating, ``keys()`` and ``values()`` give the built-in terms only (the kernel's slots, the docs' table and
    the solvers' groups are theirs), while ``TERMS[name]`` and ``name in TERMS`` also accept a user-defined term
    such as ``ax.ay@z``, parsed from its name: every module that looks a model's terms up by name handles both."""

    def __missing__(self, name):
        term = user_term(name)
        if term is None:
            raise KeyError(name)
        return term

    def __contains__(self, name) -> bool:
        return dict.__contains__(self, name) or (isinstance(name, str) and user_term(name) is not None)


TERMS: dict[str, Term] = TermTable({
    t.name: t
    for t in (
        Term("scale", _axes("K"), "scale", description="scale factors, output units per g", affine=True,
             param_unit="{out}/g"),
        Term("bias", _axes("b"), "bias", description="biases in g (output offset K·b)", affine=True,
             param_unit="g"),
        Term(
            "misalignment",
            ("S_yz", "S_zy", "S_zx"),
            "misalignment",
            description="installation angles in the identifiable gauge S_xz = S_xy = S_yx = 0, rad",
            affine=True,
            param_unit="rad",
        ),
        Term(
            "misalignment6",
            ("S_xz", "S_xy", "S_yz", "S_yx", "S_zy", "S_zx"),
            "misalignment",
            description="the seeds' six installation angles, rad (three directions unobservable)",
            affine=True,
            param_unit="rad",
        ),
        Term("quadratic", _axes("K2"), "nonlinear", description="second-order scale, output units per g²",
             param_unit="{out}/g²"),
        Term("cubic", _axes("K3"), "nonlinear", description="third-order scale, output units per g³",
             param_unit="{out}/g³"),
        Term(
            "scale_asymmetry",
            _axes("kappa"),
            "nonlinear",
            description="relative scale difference for negative inputs",
        ),
        Term(
            "cross_coupling",
            ("c_xy", "c_xz", "c_yz", "c_yx", "c_zx", "c_zy"),
            "nonlinear",
            description="cross-axis products, per g",
            param_unit="1/g",
        ),
        Term(
            "temperature_bias",
            _axes("beta"),
            "temperature",
            needs=("temp",),
            description="bias temperature coefficient, g per °C",
            param_unit="g/°C",
        ),
        Term(
            "temperature_scale",
            _axes("gamma"),
            "temperature",
            needs=("temp",),
            description="scale temperature coefficient, per °C",
            param_unit="1/°C",
        ),
        Term("bias_drift", _axes("d"), "drift", needs=("t",), description="bias drift, g per s", param_unit="g/s"),
    )
})

NAMED_MODELS: dict[str, tuple[str, ...]] = {
    "diag6": ("scale", "bias"),
    "linear9": ("scale", "bias", "misalignment"),
    "nonlinear12": ("scale", "bias", "misalignment", "quadratic"),
    "seed15": ("scale", "bias", "misalignment6", "quadratic"),
}

TERM_ORDER = list(TERMS)

# How each output unit of optcal.core.data.UNITS is written beside a number (docs/design.md, "Units and frames").
UNIT_NAMES = {"g": "g", "m/s2": "m/s²", "counts": "counts", "volts": "V", "mg": "mg"}

# The installation matrix T's off-diagonal cells (row i, column j) and the angle in each (docs/design.md,
# "The installation matrix T"): T = I + these cells, u = T·A. The one statement of this map: every module that builds
# T or reads
# angles from a matrix uses it.
T_CELLS = {(0, 1): "S_xz", (0, 2): "S_xy", (1, 0): "S_yz", (1, 2): "S_yx", (2, 0): "S_zy", (2, 1): "S_zx"}


# -- user-defined terms: effects the table lacks (docs/discovery.md, "Terms the list lacks") --------------
#
# A user-defined term adds c·φ to the linear part of one output (or each of the three), inside the scale factor
# as the bias is: N_i = K_i·(L_i + c_i·φ) + ..., so c·φ is in g. φ is a product of a monomial of the specific
# force's components (A in g, total degree at most 3) and at most one context factor: a power of the
# temperature offset or of the time offset over a stated scale, a sinusoid of the time offset with a stated
# period, or the sign of the previous pose's specific force on one axis. Its name says all of it:
#
#   ax.ay@z           z output += c·A_x·A_y               (monomials: ax, ay2, az3, ... joined by '.')
#   temp2s5@x         bias_x += c·((T − T̄)/5 °C)²         (temp<power>s<scale in °C>)
#   time2s500@xyz     bias_i += c_i·((t − t0)/500 s)²     (time<power>s<scale in s>; @xyz: each axis its own c)
#   osc600@x          bias_x += a·sin(2π(t − t0)/600 s) + b·cos(...)   (osc<period in s>; two parameters)
#   prevax@x          bias_x += c·sgn(A_x of the previous pose), 0 when that pose loads x by under 0.25 g
#                     (a pose: consecutive positions within 2° of each other, e.g. an interval cut in two)
#   temp1s5.ay@x      x output += c·((T − T̄)/5 °C)·A_y
#
# Numbers in names write their decimal point as 'p' (osc2p5: a period of 2.5 s), since '.' joins the factors.
# The scales make every factor of order one on the data it was found on, so that the parameter's Jacobian
# column is commensurate with the others (observability works in the parameters' natural units, which are 1
# for these: docs/design.md, "How the code finds them"); the coefficient in physical units is c/scale^power
# (:meth:`Feature.physical`).

PREV_DEADZONE_G = 0.25  # a previous pose loading an axis by less than this (g) leaves no sign on it
SAME_POSE_DEG = 2.0  # consecutive positions whose directions lie within this angle are one pose
_NUM = r"(\d+(?:p\d+)?)"
_FACTOR = re.compile(rf"^(?:a(?P<ax>[xyz])(?P<ap>[23]?)|temp(?P<tp>[123])s{_NUM}|time(?P<sp>[123])s(?P<ss>\d+(?:p\d+)?)"
                     rf"|osc(?P<per>\d+(?:p\d+)?)|preva(?P<prev>[xyz]))$")
OUTPUTS = {"x": (0,), "y": (1,), "z": (2,), "xyz": (0, 1, 2)}
_SUPER = {2: "²", 3: "³"}


def number_token(v: float) -> str:
    """A positive number as a name writes it: 6 significant digits, no exponent, 'p' for the decimal point."""
    text = f"{float(v):.6g}"
    if "e" in text:
        text = f"{float(v):.6f}".rstrip("0").rstrip(".")
    return text.replace(".", "p")


def _number(text: str) -> float:
    return float(text.replace("p", "."))


def previous_signs(A):
    """sgn of the previous pose's specific force on each axis, (3, ..., n) for components ``A = (A_x, A_y, A_z)``
    with the positions along their last axis (real parts: a complex step passes through). A pose is a run of
    consecutive positions within :data:`SAME_POSE_DEG` of each other (an interval cut in parts, a pose held
    twice in a row), so the previous pose of each is the run before its own; 0 on an axis that pose loaded by
    less than :data:`PREV_DEADZONE_G`, and 0 for the first pose."""
    import numpy as np

    a = np.stack([np.real(np.asarray(c)) for c in A])
    n = a.shape[-1]
    u = a / np.linalg.norm(a, axis=0, keepdims=True)
    cos = np.sum(u[..., 1:] * u[..., :-1], axis=0)
    index = np.broadcast_to(np.arange(n), cos.shape[:-1] + (n,))
    new = np.concatenate([np.ones(cos.shape[:-1] + (1,), bool), cos < np.cos(np.radians(SAME_POSE_DEG))], axis=-1)
    start = np.maximum.accumulate(np.where(new, index, 0), axis=-1)  # where each position's pose begins
    before = np.maximum(start - 1, 0)
    prev = np.take_along_axis(a, np.broadcast_to(before, a.shape), axis=-1)
    s = np.where(np.abs(prev) >= PREV_DEADZONE_G, np.sign(prev), 0.0)
    return np.where(start > 0, s, 0.0)


@dataclass(frozen=True)
class Feature:
    """φ of a user-defined term: A_x^e0·A_y^e1·A_z^e2 times at most one context factor (module comment)."""

    exps: tuple[int, int, int]
    temp: tuple[int, float] | None = None  # (power, scale °C): ((T − T̄)/scale)^power
    time: tuple[int, float] | None = None  # (power, scale s): ((t − t0)/scale)^power
    period: float | None = None  # s: sin and cos of 2π(t − t0)/period (two parameters per axis)
    prev: int | None = None  # axis k: sgn(A_k of the previous pose)

    @property
    def degree(self) -> int:
        return sum(self.exps)

    @property
    def kinds(self) -> tuple[str, ...]:
        """One parameter per axis, or the sinusoid's two (its sine and cosine)."""
        return ("sin", "cos") if self.period is not None else ("",)

    def token(self, kind: str = "") -> str:
        parts = [f"a{AXES[k]}{e if e > 1 else ''}" for k, e in enumerate(self.exps) if e]
        if self.temp is not None:
            parts.append(f"temp{self.temp[0]}s{number_token(self.temp[1])}")
        if self.time is not None:
            parts.append(f"time{self.time[0]}s{number_token(self.time[1])}")
        if self.period is not None:
            parts.append(f"{kind or 'osc'}{number_token(self.period)}")
        if self.prev is not None:
            parts.append(f"preva{AXES[self.prev]}")
        return ".".join(parts)

    @property
    def needs(self) -> tuple[str, ...]:
        return ("temp",) if self.temp is not None else ("t",) if (self.time or self.period) is not None else ()

    @property
    def group(self) -> str:
        """The parameter group (docs/design.md, "Terms and parameters") the staged solver and the fish swarms treat it
        in."""
        if self.temp is not None:
            return "temperature"
        return "drift" if self.needs else "nonlinear"

    @property
    def unit(self) -> str:
        """The coefficient's unit: c·φ is in g, A in g, the context factors dimensionless."""
        return {0: "g", 1: "1", 2: "1/g", 3: "1/g²"}[self.degree]

    def physical(self) -> tuple[float, str] | None:
        """(factor, unit): the coefficient per unit temperature or time is c·factor (c/scale^power)."""
        for ctx, unit in ((self.temp, "°C"), (self.time, "s")):
            if ctx is not None:
                p, s = ctx
                base = "g" if self.degree == 0 else self.unit
                return s ** -p, f"{base}/{unit}{_SUPER.get(p, '')}"
        return None

    # -- values ---------------------------------------------------------------------------------------
    def weight(self, dtemp, dt, kind: str = ""):
        """The data's part of φ (temperature, time; 1.0 without either): arrays over positions, or a symbolic
        evaluator's expressions (CasADi's, whose sin and cos are methods of the expression)."""
        import numpy as np

        def values(v):
            return v if hasattr(v, "sin") and not isinstance(v, np.ndarray) else np.asarray(v, float)

        w = 1.0
        if self.temp is not None:
            w = (values(dtemp) / self.temp[1]) ** self.temp[0]
        if self.time is not None:
            w = (values(dt) / self.time[1]) ** self.time[0]
        if self.period is not None:
            arg = 2.0 * np.pi * values(dt) / self.period
            w = getattr(np, kind)(arg) if isinstance(arg, np.ndarray) else getattr(arg, kind)()
        return w

    def values(self, A, ctx, kind: str = "", ops=None):
        """φ at specific force components ``A = (A_x, A_y, A_z)`` (arrays over positions, or an evaluator's
        symbols) and context ``ctx`` (its ``dtemp`` and ``dt``). The previous pose's sign needs the positions
        in order as NumPy arrays (``ops.previous_signs``: :func:`previous_signs`)."""
        v = 1.0
        for k, e in enumerate(self.exps):
            for _ in range(e):
                v = v * A[k]
        if self.needs:
            if ctx is None or getattr(ctx, "dtemp" if self.temp is not None else "dt", None) is None:
                from optcal.core.errors import InputError

                column = "temp" if self.temp is not None else "t"
                raise InputError(f"term {self.token()} needs the data's column {column}; add it or drop the term")
            v = v * self.weight(ctx.dtemp, ctx.dt, kind)
        if self.prev is not None:
            sign = getattr(ops, "previous_signs", None)
            if sign is None:
                from optcal.core.errors import InputError

                raise InputError(f"term {self.token()} needs the previous pose, which this evaluator cannot form "
                                 "(it has no order of positions); fit it with lm, scipy-lm or another NumPy solver")
            v = v * sign(A)[self.prev]
        return v

    # -- text -------------------------------------------------------------------------------------------
    def context_text(self, kind: str = "") -> str:
        if self.temp is not None:
            p, s = self.temp
            base = f"(T − T̄)/{number_token(s).replace('p', '.')} °C"
            return f"({base}){_SUPER.get(p, '')}" if p > 1 else base
        if self.time is not None:
            p, s = self.time
            base = f"(t − t0)/{number_token(s).replace('p', '.')} s"
            return f"({base}){_SUPER.get(p, '')}" if p > 1 else base
        if self.period is not None:
            return f"{kind}(2π·(t − t0)/{number_token(self.period).replace('p', '.')} s)"
        if self.prev is not None:
            return f"sgn(A_{AXES[self.prev]} of the previous pose)"
        return ""

    def text(self, kind: str = "") -> str:
        """φ written out, e.g. ``A_x·A_y`` or ``((T − T̄)/5 °C)²``."""
        parts = [f"A_{AXES[k]}{_SUPER.get(e, '')}" for k, e in enumerate(self.exps) if e]
        ctx = self.context_text(kind)
        return "·".join(parts + ([ctx] if ctx else []))


def parse_feature(token: str) -> Feature:
    """The feature of a name's part before '@'; a ValueError says what is wrong with it."""
    exps = [0, 0, 0]
    ctx: dict = {}
    for part in token.split("."):
        m = _FACTOR.match(part)
        if not m:
            raise ValueError(f"factor {part!r} is none of ax, ay2, az3, temp<power>s<scale °C>, "
                             "time<power>s<scale s>, osc<period s>, preva<x|y|z>")
        if m["ax"]:
            k = AXES.index(m["ax"])
            if exps[k]:
                raise ValueError(f"a{m['ax']} appears twice; write its power once (a{m['ax']}2)")
            exps[k] = int(m["ap"] or 1)
            continue
        if ctx:
            raise ValueError("at most one factor of temperature, time, oscillation or previous pose")
        if m["tp"]:
            ctx["temp"] = (int(m["tp"]), _number(m.group(4)))
        elif m["sp"]:
            ctx["time"] = (int(m["sp"]), _number(m["ss"]))
        elif m["per"]:
            ctx["period"] = _number(m["per"])
        else:
            ctx["prev"] = AXES.index(m["prev"])
    for key in ("temp", "time"):
        if key in ctx and not ctx[key][1] > 0:
            raise ValueError(f"the {key} scale must be positive")
    if "period" in ctx and not ctx["period"] > 0:
        raise ValueError("the period must be positive")
    feature = Feature(tuple(exps), **ctx)
    if feature.degree > 3:
        raise ValueError("the powers of ax, ay, az add up to more than 3")
    if not ctx and feature.degree < 2:
        raise ValueError("a constant or a single component is the bias, scale or misalignment already in the "
                         "table; a user-defined term has a product or power of the axes, or a context factor")
    return feature


def _term_from_name(name: str) -> Term:
    token, at, out = name.partition("@")
    if not at or out not in OUTPUTS:
        raise ValueError("a user-defined term is FEATURE@OUTPUT with OUTPUT one of x, y, z, xyz (e.g. ax.ay@z)")
    feature = parse_feature(token)
    if feature.token() != token:
        raise ValueError(f"write it as {feature.token()}@{out}")
    axes = OUTPUTS[out]
    params = tuple(f"c_{feature.token(kind)}@{AXES[i]}" for i in axes for kind in feature.kinds)
    return Term(name, params, feature.group, needs=feature.needs, description=term_formula(feature, axes),
                param_unit=feature.unit, feature=feature, axes=axes)


@functools.lru_cache(maxsize=1024)
def _parsed(name: str) -> tuple[Term | None, str]:
    if not isinstance(name, str) or "@" not in name:
        return None, ""
    try:
        return _term_from_name(name), ""
    except ValueError as exc:
        return None, str(exc)


def user_term(name: str) -> Term | None:
    """The user-defined term of that name, or None when the name is not one (:func:`user_term_error` says why)."""
    return _parsed(name)[0]


def user_term_error(name: str) -> str:
    """Why ``name`` is not a user-defined term ('' when it is one, or does not try to be: no '@')."""
    return _parsed(name)[1]


def term_formula(feature: Feature, axes: tuple[int, ...]) -> str:
    """The readable formula of a user-defined term, e.g. ``z output += c·A_x·A_y`` or
    ``bias_x += c·((T − T̄)/5 °C)²``; a term of the three outputs has one coefficient per axis."""
    each = len(axes) == 3
    a = "i" if each else AXES[axes[0]]
    lhs = f"bias_{a}" if feature.degree == 0 else f"{a} output"
    if feature.period is not None:
        coef = ("a_i", "b_i") if each else ("a", "b")
        rhs = f"{coef[0]}·{feature.text('sin')} + {coef[1]}·{feature.text('cos')}"
    else:
        rhs = f"{'c_i' if each else 'c'}·{feature.text()}"
    return f"{lhs} += {rhs}" + (" on each axis i" if each else "")


def user_terms_of(terms) -> list[str]:
    """The user-defined terms among ``terms`` (names)."""
    return [t for t in terms if t not in TERM_ORDER]
