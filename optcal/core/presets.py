"""Truth values and presets for simulation, and the presets file.

The 2020 paper's Table 1 (its simulation truth) and Table 2 did not survive in the stored text copy, so
the values below are optcal's own choice for a navigation-grade accelerometer whose output is in g
(scale factor near 1): scale-factor errors of a few hundred ppm, biases of a few hundred µg,
installation angles of tens of arcseconds and second-order coefficients of tens of µg/g². The
manufacturer's calibration that the paper uses as presets (§4.1) is modelled as the truth plus errors
about ten times the Cramér-Rao spread of a 24-position fit.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from optcal.core.errors import InputError
from optcal.core.jsonfile import read_json_object
from optcal.core.model import TERMS, Model, get_model

# One-sigma spread of each parameter family of a navigation-grade sensor, output in g (K ≈ 1).
NAV_GRADE_SPREAD = {
    "K": 300e-6, "b": 300e-6, "S": 100e-6, "K2": 20e-6, "K3": 5e-6, "kappa": 20e-6, "c": 20e-6,
    "beta": 5e-6, "gamma": 20e-6, "d": 1e-8,
}

# Default half-widths of a normalised search box around presets, per parameter family, relative to
# the scale factor's magnitude where the family is in output units (K, K2, K3).
BOX_HALFWIDTH = {
    "K": 2e-3, "b": 2e-3, "S": 1e-3, "K2": 2e-4, "K3": 1e-4, "kappa": 2e-4, "c": 2e-4,
    "beta": 5e-5, "gamma": 2e-4, "d": 1e-7,
}

# A fixed seed15 truth in the spirit of the 2020 paper's Table 1 (values chosen by optcal, see above).
PAPER_TRUTH = {
    "K_x": 1.000250, "K_y": 0.999820, "K_z": 1.000410,
    "b_x": 2.5e-4, "b_y": -1.8e-4, "b_z": 3.2e-4,
    "S_xz": 1.2e-4, "S_xy": -0.8e-4, "S_yz": 0.9e-4, "S_yx": 1.5e-4, "S_zy": -1.1e-4, "S_zx": 0.7e-4,
    "K2_x": 2.0e-5, "K2_y": -1.5e-5, "K2_z": 1.0e-5,
}


def family(name: str) -> str:
    return name.split("_", 1)[0]


def draw_truth(model: Model | str, rng: np.random.Generator, scale: float = 1.0) -> dict[str, float]:
    """Realistic navigation-grade truth values for every parameter of ``model``."""
    model = get_model(model)
    out = {}
    for n in model.names:
        f = family(n)
        v = NAV_GRADE_SPREAD[f] * rng.standard_normal()
        if f in ("K", "K2", "K3"):
            v = scale * (1.0 + v) if f == "K" else scale * v
        out[n] = float(v)
    return out


@dataclass(frozen=True)
class Presets:
    """Starting values (the manufacturer's calibration) and search half-widths, per parameter name."""

    values: dict[str, float]
    halfwidth: dict[str, float]

    def vectors(self, model: Model, scale: np.ndarray | float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """(centre, half-width) vectors for ``model``; names missing from the presets take defaults."""
        centre = model.default_vector(scale)
        centre = model.from_dict({k: v for k, v in self.values.items() if k in model.names}, centre)
        width = default_halfwidth(model, centre)
        for k, v in self.halfwidth.items():
            if k in model.names:
                width[model.index(k)] = v
        return centre, width

    def to_json(self) -> str:
        import json

        return json.dumps({"values": self.values, "halfwidth": self.halfwidth}, indent=2)


def default_halfwidth(model: Model, centre: np.ndarray) -> np.ndarray:
    kscale = np.mean(np.abs(centre[model.groups()["scale"]]))
    return np.array([BOX_HALFWIDTH[family(n)] * (kscale if family(n) in ("K", "K2", "K3") else 1.0)
                     for n in model.names])


# SD of a manufacturer's calibration error per parameter family (relative to K_x for K, K2, K3).
MANUFACTURER_ERROR_SD = {"K": 50e-6, "b": 50e-6, "S": 20e-6, "K2": 5e-6, "K3": 2e-6, "kappa": 5e-6, "c": 5e-6,
                         "beta": 1e-6, "gamma": 5e-6, "d": 2e-9}


def manufacturer_sd(names, truth: dict[str, float], error_scale: float = 1.0) -> np.ndarray:
    """SD of :func:`manufacturer_presets`' error for each parameter in ``names`` (same units)."""
    k = abs(truth.get("K_x", 1.0))
    return np.array([error_scale * MANUFACTURER_ERROR_SD[family(n)] * (k if family(n) in ("K", "K2", "K3") else 1.0)
                     for n in names])


def manufacturer_presets(truth: dict[str, float], rng: np.random.Generator, error_scale: float = 1.0) -> Presets:
    """Presets as the truth plus a manufacturer's calibration error (2020 paper §4.1)."""
    err = MANUFACTURER_ERROR_SD
    values = {k: float(v + error_scale * err[family(k)] * rng.standard_normal() * (abs(truth.get("K_x", 1.0))
              if family(k) in ("K", "K2", "K3") else 1.0)) for k, v in truth.items()}
    return Presets(values, {})


def load_presets(path: str | Path) -> Presets:
    """Read a presets JSON: ``{"values": {...}, "halfwidth": {...}}`` or a plain ``{name: value}``."""
    obj = read_json_object(path, "presets")
    values = obj.get("values", obj if "halfwidth" not in obj else {})
    if "parameters" in obj and isinstance(obj["parameters"], dict):  # a calibration file
        values = obj["parameters"]
    halfwidth = obj.get("halfwidth", {})
    known = {p for t in TERMS.values() for p in t.params}
    bad = sorted(k for k in list(values) + list(halfwidth) if k not in known)
    if bad:
        raise InputError(f"presets {path}: unknown parameter name(s) {', '.join(bad)} "
                         "(see docs/design.md, 'Terms and parameters' for names)")
    try:
        return Presets({k: float(v) for k, v in values.items()}, {k: float(v) for k, v in halfwidth.items()})
    except (TypeError, ValueError):
        raise InputError(f"presets {path}: every value must be a number") from None
