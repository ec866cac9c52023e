"""The terms of the sensor model, their parameters and units, the named models and the cell map of the
installation matrix (docs/design.md §3.1-§3.3): the table every numeric back end reads. The equations the
terms stand for are written once, in :meth:`optcal.model.Model.components`.
"""

from __future__ import annotations

from dataclasses import dataclass

AXES = ("x", "y", "z")


@dataclass(frozen=True)
class Term:
    """One named effect of the model: its parameters, its group and the data columns it needs."""

    name: str
    params: tuple[str, ...]
    group: str
    needs: tuple[str, ...] = ()
    description: str = ""
    # A typical magnitude of each parameter relative to the scale factor (for normalised search boxes
    # and for the natural scaling used in observability analysis).
    unit: float = 1.0
    # The term's output is affine in the specific force and needs no data column: a model made only of
    # such terms is inverted in closed form.
    affine: bool = False
    # The unit of each parameter (docs/design.md §3.1 "unit"), "{out}" standing for the output units.
    param_unit: str = "1"


def _axes(prefix: str) -> tuple[str, ...]:
    return tuple(f"{prefix}_{a}" for a in AXES)


TERMS: dict[str, Term] = {
    t.name: t
    for t in (
        Term("scale", _axes("K"), "scale", description="scale factors, output units per g", affine=True,
             param_unit="{out}/g"),
        Term("bias", _axes("b"), "bias", description="biases in g (output offset K·b)", affine=True,
             param_unit="g"),
        Term(
            "misalignment",
            ("S_yz", "S_zy", "S_zx"),
            "misalignment",
            description="installation angles in the identifiable gauge S_xz = S_xy = S_yx = 0, rad",
            affine=True,
            param_unit="rad",
        ),
        Term(
            "misalignment6",
            ("S_xz", "S_xy", "S_yz", "S_yx", "S_zy", "S_zx"),
            "misalignment",
            description="the seeds' six installation angles, rad (three directions unobservable)",
            affine=True,
            param_unit="rad",
        ),
        Term("quadratic", _axes("K2"), "nonlinear", description="second-order scale, output units per g²",
             param_unit="{out}/g²"),
        Term("cubic", _axes("K3"), "nonlinear", description="third-order scale, output units per g³",
             param_unit="{out}/g³"),
        Term(
            "scale_asymmetry",
            _axes("kappa"),
            "nonlinear",
            description="relative scale difference for negative inputs",
        ),
        Term(
            "cross_coupling",
            ("c_xy", "c_xz", "c_yz", "c_yx", "c_zx", "c_zy"),
            "nonlinear",
            description="cross-axis products, per g",
            param_unit="1/g",
        ),
        Term(
            "temperature_bias",
            _axes("beta"),
            "temperature",
            needs=("temp",),
            description="bias temperature coefficient, g per °C",
            param_unit="g/°C",
        ),
        Term(
            "temperature_scale",
            _axes("gamma"),
            "temperature",
            needs=("temp",),
            description="scale temperature coefficient, per °C",
            param_unit="1/°C",
        ),
        Term("bias_drift", _axes("d"), "drift", needs=("t",), description="bias drift, g per s", param_unit="g/s"),
    )
}

NAMED_MODELS: dict[str, tuple[str, ...]] = {
    "diag6": ("scale", "bias"),
    "linear9": ("scale", "bias", "misalignment"),
    "nonlinear12": ("scale", "bias", "misalignment", "quadratic"),
    "seed15": ("scale", "bias", "misalignment6", "quadratic"),
}

TERM_ORDER = list(TERMS)

# How each output unit of optcal.data.UNITS is written beside a number (docs/design.md §2).
UNIT_NAMES = {"g": "g", "m/s2": "m/s²", "counts": "counts", "volts": "V", "mg": "mg"}

# The installation matrix T's off-diagonal cells (row i, column j) and the angle in each (docs/design.md
# §3.2): T = I + these cells, u = T·A. The one statement of this map: every module that builds T or reads
# angles from a matrix uses it.
T_CELLS = {(0, 1): "S_xz", (0, 2): "S_xy", (1, 0): "S_yz", (1, 2): "S_yx", (2, 0): "S_zy", (2, 1): "S_zx"}
