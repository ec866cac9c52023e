"""Fitting a gyroscope (application layer: it runs a registered solver): the fit, its refusal when the
motions do not determine it, standard errors, and the g-sensitivity test.

Standard errors are the Cramér-Rao bound of the whitened residuals (:func:`optcal.core.analysis.crlb` with
unit noise), scaled by √(χ²/dof) when the fit's χ²/dof exceeds 1 (Birge): the whitening assumes white
noise, and real rests hold more (bias instability, a hand that is not quite still).

A fit is returned only when it is plausible (:func:`optcal.core.gyro.analysis.plausibility`, docs/gyroscope.md, "The
gates: fits refused, scales noted (issue #29)"):
scale factors positive, near the declared units' factor and one another, misalignments small and determined,
χ²/dof and the motions' residual not far above the noise; otherwise an :class:`InputError` of one line with
the likely cause and the way out, or with ``force_weak`` the fit marked as forced. A scale more than 10 %
from the declared units' factor (or the nominal scale given) is said in a note.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from optcal.core import analysis
from optcal.core.errors import InputError
from optcal.core.gyro.analysis import (
    GyroRefused,
    check_observable,
    chi2_note,
    g_sensitivity_test,
    plausibility,
    scale_note,
)
from optcal.core.gyro.data import GyroData
from optcal.core.gyro.problem import GyroProblem


@dataclass
class GyroFit:
    problem: GyroProblem
    x: np.ndarray
    stderr: np.ndarray
    observability: analysis.Observability
    result: object
    chi2_dof: float
    g_test: dict | None = None
    notes: list = field(default_factory=list)
    forced: list = field(default_factory=list)  # the reasons a `force_weak` fit would have been refused for


# A fitted scale further than this (relative) from the nominal one is fitted again with the whitening at the
# calibrated scale
RESCALE = 0.01


def _fit(data, *, g_sensitivity, bias, scale, solver, options, seed, budget) -> GyroFit:
    from optcal.solvers.registry import get

    slv = get(solver, **(options or {}))
    # least squares (tens of evaluations) integrates in NumPy, a population method with the compiled kernel
    backend = "numpy" if getattr(slv, "few_evaluations", False) else "kernel"
    p = GyroProblem(data, g_sensitivity=g_sensitivity, bias=bias, scale=scale, backend=backend)
    check_observable(p, p.centre)  # before solving: a solver wanders along an undetermined direction

    def solve(x0=None):
        res = slv.solve(p, x0=x0, rng=seed, budget=budget)  # a Generator from the seed, if the solver draws
        if not np.isfinite(res.fun):
            raise InputError(f"the gyroscope fit found no finite cost ({res.message}); check the gyroscope's "
                             "columns and units")
        return res

    res = solve()
    if np.max(np.abs(res.x_full[:3] / p.centre[:3] - 1.0)) > RESCALE:
        # the whitening turns the rests' output noise into rad/s with the nominal scale: a nominal scale 30 %
        # off (imu_tk's own for its Xsens recording) makes the χ² 1.7 times what the noise gives. Whitened at
        # the calibrated scale and fitted again from there, the weights and the χ² are the data's, whatever the
        # nominal scale was.
        p.whiten_at(res.x_full[:3])
        res = solve(res.x_full)
    obs = check_observable(p, res.x_full)
    dof = p.n_residuals - p.model.n_params
    if dof < 3:
        raise InputError(f"{data.n_motions} motions and {data.n_rests} rests leave {dof} residual degrees of freedom "
                         f"for the {p.model.n_params} gyroscope parameters; record more rests with rotations between")
    chi2_dof = res.fun / dof
    sd, _ = analysis.crlb(p, res.x_full, noise_g=max(1.0, float(np.sqrt(chi2_dof))))
    return GyroFit(p, res.x_full, sd, obs, res, chi2_dof)


def calibrate_gyro(data: GyroData, *, bias: str = "rests", g_sensitivity: bool = False, scale=None,
                   solver: str = "lm", options: dict | None = None, seed: int = 0,
                   budget: int | None = None, force_weak: bool = False) -> GyroFit:
    """Fit the gyroscope of ``data`` (:class:`GyroData`). ``g_sensitivity``: fit G as well and keep it only
    when the likelihood-ratio test finds it (:func:`optcal.core.gyro.analysis.g_sensitivity_test`; needs the
    bias fitted, ``bias="fit"``); the test's outcome is in ``g_test`` and a note either way. An implausible
    fit is refused (:func:`gate`); ``force_weak`` returns it, its ``forced`` listing the reasons."""
    return gate(_calibrate(data, bias=bias, g_sensitivity=g_sensitivity, scale=scale, solver=solver,
                           options=options, seed=seed, budget=budget), scale=scale, force_weak=force_weak)


def gate(fit: GyroFit, *, scale=None, force_weak: bool = False) -> GyroFit:
    """Refuse an implausible ``fit`` in one line (:func:`optcal.core.gyro.analysis.plausibility`), or with
    ``force_weak`` mark it as forced (a first note and ``forced``); add a note when its scale is more than
    10 % from the declared units' factor (:data:`optcal.core.gyro.calfile.NOMINAL_SCALE`) or, for units without
    one, from the nominal ``scale`` given, and one when its χ²/dof is far above the rests' white noise
    (:func:`optcal.core.gyro.analysis.chi2_note`)."""
    from optcal.core.gyro.calfile import NOMINAL_SCALE

    p = fit.problem
    units = p.data.units
    declared = NOMINAL_SCALE.get(units)
    given = None if scale is None else np.broadcast_to(np.asarray(scale, float), (3,))
    residual = float(np.degrees(np.sqrt(np.mean(p.motion_angles(fit.x) ** 2))))
    refused = plausibility(p.model.names, fit.x, fit.stderr, chi2_dof=fit.chi2_dof, residual_deg=residual,
                           units=units, nominal=declared)
    if refused and not force_weak:
        raise GyroRefused(refused)
    if refused:
        fit.forced = [r.reason for r in refused]
        fit.notes.insert(0, "gyroscope forced although implausible: " + "; ".join(fit.forced))
    if declared is not None:
        note = scale_note(fit.x[:3], units, declared, declared=True)
    elif given is not None and np.ptp(given) == 0:
        note = scale_note(fit.x[:3], units, float(given[0]), declared=False)
    else:  # searched for from the motions (or given per axis): nothing to compare with
        note = None
    if note:
        fit.notes.append(note)
    if not refused and (note := chi2_note(fit.chi2_dof, residual)):
        fit.notes.append(note)
    return fit


def _calibrate(data: GyroData, *, bias: str, g_sensitivity: bool, scale, solver: str, options, seed: int,
               budget) -> GyroFit:
    kw = dict(scale=scale, solver=solver, options=options, seed=seed, budget=budget)
    if not g_sensitivity:
        return _fit(data, g_sensitivity=False, bias=bias, **kw)
    if bias != "fit":
        raise InputError("g-sensitivity needs the gyroscope bias fitted: pass `gyro_bias` fit")
    plain = _fit(data, g_sensitivity=False, bias="fit", **kw)
    # whitened as the fit without G was (the same scale): the likelihood ratio compares like with like
    with_g = _fit(data, g_sensitivity=True, bias="fit", scale=plain.problem.whitening_scale,
                  **{k: v for k, v in kw.items() if k != "scale"})
    test = g_sensitivity_test(plain.result.fun, with_g.result.fun)
    chosen = with_g if test.detected else plain
    chosen.g_test = test.to_dict()
    chosen.notes.append(
        f"g-sensitivity {'found' if test.detected else 'not found'}: likelihood ratio {test.statistic:.1f} on "
        f"{test.dof} degrees of freedom, p = {test.p_value:.2g} (threshold 1e-3)"
        + ("" if test.detected else "; the file holds the model without it"))
    return chosen

