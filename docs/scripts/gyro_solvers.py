"""The registry's solvers on the gyroscope problem (issue #23): simulated recordings with known truth, the
table of docs/gyroscope.md.

Each trial: a truth drawn from optcal.gyro.simulate.TRUTH_SPREAD (1000 counts per rad/s, 1 % scale spread),
the 24- or 36-position scheme at 100 Hz with 3 s rests and 2 s turns, white rate noise 1e-3 rad/s per
sample, 1 mg accelerometer noise; the model gyro12 (bias fitted), started from the problem's centre
(nominal scale, rests' mean bias). Every solver gets the same problem object through the registry,
unchanged. Scores: RMSE/CRLB (the RMS over the 12 parameters of the RMS over runs of error over the
Cramér-Rao SD at the truth), the share of runs within 1 χ² unit of scipy-lm's optimum, median solver time
and evaluations. A second table adds bias instability (a bias random walk of 1e-5 rad/s/√s) and fits it
with scipy-lm, the bias fitted as a constant (gyro12) or taken from the rests (gyro9), scored against each
model's white-noise bound.

Reproduce (about 5 minutes on two cores):

    .venv/bin/python docs/scripts/gyro_solvers.py [RUNS]       # default 5 runs per scheme
"""

from __future__ import annotations

import sys

import numpy as np

LOCAL = ["scipy-lm", "scipy-trf", "nlopt-slsqp", "nlopt-lbfgs", "nlopt-bobyqa", "nlopt-neldermead", "nlopt-sbplx",
         "staged:scipy-lm"]
SEARCH = ["cmaes", "bsas", "bas", "pso", "nafsa", "afsa", "oafsa", "scipy-de", "nlopt-crs2", "staged:bsas"]
BUDGET_LOCAL, BUDGET_SEARCH = 2000, 5000


def trial(scheme: int, run: int, walk: float = 0.0, bias: str = "fit"):
    from optcal import analysis
    from optcal.gyro import GyroProblem, draw_truth, get_gyro_model, simulate_imu

    rng = np.random.default_rng([23, scheme, run])
    model = get_gyro_model(False)
    x = draw_truth(model, rng, 1000.0)
    sim = simulate_imu(model, x, poses=scheme, bias_walk=walk, rng=rng)
    p = GyroProblem(sim.data, scale=1000.0, bias=bias)
    x = p.from_sensor(x)  # the truth in the problem's coordinates (bias beyond the offset, or none)
    sd, _ = analysis.crlb(p, x, noise_g=1.0)
    return p, x, sd


def main(runs: int = 5) -> int:
    import solvers

    rows: dict[str, dict] = {}
    for scheme in (24, 36):
        for run in range(runs):
            p, x, sd = trial(scheme, run)
            ref = solvers.get("scipy-lm").solve(p, rng=run, budget=BUDGET_LOCAL)
            for name in LOCAL + SEARCH:
                budget = BUDGET_LOCAL if name in LOCAL else BUDGET_SEARCH
                res = solvers.get(name).solve(p, rng=run, budget=budget)
                r = rows.setdefault(name, {s: {"z": [], "ok": [], "t": [], "nfev": []} for s in (24, 36)})[scheme]
                r["z"].append((res.x_full - x) / sd)
                r["ok"].append(res.fun - ref.fun < 1.0)
                r["t"].append(res.runtime_s)
                r["nfev"].append(res.nfev)
    print(f"| solver | 24 positions | 36 positions | runtime s | evaluations |  ({runs} runs per scheme)")
    print("|---|---|---|---|---|")
    for name, r in rows.items():
        cells = []
        for s in (24, 36):
            z = np.array(r[s]["z"])
            score = np.sqrt(np.mean(np.mean(z**2, axis=0)))
            cells.append(f"{score:.2f} ({100 * np.mean(r[s]['ok']):.0f} %)")
        t = np.median(r[24]["t"] + r[36]["t"])
        n = int(np.median(r[24]["nfev"] + r[36]["nfev"]))
        print(f"| `{name}` | {cells[0]} | {cells[1]} | {t:.3g} | {n:,} |")
    print("\n| bias (scipy-lm, bias walk 1e-5 rad/s/√s) | 24 positions | 36 positions | χ²/dof |")
    print("|---|---|---|---|")
    for bias in ("fit", "rests"):
        cells, chi = [], []
        for scheme in (24, 36):
            Z = []
            for run in range(runs):
                p, x, sd = trial(scheme, run, 1e-5, bias)
                res = solvers.get("scipy-lm").solve(p, rng=run)
                Z.append((res.x_full - x) / sd)
                chi.append(res.fun / (p.n_residuals - p.model.n_params))
            cells.append(f"{np.sqrt(np.mean(np.array(Z) ** 2)):.2f}")
        print(f"| {bias} ({'gyro12' if bias == 'fit' else 'gyro9'}) | {cells[0]} | {cells[1]} | {np.mean(chi):.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1]) if len(sys.argv) > 1 else 5))
