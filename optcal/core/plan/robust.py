"""Robustness to placement (docs/planning.md, "Robust to placement"): a hand places a sensor degrees off the planned
pose.

Reference-free calibration never needs the true directions, but the information comes from them: a design
is scored by its criterion over M placements, each direction rotated by a random small rotation of
σ per axis (:func:`optcal.core.schemes.tilt`, the simulator's placement model), all M·N directions in one
batched call. A design is *fragile* when its criterion gets worse than planned by more than FRAGILE
(relative) in more than 5 % of placements (the 95th percentile), or, for targets, when a placement that
misses a target is more likely than 5 % although the plan meets them all.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optcal.core.errors import InputError
from optcal.core.plan.criteria import Criterion
from optcal.core.plan.sphere import tilt

FRAGILE = 0.10
DRAWS = 200


@dataclass(frozen=True)
class PlacementScore:
    sigma_deg: float
    draws: int
    planned: float  # the criterion at the planned directions
    mean: float  # its mean over placements
    p95: float  # its 95th percentile
    p_miss: float | None  # targets: share of placements missing a target
    fragile: bool

    def to_dict(self) -> dict:
        return {"placement_sd_deg": self.sigma_deg, "draws": self.draws, "planned": self.planned,
                "expected": self.mean, "p95": self.p95, "share_missing_targets": self.p_miss,
                "fragile": self.fragile}


def placement_score(crit: Criterion, directions: np.ndarray, sigma_deg: float, rng: np.random.Generator,
                    draws: int = DRAWS) -> PlacementScore:
    if not (np.isfinite(sigma_deg) and 0 <= sigma_deg <= 45):
        raise InputError(f"`placement_deg` = {sigma_deg!r}: give the placement error SD in degrees, 0 to 45 "
                         "(e.g. 3 for hand placement)")
    d = np.asarray(directions, float)
    planned = float(crit(d[None])[0])
    placed = tilt(np.tile(d, (draws, 1)), sigma_deg, rng).reshape(draws, len(d), 3)
    v = crit(placed)
    # "higher": no interpolation, so a placement that loses the model (+inf) gives +inf, not NaN
    mean, p95 = float(np.mean(v)), float(np.quantile(v, 0.95, method="higher"))
    p_miss = None
    if crit.kind == "targets":
        p_miss = float(np.mean(v > 1.0))
        fragile = planned <= 1.0 and p_miss > 0.05
    else:
        fragile = not p95 <= (1 + FRAGILE) * planned
    return PlacementScore(float(sigma_deg), draws, planned, mean, p95, p_miss, bool(fragile))
