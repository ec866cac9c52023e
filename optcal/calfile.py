"""The calibration file (docs/design.md §9.3): a versioned JSON record of a fitted calibration that can be applied
to new raw data to give calibrated specific force.

Content: ``format``, ``format_version``, ``model``, ``terms``, ``parameters`` {name: value},
``stderr`` {name: value or null}, ``units`` {``input``: "g", ``output``: the data's units}, ``g_local``
(in g), ``data`` {``n_positions``, ``rms_residual_g``, ``source``}, ``solver``, ``created`` (ISO-8601 UTC),
``observability`` {rank, n_parameters, unobservable}, and, for models with temperature or drift terms,
``context`` {``T0``, ``t0``}: the reference temperature and time of the calibration data (docs/design.md §3.4),
which applying the file to new data must reuse.

Floats are written with ``repr`` precision (Python's ``json`` does this), so a round trip is exact.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from .errors import InputError
from .model import Context, Model, get_model

FORMAT = "optcal-calibration"
FORMAT_VERSION = 1
G0 = 9.80665
CHUNK = 65_536  # samples per inverse call in apply(): temporaries stay in cache-friendly sizes (measured fastest)

REQUIRED_FIELDS = ("model", "terms", "parameters", "stderr", "units", "g_local", "data", "solver", "created")


def _finite_or_none(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def calibration_to_dict(cal, *, units_in: str = "g", units_out: str | None = None, source=None) -> dict:
    """The JSON-ready dictionary of a fitted :class:`optcal.fit.Calibration`."""
    model: Model = cal.model
    data = cal.problem.data
    if units_out is None:
        units_out = data.units
    if units_in != "g":
        raise InputError(f"the model's input is specific force in g; units_in {units_in!r} is not supported")
    out = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "model": model.name,
        "terms": list(model.terms),
        "parameters": {n: float(v) for n, v in zip(model.names, np.asarray(cal.x, float))},
        "stderr": {n: _finite_or_none(s) for n, s in zip(model.names, np.asarray(cal.stderr, float))},
        "units": {"input": units_in, "output": units_out},
        "g_local": float(cal.problem.g_local),
        "data": {
            "n_positions": len(data),
            "rms_residual_g": float(cal.fit.rms_g),
            "source": None if source is None else str(source),
        },
        "solver": str(cal.solver),
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds").replace("+00:00", "Z"),
        "observability": cal.observability.to_dict(),
    }
    context = {}
    if "temp" in model.needs and data.temp is not None:
        context["T0"] = float(np.mean(data.temp))
    if "t" in model.needs and data.t is not None:
        context["t0"] = float(np.asarray(data.t, float)[0])
    if context:
        out["context"] = context
    return out


def write_calibration(cal, path, *, units_in: str = "g", units_out: str | None = None, source=None,
                      overwrite: bool = False) -> None:
    """Write the calibration file; an existing file is kept unless ``overwrite`` (the CLI's ``--force``)."""
    path = Path(path)
    if path.exists() and not overwrite:
        raise InputError(f"{path} exists; pass --force to overwrite it or choose another -o path")
    d = calibration_to_dict(cal, units_in=units_in, units_out=units_out, source=source)
    text = json.dumps(d, indent=2)
    try:
        path.write_text(text + "\n")
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None


@dataclass
class CalibrationFile:
    """A calibration read back from its file; :meth:`apply` turns raw outputs into specific force."""

    model: Model
    x: np.ndarray
    stderr: np.ndarray  # NaN where the file has null (unobservable or not estimated)
    g_local: float
    units_in: str
    units_out: str
    meta: dict = field(default_factory=dict)  # the whole file's content

    @property
    def parameters(self) -> dict[str, float]:
        return self.model.to_dict(self.x)

    def context(self, n: int, temp=None, t=None) -> Context | None:
        """The model's context for new data, relative to the calibration's reference T0 and t0."""
        needs = self.model.needs
        if not needs:
            return None
        ctx = self.meta.get("context", {})
        dtemp = dt = None
        if "temp" in needs:
            if temp is None:
                raise InputError(f"model {self.model.name} has temperature terms; the data need temp")
            dtemp = np.asarray(temp, float).reshape(n) - float(ctx["T0"])
        if "t" in needs:
            if t is None:
                raise InputError(f"model {self.model.name} has a drift term; the data need a time column t")
            dt = np.asarray(t, float).reshape(n) - float(ctx["t0"])
        return Context(dtemp, dt)

    def apply(self, N, temp=None, t=None, *, chunk: int = CHUNK) -> np.ndarray:
        """Specific force A (n, 3) in g from raw outputs N (n, 3) in ``units_out``: the model's inverse
        (docs/design.md §3.5), vectorised over samples and done in chunks to bound memory."""
        N = np.asarray(N, float)
        if N.ndim != 2 or N.shape[1] != 3:
            raise InputError(f"raw outputs must have three columns ax, ay, az; got shape {N.shape}")
        n = len(N)
        ctx = self.context(n, temp, t)
        X = self.x[None, :]
        out = np.empty((n, 3))
        for lo in range(0, n, chunk):
            hi = min(lo + chunk, n)
            c = None if ctx is None else Context(
                None if ctx.dtemp is None else ctx.dtemp[lo:hi], None if ctx.dt is None else ctx.dt[lo:hi])
            out[lo:hi] = self.model.inverse(X, N[lo:hi], c)[0]
        return out


def _need(d: dict, key: str, path, kind=None):
    if key not in d:
        raise InputError(f"{path}: lacks the field {key!r}; re-create it with optcal calibrate -o")
    v = d[key]
    if kind is not None and not isinstance(v, kind):
        raise InputError(f"{path}: field {key!r} has the wrong type ({type(v).__name__}); file damaged")
    return v


def read_calibration(path) -> CalibrationFile:
    """Read and validate a calibration file. Another format or version, or a missing field, is an
    :class:`InputError`."""
    path = Path(path)
    try:
        d = json.loads(path.read_text())
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path} is not a JSON calibration file ({exc})") from None
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise InputError(f"{path} is not an optcal calibration file (no \"format\": \"{FORMAT}\")")
    version = d.get("format_version")
    if version != FORMAT_VERSION:
        raise InputError(
            f"{path} has format_version {version!r}; this optcal reads version {FORMAT_VERSION} only "
            "(re-create the file with this version's optcal calibrate -o)"
        )
    for key in REQUIRED_FIELDS:
        _need(d, key, path)
    terms = _need(d, "terms", path, list)
    model = get_model("+".join(terms)) if terms else get_model(_need(d, "model", path, str))
    if _need(d, "model", path, str) != model.name:
        raise InputError(f"{path}: model {d['model']!r} does not match its terms {'+'.join(terms)}")
    params = _need(d, "parameters", path, dict)
    missing = [n for n in model.names if n not in params]
    if missing:
        raise InputError(f"{path}: parameter(s) {', '.join(missing)} of model {model.name} are missing")
    try:
        x = model.from_dict({k: float(v) for k, v in params.items()})
    except (TypeError, ValueError):
        raise InputError(f"{path}: a parameter value is not a number") from None
    if not np.all(np.isfinite(x)):
        raise InputError(f"{path}: a parameter value is not finite")
    if np.any(x[model.groups()["scale"]] == 0):
        raise InputError(f"{path}: a scale factor is zero; the calibration cannot be applied")
    se = _need(d, "stderr", path, dict)
    stderr = np.array([np.nan if se.get(n) is None else float(se[n]) for n in model.names])
    units = _need(d, "units", path, dict)
    for k in ("input", "output"):
        if k not in units:
            raise InputError(f"{path}: field 'units' lacks {k!r}")
    for k in ("n_positions", "rms_residual_g"):
        if k not in _need(d, "data", path, dict):
            raise InputError(f"{path}: field 'data' lacks {k!r}")
    ctx = d.get("context", {})
    need_ctx = {"temp": "T0", "t": "t0"}
    for col in model.needs:
        if need_ctx[col] not in ctx:
            raise InputError(f"{path}: model {model.name} needs context.{need_ctx[col]}, missing here")
    g_local = _need(d, "g_local", path)
    if not isinstance(g_local, int | float) or not 0.5 < g_local < 2.0:
        raise InputError(f"{path}: g_local {g_local!r} is not a local gravity in g")
    return CalibrationFile(model, x, stderr, float(g_local), str(units["input"]), str(units["output"]), d)

