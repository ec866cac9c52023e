"""Simulated static-position data sets: truth + scheme + noise (+ time, temperature, hidden effects,
turntable reference). Every random draw comes from the ``numpy.random.Generator`` passed in.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from optcal.core.data import PositionsData
from optcal.core.errors import InputError
from optcal.core.model import Context, Model, get_model
from optcal.core.presets import draw_truth
from optcal.core.schemes import scheme as scheme_directions
from optcal.core.schemes import tilt


@dataclass(frozen=True)
class Simulation:
    data: PositionsData
    model: Model  # the model that generated the data (the fitted one plus hidden effects)
    truth: dict[str, float]
    A: np.ndarray  # true specific force, (n, 3), g

    def truth_vector(self, model: Model | str) -> np.ndarray:
        """The truth restricted to ``model``'s parameters (terms it lacks are dropped)."""
        model = get_model(model)
        return model.from_dict({k: v for k, v in self.truth.items() if k in model.names})


def simulate(
    model: Model | str,
    truth: dict[str, float] | None,
    rng: np.random.Generator | int,
    *,
    scheme: str | int = "24",
    noise_g: float = 10e-6,
    noise_density: float | None = None,
    dwell_s: float = 10.0,
    rate_hz: float = 100.0,
    g_local: float = 1.0,
    tilt_deg: float = 0.0,
    temp: tuple[float, float] | None = None,
    times: bool = False,
    move_s: float = 20.0,
    effects: dict[str, dict[str, float]] | None = None,
    reference: bool = False,
    reference_error_arcsec: float = 0.0,
) -> Simulation:
    """Simulate position means.

    ``truth`` holds the model's parameters in their units (docs/design.md, "Terms and parameters"); None draws one
    from ``rng`` as ``optcal simulate`` does without ``--truth`` (:func:`optcal.core.presets.draw_truth`, before the
    data's draws). ``rng`` is a ``numpy.random.Generator`` or an integer seed for one; the drawn truth is the
    result's ``truth``.

    Noise is white and input-referred (in g): either ``noise_g``, the SD of each position's mean per axis,
    or ``noise_density`` in g/√Hz with ``dwell_s`` and ``rate_hz`` (per-sample SD = density·√rate, so the
    SD of a mean over the dwell is density/√dwell). ``effects`` adds terms the fitted model lacks,
    e.g. ``{"cubic": {"K3_x": 1e-4}}`` (missing parameters of an added term are zero).
    With ``reference``, the data carry the turntable's commanded specific force in ``ref_*``; the true
    orientation differs from the commanded one by a random rotation of ``reference_error_arcsec`` per axis.
    """
    for name, value, low in (("noise_g", noise_g, 0.0), ("tilt_deg", tilt_deg, 0.0),
                             ("reference_error_arcsec", reference_error_arcsec, 0.0)):
        if not (np.isfinite(value) and value >= low):
            raise InputError(f"simulate: {name} = {value!r} must be a finite number of 0 or more")
    for name, value in (("dwell_s", dwell_s), ("rate_hz", rate_hz), ("g_local", g_local)):
        if not (np.isfinite(value) and value > 0):
            raise InputError(f"simulate: {name} = {value!r} must be a positive finite number")
    if noise_density is not None and not (np.isfinite(noise_density) and noise_density >= 0):
        raise InputError(f"simulate: noise_density = {noise_density!r} must be a finite number of 0 or more (g/√Hz)")
    if isinstance(rng, int | np.integer) and not isinstance(rng, bool):
        rng = np.random.default_rng(int(rng))
    if not isinstance(rng, np.random.Generator):
        raise InputError(f"simulate: `rng` must be a numpy.random.Generator or an integer seed, not "
                         f"{type(rng).__name__}")
    model = get_model(model)
    if truth is None:
        truth = draw_truth(model, rng)
    elif not isinstance(truth, Mapping):
        raise InputError(f"simulate: `truth` must be a mapping of parameter names to values (or None to draw "
                         f"one), not {type(truth).__name__}")
    gen = model
    values = dict(truth)
    for term, params in (effects or {}).items():
        gen = gen.with_term(term)
        values.update(params)
    missing = [n for n in model.names if n not in values]
    if missing:
        raise InputError(f"truth lacks parameter(s) {', '.join(missing)} of model {model.name}")
    x = gen.from_dict({k: v for k, v in values.items() if k in gen.names})
    ideal = scheme_directions(scheme, rng)
    if reference:
        true_dir = tilt(ideal, reference_error_arcsec / 3600.0, rng)
    else:
        true_dir = tilt(ideal, tilt_deg, rng)
    A = g_local * true_dir
    n = len(A)
    t = (np.arange(n) * (dwell_s + move_s) + dwell_s / 2) if (times or "t" in gen.needs) else None
    tc = None
    if temp is not None or "temp" in gen.needs:
        c1, c2 = temp if temp is not None else (20.0, 40.0)
        tc = np.linspace(c1, c2, n)
    ctx = Context.from_columns(temp=tc, t=t)
    N = gen.forward(x, A, ctx)[0]
    if noise_density is not None:
        sigma_sample = noise_density * np.sqrt(rate_hz)
        n_avg = max(1, int(round(dwell_s * rate_hz)))
        sigma_mean = sigma_sample / np.sqrt(n_avg)
    else:
        sigma_mean, n_avg, sigma_sample = noise_g, None, None
    K = np.abs(x[gen.groups()["scale"]])
    N = N + K * sigma_mean * rng.standard_normal(N.shape)
    data = PositionsData(
        N=N,
        t=t,
        temp=tc,
        n_samples=None if n_avg is None else np.full(n, float(n_avg)),
        std=None if sigma_sample is None else np.tile(K * sigma_sample, (n, 1)),
        ref=g_local * ideal if reference else None,
    )
    return Simulation(data, gen, {k: float(v) for k, v in zip(gen.names, x)}, A)
