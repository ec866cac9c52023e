"""CI tracking: run ``studies/specs/ci.toml`` and check its summary against the committed tolerances
(``studies/ci_tolerances.toml``). Accuracy (RMSE/CRLB), success rate and verification error fail when they
regress past their tolerance; run time is reported, never checked.

``python -m studies.ci [--out DIR] [--propose]`` runs the study, prints each metric beside its tolerance
and, with ``--propose``, tolerances for the values just measured (accuracy and verification × 1.25 and
× 1.10, success rate less two runs' worth), to paste into the tolerance file after a deliberate change.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

from .execute import run_study
from .metrics import groups
from .spec import load
from .store import Store

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

TOLERANCES = Path(__file__).parent / "ci_tolerances.toml"
CHECKS = (("accuracy", "max_accuracy", "<="), ("success_rate", "min_success_rate", ">="),
          ("ver_mean_ug", "max_ver_mean_ug", "<="))


def load_tolerances(path: Path = TOLERANCES) -> dict:
    return tomllib.loads(Path(path).read_text())["solvers"]


def run_ci(folder: str | Path) -> tuple[list[dict], float]:
    """Run the CI study into ``folder``; its per-solver summaries and the wall time."""
    s = run_study(load("ci"), folder, progress=False)
    with Store.open_existing(folder) as st:
        return [g.summary() for g in groups(st.rows())], s.wall_s


def check(summary: list[dict], tolerances: dict) -> list[str]:
    """Every regression past a tolerance, one line each (empty: all within)."""
    out = []
    by = {s["solver"]: s for s in summary}
    for name in sorted(set(by) ^ set(tolerances)):
        where = "the CI study has no tolerances for" if name in by else "the tolerances name a solver the study lacks:"
        out.append(f"{where} {name}")
    for name in sorted(set(by) & set(tolerances)):
        for metric, key, op in CHECKS:
            v, lim = by[name][metric], tolerances[name][key]
            ok = math.isfinite(v) and (v <= lim if op == "<=" else v >= lim)
            if not ok:
                out.append(f"{name}: {metric} = {v:.4g}, tolerance {op} {lim:.4g}")
    return out


def propose(summary: list[dict], runs: int) -> str:
    lines = []
    for s in summary:
        lines += [f'[solvers."{s["solver"]}"]',
                  f"max_accuracy = {math.ceil(s['accuracy'] * 1.25 * 100) / 100:.2f}",
                  f"min_success_rate = {max(0.0, math.floor((s['success_rate'] - 2 / runs) * 100) / 100):.2f}",
                  f"max_ver_mean_ug = {math.ceil(s['ver_mean_ug'] * 1.10 * 10) / 10:.1f}", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m studies.ci", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", help="study folder (default: a temporary one)")
    ap.add_argument("--propose", action="store_true", help="print tolerances for the measured values")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        summary, wall = run_ci(a.out or tmp)
    tol = load_tolerances() if TOLERANCES.is_file() else {}
    for s in summary:
        t = tol.get(s["solver"], {})
        print(f"{s['solver']:>16}: " + ", ".join(f"{m} {s[m]:.4g} ({op} {t.get(k, float('nan')):.4g})"
                                                  for m, k, op in CHECKS)
              + f", median runtime {s['runtime_median_s']:.3f} s")
    print(f"wall time {wall:.1f} s (reported, not checked)")
    if a.propose:
        print(propose(summary, load("ci").runs))
    bad = check(summary, tol)
    for b in bad:
        print("REGRESSION:", b)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
