"""The next-best-pose comparison of docs/planning.md §6: 100 simulated sessions per policy, each adding one
position at a time until "enough yet?" says the targets are met, judged as a user would, from the data
(the directions estimated by the closed-form linear fit of the positions recorded so far).

Every session: a navigation-grade truth drawn for nonlinear12 (optcal.core.presets.draw_truth), 10 µg per axis on
each position mean, every pose placed with 3° per axis of error (optcal.core.schemes.tilt), targets scale factors
≤ 20 ppm and biases ≤ 30 µg. Policies: `advised` (optcal plan --recorded: the next best pose for the targets),
`random` (a uniformly random orientation), `habitual` (the 24-position scheme in its order, then the 36's).
Each session draws from numpy Generators seeded (session, policy); at most 60 positions. The "true" check
recomputes the bound at the directions actually realised, to see whether "enough" was said too early.

    .venv/bin/python docs/scripts/plan_nextbest.py            # prints the table, writes docs/figures/plan_nextbest.png
"""

from pathlib import Path

import numpy as np

from optcal.core.data import PositionsData
from optcal.core.model import get_model
from optcal.core.plan.criteria import Criterion, parse_targets
from optcal.core.plan.fisher import InformationModel
from optcal.core.plan.sequential import next_best, progress, recorded_directions
from optcal.core.presets import draw_truth
from optcal.core.schemes import random_orientations, scheme, tilt

SESSIONS = 100
NOISE = 10e-6
PLACEMENT_DEG = 3.0
TARGETS = "scale<=8ppm,bias<=12ug"
MAX_POSITIONS = 60
POLICIES = ("advised", "random", "habitual")
HABIT = np.vstack([scheme("24"), scheme("36")])


def session(k: int, policy: str, crit: Criterion) -> tuple[int, bool]:
    """Positions taken until 'enough', and whether the bound at the realised directions meets the targets."""
    rng = np.random.default_rng([k, POLICIES.index(policy)])
    model = get_model("nonlinear12")
    x = model.from_dict(draw_truth(model, np.random.default_rng(k)))
    realised, outputs = [], []
    est = np.zeros((0, 3))
    for n in range(1, MAX_POSITIONS + 1):
        if policy == "advised":
            want = next_best(crit, est)[0]
        elif policy == "random":
            want = random_orientations(1, rng)[0]
        else:
            want = HABIT[n - 1]
        a = tilt(want[None], PLACEMENT_DEG, rng)[0]
        realised.append(a)
        outputs.append(model.forward(x, a[None])[0, 0] + NOISE * rng.standard_normal(3))
        est = recorded_directions(model, PositionsData(N=np.array(outputs)))
        if progress(crit, est).enough:
            return n, progress(crit, np.array(realised)).enough
    return MAX_POSITIONS + 1, False


def main() -> None:
    info = InformationModel.of("nonlinear12", NOISE)
    crit = Criterion(info, "targets", parse_targets(TARGETS, info.names))
    counts = {p: [] for p in POLICIES}
    honest = {p: [] for p in POLICIES}
    for k in range(SESSIONS):
        for p in POLICIES:
            n, ok = session(k, p, crit)
            counts[p].append(n)
            honest[p].append(ok)
    print(f"{SESSIONS} sessions, nonlinear12, {NOISE * 1e6:g} µg, placement {PLACEMENT_DEG:g}°, targets {TARGETS}")
    print("| policy | mean | median | 10th–90th percentile | max | true bound meets the targets when 'enough' |")
    print("|---|---|---|---|---|---|")
    for p in POLICIES:
        c = np.array(counts[p])
        print(f"| {p} | {c.mean():.1f} | {np.median(c):.0f} | {np.percentile(c, 10):.0f}–{np.percentile(c, 90):.0f} "
              f"| {c.max()} | {100 * np.mean(honest[p]):.0f} % |")
    a, r, h = (np.array(counts[p]) for p in POLICIES)
    print(f"advised fewer than habitual in {100 * np.mean(a < h):.0f} % of sessions, no more in "
          f"{100 * np.mean(a <= h):.0f} %; fewer than random in {100 * np.mean(a < r):.0f} %")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.0, 4.2), layout="constrained")
    ax = fig.add_subplot()
    for p, c in zip(POLICIES, ("tab:blue", "tab:orange", "tab:green")):
        v = np.sort(counts[p])
        ax.step(v, np.arange(1, len(v) + 1) / len(v), where="post", color=c, label=p)
    ax.set_xlabel("positions taken until the targets are met (judged from the data)")
    ax.set_ylabel("share of sessions")
    ax.set_title(f"{SESSIONS} simulated sessions: {TARGETS}, {NOISE * 1e6:g} µg, {PLACEMENT_DEG:g}° placement")
    ax.grid(alpha=0.3)
    ax.legend()
    out = Path(__file__).resolve().parents[1] / "figures" / "plan_nextbest.png"
    fig.savefig(out, dpi=110)
    print(f"figure: {out.relative_to(Path(__file__).resolve().parents[2])}")


if __name__ == "__main__":
    main()
