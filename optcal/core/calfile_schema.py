"""The calibration file's schema (format version 2, docs/design.md, "Calibration file") as pydantic models, and one-line
messages from pydantic's errors. Its own module so that writing a file (optcal calibrate -o, optcal imu -o)
does not import pydantic (a tenth of a second or more): :func:`optcal.core.calfile.read_calibration` imports it."""

from __future__ import annotations

import json
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from optcal.core.data import UNITS
from optcal.core.errors import InputError
from optcal.core.model import Model, get_model


def _problem(text: str) -> PydanticCustomError:
    return PydanticCustomError("calfile", "{text}", {"text": text})


class _Record(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)


class _Units(_Record):
    raw: str
    calibrated: Literal["g"]
    parameters: dict[str, str] | None = None


class _DataInfo(_Record):
    n_positions: int = Field(ge=0)
    rms_residual_g: float = Field(ge=0)
    source: str | None = None


class _Context(_Record):
    T0: float | None = Field(None, allow_inf_nan=False)
    t0: float | None = Field(None, allow_inf_nan=False)


class CalibrationRecord(_Record):
    """Format version 2 (docs/design.md, "Calibration file"), in the order the reader checks it."""

    format: Literal["optcal-calibration"]
    format_version: Literal[2, 3]
    model: str
    terms: list[str]
    parameters: dict[str, Annotated[float, Field(allow_inf_nan=False)]]
    stderr: dict[str, float | None]
    units: _Units
    g_local: float = Field(gt=0.5, lt=2.0)  # in g
    data: _DataInfo
    solver: str
    created: str
    observability: dict | None = None
    context: _Context | None = None
    forced: bool | None = None
    forced_reasons: list[str] | None = None
    gyroscope: dict | None = None  # an IMU file's gyroscope (optcal imu; optcal.core.gyro.calfile checks it)
    user_terms: dict[str, str] | None = None  # version 3: {user-defined term: its formula}
    _model: Model = PrivateAttr()

    @model_validator(mode="after")
    def _fits_its_model(self):
        """The rules that tie fields together: the model is its terms, every parameter of it has a value, the
        scale factors are non-zero, and a model with temperature or drift terms has its reference T0/t0."""
        model = get_model("+".join(self.terms)) if self.terms else get_model(self.model)
        if self.model != model.name:
            raise _problem(f"model {self.model!r} does not match its terms {'+'.join(self.terms)}")
        self._check_user_terms(model)
        missing = [n for n in model.names if n not in self.parameters]
        if missing:
            raise _problem(f"parameter(s) {', '.join(missing)} of model {model.name} are missing")
        model.from_dict(self.parameters)  # a name the model lacks: InputError naming it
        if any(self.parameters[model.names[i]] == 0 for i in model.groups()["scale"]):
            raise _problem("a scale factor is zero; the calibration cannot be applied")
        if self.units.raw not in UNITS:
            raise _problem(f"units.raw {self.units.raw!r} is not an output unit optcal knows; "
                           f"it must be one of {', '.join(UNITS)}")
        if self.units.parameters is not None and self.units.parameters != model.units(self.units.raw):
            wrong = sorted(n for n, u in model.units(self.units.raw).items() if self.units.parameters.get(n) != u)
            raise _problem(f"units.parameters disagree with units.raw {self.units.raw!r} for "
                           f"{', '.join(wrong) or 'extra names'} (docs/design.md, 'Terms and parameters'); {_RECREATE}")
        if bool(self.forced) != bool(self.forced_reasons):
            raise _problem("a forced calibration has both forced: true and its forced_reasons, and only it has "
                           f"them; {_RECREATE}")
        ctx = self.context or _Context()
        for col, key in (("temp", "T0"), ("t", "t0")):
            if col in model.needs and getattr(ctx, key) is None:
                raise _problem(f"model {model.name} needs context.{key}, missing here")
        self._model = model
        return self

    def _check_user_terms(self, model: Model) -> None:
        """Version 3 is the version of user-defined terms: it has them and ``user_terms`` states each one's formula
        as optcal defines it from the name; version 2 has neither."""
        if self.format_version == 2:
            if model.user_terms or self.user_terms is not None:
                which = ", ".join(model.user_terms) or "user_terms"
                raise _problem(f"format_version 2 has no user-defined terms ({which}); set format_version 3 or "
                               f"{_RECREATE}")
            return
        if not model.user_terms:
            raise _problem(f"format_version 3 is for user-defined terms and model {model.name} has none; set "
                           f"format_version 2 or {_RECREATE}")
        want = model.user_formulas
        if self.user_terms != want:
            bad = sorted(t for t in set(want) | set(self.user_terms or {})
                         if (self.user_terms or {}).get(t) != want.get(t))
            raise _problem(f"user_terms disagree with the model's terms for {', '.join(bad)} (expected "
                           f"{'; '.join(f'{t}: {want[t]}' for t in bad if t in want) or 'none'}); {_RECREATE}")


# the fields every file must have besides format and format_version (docs/design.md, "Calibration file" lists them)
REQUIRED_FIELDS = tuple(n for n, f in CalibrationRecord.model_fields.items()
                        if f.is_required() and n not in ("format", "format_version"))
_KINDS = {"int_type": "an integer", "float_type": "a number", "string_type": "a string",
          "list_type": "an array", "dict_type": "an object", "model_type": "an object", "none_required": "null"}
_JSON_TYPES = {bool: "boolean", int: "integer", float: "number", str: "string", list: "array", dict: "object",
               type(None): "null"}
_RECREATE = "re-create it with optcal calibrate -o"


def error_line(exc: ValidationError, version: int) -> str:
    """The first of pydantic's errors as one line naming the field (``units.output``, ``parameters.K_x``);
    ``version`` the format version the file is read as."""
    e = exc.errors(include_url=False)[0]
    loc = [str(x) for x in e["loc"]]
    field, typ, value = ".".join(loc), e["type"], e.get("input")
    if typ == "calfile" or (typ == "value_error" and isinstance(e.get("ctx", {}).get("error"), InputError)):
        return e["msg"].removeprefix("Value error, ")
    if typ == "missing":
        where = f"field '{'.'.join(loc[:-1])}' lacks {loc[-1]!r}" if len(loc) > 1 else f"lacks the field {loc[0]!r}"
        return f"{where}; {_RECREATE}"
    if typ == "extra_forbidden":
        return f"field {field!r} is not part of format version {version}; remove it or {_RECREATE}"
    if typ in ("greater_than", "less_than") and loc == ["g_local"]:
        return f"g_local {value!r} is not a local gravity in g (it must lie between 0.5 and 2 g); {_RECREATE}"
    if typ == "finite_number":
        return f"field {field!r} is {value!r}, not a finite number; {_RECREATE}"
    if typ in _KINDS or typ.endswith("_type"):
        kind = _KINDS.get(typ, typ.removesuffix("_type"))
        got = "null" if value is None else \
            f"{_JSON_TYPES.get(type(value), type(value).__name__)} {json.dumps(value, default=repr)}"
        return f"field {field!r} is not {kind} (it is {got}): the file is damaged; {_RECREATE}"
    return f"field {field!r}: {e['msg']}; {_RECREATE}"


