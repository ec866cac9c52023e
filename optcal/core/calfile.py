"""The calibration file (docs/design.md, "Calibration file"): a versioned JSON record of a fitted calibration that can
be applied to new raw data to give calibrated specific force.

Content: ``format``, ``format_version`` (2, or 3 with user-defined terms), ``model``, ``terms``, ``parameters``
{name: value}, ``stderr`` {name: value or null}, ``units`` {``raw``: the sensor's output units (what the data were
in and what :meth:`CalibrationFile.apply` takes), ``calibrated``: "g" (what it gives), ``parameters``: {name:
unit}}, ``g_local`` (in g), ``data`` {``n_positions``, ``rms_residual_g``, ``source``}, ``solver``, ``created``
(ISO-8601 UTC), ``observability`` {rank, n_parameters, unobservable}, for models with temperature or drift
terms, ``context`` {``T0``, ``t0``}: the reference temperature and time of the calibration data
(docs/design.md, "Context: temperature and time offsets"), which applying the file to new data must reuse, and, for a
fit written with ``--force-weak`` although the data did not determine it (:mod:`optcal.core.determination`), ``forced``
(true) and ``forced_reasons`` (the one-line reasons it would have been refused for).

Version 1 named the units ``input`` ("g") and ``output`` (the raw units), which read backwards to users; a
version-1 file is still read, its fields mapped by :func:`upgrade`. Version 3 is version 2 with user-defined
terms (:func:`optcal.core.terms.user_term`, e.g. ``ax.ay@z``, found by ``optcal discover``): ``user_terms``
{term: its formula} documents each, and the reader checks that the formula is the one the name defines. A file
of built-in terms is written as version 2, so that readers of version 2 read it as before.

Floats are written with ``repr`` precision (Python's ``json`` does this), so a round trip is exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from optcal.core.data import UNITS
from optcal.core.errors import InputError
from optcal.core.model import TERMS, Context, Model, get_model

FORMAT = "optcal-calibration"
FORMAT_VERSION = 2
USER_TERMS_VERSION = 3  # a file with user-defined terms (user_terms)
READ_VERSIONS = (1, 2, 3)  # version 1 is mapped to 2 on reading (upgrade)
CALIBRATED_UNITS = "g"  # what apply() gives: specific force in units of g0 (docs/design.md, "Units and frames")
CHUNK = 65_536  # samples per inverse call in apply(): temporaries stay in cache-friendly sizes (measured fastest)


def _finite_or_none(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def units_record(model: Model, raw: str) -> dict:
    """The file's ``units`` field: the raw output units, the calibrated units and each parameter's unit
    (:meth:`optcal.core.model.Model.units`)."""
    if raw not in UNITS:
        raise InputError(f"unknown raw output units {raw!r}; use one of {', '.join(UNITS)}")
    return {"raw": raw, "calibrated": CALIBRATED_UNITS, "parameters": model.units(raw)}


def upgrade(d: dict) -> dict:
    """A calibration record in the current version's fields: a record whose ``units`` still use version 1's
    names (``input``: "g", ``output``: the raw units) gets ``raw``, ``calibrated`` and ``parameters`` in
    their place and format_version 2. Anything else is returned as it is (the reader then checks it)."""
    units = d.get("units") if isinstance(d, dict) else None
    if not (isinstance(units, dict) and "output" in units and "raw" not in units):
        return d
    out = dict(d)
    raw = units["output"]
    new = {"raw": raw, "calibrated": units.get("input", CALIBRATED_UNITS)}
    try:
        terms = d.get("terms")
        model = get_model("+".join(terms) if isinstance(terms, list) and terms else d.get("model"))
        if raw in UNITS:
            new["parameters"] = model.units(raw)
    except (InputError, TypeError):
        pass  # the reader names what is wrong with the model
    out["units"] = new
    if out.get("format_version") == 1:
        out["format_version"] = FORMAT_VERSION
    return out


def calibration_to_dict(cal, *, units_in: str = "g", units_out: str | None = None, source=None) -> dict:
    """The JSON-ready dictionary of a fitted :class:`optcal.core.calibration.Calibration` (its
    :meth:`~optcal.core.calibration.Calibration.file_record`). ``units_out`` is the raw output
    units (the data's by default), written as ``units.raw``; ``units_in`` the calibrated units, always g."""
    model: Model = cal.model
    data = cal.problem.data
    if units_out is None:
        units_out = data.units
    if units_in != "g":
        raise InputError(f"the model's input is specific force in g; units_in {units_in!r} is not supported")
    out = {
        "format": FORMAT,
        "format_version": USER_TERMS_VERSION if model.user_terms else FORMAT_VERSION,
        "model": model.name,
        "terms": list(model.terms),
        "parameters": {n: float(v) for n, v in zip(model.names, np.asarray(cal.x, float))},
        "stderr": {n: _finite_or_none(s) for n, s in zip(model.names, np.asarray(cal.stderr, float))},
        "units": units_record(model, units_out),
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
    if model.user_terms:
        out["user_terms"] = model.user_formulas
    context = {}
    if "temp" in model.needs and data.temp is not None:
        context["T0"] = float(np.mean(data.temp))
    if "t" in model.needs and data.t is not None:
        context["t0"] = float(np.asarray(data.t, float)[0])
    if context:
        out["context"] = context
    forced = list(getattr(cal, "forced", None) or [])
    if forced:  # written only then, so that files of determined fits read as before (docs/design.md, "Calibration
                # file")
        out["forced"] = True
        out["forced_reasons"] = [str(r) for r in forced]
    return out


def write_calibration(cal, path, *, units_in: str = "g", units_out: str | None = None, source=None,
                      overwrite: bool = False) -> None:
    """Write the calibration file; an existing file is kept unless ``overwrite`` (the CLI's ``--force``)."""
    from optcal.core.jsonfile import write_json_object

    write_json_object(calibration_to_dict(cal, units_in=units_in, units_out=units_out, source=source), path,
                      overwrite=overwrite)


@dataclass
class CalibrationFile:
    """A calibration read back from its file; :meth:`apply` turns raw outputs into specific force."""

    model: Model
    x: np.ndarray
    stderr: np.ndarray  # NaN where the file has null (unobservable or not estimated)
    g_local: float
    units_in: str  # the calibrated output's units: "g" (the file's units.calibrated)
    units_out: str  # the raw output's units (the file's units.raw): what apply() takes
    meta: dict = field(default_factory=dict)  # the whole file's content (a version-1 file's as upgraded)

    @property
    def raw_units(self) -> str:
        """Units of the raw outputs the calibration was fitted to and applies to (``units.raw``)."""
        return self.units_out

    @property
    def calibrated_units(self) -> str:
        """Units of the calibrated specific force :meth:`apply` returns (``units.calibrated``): g."""
        return self.units_in

    @property
    def parameters(self) -> dict[str, float]:
        return self.model.to_dict(self.x)

    @property
    def forced(self) -> list[str]:
        """The reasons this calibration was refused and written anyway (``--force-weak``); empty if it was not."""
        return list(self.meta.get("forced_reasons") or []) if self.meta.get("forced") else []

    @property
    def parameter_units(self) -> dict[str, str]:
        """{parameter name: unit} (docs/design.md, "Terms and parameters") for the raw units."""
        return self.model.units(self.units_out)

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
        (docs/design.md, "The inverse: specific force from outputs"), vectorised over samples and done in chunks to
        bound memory."""
        N = np.asarray(N, float)
        if N.ndim != 2 or N.shape[1] != 3:
            raise InputError(f"raw outputs must have three columns ax, ay, az; got shape {N.shape}")
        n = len(N)
        prev = [t for t in self.model.user_terms if TERMS[t].feature.prev is not None]
        if prev:
            raise InputError(f"model {self.model.name} has the previous-pose term {prev[0]}, which needs static poses "
                             "in order; a recording's samples have none: calibrate without it to apply the file")
        ctx = self.context(n, temp, t)
        X = self.x[None, :]
        out = np.empty((n, 3))
        for lo in range(0, n, chunk):
            hi = min(lo + chunk, n)
            c = None if ctx is None else Context(
                None if ctx.dtemp is None else ctx.dtemp[lo:hi], None if ctx.dt is None else ctx.dt[lo:hi])
            out[lo:hi] = self.model.inverse(X, N[lo:hi], c)[0]
        return out


def read_calibration(path) -> CalibrationFile:
    """Read and validate a calibration file. Another format or version, a missing or unknown field, a value
    of the wrong type or out of range (the schema :class:`optcal.core.calfile_schema.CalibrationRecord`) is an
    :class:`InputError` of one line naming the field."""
    import json  # here: a command that reads no calibration file does not import it

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
    if isinstance(version, bool) or version not in READ_VERSIONS:
        raise InputError(
            f"{path} has format_version {version!r}; this optcal reads versions "
            f"{', '.join(map(str, READ_VERSIONS[:-1]))} and {READ_VERSIONS[-1]} "
            "(re-create the file with this version's optcal calibrate -o)"
        )
    if version == 1:
        units = d.get("units")
        if isinstance(units, dict) and "raw" in units:
            raise InputError(f"{path}: format_version 1 names its units input and output, not raw; "
                             "set format_version to 2 or re-create it with optcal calibrate -o")
        d = upgrade(d)
    from pydantic import ValidationError

    from optcal.core.calfile_schema import CalibrationRecord, error_line

    try:
        rec = CalibrationRecord.model_validate(d)
    except ValidationError as exc:
        raise InputError(f"{path}: {error_line(exc, d.get('format_version', FORMAT_VERSION))}") from None
    if rec.gyroscope is not None:
        from optcal.core.gyro.calfile import read_gyro_block

        read_gyro_block(d, path)  # a damaged gyroscope block: one line naming its field
    model = rec._model
    x = model.from_dict(rec.parameters)
    stderr = np.array([np.nan if rec.stderr.get(n) is None else float(rec.stderr[n]) for n in model.names])
    return CalibrationFile(model, x, stderr, float(rec.g_local), rec.units.calibrated, rec.units.raw, d)
