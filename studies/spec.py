"""Study specs (docs/design.md §11.1): a TOML file, validated completely before anything runs.

A spec names the truth (the fixed ``paper`` values, ``draw`` per run, or a table of values), the models,
the presets given to the solvers (the manufacturer's calibration, 2020 paper §4.1, or none), the schemes,
noise, placement tilt, the number of Monte-Carlo runs, the base seed, the solvers with their options (and
an optional option grid), budgets, the verification set (36 positions by default, 2020 paper §5.1),
navigation settings and the executor. Every key is checked: an unknown key, solver, option, scheme or
model, or a value of the wrong type, raises :class:`~optcal.errors.InputError` naming the key.

The validated spec is *canonical*: defaults filled in and ``name = "all"`` expanded into the solvers the
registry holds, so its hash identifies exactly what a study folder contains.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

from optcal.errors import InputError
from optcal.model import get_model
from optcal.presets import PAPER_TRUTH
from optcal.schemes import scheme as scheme_directions

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

SPEC_DIR = Path(__file__).parent / "specs"

TOP_KEYS = {
    "name", "description", "runs", "quick_runs", "seed", "models", "schemes", "truth", "presets",
    "presets_error_scale", "noise_ug", "tilt_deg", "g_local", "budget", "verification", "navigation",
    "executor", "solvers",
}
SOLVER_KEYS = {"name", "label", "options", "grid", "budget", "reference", "reference_error_arcsec",
               "staged", "exclude"}
VERIFICATION_KEYS = {"scheme", "noise_ug", "tilt_deg"}
NAVIGATION_KEYS = {"enabled", "hours", "latitude_deg", "attitude_deg"}
EXECUTOR_KEYS = {"kind", "workers", "scheduler"}
BUDGET_KEYS = {"max_evals", "max_time", "target"}
EXECUTORS = ("serial", "processes", "dask")


@dataclass(frozen=True)
class SolverConfig:
    """One configured solver of a study: a registry name with options, a budget and, for the
    traditional calibration, the turntable reference and its orientation error."""

    label: str
    name: str
    options: dict = field(default_factory=dict)
    budget: dict = field(default_factory=dict)
    reference: bool = False
    reference_error_arcsec: float = 0.0


@dataclass(frozen=True)
class Spec:
    name: str
    description: str
    runs: int
    quick_runs: int
    seed: int
    models: tuple[str, ...]
    schemes: tuple[str, ...]
    truth: str | dict
    presets: str
    presets_error_scale: float
    noise_ug: float
    tilt_deg: float
    g_local: float
    verification: dict
    navigation: dict
    executor: dict
    solvers: tuple[SolverConfig, ...]
    source: str = ""

    def canonical(self) -> dict:
        """Everything that determines the trials' results (not the executor or the source path)."""
        d = asdict(self)
        for k in ("executor", "source", "description", "quick_runs"):
            d.pop(k)
        return d

    @property
    def hash(self) -> str:
        text = json.dumps(self.canonical(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def quick(self) -> Spec:
        """The ``--quick`` variant: the same study with ``quick_runs`` Monte-Carlo runs."""
        from dataclasses import replace

        return replace(self, runs=self.quick_runs, name=f"{self.name}-quick")

    def with_runs(self, runs: int) -> Spec:
        from dataclasses import replace

        return replace(self, runs=int(runs))


# -- helpers -------------------------------------------------------------------------------------

def _err(where: str, msg: str) -> InputError:
    return InputError(f"spec {where}: {msg}")


def _type_name(v) -> str:
    return {bool: "boolean", int: "integer", float: "number", str: "string", list: "array",
            dict: "table"}.get(type(v), type(v).__name__)


def _get(table: dict, key: str, kinds, default, where: str, path: str):
    if key not in table:
        return default
    v = table[key]
    kinds = kinds if isinstance(kinds, tuple) else (kinds,)
    if float in kinds and isinstance(v, int) and not isinstance(v, bool):
        v = float(v)
    if isinstance(v, bool) and bool not in kinds or not isinstance(v, kinds):
        want = " or ".join(_type_name(k()) if k is not type(None) else "none" for k in kinds)
        raise _err(where, f"key '{path}{key}' must be a {want}, got {_type_name(v)} {v!r}")
    return v


def _check_keys(table: dict, known: set, where: str, path: str) -> None:
    unknown = sorted(set(table) - known)
    if unknown:
        raise _err(where, f"unknown key '{path}{unknown[0]}'; known keys here: {', '.join(sorted(known))}")


def _positive(v, key, where, strict=True):
    if (v <= 0) if strict else (v < 0):
        raise _err(where, f"key '{key}' must be {'positive' if strict else 'non-negative'}, got {v}")
    return v


def _budget(value, where: str, key: str) -> dict:
    if value is None:
        return {}
    if isinstance(value, bool) or not isinstance(value, int | dict):
        raise _err(where, f"key '{key}' must be an integer (evaluations) or a table "
                          f"{{max_evals, max_time, target}}, got {_type_name(value)} {value!r}")
    if isinstance(value, int):
        value = {"max_evals": value}
    _check_keys(value, BUDGET_KEYS, where, key + ".")
    out = {}
    for k in ("max_evals", "max_time", "target"):
        kinds = int if k == "max_evals" else float
        v = _get(value, k, kinds, None, where, key + ".")
        if v is not None:
            out[k] = _positive(v, f"{key}.{k}", where, strict=k != "target")
    return out


def _scheme(s, where: str, key: str) -> str:
    if isinstance(s, bool) or not isinstance(s, int | str):
        raise _err(where, f"key '{key}' must be a scheme name (\"24\", \"36\", \"6\", \"random:N\"), got {s!r}")
    s = str(s)
    try:
        scheme_directions(s)
    except InputError as exc:
        raise _err(where, f"key '{key}': {exc}") from None
    return s


def _registry():
    import solvers  # noqa: F401 - imports every solver module, which registers it
    from solvers import registry

    return registry


def _solver_configs(entries, where: str, budget: dict) -> list[SolverConfig]:
    reg = _registry()
    if not isinstance(entries, list) or not entries:
        raise _err(where, "key 'solvers' must be a non-empty array of tables ([[solvers]] name = ...)")
    out: list[SolverConfig] = []
    for i, e in enumerate(entries):
        path = f"solvers[{i}]."
        if not isinstance(e, dict):
            raise _err(where, f"key 'solvers[{i}]' must be a table with at least 'name'")
        _check_keys(e, SOLVER_KEYS, where, path)
        name = _get(e, "name", str, None, where, path)
        if not name:
            raise _err(where, f"key '{path}name' is required (a registered solver, e.g. bsas, or \"all\")")
        b = _budget(e.get("budget"), where, path + "budget") or dict(budget)
        if name == "all":
            for k in ("options", "grid", "label", "reference", "reference_error_arcsec"):
                if k in e:
                    raise _err(where, f"key '{path}{k}' cannot be used with name = \"all\" "
                                      "(solvers have different options); list the solver separately")
            staged = _get(e, "staged", bool, True, where, path)
            exclude = _get(e, "exclude", list, [], where, path)
            known = reg.names()
            for x in exclude:
                if x not in known:
                    raise _err(where, f"key '{path}exclude': unknown solver {x!r}; registered: {', '.join(known)}")
            picked = [n for n in known if n not in exclude and reg.solver_class(n)[0].is_available()]
            if staged and "staged" in reg.wrappers():
                picked += [f"staged:{n}" for n in picked]
            out += [SolverConfig(n, n, {}, b) for n in picked]
            continue
        for k in ("staged", "exclude"):
            if k in e:
                raise _err(where, f"key '{path}{k}' is only for name = \"all\"")
        options = _get(e, "options", dict, {}, where, path)
        grid = _get(e, "grid", dict, {}, where, path)
        for k, v in grid.items():
            if not isinstance(v, list) or not v:
                raise _err(where, f"key '{path}grid.{k}' must be a non-empty array of values")
        reference = _get(e, "reference", bool, False, where, path)
        arcsec = e.get("reference_error_arcsec", 0.0)
        arcsecs = arcsec if isinstance(arcsec, list) else [arcsec]
        for a in arcsecs:
            if isinstance(a, bool) or not isinstance(a, int | float) or a < 0:
                raise _err(where, f"key '{path}reference_error_arcsec' must be a non-negative number or an "
                                  f"array of them, got {a!r}")
        if "reference_error_arcsec" in e and not reference:
            raise _err(where, f"key '{path}reference_error_arcsec' needs reference = true")
        label = _get(e, "label", str, name, where, path)
        combos = [dict(zip(grid, vals)) for vals in itertools.product(*grid.values())] if grid else [{}]
        for combo in combos:
            opts = {**options, **combo}
            try:
                reg.get(name, **opts)
            except InputError as exc:
                raise _err(where, f"key '{path}{'options' if opts else 'name'}': {exc}") from None
            except Exception as exc:  # noqa: BLE001 - a wrapper's own check; still a spec error
                raise _err(where, f"key '{path}options': solver {name}: {exc}") from None
            for a in arcsecs:
                lab = label
                if combo:
                    lab += "[" + ",".join(f"{k}={v}" for k, v in combo.items()) + "]"
                if len(arcsecs) > 1 or a:
                    lab += f"@{float(a):g}as"
                out.append(SolverConfig(lab, name, opts, b, reference, float(a)))
    labels = [c.label for c in out]
    dup = sorted({x for x in labels if labels.count(x) > 1})
    if dup:
        raise _err(where, f"key 'solvers': label {dup[0]!r} appears twice; give entries distinct 'label's")
    return out


def _truth(value, models, where: str):
    if isinstance(value, str):
        if value not in ("paper", "draw"):
            raise _err(where, f"key 'truth' must be \"paper\", \"draw\" or a table of parameter values, got {value!r}")
        if value == "paper":
            for m in models:
                missing = [n for n in get_model(m).names if n not in PAPER_TRUTH]
                if missing:
                    raise _err(where, f"key 'truth': the paper's truth has no value for {missing[0]} of model {m}; "
                                      "use truth = \"draw\" or a table of values")
        return value
    if isinstance(value, dict):
        for k, v in value.items():
            if isinstance(v, bool) or not isinstance(v, int | float):
                raise _err(where, f"key 'truth.{k}' must be a number, got {v!r}")
        known = {n for m in models for n in get_model(m).names}
        unknown = sorted(set(value) - known)
        if unknown:
            raise _err(where, f"key 'truth.{unknown[0]}' is not a parameter of the study's models "
                              f"({', '.join(models)}); their parameters are {', '.join(sorted(known))}")
        for m in models:
            missing = [n for n in get_model(m).names if n not in value]
            if missing:
                raise _err(where, f"key 'truth' lacks {missing[0]} of model {m}")
        return {k: float(v) for k, v in value.items()}
    raise _err(where, f"key 'truth' must be \"paper\", \"draw\" or a table of values, got {_type_name(value)}")


def parse(obj: dict, where: str = "<spec>", default_name: str = "study") -> Spec:
    """Validate a spec given as a dict (as read from TOML) and return the canonical :class:`Spec`."""
    if not isinstance(obj, dict):
        raise _err(where, "must be a TOML table")
    _check_keys(obj, TOP_KEYS, where, "")
    name = _get(obj, "name", str, default_name, where, "")
    runs = _positive(_get(obj, "runs", int, 10, where, ""), "runs", where)
    quick_runs = _positive(_get(obj, "quick_runs", int, min(runs, 5), where, ""), "quick_runs", where)
    seed = _positive(_get(obj, "seed", int, 0, where, ""), "seed", where, strict=False)
    models = obj.get("models", ["nonlinear12"])
    models = [models] if isinstance(models, str) else models
    if not isinstance(models, list) or not models or not all(isinstance(m, str) for m in models):
        raise _err(where, "key 'models' must be a model name or a non-empty array of them")
    for m in models:
        try:
            get_model(m)
        except InputError as exc:
            raise _err(where, f"key 'models': {exc}") from None
    schemes = obj.get("schemes", ["24"])
    schemes = schemes if isinstance(schemes, list) else [schemes]
    if not schemes:
        raise _err(where, "key 'schemes' must not be empty")
    schemes = [_scheme(s, where, f"schemes[{i}]") for i, s in enumerate(schemes)]
    # Each model and scheme once: a repeat would give two trials one id (the store keys rows by it).
    for key_name, values in (("models", [get_model(m).name for m in models]), ("schemes", schemes)):
        seen = set()
        for i, v in enumerate(values):
            if v in seen:
                raise _err(where, f"key '{key_name}[{i}]': {v!r} is listed twice")
            seen.add(v)
    truth = _truth(obj.get("truth", "paper"), models, where)
    presets = _get(obj, "presets", str, "manufacturer", where, "")
    if presets not in ("manufacturer", "none"):
        raise _err(where, f"key 'presets' must be \"manufacturer\" or \"none\", got {presets!r}")
    pscale = _positive(_get(obj, "presets_error_scale", float, 1.0, where, ""), "presets_error_scale", where, False)
    noise = _positive(_get(obj, "noise_ug", float, 10.0, where, ""), "noise_ug", where)
    tilt = _positive(_get(obj, "tilt_deg", float, 0.0, where, ""), "tilt_deg", where, strict=False)
    g_local = _positive(_get(obj, "g_local", float, 1.0, where, ""), "g_local", where)
    budget = _budget(obj.get("budget"), where, "budget")

    ver = _get(obj, "verification", dict, {}, where, "")
    _check_keys(ver, VERIFICATION_KEYS, where, "verification.")
    verification = {
        "scheme": _scheme(ver.get("scheme", "36"), where, "verification.scheme"),
        "noise_ug": _positive(_get(ver, "noise_ug", float, noise, where, "verification."), "verification.noise_ug",
                              where, strict=False),
        "tilt_deg": _positive(_get(ver, "tilt_deg", float, 0.0, where, "verification."), "verification.tilt_deg",
                              where, strict=False),
    }
    nav = _get(obj, "navigation", dict, {}, where, "")
    _check_keys(nav, NAVIGATION_KEYS, where, "navigation.")
    navigation = {
        "enabled": _get(nav, "enabled", bool, True, where, "navigation."),
        "hours": _positive(_get(nav, "hours", float, 5.0, where, "navigation."), "navigation.hours", where),
        # (optcal.nav runs up to 720 h)
        "latitude_deg": _get(nav, "latitude_deg", float, 45.0, where, "navigation."),
        "attitude_deg": _get(nav, "attitude_deg", list, [0.0, 0.0, 0.0], where, "navigation."),
    }
    if navigation["hours"] > 720.0:
        raise _err(where, "key 'navigation.hours' must be at most 720 (30 days)")
    if not -89.0 <= navigation["latitude_deg"] <= 89.0:  # the navigation frame is singular at the poles
        raise _err(where, "key 'navigation.latitude_deg' must be within [-89, 89]")
    att = navigation["attitude_deg"]
    if len(att) != 3 or not all(isinstance(a, int | float) and not isinstance(a, bool) for a in att):
        raise _err(where, "key 'navigation.attitude_deg' must be three numbers [roll, pitch, yaw] in degrees")
    navigation["attitude_deg"] = [float(a) for a in att]
    ex = _get(obj, "executor", dict, {}, where, "")
    _check_keys(ex, EXECUTOR_KEYS, where, "executor.")
    executor = {
        "kind": _get(ex, "kind", str, "serial", where, "executor."),
        "workers": _positive(_get(ex, "workers", int, 2, where, "executor."), "executor.workers", where),
        "scheduler": _get(ex, "scheduler", str, "", where, "executor."),
    }
    if executor["kind"] not in EXECUTORS:
        raise _err(where, f"key 'executor.kind' must be one of {', '.join(EXECUTORS)}, got {executor['kind']!r}")
    if executor["scheduler"] and executor["kind"] != "dask":
        raise _err(where, "key 'executor.scheduler' is for kind = \"dask\" (a Dask scheduler address)")
    if "solvers" not in obj:
        raise _err(where, "key 'solvers' is required ([[solvers]] name = \"bsas\" ...)")
    configs = _solver_configs(obj["solvers"], where, budget)
    return Spec(
        name=name, description=_get(obj, "description", str, "", where, ""), runs=runs, quick_runs=quick_runs,
        seed=seed, models=tuple(models), schemes=tuple(schemes), truth=truth, presets=presets,
        presets_error_scale=pscale, noise_ug=noise, tilt_deg=tilt, g_local=g_local, verification=verification,
        navigation=navigation, executor=executor, solvers=tuple(configs), source=where,
    )


def resolve_path(spec: str | Path) -> Path:
    """A spec file path, or the name of a spec shipped in ``studies/specs`` (``compare``, ``bsas2020``...)."""
    p = Path(spec)
    if p.is_file():
        return p
    shipped = SPEC_DIR / (p.name if p.suffix == ".toml" else f"{p.name}.toml")
    if shipped.is_file() and len(p.parts) == 1:
        return shipped
    names = ", ".join(sorted(q.stem for q in SPEC_DIR.glob("*.toml")))
    raise InputError(f"spec {spec}: no such file (shipped specs: {names})")


def load(spec: str | Path) -> Spec:
    """Read and validate a TOML spec file (or a shipped spec by name)."""
    path = resolve_path(spec)
    try:
        obj = tomllib.loads(path.read_text())
    except OSError as exc:
        raise InputError(f"spec {path}: cannot read it ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"spec {path}: not valid TOML ({exc})") from None
    return parse(obj, str(path), default_name=path.stem)
