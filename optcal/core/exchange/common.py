"""The linear part of a calibration, shared by every exchange format (docs/exchange.md, "The linear part, units and
gauge").

optcal's affine terms (docs/design.md, "Terms and parameters") give, for specific force A in g (units of g0, "Units
and frames"),

    N = diag(K)·(T·A + b) = M·A + o,    M = diag(K)·T  (output units per g),   o = K ⊙ b  (output units)

with T's off-diagonal cells as docs/design.md, "The installation matrix T" maps them. Each format module converts (M,
o) to its own matrices and back; this module converts (M, o) to and from optcal's parameters, chooses the model an
import needs (diag6, linear9 or scale+bias+misalignment6: the smallest that holds the matrix exactly) and refuses
what no format can hold (nonlinear, temperature and drift terms).
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from optcal.core.errors import InputError
from optcal.core.gravity import G0
from optcal.core.jsonfile import parse_json_object
from optcal.core.model import T_CELLS, TERMS, Model, get_model

# T's off-diagonal cells, (row, column) -> parameter name (docs/design.md, "The installation matrix T"), as the model
# states them.
CELLS = T_CELLS
UPPER = ((0, 1), (0, 2), (1, 2))  # the cells the gauge of `misalignment` sets to zero (docs/design.md, "The gauge of
                                  # `misalignment`")
LOWER = ((1, 0), (2, 0), (2, 1))

# Calibrated output units a format may hold: units per g (optcal's g is g0 = 9.80665 m/s², design.md, "Units and
# frames").
CALIBRATED_UNITS = {"g": 1.0, "m/s2": G0}
# Raw output units with a fixed SI value (Kalibr's measurements are in m/s²): m/s² per unit.
SI_PER_UNIT = {"m/s2": 1.0, "g": G0, "mg": G0 / 1000.0}
LINEAR_MODELS = ("diag6", "linear9", "scale+bias+misalignment6")


@dataclass(frozen=True)
class LinearPart:
    """N = M·A + o: M (3, 3) in output units per g, o (3,) in output units, A in g; ``units`` are the raw
    outputs' (one of ``optcal.core.data.UNITS``)."""

    M: np.ndarray
    o: np.ndarray
    units: str

    def specific_force(self, N) -> np.ndarray:
        """A (n, 3) in g from raw outputs N (n, 3): the exact inverse of the affine map."""
        N = np.asarray(N, float)
        return np.linalg.solve(self.M, (N - self.o).T).T


def inverse(M) -> np.ndarray:
    """The inverse of a 3×3 matrix; a triangular one is inverted by substitution, so that its zero cells stay
    exactly zero (an import then recognises optcal's lower-triangular gauge, docs/design.md, "The gauge of
    `misalignment`")."""
    from scipy.linalg import solve_triangular

    M = np.asarray(M, float)
    eye = np.eye(3)
    if not np.all(np.isfinite(M)):
        raise InputError("the calibration matrix has a non-finite entry")
    try:
        if np.all(M[np.triu_indices(3, 1)] == 0):
            out = solve_triangular(M, eye, lower=True)
        elif np.all(M[np.tril_indices(3, -1)] == 0):
            out = solve_triangular(M, eye, lower=False)
        else:
            out = np.linalg.inv(M)
    except (np.linalg.LinAlgError, ValueError):
        out = np.full((3, 3), np.nan)
    if not np.all(np.isfinite(out)) or abs(np.linalg.det(M)) == 0:
        raise InputError("the calibration matrix is singular; the file cannot describe a sensor")
    return out


def matrix_of(model: Model, x) -> tuple[np.ndarray, np.ndarray]:
    """(M, o) of an affine model's parameter vector x (docs/design.md, "Terms and parameters"-3.2)."""
    p = model.to_dict(x)
    K = np.array([p[f"K_{a}"] for a in "xyz"])
    b = np.array([p.get(f"b_{a}", 0.0) for a in "xyz"])
    T = np.eye(3)
    for (i, j), name in CELLS.items():
        T[i, j] = p.get(name, 0.0)
    return K[:, None] * T, K * b


def linear_part(cal, fmt: str, source="the calibration") -> LinearPart:
    """The linear part of a :class:`optcal.core.calfile.CalibrationFile`. A model with terms a format cannot hold
    (anything but scale, bias and misalignment) is refused, naming the terms and their parameters."""
    model = cal.model
    extra = [t for t in model.terms if not TERMS[t].affine]
    if extra:
        params = ", ".join(p for t in extra for p in TERMS[t].params)
        raise InputError(
            f"{source}: model {model.name} has term(s) {', '.join(extra)} ({params}) that the {fmt} format cannot "
            "hold (it holds scale, bias and misalignment only); export a calibration fitted with --model linear9 "
            "(or diag6, or scale+bias+misalignment6)"
        )
    M, o = matrix_of(model, cal.x)
    return LinearPart(M, o, cal.units_out)


def parameters_of(lin: LinearPart, model: str | None = None) -> tuple[Model, np.ndarray]:
    """optcal's (model, x) holding ``lin`` exactly: K_i = M_ii, T = diag(K)⁻¹·M, b = o / K. Without ``model``
    the smallest of diag6, linear9 (T lower triangular: optcal's gauge) and scale+bias+misalignment6 whose
    cells hold every non-zero entry; a given model must hold them, or the import is refused."""
    M, o = np.asarray(lin.M, float), np.asarray(lin.o, float)
    if M.shape != (3, 3) or o.shape != (3,) or not (np.all(np.isfinite(M)) and np.all(np.isfinite(o))):
        raise InputError("the calibration needs a finite 3×3 matrix and a 3-vector offset")
    K = np.diag(M).copy()
    if np.any(K == 0):
        axis = "xyz"[int(np.flatnonzero(K == 0)[0])]
        raise InputError(f"the {axis} axis has zero sensitivity to its own input (a diagonal cell of the matrix is "
                         "0); optcal's model needs a non-zero scale factor on each axis")
    T = M / K[:, None]
    upper = any(T[c] != 0 for c in UPPER)
    lower = any(T[c] != 0 for c in LOWER)
    if model is None:
        name = "scale+bias+misalignment6" if upper else ("linear9" if lower else "diag6")
    else:
        name = get_model(model).name
        if name not in LINEAR_MODELS:
            raise InputError(f"`model` {model}: an import gives the linear part only; choose one of "
                             f"{', '.join(LINEAR_MODELS)}")
        cells = {"diag6": (), "linear9": LOWER, "scale+bias+misalignment6": UPPER + LOWER}[name]
        lost = [CELLS[c] for c in UPPER + LOWER if c not in cells and T[c] != 0]
        if lost:
            raise InputError(f"`model` {model} cannot hold this calibration's misalignment {', '.join(lost)} "
                             f"(non-zero); choose scale+bias+misalignment6 or leave `model` out")
    m = get_model(name)
    values = {f"K_{a}": float(K[i]) for i, a in enumerate("xyz")}
    values.update({f"b_{a}": float(o[i] / K[i]) for i, a in enumerate("xyz")})
    values.update({n: float(T[c]) for c, n in CELLS.items() if n in m.names})
    return m, m.from_dict(values)


def calibration_dict(lin: LinearPart, *, fmt: str, source, g_local: float = 1.0, model: str | None = None) -> dict:
    """An optcal calibration file (docs/design.md, "Calibration file") for an imported linear part: every parameter from
    :func:`parameters_of`, no standard errors (optcal did not fit it), ``data.n_positions`` 0 (no positions
    were fitted; ``rms_residual_g`` is then 0, as the file's schema requires a number), ``solver``
    "import:FORMAT" and ``data.source`` the imported file."""
    from optcal.core.calfile import FORMAT, FORMAT_VERSION, units_record

    m, x = parameters_of(lin, model)
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "model": m.name,
        "terms": list(m.terms),
        "parameters": m.to_dict(x),
        "stderr": {n: None for n in m.names},
        "units": units_record(m, lin.units),
        "g_local": float(g_local),
        "data": {"n_positions": 0, "rms_residual_g": 0.0, "source": str(source)},
        "solver": f"import:{fmt}",
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds").replace("+00:00", "Z"),
    }


def write_new(path, text: str, *, force: bool, check=None) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same folder (:func:`optcal.core.atomicfile.
    atomic_write`), renamed into place only after ``check(temporary_path)`` (if given) accepts it: a failure
    leaves nothing behind. An existing ``path`` is kept unless ``force``."""
    from optcal.core.atomicfile import EXISTS_OUTPUT as EXISTS
    from optcal.core.atomicfile import write_atomic

    path = Path(path)
    if path.exists() and not force:
        raise InputError(EXISTS.format(path=path))
    folder = path.resolve().parent
    if not folder.is_dir():
        raise InputError(f"cannot write {path}: the folder {folder} does not exist")

    def checked(tmp: str) -> None:
        try:
            check(tmp)
        except InputError as exc:  # name the file the user asked for, not the temporary one
            raise InputError(str(exc).replace(tmp, str(path))) from None

    write_atomic(path, text, overwrite=force, check=None if check is None else checked, exists=EXISTS)


def read_text(path, what: str) -> str:
    try:
        return Path(path).read_text()
    except FileNotFoundError:
        raise InputError(f"{path} does not exist; give the {what} file to import") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") from None


def read_json(path, what: str) -> dict:
    return parse_json_object(read_text(path, what), path, f"{what} file")


def matrix3(value, name: str, path, shape=(3, 3)) -> np.ndarray:
    """A numeric array of the given shape from a file's field, or an InputError naming the field."""
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{path}: {name} is not numeric") from None
    if a.shape != shape:
        raise InputError(f"{path}: {name} must have shape {shape}; it has {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{path}: {name} has a non-finite entry")
    return a


def rows(M) -> list:
    """A matrix or vector as nested lists of Python floats (JSON/YAML at full repr precision)."""
    return np.asarray(M, float).tolist()
