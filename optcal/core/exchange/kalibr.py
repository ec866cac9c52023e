"""Kalibr's IMU intrinsics, model ``scale-misalignment`` (Rehder, Nikolic, Schneider, Hinzmann & Siegwart,
ICRA 2016, the accelerometer model; docs/exchange.md, "Kalibr").

Kalibr predicts an accelerometer measurement as a_m = M·a + b(t) with a the specific force in the IMU frame
and a_m, a in m/s²: M a lower-triangular matrix (its design variable is initialised to I with only the cells
on and below the diagonal active) and b(t) a bias that Kalibr estimates as a random walk, not a constant.
Its result yaml holds, per IMU, ``model: scale-misalignment``, ``accelerometers: {M: 3×3}`` and
``gyroscopes: {M, A, C_gyro_i}`` (:mod:`optcal.core.exchange.gyro_kalibr`; the identity for a calibration without
a gyroscope); no accelerometer bias. Its imu.yaml also holds the noise model, four numbers in SI
(:data:`NOISE_FIELDS`, which ``optcal noise --kalibr-yaml`` measures): an export with them writes a complete
entry but for ``rostopic``.

From optcal's N = M_o·A + o (A in g, N in units u with s m/s² per u): M = (s/g0)·M_o and the bias s·o. M is
lower triangular exactly when T is (optcal's gauge, docs/design.md, "The gauge of `misalignment`"), so linear9 and
diag6 fit Kalibr's model; a T with cells above the diagonal (misalignment6) does not. The file has no constant bias: a
non-zero bias is refused unless the caller accepts that Kalibr estimates it online (``bias_online``).
Raw units without a fixed SI value (counts, volts) are refused: Kalibr's measurements are in m/s².
"""

from __future__ import annotations

import numpy as np

from optcal.core.errors import InputError
from optcal.core.exchange.common import CELLS, SI_PER_UNIT, UPPER, LinearPart, matrix3, rows
from optcal.core.gravity import G0 as _G0

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


# The noise fields of Kalibr's imu.yaml (its IMU noise model: white noise density and bias random walk, per
# sensor, in SI), and their units; ``optcal noise --kalibr-yaml`` writes them.
NOISE_FIELDS = {"accelerometer_noise_density": "m/s^2/sqrt(Hz)", "accelerometer_random_walk": "m/s^3/sqrt(Hz)",
                "gyroscope_noise_density": "rad/s/sqrt(Hz)", "gyroscope_random_walk": "rad/s^2/sqrt(Hz)"}


def dumps(M, comment_lines=(), gyro=None, noise: dict | None = None) -> str:
    """An ``imu0`` entry as Kalibr's result yaml writes it: the model and the intrinsics; the gyroscope's
    ``gyro`` = (M, A, C_gyro_i) (:func:`optcal.core.exchange.gyro_kalibr.gyro_to_kalibr`), or the identity
    without one; ``noise``: the fields of :data:`NOISE_FIELDS` and ``update_rate`` (:func:`load_noise`)."""
    def mat(name, A, indent):
        return [f"{indent}{name}:"] + [f"{indent}- [{', '.join(repr(float(v)) for v in r)}]" for r in rows(A)]

    Mg, A, C = (np.eye(3), np.zeros((3, 3)), np.eye(3)) if gyro is None else gyro
    lines = [f"# {c}" for c in comment_lines]
    lines += ["imu0:", f"  model: {MODEL}", "  accelerometers:"]
    lines += mat("M", M, "    ")
    lines += ["  gyroscopes:"]
    lines += mat("M", Mg, "    ") + mat("A", A, "    ") + mat("C_gyro_i", C, "    ")
    for key, unit in {**NOISE_FIELDS, "update_rate": "Hz"}.items():
        if noise and key in noise:
            lines.append(f"  {key}: {noise[key]!r}  # [{unit}]")
    return "\n".join(lines) + "\n"


def _safe_load(text: str, path, what: str) -> dict:
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
        raise InputError(f"{path} is not {what} (a mapping)")
    return doc


def load_entry(text: str, path) -> dict:
    """The one IMU entry of a Kalibr yaml (``imu0: {...}``, or the IMU's fields at the top), model
    ``scale-misalignment``."""
    doc = _safe_load(text, path, "a Kalibr imu yaml")
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
    return doc


def loads(text: str, path) -> np.ndarray:
    """Kalibr's accelerometer M from a yaml holding one IMU (:func:`load_entry`)."""
    return acc_loads(load_entry(text, path), path)


def acc_loads(entry: dict, path) -> np.ndarray:
    """Kalibr's accelerometer M of an IMU entry (:func:`load_entry`)."""
    acc = entry.get("accelerometers")
    if not isinstance(acc, dict) or "M" not in acc:
        raise InputError(f"{path}: accelerometers.M is missing")
    return matrix3(acc["M"], "accelerometers.M", path)


def gyro_loads(entry: dict, path) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Kalibr's gyroscope (M, A, C_gyro_i) of an IMU entry (:func:`load_entry`), or None when it has none."""
    g = entry.get("gyroscopes")
    if g is None:
        return None
    if not isinstance(g, dict) or "M" not in g:
        raise InputError(f"{path}: gyroscopes.M is missing")
    M = matrix3(g["M"], "gyroscopes.M", path)
    A = matrix3(g["A"], "gyroscopes.A", path) if "A" in g else np.zeros((3, 3))
    C = matrix3(g["C_gyro_i"], "gyroscopes.C_gyro_i", path) if "C_gyro_i" in g else np.eye(3)
    return M, A, C


def load_noise(text: str, path) -> dict:
    """The noise fields of a Kalibr imu.yaml (as ``optcal noise --kalibr-yaml`` writes them: at the top, or in
    the file's one IMU entry): all four of :data:`NOISE_FIELDS`, positive numbers in SI, and ``update_rate``
    in Hz when the file has it. A missing field is refused, naming it: Kalibr's imu.yaml needs all four."""
    doc = _safe_load(text, path, "a Kalibr imu.yaml")
    if not any(k in doc for k in NOISE_FIELDS):
        entries = [v for v in doc.values() if isinstance(v, dict) and any(k in v for k in NOISE_FIELDS)]
        if len(entries) == 1:
            doc = entries[0]
    missing = [k for k in NOISE_FIELDS if k not in doc]
    if missing:
        raise InputError(f"{path} lacks {', '.join(missing)}, which Kalibr's imu.yaml needs; measure them with "
                         "optcal noise --kalibr-yaml (with the gyroscope's columns and units for the gyroscope's)")
    out = {}
    for key in (*NOISE_FIELDS, "update_rate"):
        if key not in doc:
            continue
        v = doc[key]
        if isinstance(v, bool) or not isinstance(v, int | float) or not (np.isfinite(v) and v > 0):
            raise InputError(f"{path}: {key} is {v!r}; it must be a positive number "
                             f"({NOISE_FIELDS.get(key, 'Hz')})")
        out[key] = float(v)
    return out
