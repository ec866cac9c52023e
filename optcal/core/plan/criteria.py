"""Design criteria (docs/planning.md, "Criteria"): scalar functions of the observable information F_obs, smaller is
better.

With λ_1 ≤ … ≤ λ_r the eigenvalues of F_obs (natural units, noise included):

- D: (det F_obs)^(−1/r) = exp(−(1/r) Σ log λ_k), the geometric mean of the variances along the principal axes
  (Kiefer 1959; the r-th root makes it a variance, so "within 1 %" is a 1 % change of a variance);
- A: (1/r) tr F_obs⁻¹ = (1/r) Σ 1/λ_k, the mean variance;
- E: 1/λ_1, the variance of the worst-determined combination;
- targets: max_i SD_i / t_i over the parameters given a target t_i (every SD in the parameter's own unit),
  ≤ 1 when every target is met. A maximum is not smooth; optimisation uses the p-norm of the ratios (p = 16,
  then 64 and 256 in the refinement), whose value lies within a factor m^(1/p) of the maximum (m targets), and
  reports the maximum.

A design whose F_obs is singular (relative eigenvalue below RTOL², the observability threshold) scores +inf.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from optcal.core.errors import InputError
from optcal.core.gauge import RTOL
from optcal.core.plan.fisher import InformationModel
from optcal.core.presets import family

CRITERIA = ("D", "A", "E", "targets")
SMOOTH_P = 16

# Units a target may be written in, as multiples of the parameter's own unit (outputs in g: K is 1 per g and a
# relative change of it is in ppm; b in g; angles in rad; K2 in 1/g).
TARGET_UNITS = {"ppm": 1e-6, "ug": 1e-6, "µg": 1e-6, "mg": 1e-3, "g": 1.0, "urad": 1e-6, "µrad": 1e-6,
                "mrad": 1e-3, "rad": 1.0, "arcsec": np.pi / 180 / 3600, "deg": np.pi / 180, "ppm/g": 1e-6}
# Which units fit which parameter family (a bias in ppm is a typo, not a request)
_FAMILY_UNITS = {"K": ("ppm",), "b": ("ug", "µg", "mg", "g"), "S": ("urad", "µrad", "mrad", "rad", "arcsec", "deg"),
                 "K2": ("ppm/g",), "K3": ("ppm/g",)}
_GROUP_ALIASES = {"scale": "K", "bias": "b", "misalignment": "S", "quadratic": "K2", "cubic": "K3"}
_TARGET_RE = re.compile(r"^\s*([A-Za-z0-9_]+)\s*(?:<=|=|≤)\s*([0-9.eE+-]+)\s*([A-Za-zµ/0-9]+)\s*$")


def parse_targets(text: str, names: tuple[str, ...]) -> dict[str, float]:
    """``"scale<=20ppm, bias<=30ug"`` → {parameter: target SD in its own unit}. A key is a parameter
    name (K_x), a family (K, b, S, K2) or a group (scale, bias, misalignment, quadratic)."""
    out: dict[str, float] = {}
    for part in filter(None, (s.strip() for s in str(text).split(","))):
        m = _TARGET_RE.match(part)
        if not m:
            raise InputError(f"target {part!r}: write NAME<=VALUE UNIT, e.g. scale<=20ppm, bias<=30ug, K_x<=10ppm")
        key, value, unit = m.group(1), float(m.group(2)), m.group(3)
        if not (np.isfinite(value) and value > 0):
            raise InputError(f"target {part!r}: the value must be a positive number")
        fam = _GROUP_ALIASES.get(key, key)
        hit = [n for n in names if n == key or family(n) == fam]
        if not hit:
            raise InputError(f"target {part!r}: the model has no parameter or group {key!r}; use scale, bias, "
                             f"misalignment, quadratic or one of {', '.join(names)}")
        for n in hit:
            ok = _FAMILY_UNITS.get(family(n), tuple(TARGET_UNITS))
            if unit not in ok:
                raise InputError(f"target {part!r}: {n} takes a target in {' or '.join(ok)}")
            out[n] = value * TARGET_UNITS[unit]
    if not out:
        raise InputError("no targets given: write e.g. --targets 'scale<=20ppm,bias<=30ug'")
    return out


@dataclass(frozen=True)
class Criterion:
    """A criterion for one information model: ``kind`` in CRITERIA and, for targets, {name: SD}."""

    info: InformationModel
    kind: str = "D"
    targets: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.kind not in CRITERIA:
            raise InputError(f"unknown criterion {self.kind!r}; use one of {', '.join(CRITERIA)}")
        if self.kind == "targets" and not self.targets:
            raise InputError("the targets criterion needs targets, e.g. 'scale<=20ppm,bias<=30ug'")

    @property
    def target_index(self) -> tuple[np.ndarray, np.ndarray]:
        names = self.info.names
        idx = np.array([names.index(n) for n in self.targets], int)
        return idx, np.array([self.targets[n] for n in self.targets], float)

    def of_information(self, F: np.ndarray, smooth: bool | int = False, ridge: float = 0.0) -> np.ndarray:
        """The criterion (S,) of F_obs (S, r, r); ``smooth``: the targets' p-norm instead of the maximum (True:
        p = SMOOTH_P, an int: that p);
        ``ridge`` > 0: of F_obs + ridge·I, a prior that determines every direction (no singularity test), so
        that designs which do not yet determine the model still have an order (Bayesian design)."""
        F = np.asarray(F, float)
        if ridge > 0:
            F = F + ridge * np.eye(F.shape[-1])
        if self.kind == "targets":
            idx, t = self.target_index
            ratio = self.info.sd(F, check=ridge <= 0)[:, idx] / t
            if not smooth:
                return ratio.max(axis=1)
            with np.errstate(over="ignore", invalid="ignore"):
                top = ratio.max(axis=1, keepdims=True)
                pn = SMOOTH_P if smooth is True else int(smooth)
                v = top[:, 0] * np.sum((ratio / top) ** pn, axis=1) ** (1.0 / pn)
            return np.where(np.isfinite(top[:, 0]), v, np.inf)
        lam = np.linalg.eigvalsh(F)
        ok = (lam[:, 0] > RTOL**2 * np.maximum(lam[:, -1], 1e-300)) | (ridge > 0)
        lam = np.where(ok[:, None], lam, 1.0)
        if self.kind == "D":
            v = np.exp(-np.mean(np.log(lam), axis=1))
        elif self.kind == "A":
            v = np.mean(1.0 / lam, axis=1)
        else:
            v = 1.0 / lam[:, 0]
        return np.where(ok, v, np.inf)

    def __call__(self, directions: np.ndarray, smooth: bool | int = False) -> np.ndarray:
        """The criterion (S,) of designs (S, N, 3)."""
        return self.of_information(self.info.information(directions), smooth)

    def label(self) -> str:
        return self.kind if self.kind != "targets" else "targets (max SD/target)"
