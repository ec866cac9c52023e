"""bas, bsas and pso: the 2020 paper's BSAS-versus-BAS claim (its Figs. 5 and 6) and the solvers' contract.

The claim is measured on the paper's setting: ``seed15`` with manufacturer presets (truth
``PAPER_TRUTH``; the search box is the presets' default half-widths), 24 positions, 10 µg noise, 50 runs,
each with its own data seed and solver seed from one ``SeedSequence``, and the same evaluation budget
for both solvers. Each run's least-squares optimum in the box (scipy-trf) is computed too, so the spread
of the final costs can be read against the spread that the noise alone gives the optimum.

Budget: 601 evaluations per run. BAS's step shrinks by 0.95 per iteration, so by then (200 iterations)
it has all but stopped moving: its best cost after 601 evaluations is within 1e-3 of the one after 1801
(``test_bas_has_stopped_improving_by_the_claim_budget``); more budget would only help BSAS. Both use
their defaults δ0 = d0 = 0.03 in the unit box, the best of 0.01, 0.02, 0.03, 0.05, 0.1 for BAS here
(median final cost over these 50 runs: 1.8e-8, 5.3e-9, 4.9e-9, 7.6e-9, 2.5e-8). BSAS runs with m = 2
beetles (the toolbox default k = 2, one of the values of the paper's Fig. 3), so the budget gives it
100 iterations. Run with ``-s`` to see the measured numbers.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from optcal import solvers
from optcal.core.errors import InputError
from optcal.core.presets import PAPER_TRUTH, manufacturer_presets
from optcal.core.problem import CalibrationProblem
from optcal.core.simulate import simulate

RUNS = 50
CLAIM_BUDGET = 601
CLAIM_M = 2
CLAIM_SEED = 2020

# Small configurations for the contract tests, and what one run of each evaluates when nothing binds.
SMALL = {
    "bas": ({"iterations": 20}, 1 + 3 * 20),
    "bsas": ({"m": 4, "iterations": 10}, 1 + 3 * 4 * 10),
    "pso": ({"n_particles": 8, "iterations": 10}, 8 * 11),
}


def paper_problem(data_seed, cls=CalibrationProblem) -> CalibrationProblem:
    """The 2020 paper's simulation setting (§4.1) for one data seed."""
    rng = np.random.default_rng(data_seed)
    presets = manufacturer_presets(PAPER_TRUTH, rng)
    sim = simulate("seed15", PAPER_TRUTH, rng, scheme="24", noise_g=10e-6)
    return cls("seed15", sim.data, presets=presets)


@functools.cache
def paper_runs() -> list[tuple[CalibrationProblem, np.random.SeedSequence, float]]:
    """(problem, solver seed, least-squares optimum cost in the box) of each of the 50 runs."""
    out = []
    for child in np.random.SeedSequence(CLAIM_SEED).spawn(RUNS):
        data_seed, solver_seed = child.spawn(2)
        problem = paper_problem(data_seed)
        f_opt = solvers.get("scipy-trf").solve(problem, budget=200, rng=0).fun
        out.append((problem, solver_seed, f_opt))
    return out


def run_all(name: str, **options) -> tuple[np.ndarray, np.ndarray]:
    """Final cost and evaluations of ``name`` on every run, same budget, the run's own solver seed."""
    fun, nfev = [], []
    for problem, seed, _ in paper_runs():
        res = solvers.get(name, **options).solve(problem, budget=CLAIM_BUDGET, rng=np.random.default_rng(seed))
        fun.append(res.fun)
        nfev.append(res.nfev)
    return np.array(fun), np.array(nfev)


def spread(f: np.ndarray) -> dict[str, float]:
    f_opt = np.array([r[2] for r in paper_runs()])
    q1, q3 = np.percentile(f, [25, 75])
    return {"median": float(np.median(f)), "min": float(f.min()), "max": float(f.max()), "iqr": float(q3 - q1),
            "range": float(f.max() - f.min()), "sd_log10": float(np.std(np.log10(f))),
            "median_over_opt": float(np.median(f / f_opt)), "sd_log10_over_opt": float(np.std(np.log10(f / f_opt)))}


def report(title: str, stats: dict[str, dict[str, float]]) -> None:
    f_opt = np.array([r[2] for r in paper_runs()])
    print(f"\n{title}: {RUNS} runs, {CLAIM_BUDGET} evaluations each")
    print(f"  least-squares optimum per run: median {np.median(f_opt):.3g}, min {f_opt.min():.3g}, "
          f"max {f_opt.max():.3g}, SD(log10) {np.std(np.log10(f_opt)):.3f}")
    for name, s in stats.items():
        print(f"  {name:12s} final cost median {s['median']:.3g}  min {s['min']:.3g}  max {s['max']:.3g}  "
              f"IQR {s['iqr']:.3g}  SD(log10) {s['sd_log10']:.3f}  | cost/optimum: median "
              f"{s['median_over_opt']:.3g}, SD(log10) {s['sd_log10_over_opt']:.3f}")


# -- the 2020 paper's claim ---------------------------------------------------------------------------
def test_bsas_ends_lower_and_spreads_less_than_bas_on_the_paper_setting():
    """Figs. 5 and 6 of the 2020 paper: over 50 runs BSAS's final costs are lower and far less scattered
    than BAS's. Joint search of all 15 parameters in the unit box, the same budget for both."""
    f_bas, n_bas = run_all("bas", iterations=(CLAIM_BUDGET - 1) // 3)
    f_bsas, n_bsas = run_all("bsas", m=CLAIM_M, iterations=10**6)
    bas, bsas = spread(f_bas), spread(f_bsas)
    report("joint search, seed15", {"bas": bas, f"bsas (m={CLAIM_M})": bsas})
    assert (n_bas == CLAIM_BUDGET).all() and (n_bsas == CLAIM_BUDGET).all()  # same evaluations, all used
    # Measured: median 4.9e-9 vs 2.1e-9 (2.4x), IQR 5.7e-9 vs 7.5e-10 (7.6x), range 1.6e-8 vs 2.7e-9
    # (5.8x), SD of log10(cost) 0.26 vs 0.13.
    assert bas["median"] > 1.6 * bsas["median"]
    assert bas["iqr"] > 4 * bsas["iqr"]
    assert bas["range"] > 3.5 * bsas["range"]
    assert bsas["sd_log10"] < 0.65 * bas["sd_log10"]
    # Against each run's least-squares optimum (which the noise alone scatters by 0.19 in log10), BSAS
    # ends at 1.8 times it (median) and BAS at 4.7 times, with SD(log10) 0.14 vs 0.29.
    assert bsas["sd_log10_over_opt"] < 0.65 * bas["sd_log10_over_opt"]
    assert bsas["median_over_opt"] < 3.0 < bas["median_over_opt"]


def test_staged_bsas_against_staged_bas_on_the_paper_setting():
    """The same claim through the papers' four-stage procedure (``staged:``, its default options: equal
    shares of the budget, up to 5 cycles). The stages (3 to 6 parameters each) are easier for BAS than
    the joint search, so the contrast is smaller, but it holds: BSAS ends lower and scatters less."""
    f_bas, n_bas = run_all("staged:bas")
    f_bsas, n_bsas = run_all("staged:bsas", **{"inner.m": CLAIM_M})
    bas, bsas = spread(f_bas), spread(f_bsas)
    report("four stages (staged:), seed15", {"staged:bas": bas, f"staged:bsas (m={CLAIM_M})": bsas})
    print(f"  evaluations used: staged:bas mean {n_bas.mean():.0f}, staged:bsas mean {n_bsas.mean():.0f}")
    # The wrapper ends a run early when a cycle stops improving (its rtol), so not every run uses it all.
    assert (n_bas <= CLAIM_BUDGET).all() and (n_bsas <= CLAIM_BUDGET).all()
    # Measured: median 4.1e-9 vs 2.3e-9 (1.8x), IQR 2.0e-9 vs 8.0e-10 (2.5x), range 7.8e-9 vs 3.4e-9
    # (2.3x), SD of log10(cost) 0.17 vs 0.12.
    assert bas["median"] > 1.4 * bsas["median"]
    assert bas["iqr"] > 1.8 * bsas["iqr"]
    assert bas["range"] > 1.6 * bsas["range"]
    assert bsas["sd_log10"] < 0.9 * bas["sd_log10"]


def test_bas_has_stopped_improving_by_the_claim_budget():
    """The claim's budget does not starve BAS: with three times the iterations its best cost changes by
    less than 1e-3 (relative) after the claim's 601 evaluations."""
    for problem, seed, _ in paper_runs()[:2]:
        res = solvers.get("bas", iterations=600).solve(problem, budget=1801, rng=np.random.default_rng(seed))
        trace = np.array(res.trace)
        at_claim = trace[trace[:, 0] <= CLAIM_BUDGET, 1].min()
        assert res.nfev == 1801
        assert at_claim <= res.fun * (1 + 1e-3)


# -- contract ---------------------------------------------------------------------------------------
class Spy(CalibrationProblem):
    """Records every batch passed to cost_batch (views are shallow copies, so they share the list)."""

    def cost_batch(self, X):
        self.calls.append(np.array(X, float))
        return super().cost_batch(X)


class Holes(CalibrationProblem):
    """NaN costs where z_0 > 0.2 and inf costs where z_1 < -0.2 (z: unit-box coordinates); NaN everywhere
    with ``everywhere``."""

    everywhere = False

    def residuals_full(self, X_full):
        R = super().residuals_full(X_full)
        z = (np.atleast_2d(X_full) - self.centre) / self.halfwidth
        R[z[:, 0] > 0.2] = np.nan
        R[z[:, 1] < -0.2] = np.inf
        if self.everywhere:
            R[:] = np.nan
        return R


def true_cost(problem: CalibrationProblem, Z) -> np.ndarray:
    """Costs of unit-box points of ``problem`` without touching its evaluation counter."""
    zp = problem.normalised()
    return np.sum(zp.residuals_full(zp.to_full(Z)) ** 2, axis=1)


@functools.cache
def unit_problem() -> CalibrationProblem:
    return paper_problem(7)


NAMES = sorted(SMALL)


@pytest.mark.parametrize("name", NAMES)
def test_budget_is_used_exactly_when_it_binds(name):
    options, needed = SMALL[name]
    problem = unit_problem()
    for budget in (1, 2, 37, needed - 1):
        res = solvers.get(name, **options).solve(problem, budget=budget, rng=3)
        assert res.nfev == budget and res.success and np.isfinite(res.fun)
        if budget < 40:  # stopped by the budget (at needed - 1 the last call may just lose its last candidate)
            assert res.status == 1
    res = solvers.get(name, **options).solve(problem, budget=10 * needed, rng=3)
    assert res.nfev == needed and res.status == 0 and res.nit == options["iterations"]
    # Without a budget a solver uses exactly what its iterations need.
    assert solvers.get(name, **options).solve(problem, rng=3).nfev == needed


@pytest.mark.parametrize("name", NAMES)
def test_same_seed_same_result_and_different_seeds_differ(name):
    # PSO needs a few more iterations than SMALL gives before any particle beats the start.
    options = {"n_particles": 10, "iterations": 40} if name == "pso" else SMALL[name][0]
    problem = unit_problem()
    a, b, c = (solvers.get(name, **options).solve(problem, budget=500, rng=s) for s in (11, 11, 12))
    np.testing.assert_array_equal(a.x, b.x)
    assert a.fun == b.fun and a.nfev == b.nfev
    assert a.fun != c.fun and not np.array_equal(a.x, c.x)


@pytest.mark.parametrize("name", NAMES)
def test_each_iteration_makes_the_batched_calls(name):
    options, _ = SMALL[name]
    problem = paper_problem(7, Spy)
    problem.calls = []
    nits = []
    res = solvers.get(name, **options).solve(problem, budget=10_000, rng=5,
                                             callback=lambda info: nits.append(info["nit"]))
    sizes = [len(X) for X in problem.calls]
    T = options["iterations"]
    if name == "bas":
        assert sizes == [1] + [2, 1] * T
    elif name == "bsas":
        m = options["m"]
        assert sizes == [1] + [2 * m, m] * T
    else:
        assert sizes == [options["n_particles"]] * (T + 1)
    assert nits == list(range(1, T + 1)) and res.nit == T
    # Every point searched lies in the unit box (the search works in normalised coordinates).
    assert all(np.abs(X).max() <= 1.0 for X in problem.calls)


@pytest.mark.parametrize("name", NAMES)
def test_nan_and_inf_costs_are_survived(name):
    options, _ = SMALL[name]
    problem = paper_problem(7, Holes)
    res = solvers.get(name, **options).solve(problem, budget=2000, rng=2)
    assert res.success and np.isfinite(res.fun)
    z = problem.normalised().from_full(res.x_full)
    assert z[0] <= 0.2 and z[1] >= -0.2  # the best point is a finite one
    assert res.fun <= true_cost(problem, np.zeros((1, problem.n)))[0]

    problem.everywhere = True
    res = solvers.get(name, **options).solve(problem, budget=300, rng=2)
    assert not res.success and "no finite cost" in res.message and not np.isfinite(res.fun)


@pytest.mark.parametrize("name", NAMES)
def test_works_on_a_restricted_view_as_the_stages_do(name):
    problem = unit_problem()
    at = problem.centre.copy()
    view = problem.restrict(["bias"], at=at)
    options, _ = SMALL[name]
    start = np.sum(problem.residuals_full(at) ** 2)
    res = solvers.get(name, **options).solve(view, budget=3000, rng=4)
    assert res.x.shape == (3,) and res.fun < start
    others = np.setdiff1d(np.arange(problem.model.n_params), problem.model.groups()["bias"])
    np.testing.assert_array_equal(res.x_full[others], at[others])


@pytest.mark.parametrize(
    ("name", "options", "match"),
    [
        ("bsas", {"beetles": 3}, "unknown option"),
        ("bas", {"alpha": 1.0}, "unknown option"),
        ("pso", {"inertia": 0.5}, "unknown option"),
        ("bsas", {"m": -2}, "option m=-2 is invalid"),
        ("bsas", {"m": 0}, "option m=0 is invalid"),
        ("bsas", {"m": "-3"}, "option m=-3 is invalid"),
        ("bsas", {"p_pos": 1.5}, "option p_pos=1.5 is invalid"),
        ("bsas", {"p_st": -0.1}, "option p_st=-0.1 is invalid"),
        ("bsas", {"c": -1.0}, "option c=-1.0 is invalid"),
        ("bsas", {"m": 2.5}, "must be int"),
        ("bas", {"eta_step": 1.5}, "option eta_step=1.5 is invalid"),
        ("bas", {"step_init": 0.0}, "option step_init=0.0 is invalid"),
        ("pso", {"n_particles": 1}, "option n_particles=1 is invalid"),
        ("pso", {"v_clamp": 0.0}, "option v_clamp=0.0 is invalid"),
        ("pso", {"init": "latin"}, "choose one of start, uniform"),
        ("bsas", {"eta": 0.0}, "option eta=0.0 is invalid"),
        ("bsas", {"eta_d": 0.9}, "unknown option"),
    ],
)
def test_bad_options_are_refused(name, options, match):
    with pytest.raises(InputError, match=match):
        solvers.get(name, **options)


# -- algorithm details ------------------------------------------------------------------------------
def test_bas_decays_antenna_and_step_as_in_the_paper():
    T = 30
    res = solvers.get("bas", iterations=T, d_init=0.3, step_init=0.2).solve(unit_problem(), rng=0)
    assert res.extra["step"] == pytest.approx(0.2 * 0.95**T, rel=1e-12)
    # d = 0.95·d + 0.01 from 0.3: its fixed point is 0.2.
    assert res.extra["d"] == pytest.approx(0.2 + (0.3 - 0.2) * 0.95**T, rel=1e-12)


def test_bas_probes_at_plus_minus_d_and_always_moves():
    problem = paper_problem(7, Spy)
    problem.calls = []
    solvers.get("bas", iterations=5, d_init=0.05, step_init=0.04, d_floor=0.0, eta_d=1.0, eta_step=1.0).solve(
        problem, rng=1)
    z = problem.calls[0][0]
    for t in range(5):
        antennae, move = problem.calls[1 + 2 * t], problem.calls[2 + 2 * t][0]
        np.testing.assert_allclose(antennae.mean(axis=0), z, atol=1e-15)
        assert np.linalg.norm(antennae[0] - antennae[1]) == pytest.approx(2 * 0.05)
        assert np.linalg.norm(move - z) == pytest.approx(0.04)  # a step of δ, better or not
        z = move


def test_bsas_moves_only_on_improvement():
    """Elitism: x moves exactly when a candidate beats the best cost so far, and then to such a candidate."""
    problem = paper_problem(7, Spy)
    problem.calls = []
    m = 3
    solvers.get("bsas", m=m, iterations=40, step_init=0.02, d_init=0.02).solve(problem, rng=6)
    z, f_best = problem.calls[0][0], true_cost(problem, problem.calls[0])[0]
    moves_seen = 0
    for t in range(40):
        antennae, moves = problem.calls[1 + 2 * t], problem.calls[2 + 2 * t]
        np.testing.assert_allclose((antennae[:m] + antennae[m:]) / 2, np.tile(z, (m, 1)), atol=1e-15)
        f_moves = true_cost(problem, moves)
        if t + 1 < 40:  # where the next antennae are centred tells where x went
            nxt = problem.calls[3 + 2 * t]
            z_next = ((nxt[:m] + nxt[m:]) / 2).mean(axis=0)
        else:
            break
        if f_moves.min() < f_best:
            i = int(np.argmin(np.linalg.norm(moves - z_next, axis=1)))
            assert np.linalg.norm(moves[i] - z_next) < 1e-14 and f_moves[i] < f_best
            z, f_best = moves[i], f_moves[i]
            moves_seen += 1
        else:
            assert np.linalg.norm(z_next - z) < 1e-14
    assert moves_seen >= 3


def test_bsas_tuned_variant_ties_antenna_to_step():
    problem = unit_problem()
    tuned = solvers.get("bsas", m=3, iterations=60, c=4.0).solve(problem, rng=0)
    assert tuned.extra["d"] == pytest.approx(tuned.extra["step"] / 4.0, rel=1e-12)
    assert tuned.extra["step"] < 0.1  # the step did shrink, so d followed it
    plain = solvers.get("bsas", m=3, iterations=60).solve(problem, rng=0)
    assert plain.extra["d"] != pytest.approx(plain.extra["step"] / 4.0)


def test_bsas_stops_when_the_step_falls_below_its_tolerance():
    res = solvers.get("bsas", m=2, iterations=10_000, step_tol=0.05).solve(unit_problem(), budget=100_000, rng=0)
    assert res.status == 0 and "below step_tol" in res.message
    assert res.extra["step"] < 0.05 and res.nit < 10_000 and res.nfev == 1 + 6 * res.nit


def test_pso_uniform_init_leaves_the_start_out():
    problem = paper_problem(7, Spy)
    problem.calls = []
    solvers.get("pso", n_particles=6, iterations=1, init="uniform").solve(problem, rng=9)
    assert np.abs(problem.calls[0]).min(axis=1).max() > 0  # no particle at z = 0
    assert np.abs(problem.calls[0]).max() <= 1.0


def test_pso_starts_from_x0_and_clamps_velocity():
    problem = paper_problem(7, Spy)
    problem.calls = []
    n_p, T, clamp = 6, 8, 0.01
    res = solvers.get("pso", n_particles=n_p, iterations=T, v_clamp=clamp).solve(problem, rng=9)
    X = np.array(problem.calls)  # (T + 1, n_p, n)
    np.testing.assert_array_equal(X[0, 0], problem.normalised().from_full(problem.centre))
    assert np.abs(np.diff(X, axis=0)).max() <= 2 * clamp + 1e-15
    assert res.fun <= true_cost(problem, X[0, :1])[0]


def test_a_budget_stop_reports_the_iterations_completed():
    """nit of a run that the budget ends is the iterations done, not 0: PSO with 10 particles evaluates
    10 at the start and 10 per iteration: 60 evaluations are 5 iterations; with 65 a sixth iteration
    runs on the 5 candidates the budget still allows."""
    for budget, nit in ((60, 5), (65, 6)):
        res = solvers.get("pso", n_particles=10, iterations=100).solve(unit_problem(), budget=budget, rng=1)
        assert res.status == 1 and res.nfev == budget and res.nit == nit
