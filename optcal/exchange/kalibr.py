"""Kalibr's IMU intrinsics, model ``scale-misalignment`` (Rehder, Nikolic, Schneider, Hinzmann & Siegwart,
ICRA 2016, the accelerometer model; docs/exchange.md §4).

Kalibr predicts an accelerometer measurement as a_m = M·a + b(t) with a the specific force in the IMU frame
and a_m, a in m/s²: M a lower-triangular matrix (its design variable is initialised to I with only the cells
on and below the diagonal active) and b(t) a bias that Kalibr estimates as a random walk, not a constant.
Its result yaml holds, per IMU, ``model: scale-misalignment``, ``accelerometers: {M: 3×3}`` and
``gyroscopes: {M, A, C_gyro_i}``; no accelerometer bias.

From optcal's N = M_o·A + o (A in g, N in units u with s m/s² per u): M = (s/g0)·M_o and the bias s·o. M is
lower triangular exactly when T is (optcal's gauge, docs/design.md §6.3), so linear9 and diag6 fit Kalibr's
model; a T with cells above the diagonal (misalignment6) does not. The file has no constant bias: a
non-zero bias is refused unless the caller accepts that Kalibr estimates it online (``bias_online``).
Raw units without a fixed SI value (counts, volts) are refused: Kalibr's measurements are in m/s².
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..gravity import G0 as _G0
from .common import CELLS, SI_PER_UNIT, UPPER, LinearPart, matrix3, rows

FORMAT = "kalibr"
MODEL = "scale-misalignment"


def to_kalibr(lin: LinearPart, *, bias_online: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(M, bias) of Kalibr's a_m = M·a + b for optcal's linear part, a_m and a in m/s²."""
    if lin.units not in SI_PER_UNIT:
        raise InputError(f"Kalibr's measurements are in m/s², and this calibration's outputs are in {lin.units}, "
                         "which have no fixed value in m/s²; use the imu_tk, imucal or matrix format")
    s = SI_PER_UNIT[lin.units]
    M = (s / _G0) * np.asarray(lin.M, float)
    above = [CELLS[c] for c in UPPER if M[c] != 0]
    if above:
        raise InputError(f"Kalibr's M is lower triangular, but this calibration's T has {', '.join(above)} non-zero "
                         "(cells above the diagonal); fit --model linear9 (optcal's lower-triangular gauge) to "
                         "export to Kalibr")
    bias = s * np.asarray(lin.o, float)
    if np.any(bias != 0) and not bias_online:
        raise InputError("Kalibr's imu yaml holds no accelerometer bias (Kalibr estimates it online as a random "
                         f"walk), and this calibration's is {', '.join(f'{v:.6g}' for v in bias)} m/s²; pass "
                         "`bias_online` to export M alone, or choose another format")
    return M, bias


def from_kalibr(M, units: str = "m/s2") -> LinearPart:
    """optcal's linear part of Kalibr's M, no bias in the file: M_o = (g0/s)·M, o = 0, for raw outputs in
    ``units`` worth s m/s² each (Kalibr's own measurements are in m/s²; g or mg when the raw data were
    converted from those)."""
    if units not in SI_PER_UNIT:
        raise InputError(f"Kalibr's measurements are in m/s²; raw units {units!r} have no fixed value in m/s² "
                         f"(use {', '.join(SI_PER_UNIT)})")
    return LinearPart((_G0 / SI_PER_UNIT[units]) * np.asarray(M, float), np.zeros(3), units)


def dumps(M, comment_lines=()) -> str:
    """An ``imu0`` entry as Kalibr's result yaml writes it: the model and the intrinsics (gyroscope identity)."""
    def mat(name, A, indent):
        return [f"{indent}{name}:"] + [f"{indent}- [{', '.join(repr(float(v)) for v in r)}]" for r in rows(A)]

    lines = [f"# {c}" for c in comment_lines]
    lines += ["imu0:", f"  model: {MODEL}", "  accelerometers:"]
    lines += mat("M", M, "    ")
    lines += ["  gyroscopes:"]
    lines += mat("M", np.eye(3), "    ") + mat("A", np.zeros((3, 3)), "    ") + mat("C_gyro_i", np.eye(3), "    ")
    return "\n".join(lines) + "\n"


def loads(text: str, path) -> np.ndarray:
    """Kalibr's accelerometer M from a yaml holding one IMU (``imu0: {...}``, or the IMU's fields at the top)."""
    try:
        import yaml
    except ImportError:  # pragma: no cover - PyYAML comes with dask, a dependency of optcal
        raise InputError("reading Kalibr's yaml needs PyYAML (pip install pyyaml)") from None
    # OpenCV-style files (as some consumers of Kalibr's results write them) start with "%YAML:1.0".
    body = "\n".join(line for line in text.splitlines() if not line.startswith("%YAML"))
    try:
        doc = yaml.safe_load(body)
    except yaml.YAMLError as exc:
        raise InputError(f"{path} is not a YAML file ({str(exc).splitlines()[0]})") from None
    if not isinstance(doc, dict):
        raise InputError(f"{path} is not a Kalibr imu yaml (a mapping)")
    if "accelerometers" not in doc and "model" not in doc:
        imus = [k for k, v in doc.items() if isinstance(v, dict) and ("accelerometers" in v or "model" in v)]
        if len(imus) != 1:
            raise InputError(f"{path} holds {'no' if not imus else len(imus)} IMU entries "
                             f"{'(' + ', '.join(imus) + ') ' if imus else ''}with intrinsics; optcal imports one")
        doc = doc[imus[0]]
    model = doc.get("model")
    if model != MODEL:
        raise InputError(f"{path}: IMU model {model!r}; optcal imports Kalibr's {MODEL!r} model (the "
                         "'calibrated' model has no intrinsics, and the size effect is not a calibration term)")
    acc = doc.get("accelerometers")
    if not isinstance(acc, dict) or "M" not in acc:
        raise InputError(f"{path}: accelerometers.M is missing")
    return matrix3(acc["M"], "accelerometers.M", path)
