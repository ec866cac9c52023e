"""docs/figures/plan_d24.png: the D-optimal 24 hand-held positions for nonlinear12 (plan:D24, in handling
order), with the papers' 24-position scheme as grey crosses.

    .venv/bin/python docs/scripts/plan_figures.py
"""

from pathlib import Path

from optcal.core.plan.figure import plan_figure
from optcal.core.plan.fixtures import handling_order
from optcal.core.schemes import scheme


def main() -> None:
    d = scheme("plan:D24")
    d = d[handling_order(d)]
    fig = plan_figure(d, "plan:D24 (D-optimal for nonlinear12, hand-held), numbered in handling order",
                      reference=scheme("24"), reference_label="the papers' 24-position scheme")
    out = Path(__file__).resolve().parents[1] / "figures" / "plan_d24.png"
    fig.savefig(out, dpi=110)
    print(out)


if __name__ == "__main__":
    main()
