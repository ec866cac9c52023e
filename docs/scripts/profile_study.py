"""Where a study's time goes, per solver: evaluation kernel, the solver's own Python, trial set-up.

Runs the trials of a few Monte-Carlo runs of a study spec in this process (serially) and splits each
trial's wall time into
  * kernel: time inside the problem's evaluation (the compiled kernel's entry points, or the NumPy
    residuals and Jacobian where there is no kernel), measured by wrapping them;
  * solver: the rest of the solver's run time (its own Python, NLopt's or SciPy's code, budget and
    best-point book-keeping);
  * set-up and scoring: the rest of the trial (simulation, problem, bound, verification, navigation).
Prints one row per solver configuration (summed over the trials run), as a Markdown table.

    python docs/scripts/profile_study.py compare --runs 2 [--model seed15 --scheme 24]

docs/performance.md shows its output before and after the compiled kernel.
"""

from __future__ import annotations

import argparse
import functools
import time
from collections import defaultdict

from optcal.studies import spec as specs
from optcal.studies.trial import run_trial, trials

SPENT = [0.0]


def timed(fn):
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        t = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            SPENT[0] += time.perf_counter() - t

    return wrapper


def instrument() -> str:
    """Wrap the evaluation entry points; returns which ones were found."""
    from optcal.core.problem import CalibrationProblem

    if not hasattr(CalibrationProblem, "residuals_full_numpy"):
        # the code before the compiled kernel: time the NumPy evaluation instead
        CalibrationProblem.residuals_full = timed(CalibrationProblem.residuals_full)
        CalibrationProblem.jacobian_full = timed(CalibrationProblem.jacobian_full)
        return "numpy residuals_full / jacobian_full"
    from optcal.core.kernels import evaluate

    for name in ("cost_one", "evaluate_batch", "jacobian"):
        setattr(evaluate, name, timed(getattr(evaluate, name)))
    return "compiled kernel (cost_one, evaluate_batch, jacobian)"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("spec")
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--model", default=None)
    ap.add_argument("--scheme", default=None)
    args = ap.parse_args()
    spec = specs.load(args.spec)
    todo = [t for t in trials(spec) if t.run < args.runs and (args.model in (None, t.model))
            and (args.scheme in (None, t.scheme))]
    hooked = instrument()
    run_trial(todo[0])  # warm-up: imports, compiled code loaded
    rows = defaultdict(lambda: defaultdict(float))
    for t in todo:
        SPENT[0] = 0.0
        start = time.perf_counter()
        row = run_trial(t)
        wall = time.perf_counter() - start
        r = rows[t.config.label]
        r["trials"] += 1
        r["wall"] += wall
        r["kernel"] += SPENT[0]
        r["solver"] += (row.get("runtime_s") or 0.0) - SPENT[0]
        r["nfev"] += row.get("nfev") or 0
    total = sum(r["wall"] for r in rows.values())
    print(f"{len(todo)} trials ({args.spec}, runs < {args.runs}); evaluation timed in: {hooked}\n")
    print("| solver | trials | wall s | kernel s | solver Python s | set-up & scoring s | evals/s | share |")
    print("|---|---|---|---|---|---|---|---|")
    for label, r in sorted(rows.items(), key=lambda kv: -kv[1]["wall"]):
        setup = r["wall"] - r["kernel"] - r["solver"]
        rate = r["nfev"] / max(r["kernel"] + r["solver"], 1e-12)
        print(f"| `{label}` | {int(r['trials'])} | {r['wall']:.3f} | {r['kernel']:.3f} | {r['solver']:.3f} | "
              f"{setup:.3f} | {rate:,.0f} | {100 * r['wall'] / total:.1f} % |")
    k = sum(r["kernel"] for r in rows.values())
    s = sum(r["solver"] for r in rows.values())
    print(f"| **all** | {len(todo)} | {total:.2f} | {k:.2f} | {s:.2f} | {total - k - s:.2f} | | 100 % |")


if __name__ == "__main__":
    main()
