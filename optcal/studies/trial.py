"""One trial of a study: simulate run i's data, solve it with one configured solver, score the result.

Seeds (docs/design.md, "Seeds and streams"). Every random stream is a child of the spec's base seed through
``numpy.random.SeedSequence(seed, spawn_key=(stream, run, ...))``: the truth and presets depend on
(run, model), the data on (run, model, scheme), the solver's generator on (run, model, scheme, solver
label). Run i of every solver therefore sees the same data, and no result depends on the executor, the
number of workers or the order in which trials finish. Names enter the keys through CRC-32, so adding
a solver to a spec leaves the other solvers' streams unchanged.

A trial never raises: a solver that raises or returns a non-finite point is stored as failed with its
message, and the study goes on.

A gyroscope study (``problem = "gyroscope"``) has the same streams, trials and row columns: run i's truth
is the simulated sensor's (:func:`optcal.core.gyro.simulate.draw_truth`, or the spec's table), its data an IMU
recording of the scheme's poses with rotations between them (:func:`optcal.core.gyro.simulate.simulate_imu`),
its in-field problem :class:`optcal.core.gyro.GyroProblem` and its bound the Cramér-Rao bound of that problem's
whitened residuals (noise 1). It has no presets, verification set or navigation: those columns are empty.
"""

from __future__ import annotations

import copy
import functools
import json
import time
import traceback
import zlib
from dataclasses import dataclass

import numpy as np

from optcal.core.analysis import observability, projected_crlb
from optcal.core.gyro import GyroProblem, simulate_imu
from optcal.core.gyro import draw_truth as draw_gyro_truth
from optcal.core.model import get_model
from optcal.core.presets import PAPER_TRUTH, draw_truth, manufacturer_presets, manufacturer_sd
from optcal.core.problem import CalibrationProblem, Counter
from optcal.core.simulate import simulate
from optcal.solvers.base import Stagnation
from optcal.studies.scoring import (
    accuracy_of as accuracy_of,  # re-exported: the names optcal.studies.trial has always had
)
from optcal.studies.scoring import anytime_on_grid, crlb_with_presets, seconds_on_grid
from optcal.studies.scoring import trace_on_grid as trace_on_grid
from optcal.studies.spec import SolverConfig, Spec
from optcal.studies.spec_schema import GYRO_MODELS, gyro_sensor

TRUTH, PRESETS, DATA, VERIFY, TURNTABLE, SOLVER, OPTIMUM = range(7)
CONVERGED_QUANTILE = 0.999  # χ² quantile of the final cost that counts as "reached the noise floor"
# The final target of every in-field trial, as COCO sets one (Hansen et al. 2021, "COCO: a platform for
# comparing continuous optimizers in a black-box setting", §4: 1e-8 is the last target and a run may stop
# there): a trial stops once its relative gap (f − f_opt) / f_opt to its data's optimum is at most this.
# Every target the analyses use (optcal.studies.anytime, at most 1e-3) is met before it, so the anytime record
# beyond it would be flat; and a gap of 1e-8 puts the estimate within √(1e-8 · f_opt/σ²) ≈ 5e-4 CRLB of the
# optimum (f_opt/σ² is about the degrees of freedom, 12-24 here), far below the accuracy's printed digits.
# Before this, staged CMA-ES spent most of its 14,600 evaluations a calibration after it had converged.
FINAL_GAP: float | None = 1e-8  # None: no early stop (the tests' reference runs)
# The stagnation rule (optcal.solvers.base.Stagnation): a trial whose solver takes it (Solver.stops_on_stagnation:
# CMA-ES, inside staged:'s stages too; nevergrad's and mealpy's optimisers with stop_on_stagnation) ends once its best
# cost has improved by no more than 1e-5 of itself over the last tenth of its evaluation budget (of each
# stage's budget inside staged:). 1e-5 of the cost is Δχ² ≈ 1e-4 at the noise floor (f/σ² is about the degrees of
# freedom, 12-24 here): no accuracy digit moves, and every cost target of the anytime analyses (gaps down to 1e-3) that
# a run meets it meets before such a stretch (on the compare study's 50 runs: staged:cmaes 30 % fewer evaluations, the
# same RMSE/CRLB to three digits, no cost target missed). The solvers whose best cost stays flat for long stretches
# and then improves again (the swarms, nevergrad's TwoPointsDE, NLopt's global methods, differential evolution,
# mealpy's grey wolf) do not take it: docs/performance.md, "Stopping at convergence". None: no rule.
STAGNATION: Stagnation | None = Stagnation(share=0.1, rtol=1e-5)
NAV_POINTS = 61


def key(name: str) -> int:
    return zlib.crc32(name.encode())


def stream(seed: int, *keys: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=tuple(int(k) for k in keys)))


@dataclass(frozen=True)
class Trial:
    """Everything a worker needs to run one trial (small and picklable)."""

    id: str
    run: int
    model: str
    scheme: str
    config: SolverConfig
    seed: int
    truth: str | dict
    presets: str
    presets_error_scale: float
    noise_ug: float
    tilt_deg: float
    g_local: float
    verification: dict
    navigation: dict
    problem: str = "accelerometer"
    gyroscope: dict | None = None  # the gyroscope study's recording (spec_schema.Gyroscope)

    @property
    def gyro(self) -> bool:
        return self.problem == "gyroscope"


def model_names(t: Trial) -> list[str]:
    """The names of the fitted model's parameters (the gyroscope's gyro9 has no bias: the rests give it)."""
    return list(GYRO_MODELS[t.model].names if t.gyro else get_model(t.model).names)


def trial_id(model: str, scheme: str, label: str, run: int) -> str:
    return f"{model}|{scheme}|{label}|{run}"


def trials(spec: Spec) -> list[Trial]:
    """The study's trials in a fixed order: run, model, scheme, solver. Run-first, so that every model ×
    scheme of the report has results from the first minutes of a study on (the headline table written while
    it runs); the solvers of one run, model and scheme stay together, sharing their World. Each trial carries
    its own seeds: the order changes no result."""
    out = []
    for run in range(spec.runs):
        for model in spec.models:
            for scheme in spec.schemes:
                for cfg in spec.solvers:
                    out.append(Trial(
                        trial_id(model, scheme, cfg.label, run), run, model, scheme, cfg, spec.seed, spec.truth,
                        spec.presets, spec.presets_error_scale, spec.noise_ug, spec.tilt_deg, spec.g_local,
                        dict(spec.verification), dict(spec.navigation), spec.problem, dict(spec.gyroscope) or None))
    return out


# -- the simulated world of run i ----------------------------------------------------------------

def truth_of(t: Trial) -> dict[str, float]:
    model = get_model(t.model)
    if t.truth == "paper":
        values = PAPER_TRUTH
    elif t.truth == "draw":
        values = draw_truth(model, stream(t.seed, TRUTH, t.run, key(t.model)))
    else:
        values = t.truth
    return {n: float(values[n]) for n in model.names}


def presets_of(t: Trial, truth: dict):
    if t.presets == "none":
        return None
    return manufacturer_presets(truth, stream(t.seed, PRESETS, t.run, key(t.model)), t.presets_error_scale)


def infield_data(t: Trial, truth: dict):
    rng = stream(t.seed, DATA, t.run, key(t.model), key(t.scheme))
    return simulate(t.model, truth, rng, scheme=t.scheme, noise_g=t.noise_ug * 1e-6, tilt_deg=t.tilt_deg,
                    g_local=t.g_local)


def gyro_truth(t: Trial) -> np.ndarray:
    """The simulated gyroscope's parameter vector (its sensor model's: with the bias, also for gyro9)."""
    sensor = gyro_sensor(t.model)
    if t.truth == "draw":
        return draw_gyro_truth(sensor, stream(t.seed, TRUTH, t.run, key(t.model)), t.gyroscope["scale"])
    return sensor.vector(t.truth)


def gyro_data(t: Trial, truth: np.ndarray):
    """Run i's IMU recording: the scheme's poses held ``rest_s``, turned between along the rotation profile.
    White rate noise: density · √rate per sample (the sampled white noise of Kalibr's noise model); the
    accelerometer's white noise per sample is ``noise_ug`` (the SD of a rest's mean, as of an accelerometer
    position's) · √(samples per rest)."""
    g = t.gyroscope
    n_rest = round(g["rest_s"] * g["rate_hz"])
    return simulate_imu(gyro_sensor(t.model), truth, poses=t.scheme, rate_hz=g["rate_hz"], rest_s=g["rest_s"],
                        motion_s=g["motion_s"], profile=g["profile"],
                        noise_rate=g["noise_rad_s_rthz"] * np.sqrt(g["rate_hz"]),
                        bias_walk=g["bias_walk_rad_s2_rthz"], noise_acc_g=t.noise_ug * 1e-6 * np.sqrt(n_rest),
                        rng=stream(t.seed, DATA, t.run, key(t.model), key(t.scheme)))


def turntable_data(t: Trial, truth: dict):
    # One stream for every orientation error: the errors at 10, 60 and 300 arcsec are the same random
    # rotations scaled, so the comparison between levels is not blurred by different draws.
    rng = stream(t.seed, TURNTABLE, t.run, key(t.model), key(t.scheme))
    return simulate(t.model, truth, rng, scheme=t.scheme, noise_g=t.noise_ug * 1e-6, g_local=t.g_local,
                    reference=True, reference_error_arcsec=t.config.reference_error_arcsec)


def verification_data(t: Trial, truth: dict):
    v = t.verification
    rng = stream(t.seed, VERIFY, t.run, key(t.model))
    return simulate(t.model, truth, rng, scheme=v["scheme"], noise_g=v["noise_ug"] * 1e-6, tilt_deg=v["tilt_deg"],
                    g_local=t.g_local)


# -- scoring ------------------------------------------------------------------------------------

def _navigation(model, x_true, x_est, nav: dict):
    """Max and mean 5-hour static navigation error (nmi) and a resampled curve; None without optcal.core.nav."""
    if not nav.get("enabled", True):
        return None
    try:
        from optcal.core.nav import navigation_error
    except ImportError:
        return None
    r = navigation_error(model, x_true, x_est, hours=nav["hours"], latitude_deg=nav["latitude_deg"],
                         attitude_deg=tuple(nav.get("attitude_deg", (0.0, 0.0, 0.0))))
    t = np.asarray(r.t_s, float)
    grid = np.linspace(0.0, nav["hours"] * 3600.0, NAV_POINTS)
    curve = np.interp(grid, t, np.asarray(r.error_nmi, float))
    return float(r.max_error_nmi), float(r.mean_error_nmi), [float(v) for v in curve]


@dataclass
class World:
    """What every solver of run i on one model and scheme shares: truth, presets, data, the in-field
    problem, its bounds and the verification set. Built once per process for the consecutive trials of a
    chunk (the solvers of one run), instead of once per trial."""

    model: object
    truth: dict
    presets: object
    x_true: np.ndarray
    yard: CalibrationProblem | GyroProblem
    bound: tuple  # projected_crlb(yard, x_true, sigma)
    sd_presets: list | None
    ver: CalibrationProblem | None  # None: no verification set (the gyroscope)
    ver_truth: np.ndarray | None
    f_opt: float | None  # the in-field problem's optimum cost (reference least-squares fit), None if it failed
    sigma: float  # the residuals' noise SD: g for the accelerometer, 1 for the gyroscope's whitened residuals


def world_key(t: Trial) -> str:
    """The inputs a World depends on (everything of a Trial but its solver)."""
    return json.dumps([t.seed, t.run, t.model, t.scheme, t.truth, t.presets, t.presets_error_scale, t.noise_ug,
                       t.tilt_deg, t.g_local, t.verification, t.problem, t.gyroscope], sort_keys=True)


_WORLDS: dict[str, World] = {}


def world(t: Trial) -> World:
    """The World of ``t``, from this process's cache of the last few."""
    k = world_key(t)
    w = _WORLDS.get(k)
    if w is None:
        if len(_WORLDS) >= 4:
            _WORLDS.pop(next(iter(_WORLDS)))
        w = _WORLDS[k] = _build_world(t)
    return w


def _build_world(t: Trial) -> World:
    if t.gyro:
        return _build_gyro_world(t)
    model = get_model(t.model)
    sigma = t.noise_ug * 1e-6
    truth = truth_of(t)
    presets = presets_of(t, truth)
    sim = infield_data(t, truth)
    x_true = sim.truth_vector(model)
    yard = CalibrationProblem(model, sim.data, g_local=t.g_local, presets=presets, noise_g=sigma)
    sd_presets = None
    if t.presets == "manufacturer":
        prior = manufacturer_sd(model.names, truth, t.presets_error_scale)
        sd_presets = [float(v) for v in crlb_with_presets(yard, x_true, sigma, prior)]
    ver = CalibrationProblem(model, verification_data(t, truth).data, g_local=t.g_local, check=False)
    return World(model, truth, presets, x_true, yard, projected_crlb(yard, x_true, sigma), sd_presets, ver,
                 _abs_norm_error_ug(ver, x_true), optimum_cost(t, yard), sigma)


def _build_gyro_world(t: Trial) -> World:
    """Run i's gyroscope World: the problem at the nominal scale, the truth in its coordinates (the bias
    beyond the rests' mean output, or none for gyro9: :meth:`GyroProblem.from_sensor`), the bound of its
    whitened residuals."""
    sensor_truth = gyro_truth(t)
    model = GYRO_MODELS[t.model]
    yard = GyroProblem(gyro_data(t, sensor_truth).data, g_sensitivity=model.g_sensitivity,
                       bias="fit" if model.bias else "rests", scale=t.gyroscope["scale"])
    x_true = yard.from_sensor(sensor_truth)
    truth = dict(zip(gyro_sensor(t.model).names, map(float, sensor_truth), strict=True))
    return World(yard.model, truth, None, x_true, yard, projected_crlb(yard, x_true, 1.0), None, None, None,
                 optimum_cost(t, yard), 1.0)


def optimum_cost(t: Trial, yard: CalibrationProblem) -> float | None:
    """The optimum cost of run i's in-field data: a reference least-squares fit (scipy-lm from the presets,
    or from the solvers' usual start without them) on a detached copy of the problem, so the World's
    problem and its counter are untouched. The cost targets of the anytime analyses are gaps to it
    (:mod:`optcal.studies.anytime`). None when the fit fails (the trials then have no cost targets)."""
    from optcal import solvers

    problem = copy.copy(yard)
    problem.counter = Counter()
    try:
        res = solvers.get("scipy-lm").solve(problem, rng=stream(t.seed, OPTIMUM, t.run, key(t.model), key(t.scheme)))
    except Exception:  # noqa: BLE001 - no optimum: the study goes on without cost targets for this run
        return None
    return float(res.fun) if np.isfinite(res.fun) else None


@functools.lru_cache(maxsize=64)
def converged_threshold(dof: int) -> float:
    """The χ² quantile CONVERGED_QUANTILE of ``dof`` degrees of freedom (cost/σ² at the noise floor)."""
    from scipy import stats

    return float(stats.chi2.ppf(CONVERGED_QUANTILE, dof))


def _abs_norm_error_ug(problem: CalibrationProblem, x) -> np.ndarray:
    A = problem.specific_force(x)
    return np.abs(np.linalg.norm(A, axis=1) - problem.g_local) * 1e6


def base_row(t: Trial) -> dict:
    cfg = t.config
    return {"trial_id": t.id, "model": t.model, "scheme": t.scheme, "solver": cfg.label, "solver_name": cfg.name,
            "run": t.run, "reference": int(cfg.reference), "reference_error_arcsec": cfg.reference_error_arcsec,
            "names": model_names(t)}


def failed_row(t: Trial, message: str, wall_s: float | None = None) -> dict:
    """The row of a trial that produced no result (the solver raised, or its worker was lost)."""
    return {**base_row(t), "status": "failed", "message": message[:500], "success": 0, "converged": 0,
            "wall_s": wall_s}


def run_trial(t: Trial) -> dict:
    """Run one trial and return its row (see :mod:`optcal.studies.store` for the columns)."""
    t_start = time.perf_counter()
    cfg = t.config
    try:
        w = world(t)
    except Exception as exc:  # noqa: BLE001 - data the problem refuses (a scheme too poor for it) fail the trial
        return failed_row(t, f"the run's data: {type(exc).__name__}: {exc}", time.perf_counter() - t_start)
    sigma = w.sigma
    row = {**base_row(t), "x_true": [float(v) for v in w.x_true]}
    try:
        if cfg.reference:
            problem = CalibrationProblem(w.model, turntable_data(t, w.truth).data, g_local=t.g_local,
                                         reference=True, presets=w.presets, noise_g=sigma)
        else:
            # The shared in-field problem with an evaluation counter of this trial's own.
            problem = copy.copy(w.yard)
            problem.counter = Counter()
        from optcal import solvers

        solver = solvers.get(cfg.name, **cfg.options)
        rng = stream(t.seed, SOLVER, t.run, key(t.model), key(t.scheme), key(cfg.label))
        budget = trial_budget(cfg, solver, None if cfg.reference else w.f_opt)
        row["max_evals"] = (budget or {}).get("max_evals", solver.default_budget)
        row["target_f"] = final_target(None if cfg.reference else w.f_opt)
        # a turntable fit (reference) minimises another cost: it runs as configured
        res = solver.solve(problem, budget=budget, rng=rng, stagnation=None if cfg.reference else STAGNATION)
        row["at_target"] = int(problem.counter.stopped == "target cost reached")
        row["stop_reason"] = res.stop_reason
        x_est = np.asarray(res.x_full, float)
        if not np.all(np.isfinite(x_est)) or not np.isfinite(res.fun):
            raise FloatingPointError(f"solver returned a non-finite result ({res.message})")
    except Exception as exc:  # noqa: BLE001 - any solver error is a failed trial, not a failed study
        tb = traceback.extract_tb(exc.__traceback__)
        where = f" at {tb[-1].filename.rsplit('/', 1)[-1]}:{tb[-1].lineno}" if tb else ""
        return {**failed_row(t, f"{type(exc).__name__}: {exc}{where}", time.perf_counter() - t_start),
                "x_true": row["x_true"]}
    try:
        row.update(_score(t, w, x_est, res, problem, sigma))
    except Exception as exc:  # noqa: BLE001 - a trial never raises: scoring errors fail this trial only
        return {**failed_row(t, f"scoring failed: {type(exc).__name__}: {exc}", time.perf_counter() - t_start),
                "x_true": row["x_true"]}
    row["wall_s"] = time.perf_counter() - t_start
    return row


def final_target(f_opt: float | None) -> float | None:
    """The cost at which an in-field trial stops (:data:`FINAL_GAP` above its data's optimum), or None."""
    if FINAL_GAP is None or f_opt is None or not np.isfinite(f_opt) or f_opt <= 0:
        return None
    return float(f_opt) * (1.0 + FINAL_GAP)


def trial_budget(cfg: SolverConfig, solver, f_opt: float | None) -> dict | None:
    """The budget a trial's solver runs under: the configuration's (or the solver's default evaluation
    count), stopped at the final target when the data's optimum is known (turntable trials pass None: they
    minimise another cost). The evaluation count, and so every iteration count a solver derives from it,
    is the configuration's whether or not the target stops the run earlier."""
    b = dict(cfg.budget)
    target = final_target(f_opt)
    if target is None:
        return b or None
    if not b:
        b = {"max_evals": solver.default_budget}
    b["target"] = min(b.get("target", np.inf), target)
    return b


def run_chunk(chunk: list[Trial]) -> list[dict]:
    """Run consecutive trials in one worker call (they share their World): one scheduling round trip per
    chunk instead of per trial."""
    return [run_trial(t) for t in chunk]


def _score(t: Trial, w: World, x_est, res, problem, sigma) -> dict:
    """The metrics of one finished solve (the columns of :mod:`optcal.studies.store`)."""
    cfg = t.config
    model, x_true = w.model, w.x_true
    sd, P, u, obs = w.bound
    e = x_est - x_true
    e_proj = (P @ (e / u)) * u
    null = obs.null_space
    null_coef = (np.linalg.pinv(null) @ (e / u)) if null.size else np.zeros(0)
    rank = obs.rank if not cfg.reference else observability(problem, x_true).rank
    # The positions' residuals only: the gauge rows (seed15) hold unobservable directions, not data.
    dof = max(problem.n_position_residuals - rank, 1)
    chi2 = float(res.fun) / sigma**2
    converged = chi2 <= converged_threshold(dof)

    # no verification set (the gyroscope): empty columns
    ver_err = _abs_norm_error_ug(w.ver, x_est) if w.ver is not None else np.zeros(0)
    ver_truth = w.ver_truth if w.ver_truth is not None else np.zeros(0)
    nav = _navigation(model, x_true, x_est, t.navigation)
    anytime = anytime_on_grid(res.trace, res.trace_x, x_true, w.bound)
    return dict(
        status="ok", message=str(res.message)[:500], success=int(bool(res.success)), converged=int(converged),
        fun=float(res.fun), chi2=chi2, dof=int(dof), nfev=int(res.nfev), nit=int(res.nit),
        runtime_s=float(res.runtime_s),
        accuracy=float(np.sqrt(np.mean((e_proj / sd) ** 2))),
        ver_mean_ug=float(np.mean(ver_err)) if ver_err.size else None,
        ver_sd_ug=float(np.std(ver_err, ddof=1)) if ver_err.size else None,
        ver_truth_mean_ug=float(np.mean(ver_truth)) if ver_truth.size else None,
        nav_max_nmi=None if nav is None else nav[0], nav_mean_nmi=None if nav is None else nav[1],
        x_est=[float(v) for v in x_est], err=[float(v) for v in e], err_proj=[float(v) for v in e_proj],
        crlb=[float(v) for v in sd], crlb_presets=w.sd_presets, observable=[int(v) for v in obs.observable_mask()],
        null_dirs=obs.unobservable, null_err=[float(v) for v in null_coef],
        ver_err=[float(v) for v in ver_err], ver_truth=[float(v) for v in ver_truth],
        trace=[a[:2] for a in anytime], nav_curve=None if nav is None else nav[2],  # = trace_on_grid(res.trace)
        # the in-field optimum: meaningless for a turntable fit, which minimises another cost
        f_opt=None if cfg.reference else w.f_opt, anytime=anytime, anytime_s=seconds_on_grid(res.trace),
    )
