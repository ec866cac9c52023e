"""Whether the data determine a fit (issue #20; docs/design.md, "Per-position residuals, outliers, the robust loss,
what the data determine and weak fits", "What the data determine"): one place that
judges a calibration before anything is written, for any model and any output units.

Four classes of refusal, each one line naming the reason and the way out:

- ``too_few``: fewer residuals than the model has parameters;
- ``rank``: directions of the parameters that these positions do not see (:func:`optcal.core.analysis.observability`);
- ``dof``, ``exact`` and ``exact_data``: fewer than :data:`MIN_DOF` residual degrees of freedom, none at all
  (an exact fit), or residuals at rounding level (below :data:`ROUNDING_G`, or χ²/dof below
  :data:`EXACT_CHI2` when the noise is known: exact data), whose residuals cannot show a bad position, a
  missing effect or the noise;
- ``implausible``: fitted parameters outside physical bounds (:func:`plausibility`).

Core layer: it reads a problem, an observability and a goodness of fit; it runs no solver. The fallback to a
smaller model and the expert's override (``force_weak``) are :func:`optcal.app.fit.calibrate`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from optcal.core.analysis import GoodnessOfFit, Observability
from optcal.core.data import MANY_POSITIONS, PositionsData
from optcal.core.errors import InputError, listing
from optcal.core.gravity import G0
from optcal.core.model import Model, get_model
from optcal.core.problem import CalibrationProblem

MANY_ROWS_AS_SAMPLES = MANY_POSITIONS  # positions: an implausible fit of this many may be a recording's samples

# Residual degrees of freedom a fit needs: with fewer, the residuals can hardly show a bad position or a
# missing effect, and a noise estimate from 1 or 2 degrees of freedom is uncertain by a factor of several
# (the 95 % interval of σ̂/σ with 2 degrees of freedom is 0.16-1.92).
MIN_DOF = 3
# An exact fit: residuals at the rounding of the numbers (a CSV of 10 significant digits rounds a 1 g output at
# about 5e-11 g), far below the noise of any accelerometer's position mean (0.1 µg and more) ...
ROUNDING_G = 1e-9
# ... or, with the noise of the position means known, χ²/dof below this: with 3 or more degrees of freedom the
# chance of so small a χ² from noise of the stated size is below 1e-8, so the data are not noisy measurements.
EXACT_CHI2 = 1e-6
# Plausibility (docs/design.md, "Per-position residuals, outliers, the robust loss, what the data determine and weak
# fits"). Scale factors within ±30 % of the nominal: MEMS datasheets state their
# sensitivity to a few per cent (the MPU-6050's 16384 LSB/g ±3 %), so 30 % is ten times that and more.
SCALE_TOL = 0.30
# Offsets within ±0.5 g: datasheet zero-g offsets are tens of mg (the MPU-6050's ±50 mg, ±80 mg on z); an axis
# offset by half of gravity would read +0.5 and +1.5 g where it should read ±1 g, which no working sensor does.
BIAS_MAX_G = 0.5
# Installation angles within ±5°: cross-axis sensitivities of MEMS parts are 1-2 % (about 1°), board mounting
# adds a degree or two; the determined fits of the real corpus's recordings (docs/real_data.md) show at most 1.4°.
ANGLE_MAX_RAD = math.radians(5.0)
# Nonlinear terms: their effect at 1 g at most 5 % of the scale factor's (50 mg), ten times the 0.5 % of full
# scale that MEMS datasheets state as nonlinearity. Temperature and drift terms: their effect over the data's
# own temperature and time spans within the same bounds as an offset (0.5 g) or a scale factor (30 %).
NONLINEAR_MAX = 0.05
# The fallback chain of the default model: each drops the last term of the one before (docs/design.md, "Named models
# and parameter order").
DEFAULT_MODEL = "nonlinear12"
FALLBACK = ("nonlinear12", "linear9", "diag6")


def first_found(find, model=None, raw: bool = True):
    """``find(name)`` for ``model``; for the default (None), for each model of :data:`FALLBACK` in turn until one
    is found: a raw recording's detection may find too few intervals for nonlinear12, and then looks again for
    linear9, then diag6, whose fit says so (docs/design.md, "Per-position residuals, outliers, the robust loss, what
    the data determine and weak fits"). The last model's error is the one raised;
    positions that are not a raw recording (``raw`` False) are read once, for the first model. The one fallback
    loop of ``optcal calibrate`` and :func:`optcal.calibrate`."""
    names = (model,) if model is not None else FALLBACK
    for k, name in enumerate(names):
        try:
            return find(name)
        except InputError:
            if not raw or k == len(names) - 1:
                raise
    raise AssertionError("unreachable")  # pragma: no cover - the loop returns or raises
# The nominal scale factor (output units per g) of units with a physical zero and gain (docs/design.md, "Units and
# frames").
NOMINAL_SCALE = {"g": 1.0, "mg": 1000.0, "m/s2": G0}


@dataclass(frozen=True)
class Refusal:
    """Why the data do not determine a fit: ``kind`` (too_few, rank, dof, exact, exact_data, implausible, and
    undetermined: a parameter of the default chain's last model known no better than its datasheet) and
    ``reason``, one clause. :func:`way_out` gives the clause that says what to do."""

    kind: str
    reason: str


def structure(problem: CalibrationProblem, obs: Observability, *, gauge: bool = False) -> list[Refusal]:
    """What the positions leave undetermined before anything is fitted: too few positions for the model, an
    unobservable direction (not when ``gauge``: presets or seed15's rotations hold them, docs/design.md,
    "Minimum-constraint gauge rows"), fewer than :data:`MIN_DOF` residual degrees of freedom, or none (an exact fit)."""
    model, n_pos = problem.model, len(problem.data)
    m, p = problem.n_position_residuals, model.n_params
    if m < p:
        return [Refusal("too_few", f"{n_pos} positions give {m} residuals, fewer than the {p} parameters of "
                                   f"{model.name}")]
    if obs.rank < p and not gauge:
        dirs = describe_directions(obs.unobservable)
        return [Refusal("rank", f"these positions leave model {model.name} unobservable (rank {obs.rank} of {p}; "
                                f"directions: {dirs})")]
    dof = m - obs.rank
    if dof == 0:
        return [Refusal("exact", f"{n_pos} positions give {m} residuals for the {obs.rank} determined parameters "
                                 f"of {model.name}: an exact fit, with no residual left to judge it by")]
    if dof < MIN_DOF:
        return [Refusal("dof", f"{n_pos} positions leave {model.name} only {dof} residual degree(s) of freedom "
                               f"({obs.rank} determined parameters), fewer than {MIN_DOF}")]
    return []


def describe_directions(directions: list[list[dict]], most: int = 3) -> str:
    """Unobservable directions for one line: each by its ``most`` largest weights, at most ``most`` of them."""
    def one(d):
        tail = " …" if len(d) > most else ""
        return " ".join(f"{w['weight']:+.2f}·{w['name']}" for w in d[:most]) + tail

    more = f"; and {len(directions) - most} more" if len(directions) > most else ""
    return "; ".join(one(d) for d in directions[:most]) + more


def exact(gof: GoodnessOfFit, n_pos: int) -> list[Refusal]:
    """An exact fit after the fact: residuals at rounding level, or far below the stated noise (not a fit that
    is exact by construction, dof 0: its residuals are 0 whatever the data's noise)."""
    if gof.dof == 0:
        return []
    if gof.rms_g <= ROUNDING_G:
        return [Refusal("exact_data", f"the residual RMS over {n_pos} positions is {gof.rms_g:.2g} g, at the rounding "
                                 "of the numbers: the data are exact (simulated without noise or copied), not "
                                 "measurements, and nothing measures their noise")]
    if gof.chi2 is not None and gof.dof > 0 and gof.chi2 / gof.dof < EXACT_CHI2:
        return [Refusal("exact_data", f"the residual RMS over {n_pos} positions is {gof.rms_g * 1e6:.3g} µg, "
                                 f"{gof.noise_g / gof.rms_g:.3g} times below the noise of the position means "
                                 f"({gof.noise_g * 1e6:.3g} µg): an exact fit, or a noise stated far too high")]
    return []


def nominal_scale(data: PositionsData, g_local: float = 1.0) -> tuple[float | None, np.ndarray | None]:
    """The nominal scale factor (output units per g) and, for units without a physical zero, the zero-g output.

    g, mg and m/s² have both by definition (1, 1000 and g0 per g; zero at zero). Counts and volts have neither
    (an unsigned ADC or a ratiometric output sits at half its range at zero g): the sphere that best fits the
    outputs (‖N − c‖ = r, a linear least-squares fit in c and r² − ‖c‖²) gives them, r/g_local and c. None when
    fewer than 4 positions or a degenerate sphere leave them unknown."""
    if data.units in NOMINAL_SCALE:
        return NOMINAL_SCALE[data.units], None
    N = np.asarray(data.N, float)
    if len(N) < 4:
        return None, None
    M = np.column_stack([2 * N, np.ones(len(N))])
    sol, *_ = np.linalg.lstsq(M, np.einsum("ij,ij->i", N, N), rcond=None)
    c = sol[:3]
    r2 = sol[3] + c @ c
    if not (np.isfinite(r2) and r2 > 0 and np.linalg.matrix_rank(M) == 4):
        return None, None
    return float(np.sqrt(r2)) / g_local, c


def plausibility(model: Model, x: np.ndarray, data: PositionsData, g_local: float = 1.0) -> list[Refusal]:
    """The fitted parameters against physical bounds (docs/design.md, "Per-position residuals, outliers, the robust
    loss, what the data determine and weak fits"): scale factors within
    :data:`SCALE_TOL` of the nominal (:func:`nominal_scale`), offsets within :data:`BIAS_MAX_G` (for counts
    and volts: the zero-g output K·b within 0.5 g of the outputs' sphere centre), angles within
    :data:`ANGLE_MAX_RAD`, nonlinear terms' effect at 1 g within :data:`NONLINEAR_MAX` of the scale, and
    temperature and drift terms' effect over the data's spans within the offset and scale bounds. One
    Refusal naming every parameter out of bounds (the first in full)."""
    x = np.asarray(x, float)
    P = model.to_dict(x)
    units = model.units(data.units)
    nominal, centre = nominal_scale(data, g_local)
    K = {a: abs(P[f"K_{a}"]) for a in "xyz" if f"K_{a}" in P}
    bad: list[str] = []
    names: list[str] = []

    def out(name, text):
        names.append(name)
        bad.append(f"{name} = {P[name]:.4g} {units.get(name, '')} {text}".replace("  ", " "))

    for a, k in K.items():
        if nominal is not None and not abs(k / nominal - 1) <= SCALE_TOL:
            out(f"K_{a}", f"against the nominal {nominal:.5g} ± {SCALE_TOL:.0%}")
    dtemp = span(data.temp, centred=True) if "temp" in model.needs else 0.0
    dt = span(data.t, centred=False) if "t" in model.needs else 0.0
    for k, name in enumerate(model.names):
        fam, a = name.rsplit("_", 1)[0], name[-1]
        v = abs(x[k])
        if fam == "b":
            if centre is None and not v <= BIAS_MAX_G:
                out(name, f"is beyond ±{BIAS_MAX_G} g")
            elif centre is not None and K.get(a) and not abs(x[k] * P[f"K_{a}"] - centre["xyz".index(a)]) \
                    <= BIAS_MAX_G * K[a]:
                out(name, f"puts the zero-g output {x[k] * P[f'K_{a}']:.4g} more than {BIAS_MAX_G} g from the "
                          f"outputs' centre {centre['xyz'.index(a)]:.4g}")
        elif fam == "S" and not v <= ANGLE_MAX_RAD:
            out(name, f"({math.degrees(v):.3g}°) is beyond ±{math.degrees(ANGLE_MAX_RAD):.0f}°")
        elif fam in ("K2", "K3") and K.get(a) and not v / K[a] <= NONLINEAR_MAX:
            out(name, f"changes the output at 1 g by {v / K[a]:.3g} of the scale factor, bound {NONLINEAR_MAX:g}")
        elif fam in ("kappa", "c") and not v <= NONLINEAR_MAX:
            out(name, f"changes the output at 1 g by {v:.3g} of the scale factor, bound {NONLINEAR_MAX:g}")
        elif fam == "beta" and not v * dtemp <= BIAS_MAX_G:
            out(name, f"moves the offset by {v * dtemp:.3g} g over the data's ±{dtemp:.3g} °C, bound {BIAS_MAX_G} g")
        elif fam == "gamma" and not v * dtemp <= SCALE_TOL:
            out(name, f"changes the scale by {v * dtemp:.3g} over the data's ±{dtemp:.3g} °C, bound {SCALE_TOL:g}")
        elif fam == "d" and not v * dt <= BIAS_MAX_G:
            out(name, f"moves the offset by {v * dt:.3g} g over the data's {dt:.4g} s, bound {BIAS_MAX_G} g")
    if not bad:
        return []
    # the first parameter out of bounds in full and the others by name: one clause of the line, which the CLI's
    # cut to 300 characters would otherwise shred (a new user saw "K_y = 1.136e+06 (m/s²)/g is … nominal 9.8066
    # (bounds ±30%); … is 487 …")
    more = f" (also {listing(names[1:], 4)})" if len(bad) > 1 else ""
    many = f"; {len(data)} rows: a recording's samples? pass `raw`" if len(data) >= MANY_ROWS_AS_SAMPLES else ""
    return [Refusal("implausible", f"the fit of {model.name} is physically implausible: {bad[0]}{more}"
                    + many)]


# What a sensor's datasheet already says, as the spread of a parameter across parts (MPU-6050, LIS3DH,
# ADXL345 class: sensitivity ±3 %, zero-g offset ±50 mg, cross-axis 1-2 % ≈ 1°, nonlinearity 0.5 %): a fitted
# parameter whose standard error exceeds half of it tells no more than the datasheet, so the data do not
# determine it (the default model then falls back, optcal.app.fit.calibrate).
DATASHEET = {"K": 0.03, "b": 0.05, "S": math.radians(1.0), "K2": 0.005, "K3": 0.005, "kappa": 0.005, "c": 0.005}


def undetermined(model: Model, x: np.ndarray, sd: np.ndarray) -> list[str]:
    """The parameters of ``model`` whose standard error ``sd`` exceeds half their :data:`DATASHEET` spread
    (scale factors and second-order terms relative to the axis's scale factor, offsets in g, angles in rad);
    a parameter without a standard error (unobservable, held by the gauge) is not judged here."""
    P = model.to_dict(np.asarray(x, float))
    out = []
    for k, name in enumerate(model.names):
        fam, a = name.rsplit("_", 1)[0], name[-1]
        if fam not in DATASHEET or not np.isfinite(sd[k]):
            continue
        rel = abs(P.get(f"K_{a}", 1.0)) if fam in ("K", "K2", "K3") else 1.0
        if sd[k] / rel > DATASHEET[fam] / 2:
            out.append(name)
    return out


def span(values, *, centred: bool) -> float:
    """The largest distance of ``values`` from their mean (temperature, design.md, "Context: temperature and time
    offsets"'s T0) or first value (time, t0)."""
    if values is None:
        return 0.0
    v = np.asarray(values, float)
    return float(np.max(np.abs(v - (np.mean(v) if centred else v[0])))) if v.size else 0.0


def way_out(refusals: list[Refusal], model: Model, smaller: str | None) -> str:
    """What to do about ``refusals`` of ``model``: more positions or a smaller model (``smaller``, the richest
    model of :data:`FALLBACK` these positions determine, when there is one), or the expert's override. The
    parameters are named in backquotes (the CLI turns them into its options)."""
    kinds = {r.kind for r in refusals}
    force = "or pass `force_weak` to write it anyway, marked as forced"
    if "implausible" in kinds:
        return f"check the units and the poses, {force}"
    if "exact_data" in kinds:
        return f"calibrate from recorded positions, whose means carry noise; {force}"
    need = model.n_params + MIN_DOF
    alt = f", fit a smaller model (`model` {smaller})" if smaller and smaller != model.name else ""
    more = ("more varied positions" if kinds <= {"rank", "undetermined"}
            else f"at least {need} positions (more varied)")
    return f"record {more}{alt}, {force}"


def line(refusals: list[Refusal], model: Model, smaller: str | None, *, chain_tried: bool = False) -> str:
    """The one-line refusal: the reasons, that no smaller model of the chain is determined either
    (``chain_tried``: the default model's fallback found none), then the way out."""
    least = get_model(FALLBACK[-1])
    also = (f" (nor any smaller model of {'/'.join(FALLBACK)}: {least.name} needs {least.n_params + MIN_DOF} varied "
            "positions)" if chain_tried else "")
    return "; ".join(r.reason for r in refusals) + also + "; " + way_out(refusals, model, smaller)


def chain(model) -> tuple[str, ...]:
    """The models to try for ``model``: :data:`FALLBACK` for None (the user named none), else just it."""
    return FALLBACK if model is None else (get_model(model).name,)
