"""The study spec's schema (docs/design.md, "The spec") as pydantic models, and the translation of pydantic's
errors into one line naming the key in the spec file's own terms (``solvers[2].name``, ``verification.scheme``).

Types and bounds are the models' fields (strict: a string is never read as a number, nor a number as a
boolean); unknown keys are refused (``extra="forbid"``). Validators do only what a field type cannot: turn
the short forms into the long ones (``budget = 300``, ``models = "seed15"``, ``schemes = 24``), check names
against the model and scheme tables, and the rules that tie keys together (the truth against the models,
``name = "all"`` against the keys it excludes, ``scheduler`` against ``kind``, the ``problem`` against the
keys only the other problem has). Solver names and options are checked against the registry by
:func:`optcal.studies.spec.parse`, which also expands the entries.

``problem`` selects what is calibrated: the accelerometer (the default: position means, the norm cost) or
the gyroscope (rests with rotations between them, Tedaldi et al., ICRA 2014; :mod:`optcal.core.gyro`), whose
recording is described by the ``[gyroscope]`` table.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, get_args

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from optcal.core.errors import InputError
from optcal.core.gyro.model import get_gyro_model
from optcal.core.gyro.simulate import PROFILES
from optcal.core.model import get_model
from optcal.core.presets import PAPER_TRUTH
from optcal.core.schemes import scheme as scheme_directions

EXECUTORS = ("serial", "processes", "dask")
SCHEME_HINT = 'a scheme name ("24", "36", "6", "random:N")'
PROBLEMS = ("accelerometer", "gyroscope")
# The gyroscope's models by name: scale and misalignment with the bias taken from the rests (gyro9), with the
# bias fitted (gyro12), and with g-sensitivity (gyro21) (optcal.core.gyro.model).
GYRO_MODELS = {m.name: m for m in (get_gyro_model(False, bias=False), get_gyro_model(False), get_gyro_model(True))}
# The keys that describe the accelerometer's problem only: given with problem = "gyroscope" they are refused
# rather than ignored.
ACCELEROMETER_ONLY = ("presets_error_scale", "tilt_deg", "g_local", "verification", "navigation")


def gyro_sensor(model: str):
    """The sensor model a gyroscope study simulates for the fitted model ``model``: the sensor always has a
    bias (gyro9 takes it from the rests instead of fitting it)."""
    return get_gyro_model(GYRO_MODELS[model].g_sensitivity)


def _problem(text: str, at: str = "") -> PydanticCustomError:
    """An error whose text follows the key; ``at`` extends the key (``[1]``, ``.options``) where a validator
    of a whole list or table finds the fault in one of its items."""
    return PydanticCustomError("spec", "{text}", {"text": text, "at": at})


def _name_of_number(v):
    """Schemes may be written as numbers (``schemes = [24, 36]``); booleans stay booleans (refused)."""
    return str(v) if isinstance(v, int) and not isinstance(v, bool) else v


def _check_scheme(s: str) -> str:
    scheme_directions(s)  # raises InputError naming the problem
    return s


def _as_list(v):
    return v if isinstance(v, list) else [v]


def _budget_table(v):
    return {"max_evals": v} if isinstance(v, int) and not isinstance(v, bool) else v


def _repeats(values: list) -> None:
    """Each model and scheme once: a repeat would give two trials one id (the store keys rows by it)."""
    seen = set()
    for i, v in enumerate(values):
        if v in seen:
            raise _problem(f"lists {v!r} a second time; give each once", f"[{i}]")
        seen.add(v)


SchemeName = Annotated[str, BeforeValidator(_name_of_number), AfterValidator(_check_scheme)]


class _Table(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)


class Budget(_Table):
    max_evals: int | None = Field(None, gt=0, description="an integer number of evaluations")
    max_time: float | None = Field(None, gt=0, description="a number of seconds")
    target: float | None = Field(None, ge=0, description="a number: the cost at which to stop")


BudgetField = Annotated[
    Budget | None,
    BeforeValidator(_budget_table),
    Field(description="an integer (evaluations) or a table {max_evals, max_time, target}"),
]


class Verification(_Table):
    scheme: SchemeName = Field("36", description=SCHEME_HINT)
    noise_ug: float | None = Field(None, ge=0, description="a number of µg (default: the study's noise_ug)")
    tilt_deg: float = Field(0.0, ge=0, description="a number of degrees")


class Navigation(_Table):
    enabled: bool = True
    hours: float = Field(5.0, gt=0, le=720.0, description="a number of hours")
    # the navigation frame is singular at the poles
    latitude_deg: float = Field(45.0, ge=-89.0, le=89.0, description="a number of degrees")
    attitude_deg: list[float] = Field([0.0, 0.0, 0.0], min_length=3, max_length=3,
                                      description="three numbers [roll, pitch, yaw] in degrees")


class Gyroscope(_Table):
    """The simulated recording of a gyroscope study (:func:`optcal.core.gyro.simulate.simulate_imu`)."""

    rate_hz: float = Field(100.0, gt=0, le=10_000, description="a number of Hz")
    rest_s: float = Field(3.0, gt=0, description="a number of seconds")
    motion_s: float = Field(2.0, gt=0, description="a number of seconds")
    profile: Literal[tuple(PROFILES)] = Field(
        "smooth", description=f"a rotation profile: {' or '.join(repr(p) for p in PROFILES)}")
    # white rate noise, Kalibr's gyroscope_noise_density: per-sample SD = density · √rate_hz
    noise_rad_s_rthz: float = Field(1e-4, gt=0, description="a number of rad/s/√Hz")
    # bias instability as a random walk of the rate bias, Kalibr's gyroscope_random_walk
    bias_walk_rad_s2_rthz: float = Field(0.0, ge=0, description="a number of rad/s²/√Hz (rad/s per √s)")
    scale: float = Field(1000.0, gt=0, description="a number of output units (counts) per rad/s")

    @model_validator(mode="after")
    def _samples_to_integrate(self):
        # a rest needs samples to average and a motion samples to integrate
        if self.rest_s * self.rate_hz < 10:
            raise _problem("holds fewer than 10 samples at rate_hz; lengthen the rests", ".rest_s")
        if self.motion_s * self.rate_hz < 10:
            raise _problem("holds fewer than 10 samples at rate_hz; lengthen the motions", ".motion_s")
        return self


class Executor(_Table):
    kind: Literal[EXECUTORS] = "serial"
    workers: int = Field(2, gt=0, description="an integer number of worker processes")
    scheduler: str = Field("", description='a string: the Dask scheduler address, for kind = "dask"')

    @model_validator(mode="after")
    def _scheduler_is_for_dask(self):
        if self.scheduler and self.kind != "dask":
            raise _problem('is for kind = "dask" (a Dask scheduler address)', ".scheduler")
        return self


ONLY_WITHOUT_ALL = ("options", "grid", "label", "reference", "reference_error_arcsec")


class SolverEntry(_Table):
    name: str = Field(min_length=1, description='a registered solver, e.g. bsas, or "all"')
    label: str | None = Field(None, description="a string: the label in the report (default: the name)")
    options: dict[str, Any] = {}
    grid: dict[str, Annotated[list[Any], Field(min_length=1)]] = Field(
        {}, description="a table of option = non-empty array of values")
    budget: BudgetField = None
    reference: bool = False
    reference_error_arcsec: Annotated[list[Annotated[float, Field(ge=0)]], BeforeValidator(_as_list)] = Field(
        [0.0], description="a non-negative number of arcseconds or an array of them")
    staged: bool = True
    exclude: list[str] = []

    @model_validator(mode="after")
    def _keys_that_go_together(self):
        given = self.model_fields_set
        if self.name == "all":
            for k in ONLY_WITHOUT_ALL:
                if k in given:
                    raise _problem('cannot be used with name = "all" (solvers have different options); list the '
                                   "solver separately", f".{k}")
        else:
            for k in ("staged", "exclude"):
                if k in given:
                    raise _problem('is only for name = "all"', f".{k}")
            if "reference_error_arcsec" in given and not self.reference:
                raise _problem("needs reference = true", ".reference_error_arcsec")
        return self


def _truth_kind(v):
    return "|table" if isinstance(v, dict) else "|name" if isinstance(v, str) else None


# A union told apart by the value's type; its tags start with "|" so that error_line can drop them from
# the key path.
TruthField = Annotated[
    Annotated[Literal["paper", "draw"], Tag("|name")] | Annotated[dict[str, float], Tag("|table")],
    Discriminator(_truth_kind, custom_error_type="spec", custom_error_message="{text}",
                  custom_error_context={"text": 'must be "paper", "draw" or a table of parameter values'}),
    Field(description='"paper", "draw" or a table of parameter values'),
]


# A stated limit: each trial is a record in memory before it runs, so a mistyped run count (1e8) would
# exhaust the machine's memory instead of failing. 10,000 runs is already 200 times the compare study's.
MAX_RUNS = 10_000


class SpecFile(_Table):
    """The spec as written: every key, its type and bounds, and the defaults that need no other key."""

    name: str | None = None
    description: str = ""
    problem: Literal[PROBLEMS] = Field("accelerometer", description='"accelerometer" or "gyroscope"')
    runs: int = Field(10, gt=0, le=MAX_RUNS, description="an integer number of Monte-Carlo runs")
    quick_runs: int | None = Field(None, gt=0, le=MAX_RUNS,
                                   description="an integer number of runs (default min(runs, 5))")
    seed: int = Field(0, ge=0, description="a non-negative integer")
    # models, truth and presets not given default by the problem (the _defaults_of_the_problem validator)
    models: Annotated[list[str], BeforeValidator(_as_list)] = Field(
        ["nonlinear12"], min_length=1, description="a model name or a non-empty array of them")
    schemes: Annotated[list[SchemeName], BeforeValidator(_as_list)] = Field(
        ["24"], min_length=1, description=f"{SCHEME_HINT} or an array of them")
    truth: TruthField = "paper"
    presets: Literal["manufacturer", "none"] = "manufacturer"
    presets_error_scale: float = Field(1.0, gt=0, description="a positive number: the factor on the manufacturer's "
                                       "error SDs (0, exact presets, leaves the bound with presets undefined: give "
                                       "a small factor such as 1e-3)")
    noise_ug: float = Field(10.0, gt=0, description="a number of µg")
    tilt_deg: float = Field(0.0, ge=0, description="a number of degrees")
    g_local: float = Field(1.0, gt=0, description="a number: the local gravity in g")
    budget: BudgetField = None
    verification: Verification = Verification()
    navigation: Navigation = Navigation()
    executor: Executor = Executor()
    gyroscope: Gyroscope | None = None
    solvers: list[SolverEntry] = Field(min_length=1, description='an array of tables ([[solvers]] name = "bsas" ...)')

    @field_validator("models")
    @classmethod
    def _known_models(cls, models: list[str], info: ValidationInfo) -> list[str]:
        if info.data.get("problem") == "gyroscope":
            for i, m in enumerate(models):
                if m not in GYRO_MODELS:
                    raise _problem(f"is {m!r}, not a gyroscope model; use {', '.join(GYRO_MODELS)}", f"[{i}]")
            _repeats(models)
            return models
        canonical = [get_model(m).name for m in models]  # an unknown model raises InputError
        _repeats(canonical)
        return models

    @model_validator(mode="after")
    def _defaults_of_the_problem(self):
        gyro = self.problem == "gyroscope"
        given = self.model_fields_set
        if gyro:
            for k in ACCELEROMETER_ONLY:
                if k in given:
                    raise _problem('is for the accelerometer\'s problem; a gyroscope study describes its recording '
                                   'in [gyroscope]', f".{k}")
            if "truth" in given and self.truth == "paper":
                raise _problem('cannot be "paper" for the gyroscope (the papers calibrate accelerometers); use '
                               'truth = "draw" or a table of values', ".truth")
            if "presets" in given and self.presets == "manufacturer":
                raise _problem('cannot be "manufacturer" for the gyroscope: its search starts at the nominal scale '
                               "and the rests' mean bias; leave presets out", ".presets")
            for i, e in enumerate(self.solvers):
                if e.reference:
                    raise _problem("is the accelerometer's turntable calibration; a gyroscope study has none",
                                   f"solvers[{i}].reference")
        elif self.gyroscope is not None:
            raise _problem('is for problem = "gyroscope"', ".gyroscope")
        if gyro:
            self.models = self.models if "models" in given else ["gyro12"]
            self.truth = self.truth if "truth" in given else "draw"
            self.presets = "none"
            self.gyroscope = self.gyroscope or Gyroscope()
        return self

    @field_validator("schemes")
    @classmethod
    def _each_scheme_once(cls, schemes: list[str]) -> list[str]:
        _repeats(schemes)
        return schemes

    @model_validator(mode="after")
    def _truth_fits_the_models(self):
        # the gyroscope's truth is the sensor's (with its bias also where gyro9 takes the bias from the rests)
        gyro = self.problem == "gyroscope"
        names = {m: gyro_sensor(m).names if gyro else get_model(m).names for m in self.models}
        of = (lambda m: f"the sensor simulated for model {m}") if gyro else (lambda m: f"model {m}")
        if self.truth == "paper":
            for m, ns in names.items():
                missing = [n for n in ns if n not in PAPER_TRUTH]
                if missing:
                    raise _problem(f"cannot be \"paper\": the paper's truth has no value for {missing[0]} of model "
                                   f'{m}; use truth = "draw" or a table of values', ".truth")
        elif isinstance(self.truth, dict):
            known = {n for ns in names.values() for n in ns}
            unknown = sorted(set(self.truth) - known)
            if unknown:
                raise _problem(f"is not a parameter of the study's models ({', '.join(self.models)}); their "
                               f"parameters are {', '.join(sorted(known))}", f".truth.{unknown[0]}")
            for m, ns in names.items():
                missing = [n for n in ns if n not in self.truth]
                if missing:
                    raise _problem(f"lacks {missing[0]} of {of(m)}", ".truth")
        return self


# -- pydantic's errors as one line ---------------------------------------------------------------------

_KINDS = {"int_type": "an integer", "float_type": "a number", "string_type": "a string",
          "bool_type": "a boolean (true or false)", "list_type": "an array", "dict_type": "a table",
          "model_type": "a table", "model_attributes_type": "a table"}


def _toml_type(v) -> str:
    return {bool: "boolean", int: "integer", float: "number", str: "string", list: "array",
            dict: "table"}.get(type(v), type(v).__name__)


def _toml_value(v) -> str:
    return ("true" if v else "false") if isinstance(v, bool) else repr(v)


def _model_in(annotation) -> type[BaseModel] | None:
    """The pydantic model inside an annotation (``Budget | None``, ``list[SolverEntry]``), if any."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in get_args(annotation):
        found = _model_in(arg)
        if found is not None:
            return found
    return None


def _walk(root: type[BaseModel], loc: tuple) -> tuple[str, Any, bool, type[BaseModel] | None]:
    """The key path of ``loc`` as the spec writes it (``solvers[0].grid.ftol``); the last field on it (for
    its description) and whether the path ends at that field or an item of its array (not inside a table
    of free keys such as ``truth.K_x``); and the table that holds the last key (for the keys it knows)."""
    path, field, exact, model, parent = "", None, True, root, root
    for el in loc:
        if isinstance(el, int):
            path += f"[{el}]"
            continue
        if el.startswith("|"):
            continue  # the tag of a union member, not a key
        path += ("." if path else "") + el
        parent = model
        if model is not None and el in model.model_fields:
            field, exact = model.model_fields[el], True
            model = _model_in(field.annotation)
        else:
            model, exact = None, False
    return path, field, exact, parent


def _bounds(field) -> list[tuple[str, float]]:
    """The field's bounds as [(kind, value)], lower first: kind "gt", "ge", "lt" or "le"."""
    meta = getattr(field, "metadata", [])
    return [(k, getattr(m, k)) for k in ("gt", "ge", "lt", "le") for m in meta if getattr(m, k, None) is not None]


def error_line(exc: ValidationError, root: type[BaseModel] = SpecFile) -> str:
    """The first of pydantic's errors as one line: ``key 'PATH' <what is wrong and what it must be>``, in the
    spec's terms (TOML types, key paths as written) and with the field's description of what it takes."""
    e = exc.errors(include_url=False)[0]
    path, field, exact, parent = _walk(root, e["loc"])
    typ, ctx, value = e["type"], e.get("ctx", {}), e.get("input")
    want = getattr(field, "description", None) if exact else None
    if typ in ("model_type", "dict_type") and isinstance(e["loc"][-1], int):
        want = None  # an item of an array of tables: "must be a table" says it
    got = f"got {_toml_type(value)} {_toml_value(value)}"
    if typ == "spec":  # our validators' own errors
        at = ctx.get("at", "")
        path += at if path else at.lstrip(".")
        return f"key '{path}' {ctx['text']}" + (f", {got}" if ctx["text"].startswith("must be") else "")
    if not path:
        return "must be a TOML table of keys" if typ in _KINDS else e["msg"]
    if typ == "extra_forbidden":
        known = ", ".join(sorted(parent.model_fields)) if parent is not None else ""
        return f"unknown key '{path}'" + (f"; known keys here: {known}" if known else "")
    if typ == "missing":
        return f"key '{path}' is required" + (f": {want}" if want else "")
    if typ == "value_error" and isinstance(ctx.get("error"), InputError):
        return f"key '{path}': {ctx['error']}"
    if typ in _KINDS or typ == "literal_error":
        return f"key '{path}' must be {want or _KINDS.get(typ) or ctx['expected']}, {got}"
    if typ in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        words = {"gt": "above", "ge": "at least", "lt": "below", "le": "at most"}
        kind = {"greater_than": "gt", "greater_than_equal": "ge", "less_than": "lt", "less_than_equal": "le"}[typ]
        bounds = _bounds(field)
        if kind not in dict(bounds):  # the bound of an array's item, not of the field
            bounds = [(kind, ctx[kind])]
        if len(bounds) == 2 and {k for k, _ in bounds} == {"ge", "le"}:
            phrase = f"within [{bounds[0][1]:g}, {bounds[1][1]:g}]"
        elif len(bounds) == 1 and bounds[0][1] == 0 and bounds[0][0] in ("gt", "ge"):
            phrase = "positive" if bounds[0][0] == "gt" else "non-negative"
        else:
            phrase = " and ".join(f"{words[k]} {v:g}" for k, v in bounds)
        return f"key '{path}' must be {phrase}, got {_toml_value(value)}"
    if typ in ("too_short", "string_too_short") and ctx.get("min_length") == 1:
        return f"key '{path}' must not be empty: give " + (want or "an array of values")
    if typ in ("too_short", "too_long"):
        return f"key '{path}' must be {want or 'an array of another length'}, got {_toml_value(value)}"
    return f"key '{path}': {e['msg']}" + (f" ({want})" if want else "")
