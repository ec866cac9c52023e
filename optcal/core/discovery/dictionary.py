"""The generated dictionary of candidate features that the term table lacks, and its linearised screening
(docs/discovery.md, "Terms the list lacks"). Core: nothing here runs a solver.

The library is SINDy's idea (Brunton, Proctor & Kutz 2016, PNAS 113:3932, Eq. 2-4: a library Θ of candidate
functions, a sparse coefficient vector chosen by regression): products and powers of the specific force's
components up to order 3 on each output, powers of the temperature and time offsets, sinusoids of time at the
periods the residuals' periodogram shows, and the sign of the previous pose on each axis, each a user-defined
term (:func:`optcal.core.terms.user_term`). Where SINDy thresholds a least-squares fit of the whole library, the
search here is forward stepwise selection (orthogonal matching pursuit: Pati, Rezaiifar & Krishnaprasad 1993)
with the family-wise error control and information criterion of discovery's candidate terms (the F-test at
α/k and ΔBIC, :mod:`optcal.core.discovery.statistics`): with 24–40 positions and 9–15 parameters the library has more
columns than the residuals have degrees of freedom, so a joint least-squares fit of it is not determined.

Screening is linear and joint with the sensor model. A term adding c·φ to output i moves the norm residual
e_j = ‖A_j‖ − g by −w_ji·K_i·φ_j·c, with (∂F/∂A)ᵀ w_j = A_j/‖A_j‖ (the implicit-function Jacobian of
docs/design.md, "Evaluation paths and the Jacobian"). Every feature's column is built at once from arrays of exponents
and context factors, its part in the span of the model's own Jacobian (what the fit absorbs by moving its parameters)
is removed, and the reduction of the residual sum of squares, RSS₀ − RSS₁ = ‖P r‖² with P the projection on the
feature's remaining columns, gives F = ((RSS₀ − RSS₁)/q) / (RSS₁/(m − p − q)) for every feature in a few matrix products
(a batched QR for features of several columns). The best one is then refitted exactly by the workflow.

Two features the norm cannot tell apart are one candidate. The norm residual sees c·φ on output i as
â_i·φ to first order, so "z output += c·A_x·A_y", "x output += c·A_y·A_z" and "y output += c·A_x·A_z" all
move it by c·A_x·A_y·A_z: the monomial A_i·φ is what the positions determine. Each such class is one atom,
named by the output with the highest power in that monomial (ties: the last axis), with the others listed as
its equivalents.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import combinations_with_replacement

import numpy as np

from optcal.core.distributions import f_sf
from optcal.core.gauge import RTOL
from optcal.core.model import AXES, TERMS, Context, Model
from optcal.core.terms import OUTPUTS, Feature, previous_signs

MONOMIAL_ORDERS = (2, 3)  # products and powers of the axes on an output (the "up to order 3")
CONTEXT_POWERS = (1, 2, 3)  # powers of the temperature and time offsets
# A feature column with less than this share of its size left outside the model's span adds nothing: the
# observability analysis's threshold (docs/design.md, "How the code finds them"). Far smaller leftovers are not
# rounding but the model's own nonlinearity (|A| − g is the residual itself), which lines up with the residual and would
# look like a perfect fit.
RANK_RTOL = RTOL


def nice_scale(v: float) -> float:
    """The 1-2-5 number nearest ``v`` on a log scale (a feature's scale: the data's spread, rounded)."""
    e = math.floor(math.log10(v))
    steps = np.array([1.0, 2.0, 5.0, 10.0]) * 10.0**e
    return float(steps[np.argmin(np.abs(np.log(steps / v)))])


@dataclass(frozen=True)
class Atom:
    """One candidate of the dictionary: a user-defined term, the terms the norm cannot tell from it, and its
    share of the Bonferroni count (1; a sinusoid's a share of the independent frequencies searched)."""

    term: str
    equivalents: tuple[str, ...] = ()
    weight: float = 1.0
    kind: str = "regular"  # regular | sinusoid

    @property
    def list_part(self) -> str | None:
        """The list's parameter this feature is on its one output (up to the scale factor or the scale of its
        context), e.g. "cubic's K3_z": the feature then says the list's term is there on that output alone."""
        return list_part(self.term)


def list_part(term: str) -> str | None:
    """The built-in term's parameter a one-output feature equals (see :attr:`Atom.list_part`), or None."""
    t = TERMS[term]
    f = t.feature
    if len(t.axes) != 1:
        return None
    i = t.axes[0]
    a = AXES[i]
    unit = tuple(int(k == i) for k in range(3))
    context = (f.temp, f.time, f.period, f.prev)
    if all(c is None for c in context):
        if f.exps == tuple(2 * u for u in unit):
            return f"quadratic's K2_{a}"
        if f.exps == tuple(3 * u for u in unit):
            return f"cubic's K3_{a}"
        if f.degree == 2 and f.exps[i] == 1:
            return f"cross_coupling's c_{a}{AXES[next(k for k in range(3) if k != i and f.exps[k])]}"
        return None
    if f.temp is not None and f.temp[0] == 1 and f.exps == (0, 0, 0):
        return f"temperature_bias's beta_{a}"
    if f.temp is not None and f.temp[0] == 1 and f.exps == unit:
        return f"temperature_scale's gamma_{a}"
    if f.time is not None and f.time[0] == 1 and f.exps == (0, 0, 0):
        return f"bias_drift's d_{a}"
    return None


# The three-output features that are a built-in term whole: the list has tested them already
LIST_TERMS_WHOLE = {(("temp", 1), "xyz"): "temperature_bias", (("time", 1), "xyz"): "bias_drift"}


@dataclass
class AtomScore:
    """The linearised test of one atom at the current fit (the workflow refits the chosen one exactly)."""

    atom: Atom
    note: str = ""
    q: int = 0
    dof: int = 0
    rss_after: float = float("nan")
    f_statistic: float = float("nan")
    p_value: float = float("nan")
    delta_bic: float = float("nan")

    @property
    def term(self) -> str:
        return self.atom.term

    @property
    def tested(self) -> bool:
        return not self.note

    def to_dict(self, m: int) -> dict:
        from optcal.core.discovery.statistics import num

        d = {"term": self.term, "formula": TERMS[self.term].description, "tested": self.tested}
        if self.atom.equivalents:
            d["equivalents"] = list(self.atom.equivalents)
        if self.tested:
            d.update(rms_after_g=float(np.sqrt(self.rss_after / m)), statistic=num(self.f_statistic),
                     df=[self.q, self.dof], p_value=num(self.p_value), delta_bic=num(self.delta_bic))
        else:
            d["note"] = self.note
        return d


@dataclass
class Dictionary:
    """The atoms of one round with what they were generated from."""

    atoms: list[Atom]
    temp_scale: float | None = None
    time_scale: float | None = None
    periods: tuple[float, ...] = ()
    n_independent_frequencies: int = 0
    notes: list[str] = field(default_factory=list)

    def k_effective(self, tested: list[Atom]) -> float:
        """The Bonferroni count of the atoms tested: one each, and for the sinusoids the four output sets
        (x, y, z, xyz) times the independent frequencies searched, shared by the periods tried (the
        periodogram chooses a period from about that many independent ones: Horne & Baliunas 1986)."""
        return float(sum(a.weight for a in tested))


# -- generating the atoms ------------------------------------------------------------------------------

def _representative(seen: tuple[int, int, int]) -> int:
    """The output an atom of this first-order monomial is named by: the highest power, ties the last axis."""
    top = max(seen)
    return max(k for k in range(3) if seen[k] == top)


def _monomial_class(seen: tuple[int, int, int], context: dict) -> tuple[str, tuple[str, ...]]:
    """(representative, equivalents) of the atoms whose output i and monomial e give A_i·A^e = ``seen``."""
    names = []
    for i in range(3):
        if seen[i] == 0:
            continue
        exps = tuple(seen[k] - (k == i) for k in range(3))
        feature = Feature(exps, **context)
        if not context and feature.degree < 2:
            continue
        names.append((i, f"{feature.token()}@{AXES[i]}"))
    rep = _representative(seen)
    first = [n for i, n in names if i == rep]
    return first[0], tuple(n for i, n in names if i != rep)


def _monomials(degree: int) -> list[tuple[int, int, int]]:
    out = []
    for combo in combinations_with_replacement(range(3), degree):
        out.append(tuple(combo.count(k) for k in range(3)))
    return out


def generate(model: Model, data, periods=(), n_independent: int = 0) -> Dictionary:
    """The atoms for ``model`` on ``data``: every feature of the module docstring whose columns the data have
    and whose parameters the model does not hold already."""
    atoms: list[Atom] = []
    notes = []
    # products and powers of the axes: the first-order monomials A_i·A^e of degree 3 and 4
    for order in MONOMIAL_ORDERS:
        for seen in _monomials(order + 1):
            rep, eq = _monomial_class(seen, {})
            atoms.append(Atom(rep, eq))
    temp_scale = time_scale = None
    if data.temp is not None and np.ptp(data.temp) > 0:
        temp_scale = nice_scale(float(np.std(data.temp)))
        for p in CONTEXT_POWERS:
            token = Feature((0, 0, 0), temp=(p, temp_scale)).token()
            atoms += [Atom(f"{token}@{out}") for out in OUTPUTS if (("temp", p), out) not in LIST_TERMS_WHOLE]
        # the temperature times one component: A_i·A_j·(T − T̄), scale and misalignment changing with temperature
        for seen in _monomials(2):
            rep, eq = _monomial_class(seen, {"temp": (1, temp_scale)})
            atoms.append(Atom(rep, eq))
    elif data.temp is not None:
        notes.append("the temperature does not change: no temperature features")
    if data.t is not None and np.ptp(data.t) > 0:
        dt = np.asarray(data.t, float) - float(data.t[0])
        time_scale = nice_scale(float(np.std(dt)))
        for p in CONTEXT_POWERS:
            token = Feature((0, 0, 0), time=(p, time_scale)).token()
            atoms += [Atom(f"{token}@{out}") for out in OUTPUTS if (("time", p), out) not in LIST_TERMS_WHOLE]
        if periods and n_independent:
            share = n_independent / len(periods)  # the four output sets × n_independent, over the atoms
            for period in periods:
                token = Feature((0, 0, 0), period=period).token()
                atoms += [Atom(f"{token}@{out}", weight=share, kind="sinusoid") for out in OUTPUTS]
    # the previous pose: output i shifted by the sign of the pose before on axis k
    for k in range(3):
        token = Feature((0, 0, 0), prev=k).token()
        atoms += [Atom(f"{token}@{AXES[i]}") for i in range(3)]
    held = set(model.names)
    atoms = [a for a in atoms if a.term not in model.terms and not set(TERMS[a.term].params) & held]
    return Dictionary(atoms, temp_scale, time_scale, tuple(periods), n_independent, notes)


def feature_context(data) -> Context:
    """The temperature and time offsets of every position (docs/design.md, "Context: temperature and time offsets"),
    whatever the model needs."""
    return Context.from_columns(temp=data.temp, t=data.t)


# -- the columns, all at once --------------------------------------------------------------------------

def _layout(atoms: list[Atom]) -> dict:
    """Per column of the dictionary (one per parameter of each atom): its atom, output axis, exponents and
    context factors, as arrays."""
    rows = []
    for a, atom in enumerate(atoms):
        term = TERMS[atom.term]
        f = term.feature
        for i in term.axes:
            for kind in f.kinds:
                rows.append((a, i, *f.exps,
                             0 if f.temp is None else f.temp[0], 1.0 if f.temp is None else f.temp[1],
                             0 if f.time is None else f.time[0], 1.0 if f.time is None else f.time[1],
                             0.0 if f.period is None else f.period, 1 if kind == "sin" else 0,
                             -1 if f.prev is None else f.prev))
    R = np.array(rows, float).reshape(-1, 12)
    return {"atom": R[:, 0].astype(int), "axis": R[:, 1].astype(int), "exps": R[:, 2:5].astype(int),
            "tp": R[:, 5], "ts": R[:, 6], "sp": R[:, 7], "ss": R[:, 8], "period": R[:, 9],
            "sin": R[:, 10].astype(bool), "prev": R[:, 11].astype(int)}


def feature_values(atoms: list[Atom], A: np.ndarray, ctx: Context) -> tuple[np.ndarray, dict]:
    """φ of every parameter of every atom at specific force ``A`` (n, 3): (n, D), and the layout. The same
    values :meth:`optcal.core.terms.Feature.values` gives one at a time (a test checks it), in a few array
    operations."""
    L = _layout(atoms)
    n = len(A)
    phi = np.prod(A[:, None, :] ** L["exps"][None, :, :], axis=2)
    if (L["tp"] > 0).any():
        phi = phi * np.where(L["tp"] > 0, (np.asarray(ctx.dtemp)[:, None] / L["ts"]) ** L["tp"], 1.0)
    if (L["sp"] > 0).any():
        phi = phi * np.where(L["sp"] > 0, (np.asarray(ctx.dt)[:, None] / L["ss"]) ** L["sp"], 1.0)
    osc = L["period"] > 0
    if osc.any():
        arg = 2.0 * np.pi * np.asarray(ctx.dt)[:, None] / np.where(osc, L["period"], 1.0)
        phi = phi * np.where(osc, np.where(L["sin"], np.sin(arg), np.cos(arg)), 1.0)
    prev = L["prev"] >= 0
    if prev.any():
        signs = previous_signs(A.T)  # (3, n)
        phi = phi * np.where(prev, signs[np.maximum(L["prev"], 0)].T, 1.0)
    return phi.reshape(n, -1), L


def sensitivity(fit) -> np.ndarray:
    """−w_ji·K_i (n, 3): the norm residual's change per unit added to output i inside its scale factor, at the
    fit (the implicit-function Jacobian: (∂F/∂A)ᵀ w = A/‖A‖)."""
    model, x = fit.model, fit.x
    A = fit.specific_force
    Fa = model.dforward_dA(x[None], A[None], fit.problem.ctx)[0]
    u = A / np.linalg.norm(A, axis=1, keepdims=True)
    w = np.linalg.solve(np.transpose(Fa, (0, 2, 1)), u[:, :, None])[:, :, 0]
    K = x[model.groups()["scale"]]
    return -w * K


def columns(fit, atoms: list[Atom], ctx: Context) -> tuple[np.ndarray, dict]:
    """The linearised Jacobian columns (n, D) of every atom's parameters at ``fit``, and the layout."""
    phi, L = feature_values(atoms, fit.specific_force, ctx)
    return sensitivity(fit)[:, L["axis"]] * phi, L


def model_basis(fit) -> np.ndarray:
    """An orthonormal basis (n, rank) of the span of the fit's Jacobian columns over the positions (in the
    parameters' natural units, so that the rank is the observability analysis's)."""
    from optcal.core.gauge import natural_units

    n = fit.problem.n_position_residuals
    J = fit.problem.jacobian_full(fit.x)[:n] * natural_units(fit.problem, fit.x)
    U, _, _ = np.linalg.svd(J, full_matrices=False)
    return U[:, :fit.rank]


def project_out(Q: np.ndarray, M: np.ndarray) -> np.ndarray:
    """M with its part in span(Q) removed (Q orthonormal)."""
    return M - Q @ (Q.T @ M)


def reductions(Phi: np.ndarray, groups: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each group of columns of ``Phi`` (already orthogonal to the model): the reduction of ‖r‖² by a
    least-squares fit on them, and the number of columns they contribute (their rank). ``groups`` gives each
    column's group; groups of the same size are solved together by one batched QR."""
    k = int(groups.max()) + 1 if groups.size else 0
    red = np.zeros(k)
    rank = np.zeros(k, int)
    sizes = np.bincount(groups, minlength=k)
    norms = np.linalg.norm(Phi, axis=0)
    for q in np.unique(sizes):
        which = np.flatnonzero(sizes == q)
        # the columns of a group are contiguous and groups come in order: each starts where its index first appears
        cols = np.searchsorted(groups, which)[:, None] + np.arange(q)
        B = np.transpose(Phi[:, cols], (1, 0, 2))  # (g, n, q)
        Qb, Rb = np.linalg.qr(B)
        d = np.abs(np.diagonal(Rb, axis1=1, axis2=2))
        ok = d > RANK_RTOL * np.maximum(norms[cols], np.finfo(float).tiny)
        proj = np.einsum("gnq,n->gq", Qb, r) * ok
        red[which] = np.sum(proj**2, axis=1)
        rank[which] = ok.sum(axis=1)
    return red, rank


def screen(fit, dictionary: Dictionary, ctx: Context, Q: np.ndarray | None = None) -> list[AtomScore]:
    """The linearised F-test and ΔBIC of every atom against ``fit`` (module docstring). An atom the model
    already explains (a column wholly in its span) or that would leave no degree of freedom is skipped with the
    reason."""
    atoms = dictionary.atoms
    if not atoms:
        return []
    n = fit.problem.n_position_residuals
    r = fit.residuals[:n]
    Q = model_basis(fit) if Q is None else Q
    C, L = columns(fit, atoms, ctx)
    Phi = project_out(Q, C)
    r = project_out(Q, r[:, None])[:, 0]
    red, q = reductions(Phi, L["atom"], r)
    rss0 = float(r @ r)
    out = []
    width = np.bincount(L["atom"], minlength=len(atoms))
    for a, atom in enumerate(atoms):
        dof = n - fit.rank - q[a]
        if q[a] < width[a]:
            out.append(AtomScore(atom, note="explained by the model already (a column in its span)"))
            continue
        if dof < 1:
            out.append(AtomScore(atom, note=f"{n} residuals leave no degrees of freedom"))
            continue
        rss1 = max(rss0 - red[a], np.finfo(float).tiny)
        f = (red[a] / q[a]) / (rss1 / dof)
        out.append(AtomScore(atom, q=int(q[a]), dof=int(dof), rss_after=rss1, f_statistic=float(f),
                             p_value=float(f_sf(f, q[a], dof)),
                             delta_bic=float(n * np.log(rss1 / rss0) + q[a] * np.log(n))))
    return out


def refine_period(fit, atom: Atom, ctx: Context, Q: np.ndarray, span: float, points: int = 41) -> Atom:
    """The sinusoid ``atom`` at the period, within one frequency bin (1/span) of its own, that reduces the residual
    most once the model's span is removed (the periodogram's peak ignores what the model absorbs), rounded to three
    significant digits: one batched evaluation of ``points`` periods."""
    term = TERMS[atom.term]
    f0 = 1.0 / term.feature.period
    freqs = f0 + np.linspace(-1.0, 1.0, points) / span
    freqs = freqs[freqs > 0]
    out = "xyz" if len(term.axes) == 3 else AXES[term.axes[0]]
    trial = [Atom(f"{Feature((0, 0, 0), period=1.0 / f).token()}@{out}") for f in freqs]
    C, L = columns(fit, trial, ctx)
    n = fit.problem.n_position_residuals
    r = project_out(Q, fit.residuals[:n, None])[:, 0]
    red, _ = reductions(project_out(Q, C), L["atom"], r)
    period = float(f"{1.0 / freqs[int(np.argmax(red))]:.3g}")
    return Atom(f"{Feature((0, 0, 0), period=period).token()}@{out}", atom.equivalents, atom.weight, atom.kind)


def best(scores: list[AtomScore]) -> AtomScore | None:
    """The tested atom with the lowest p-value; ties (p-values that underflow to 0) to the lowest ΔBIC."""
    tested = [s for s in scores if s.tested]
    return min(tested, key=lambda s: (s.p_value, s.delta_bic)) if tested else None


