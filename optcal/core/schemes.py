"""Static position schemes (docs/design.md, "Position schemes"): unit gravity directions in the body frame.

Group x turns about the horizontal x axis: A = (0, sin θ, cos θ); group y: A = (cos θ, 0, sin θ);
group z: A = (sin θ, cos θ, 0). The 24-position scheme uses 45° steps (2020 paper §3.3, 2015 paper §7.1),
the 36-position scheme 30° steps (2020 paper §5.1). Each returns unit vectors of shape (n, 3); multiply by
g_local (in g) for specific force. Planned schemes (docs/planning.md) are named ``plan:D12`` (criterion D, A
or E, N positions, model nonlinear12; ``plan:D12:linear9`` for another model) and resolved here without any
solver: the planner's exchange algorithm and refinement (:func:`optcal.core.plan.design.plan`), deterministic
(seed 0), computed once per process. A path to a CSV scheme file (``optcal plan -o``) is read as a scheme.
The direction primitives live in :mod:`optcal.core.plan.sphere` (below both this module and the planner).
"""

from __future__ import annotations

import numpy as np

from optcal.core.errors import InputError
from optcal.core.plan.sphere import random_orientations, rotation_groups, six_position, tilt

__all__ = ["rotation_groups", "six_position", "random_orientations", "tilt", "scheme", "planned",
           "MAX_RANDOM_POSITIONS"]


# A calibration uses tens of positions; a million already takes 100 MB per array of outputs and samples.
MAX_RANDOM_POSITIONS = 1_000_000


PLAN_MAX_POSITIONS = 200


def planned(spec: str) -> np.ndarray:
    """The directions of ``plan:<D|A|E><N>[:<model>]`` (hand-held, nominal parameters, seed 0)."""
    parts = spec.split(":")
    body = parts[1] if len(parts) > 1 else ""
    model = parts[2] if len(parts) > 2 else "nonlinear12"
    kind, digits = body[:1], body[1:]
    if len(parts) > 3 or kind not in ("D", "A", "E") or not digits.isdigit():
        raise InputError(f"scheme {spec!r}: a planned scheme is plan:<D|A|E><N>[:<model>], e.g. plan:D12 or "
                         "plan:A18:seed15")
    n = int(digits)
    if n > PLAN_MAX_POSITIONS:
        raise InputError(f"scheme {spec!r}: plan at most {PLAN_MAX_POSITIONS} positions by name; use optcal plan "
                         "for more")
    from optcal.core.plan.design import planned_directions

    return planned_directions(kind, n, model)


def scheme(spec: str | int, rng: np.random.Generator | None = None) -> np.ndarray:
    """Directions for a scheme given as ``6``, ``24``, ``36``, ``random:N``, ``plan:D12`` or a scheme file."""
    spec = str(spec).strip()
    if spec.startswith("plan:"):
        return planned(spec)
    if spec.lower().endswith(".csv"):
        from optcal.core.plan.schemefile import read_scheme

        return read_scheme(spec)
    if spec == "6":
        return six_position()
    if spec == "24":
        return rotation_groups(45.0)
    if spec == "36":
        return rotation_groups(30.0)
    if spec.startswith("random:"):
        try:
            n = int(spec.split(":", 1)[1])
        except ValueError:
            n = 0
        if n < 1:
            raise InputError(f"scheme {spec!r}: give the number of orientations, e.g. random:30")
        if n > MAX_RANDOM_POSITIONS:
            raise InputError(f"scheme {spec!r}: {n:,} orientations is more than optcal handles "
                             f"({MAX_RANDOM_POSITIONS:,}); a calibration needs tens, e.g. random:30")
        return random_orientations(n, rng if rng is not None else np.random.default_rng(0))
    raise InputError(f"unknown scheme {spec!r}; use 6, 24, 36, random:N, plan:D12 (planned) or a scheme file "
                     "(.csv, from optcal plan -o)")
