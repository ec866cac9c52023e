"""Fitting a positions data set end to end: problem, solver (from the registry, by name), standard errors,
observability and goodness of fit.

Application layer (CONTRIBUTING.md, "Layers"): this module runs a solver, so it imports ``solvers``; the
core modules it builds on (problem, analysis, data, model, presets) do not. The import is inside
:func:`get_solver` only because importing the solver modules loads their back-ends (cvxpy, CasADi, NLopt).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optcal.core import determination
from optcal.core.analysis import (
    GoodnessOfFit,
    Observability,
    PositionDiagnostics,
    crlb,
    goodness_of_fit,
    loss_weights,
    natural_units,
    observability,
    position_diagnostics,
    position_sigma,
)
from optcal.core.calibration import Calibration
from optcal.core.data import PositionsData
from optcal.core.errors import InputError, listing
from optcal.core.model import Model, get_model
from optcal.core.presets import Presets
from optcal.core.problem import CalibrationProblem

# A fit whose χ² has a p-value below this does not match the stated noise (see `calibrate`).
MISFIT_P = 1e-3
# Weak fits (docs/design.md, "Per-position residuals, outliers, the robust loss, what the data determine and weak
# fits"): fewer residual degrees of freedom than this, or than the parameters, are
# noted; a parameter is "not determined" when its standard error exceeds half its value and this many natural
# units (1 mrad, 1 mg, 0.1 % of the scale factor), so a small, well-measured term near zero is not reported.
MIN_DOF = determination.MIN_DOF
WEAK_SE = 1e-3
# More outliers than this fraction of the positions point at the noise level or the model, not at positions.
MANY_OUTLIERS = 0.2


def get_solver(name: str, **options):
    """A configured solver from the registry (``optcal.solvers.registry.get``: a name, a ``wrapper:inner`` or a
    ``family:NAME``; docs/design.md, "The solver contract")."""
    from optcal import solvers

    return solvers.get(name, **options)


def calibrate(data: PositionsData, model: str | Model | None = None, *, solver: str = "lm",
              options: dict | None = None, g_local: float = 1.0, reference: bool = False,
              presets: Presets | None = None, seed: int | None = 0, budget=None, x0=None,
              noise_g: float | None = None, force_weak: bool = False, backend: str | None = None,
              recheck: bool = True) -> Calibration:
    """Fit ``model`` to ``data`` with the named solver and report parameters with standard errors.

    A calibration is returned only when the data determine it (:mod:`optcal.core.determination`, docs/design.md,
    "Per-position residuals, outliers, the robust loss, what the data determine and weak fits"): too few positions for
    the model, an unobservable direction, fewer than 3 residual degrees of
    freedom, an exact fit and physically implausible parameters are an :class:`InputError` of one line with
    the reason and the way out. ``model`` None is the default, ``nonlinear12``: when the positions do not
    determine it, the richest model of nonlinear12 → linear9 → diag6 that they do determine is fitted, and
    the first note says so. ``force_weak`` fits and returns a weak calibration anyway; its ``forced`` lists
    the reasons it would have been refused for (the calibration file records them). ``backend`` is the
    problem's evaluation (:data:`optcal.core.problem.BACKENDS`); by default NumPy for a solver that needs few
    evaluations (``few_evaluations``: least squares), the compiled kernel otherwise. ``recheck``: positions of a
    raw recording found off the fit of the others are re-examined sample by sample (``data.extra["recheck"]``,
    :func:`optcal.core.recording.positions.recheck_poses`: a motion at a pose's ends cut off, a moving pose dropped)
    and the fit is made again on what survives, said in the notes."""
    requested = get_model(determination.DEFAULT_MODEL if model is None else model)
    slv = get_solver(solver, **(options or {}))
    if backend is None:
        backend = "numpy" if getattr(slv, "few_evaluations", False) else "kernel"
    named = model is not None
    candidates, first, tried = [], None, []
    for name in determination.chain(model):
        m = get_model(name)
        problem = CalibrationProblem(m, data, g_local=g_local, reference=reference, presets=presets,
                                     noise_g=noise_g, check=False, backend=backend)
        obs = observability(problem)
        refused = determination.structure(problem, obs, gauge=presets is not None or m.name == "seed15")
        if not refused:
            candidates.append(problem)
        first = first or (problem, refused, obs)
        tried.append((problem, obs, refused))
    if not candidates:
        problem, refused, obs = first
        if not force_weak:
            smaller = _richest_determined(data, problem.model, g_local, reference, presets, noise_g)
            raise InputError(determination.line(refused, problem.model, smaller, chain_tried=not named))
        # forced: the richest model of the chain whose parameters these positions all reach (six positions force
        # diag6's exact fit, not nonlinear12 at rank 6 of 12), else the first
        forced = next((t for t in tried if t[1].rank == t[0].model.n_params), tried[0])
        why = [] if forced[0] is problem else [f"{refused[0].reason}"]
        candidates, first = [forced[0]], (forced[0], forced[2], forced[1])
    else:
        why = [] if first[1] == [] or candidates[0] is first[0] else [f"{first[1][0].reason}"]
    # The default model falls back past a fit that its positions leave undetermined (a parameter known no better
    # than its datasheet says, design.md, "Per-position residuals, outliers, the robust loss, what the data determine
    # and weak fits") or implausible: the data determine the smaller model, not that one. A named
    # model is fitted as named, and refused or forced.
    for k, problem in enumerate(candidates):
        fit = _fit(problem, slv, solver, x0, budget, seed, noise_g, refused=first[1] if problem is first[0] else [])
        last = k == len(candidates) - 1
        if named or last or not (fit.refused or fit.undetermined):
            break
        why.append(f"{problem.model.name}: " + ("; ".join(r.reason for r in fit.refused) if fit.refused else
                                                 f"{', '.join(fit.undetermined)} known no better than a datasheet "
                                                 "says (standard error above half its spread)"))
    cal, refused = fit.calibration, fit.refused
    if fit.undetermined and not named:  # the smallest model of the chain, and still undetermined
        refused = refused + [determination.Refusal(
            "undetermined", f"{', '.join(fit.undetermined)} of {cal.model.name} known no better than a datasheet "
            "says (standard error above half its spread)")]
    if refused and not force_weak:
        raise InputError(determination.line(refused, cal.model, None))
    if refused:
        cal.notes.insert(0, "forced although the data do not determine it: " + "; ".join(r.reason for r in refused))
    if cal.model.name != requested.name:
        cal.notes.insert(0, f"{requested.name} (the default model) is not determined by these positions: "
                            + "; ".join(why) + f"; fitted {cal.model.name} instead, the richest of "
                            f"{' → '.join(determination.FALLBACK)} that they "
                            + ("reach in every parameter (forced: see below)" if refused else "determine"))
        cal.requested_model = requested.name
    cal.forced = [r.reason for r in refused]
    if recheck and cal.diagnostics is not None and not cal.model.needs:
        again = _rechecked(data, cal, model, solver=solver, options=options, g_local=g_local, reference=reference,
                           presets=presets, seed=seed, budget=budget, x0=x0, noise_g=noise_g,
                           force_weak=force_weak, backend=backend)
        if again is not None:
            return again
    return cal


def _rechecked(data: PositionsData, cal: Calibration, model, **kw) -> Calibration | None:
    """The calibration refitted after its outlying positions were re-examined sample by sample, or None when
    there are none (or too many to be single poses: then the model or the noise is at fault, not a pose)."""
    recheck_poses = data.extra.get("recheck") if isinstance(data.extra, dict) else None
    idx = np.flatnonzero(cal.diagnostics.outlier)
    if recheck_poses is None:  # positions not from a raw recording (optcal.core.recording.positions sets it)
        return None
    if not idx.size or idx.size > max(2, MANY_OUTLIERS * len(idx if cal.diagnostics.index is None
                                                               else cal.diagnostics.index)):
        return None
    new, notes = recheck_poses(data, cal.model, cal.x, idx, cal.diagnostics.name)
    if new is None:
        return None
    again = calibrate(new, model, recheck=False, **kw)
    again.notes = notes + again.notes
    return again


@dataclass
class _Fit:
    calibration: Calibration
    refused: list  # determination.Refusal after the fit (exact, implausible), with the structural ones given
    undetermined: list[str]  # parameters known no better than the datasheet (determination.undetermined)


def _fit(problem: CalibrationProblem, slv, solver: str, x0, budget, seed, noise_g, refused) -> _Fit:
    """One model's fit with its standard errors, notes and the post-fit judgement (:mod:`optcal.core.determination`)."""
    model = problem.model
    rng = seed  # the solver builds its Generator from the seed, if it draws at all (Solver.uses_rng)
    result = slv.solve(problem, x0=x0, budget=budget, rng=rng)
    x = problem.to_full(result.x)[0]
    obs = observability(problem, x)
    loss = (result.extra or {}).get("loss", "linear")
    f_scale = (result.extra or {}).get("f_scale")
    weights = None if loss == "linear" or f_scale is None else loss_weights(problem.position_residuals(x), loss,
                                                                            f_scale)
    diag = position_diagnostics(problem, x, noise_g, weights, f_scale)
    gof = goodness_of_fit(problem, x)
    if weights is not None and diag.outlier.any():
        # χ² and the Birge ratio of a robust fit come from the positions it did not reject
        gof = _gof_without(problem, x, diag.outlier, obs.rank, gof)
    sigma, notes = gof.noise_g, []
    if gof.p_value is not None and gof.p_value < MISFIT_P:
        # The residuals are larger than the noise of the position means (the within-interval scatter of a
        # recording, or the given noise): the model misses an effect, or the positions were not static.
        # Bounds from that noise would be too small; scale them by the Birge ratio sqrt(χ²/E), which is the
        # residual-based noise estimate (Birge 1932; the usual practice in metrology). E, the mean of χ² under
        # the floor's correlated noise, is the dof for white noise (docs/noise.md).
        expected = gof.expected_chi2 or gof.dof
        birge = float(np.sqrt(gof.chi2 / expected))
        sigma = gof.noise_g * birge
        notes.append(f"chi2/E = {gof.chi2 / expected:.3g} (p = {gof.p_value:.2g}): the residuals exceed the noise "
                     f"of the position means, so the standard errors are scaled by the Birge ratio {birge:.3g}; "
                     "the model may miss an effect (try optcal discover)"
                     + ("; or the outlying position(s) named below are the cause" if diag.outlier.any() else ""))
    sd, _ = crlb(problem, x, sigma, weights=weights)
    notes += _outlier_notes(diag, loss) + _unchecked_notes(diag)
    if weights is not None:
        low = np.flatnonzero(diag.weight < 0.5)
        notes.append(f"robust loss {loss} (f_scale = {f_scale * 1e6:.3g} µg): standard errors weight each position "
                     "by the loss (IRLS weights)"
                     + (f"; it gives less than half weight to {listing((diag.name(i) for i in low), 5)}, so the "
                        "errors assume the noise of the positions kept" if low.size else ""))
    notes += _weak_notes(problem, x, sd, obs, gof)
    refused = list(refused)
    # no residual at all says it once; a model with unobservable directions fits any data exactly (its rank, not the
    # data, is the cause: the structural refusal says so, and the data are not called copies)
    if not any(r.kind == "exact" for r in refused) and obs.rank >= model.n_params:
        refused += determination.exact(gof, len(problem.data))
    refused += determination.plausibility(model, x, problem.data, problem.g_local)
    weak = determination.undetermined(model, x, sd)
    cal = Calibration(model, x, sd, obs, gof, problem, solver, result, notes, diag, loss,
                      None if f_scale is None else float(f_scale), [], None)
    return _Fit(cal, refused, weak)


def _richest_determined(data: PositionsData, model: Model, g_local: float, reference: bool,
                        presets: Presets | None, noise_g: float | None) -> str | None:
    """The richest model of the fallback chain, other than ``model``, that these positions determine before
    any fit (:func:`optcal.core.determination.structure`), for a refusal to name; None if there is none."""
    for name in determination.FALLBACK:
        m = get_model(name)
        if m.name == model.name or m.n_params >= model.n_params:
            continue
        problem = CalibrationProblem(m, data, g_local=g_local, reference=reference, presets=presets,
                                     noise_g=noise_g, check=False)
        if not determination.structure(problem, observability(problem), gauge=presets is not None):
            return m.name
    return None


def _gof_without(problem: CalibrationProblem, x: np.ndarray, drop: np.ndarray, rank: int,
                 gof: GoodnessOfFit) -> GoodnessOfFit:
    """Goodness of fit over the positions not in ``drop`` (a robust fit's rejected positions): χ² over the kept
    positions' own floors when the noise comes from the data (as :func:`~optcal.core.analysis.goodness_of_fit`)."""
    from optcal.core.distributions import chi2_sf

    d = problem.rows_per_position
    keep = ~np.asarray(drop, bool)
    r = problem.position_residuals(x).reshape(-1, d)[keep].ravel()
    dof = max(len(r) - rank, 1)
    cost = float(r @ r)
    if problem.noise_g is None:
        return GoodnessOfFit(gof.rms_g, gof.cost, dof, float(np.sqrt(cost / dof)), None, None)
    if problem.noise_from_data:
        sig = position_sigma(problem, x).reshape(-1, d)[keep].ravel()
        chi2 = float(np.sum((r / sig) ** 2))
    else:
        chi2 = cost / problem.noise_g**2
    return GoodnessOfFit(gof.rms_g, gof.cost, dof, gof.noise_g, chi2, float(chi2_sf(chi2, dof)),
                         gof.noise_source, gof.estimator, gof.white_noise_g)


def _outlier_notes(diag: PositionDiagnostics, loss: str) -> list[str]:
    """A note per outlier naming the position and the fix, or one note when too many to be positions."""
    idx = np.flatnonzero(diag.outlier)
    if not idx.size:
        return []
    if idx.size > max(2, MANY_OUTLIERS * len(diag.index)):
        return [f"{idx.size} of {len(diag.index)} positions have residuals beyond {diag.threshold:.2f} σ "
                f"({diag.sigma_source} noise): the noise is understated or the model misses an effect, more than "
                "single positions are off (see the positions table; try optcal discover)"]
    fix = ("it is down-weighted by the robust loss; re-record or remove it to be sure" if loss != "linear" else
           "try the robust loss: --solver scipy-trf --option loss=cauchy, or re-record or remove it")
    return [f"{diag.name(i)} is {_micro_g(diag.off[i])} off the fit of the other positions, "
            f"{diag.statistic[i]:.3g} σ "
            f"({diag.sigma_source} noise {_micro_g(diag.noise_g[i])}, threshold {diag.threshold:.2f} σ): "
            f"displaced or moved during the position? {fix}" for i in idx]


def _micro_g(v: float) -> str:
    """A small force in g as µg, or as mg from 1 mg on (never in powers of ten)."""
    return f"{v * 1e6:.4g} µg" if abs(v) < 1e-3 else f"{v * 1e3:.4g} mg"


def _unchecked_notes(diag: PositionDiagnostics) -> list[str]:
    """A note per pose whose positions alone pin part of the model (:func:`optcal.core.analysis._unchecked`): no
    outlier test can judge them. A pose that alone sees an axis from one side is named with that axis: its scale
    factor and offset rest on that pose (a rest split in two by a drift is still one pose)."""
    flag = np.zeros(len(diag.index), bool)
    for f in (diag.unchecked, diag.unchecked_pose):
        if f is not None:
            flag |= f
    idx = np.flatnonzero(flag)
    if not idx.size:
        return []
    pose = diag.pose if diag.pose is not None else np.arange(len(diag.index))
    poses = np.unique(pose)
    if len(poses) > 1 and np.isin(poses, pose[idx]).all():  # as many poses as the model has parameters, or fewer
        return [f"each of the {len(poses)} poses ({len(pose)} positions) alone pins part of the model, so no pose "
                "can check another for a displacement; record more poses, in other orientations"]
    notes = []
    for g in dict.fromkeys(pose[idx].tolist()):  # each pose once, in order
        at = idx[pose[idx] == g]
        one = at.size == 1
        what = diag.name(int(at[0])) if one else f"{listing((diag.name(int(i)) for i in at), limit=6)} (one pose)"
        side = _one_sided(diag.force_g, at) if diag.force_g is not None else ""
        check = ("so the other positions cannot check it for a displacement (not tested)" if one else
                 "so no other pose can check them for a displacement of the pose as a whole")
        notes.append(f"{what}: alone {'pins' if one else 'pin'} part of the model (leverage "
                     f"{listing((format(float(diag.leverage[i]), '.4f') for i in at), limit=6, sep='/')}), {check}"
                     f"{side}; record another pose near it" + (", or one with that axis the other way up"
                                                                   if side else ""))
    return notes


def _one_sided(force: np.ndarray, at: np.ndarray) -> str:
    """The clause naming the axis that the pose ``at`` (its positions; ``force`` every position's specific force,
    g) alone sees near ±1 g when no position sees it the other way up, or "" (then it pins something else)."""
    f = force[at].mean(axis=0)
    k = int(np.argmax(np.abs(f)))
    sign = np.sign(f[k])
    others = np.delete(force[:, k], at)
    if abs(f[k]) < 0.5 or not len(others) or np.any(sign * others > 0.5) or np.any(sign * others < -0.5):
        return ""
    way, least = ("down", float(np.min(force[:, k]))) if sign > 0 else ("up", float(np.max(force[:, k])))
    return (f"; the {'xyz'[k]} axis never points {way} (its {'least' if sign > 0 else 'greatest'} reading "
            f"{least:+.2f} g), so its scale factor and offset rest on this pose")


def _weak_notes(problem: CalibrationProblem, x: np.ndarray, sd: np.ndarray, obs: Observability,
                gof: GoodnessOfFit) -> list[str]:
    """Notes on what these positions do not determine (docs/design.md, "Per-position residuals, outliers, the robust
    loss, what the data determine and weak fits")."""
    model, n_pos = problem.model, len(problem.data)
    notes = []
    dof = max(len(problem.position_residuals(x)) - obs.rank, 0)  # every position, a robust fit's rejected too
    if dof == 0:
        notes.append(f"no residual degree of freedom ({n_pos} positions, {obs.rank} determined parameters): the "
                     "residuals cannot show a bad position or a missing effect; record more positions (at least "
                     f"{2 * obs.rank} for {model.name})")
    elif dof < MIN_DOF or dof < obs.rank:
        notes.append(f"only {dof} residual degree(s) of freedom ({n_pos} positions, {obs.rank} determined "
                     "parameters): the residuals can hardly show a bad position or a missing effect and the noise "
                     f"estimate rests on {dof} degree(s) of freedom; record more positions (at least "
                     f"{2 * obs.rank} for {model.name})")
    if obs.rank < model.n_params:
        notes.append(f"{model.n_params - obs.rank} direction(s) of the parameters are not seen by these positions "
                     "(observability): their values are those of the presets or the start, not measurements, and "
                     "the parameters in them have no standard error")
    units = model.units(problem.data.units)
    nat = natural_units(problem, x)
    for k, name in enumerate(model.names):
        if np.isfinite(sd[k]) and sd[k] > abs(x[k]) / 2 and sd[k] / nat[k] > WEAK_SE:
            notes.append(f"{name} = {x[k]:.3g} ± {sd[k]:.2g} {units.get(name, '')}: not determined by these "
                         "positions (its standard error exceeds half its value); record more varied positions or "
                         "drop the term")
    return notes
