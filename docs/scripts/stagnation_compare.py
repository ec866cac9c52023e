"""The stagnation rule on the headline study: its configurations that take the rule, with and without it.

Runs the compare spec's configurations whose solver takes the rule (optcal.studies.trial.STAGNATION; in the compare
spec: cmaes and staged:cmaes), and those named with --also with the rule forced on (the swarms, nevergrad's:
what the rule would do to the solvers that do not take it), twice into two folders, once with the rule and
once without, and prints per
configuration and model × scheme: RMSE/CRLB and RMSE/CRLB with presets with their 95 % bootstrap intervals
(without the rule), the same with it, the evaluations and the solver time summed over the trials, the
reasons the trials ended, and the (run, cost target) pairs met without the rule that are missed with it. The
other configurations take no rule and run exactly as without it (tests/test_study_stagnation.py), so these
rows are the whole difference the rule makes to the study.

    python docs/scripts/stagnation_compare.py [--runs 50] [--out out/stagnation]
    python docs/scripts/stagnation_compare.py --runs 10 --only --also afsa,oafsa,nafsa,pso,ng:TwoPointsDE

docs/performance.md, "Stopping at convergence", shows its output.
"""

from __future__ import annotations

import argparse
import time
from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np

from optcal import solvers
from optcal.studies import anytime, trial
from optcal.studies.execute import run_study
from optcal.studies.metrics import cells, groups
from optcal.studies.spec import load
from optcal.studies.store import Store


def takers(spec) -> tuple:
    """The spec's configurations whose solver takes the stagnation rule."""
    return tuple(c for c in spec.solvers if solvers.get(c.name, **c.options).stops_on_stagnation)


def forced(spec, labels: list[str]) -> tuple:
    """The configurations ``labels`` with the rule forced on: nevergrad's and mealpy's by their option
    ``stop_on_stagnation``, the others by setting their (innermost) solver class's ``stops_on_stagnation``
    in this process (the runs are serial, in this process)."""
    out = []
    for c in spec.solvers:
        if c.label not in labels:
            continue
        if c.name.startswith(("ng:", "mealpy:")):
            out.append(replace(c, options={**c.options, "stop_on_stagnation": True}))
            continue
        s = solvers.get(c.name, **c.options)
        while getattr(s, "inner", None) is not None:
            s = s.inner
        type(s).stops_on_stagnation = True
        out.append(c)
    unknown = sorted(set(labels) - {c.label for c in out})
    if unknown:
        raise SystemExit(f"--also: not configurations of the compare spec: {', '.join(unknown)}")
    return tuple(out)


def run(spec, folder: Path, rule) -> tuple[list[dict], float]:
    """The spec's trials in this process (worker processes would read the module's own rule), with ``rule``."""
    trial.STAGNATION = rule
    t0 = time.perf_counter()
    run_study(spec, folder, executor="serial", progress=False)
    with Store.open_existing(folder) as st:
        return st.rows(), time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--out", default="out/stagnation")
    ap.add_argument("--also", default="", help="comma-separated labels of the compare spec to run with the rule "
                                               "forced on")
    ap.add_argument("--only", action="store_true", help="only the --also configurations")
    args = ap.parse_args()
    base = load("compare").with_runs(args.runs)
    labels = [x for x in args.also.split(",") if x]
    take = tuple(c for c in takers(base) if c.label not in labels)  # before any class is forced
    also = forced(base, labels)
    spec = replace(base, solvers=also + (() if args.only else take))
    rule = trial.STAGNATION
    without, t_without = run(spec, Path(args.out) / "without", None)
    with_rule, t_with = run(spec, Path(args.out) / "with", rule)
    trial.STAGNATION = rule
    print(f"{len(spec.solvers)} configurations with the rule ({', '.join(c.label for c in spec.solvers)}), "
          f"{args.runs} runs; rule: share {rule.share:g}, rtol {rule.rtol:g}; wall {t_without:.0f} s without, "
          f"{t_with:.0f} s with (one process)\n")
    print("| configuration | model, scheme | RMSE/CRLB without [95 % CI] | with | with presets without [95 % CI] "
          "| with | evaluations without → with | solver s without → with | ended by (with) | targets missed |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    ca, cb = cells(groups(without)), cells(groups(with_rule))
    ha, hb = anytime.collect(without), anytime.collect(with_rule)
    for key, ga_list in ca.items():
        for ga in ga_list:
            gb = next(g for g in cb[key] if g.solver == ga.solver)
            ci = anytime.group_ci(ga, base.seed)
            s = ha.solvers.index(ga.solver)
            rows = [i for i, p in enumerate(ha.problems) if p[:2] == key]
            met = np.isfinite(ha.hits["cost"][rows, s])
            missed = int(np.sum(met & ~np.isfinite(hb.hits["cost"][rows, s])))
            reasons = Counter(r["stop_reason"] for r in gb.rows)
            ended = ", ".join(f"{k} {100 * v / len(gb.rows):.0f} %" for k, v in reasons.most_common())
            print(f"| `{ga.solver}` | {key[0]}, {key[1]} | {ga.accuracy:.3f} [{ci['accuracy'][0]:.3f}, "
                  f"{ci['accuracy'][1]:.3f}] | {gb.accuracy:.3f} | {ga.accuracy_presets:.3f} "
                  f"[{ci['accuracy_presets'][0]:.3f}, {ci['accuracy_presets'][1]:.3f}] | {gb.accuracy_presets:.3f} | "
                  f"{int(ga.column('nfev').sum()):,} → {int(gb.column('nfev').sum()):,} | "
                  f"{ga.column('runtime_s').sum():.1f} → {gb.column('runtime_s').sum():.1f} | {ended} | "
                  f"{missed} of {int(met.sum())} |")


if __name__ == "__main__":
    main()
