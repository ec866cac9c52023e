"""Study specs (docs/design.md, "The spec"): a TOML file, validated completely before anything runs.

A spec names the problem (the accelerometer's, or the gyroscope's with its simulated recording in
``[gyroscope]``), the truth (the fixed ``paper`` values, ``draw`` per run, or a table of values), the models,
the presets given to the solvers (the manufacturer's calibration, 2020 paper §4.1, or none), the schemes,
noise, placement tilt, the number of Monte-Carlo runs, the base seed, the solvers with their options (and
an optional option grid), budgets, the verification set (36 positions by default, 2020 paper §5.1),
navigation settings and the executor. Every key is checked (the schema: :mod:`optcal.studies.spec_schema`, pydantic
models): an unknown key, solver, option, scheme or model, or a value of the wrong type, raises
:class:`~optcal.core.errors.InputError` naming the key.

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

from pydantic import ValidationError

from optcal.core.errors import InputError
from optcal.studies.spec_schema import EXECUTORS as EXECUTORS  # re-exported: optcal.studies.execute reads it
from optcal.studies.spec_schema import Budget, Executor, Navigation, SolverEntry, SpecFile, Verification, error_line

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

SPEC_DIR = Path(__file__).parent / "specs"

# The keys each table takes (the schema's fields).
TOP_KEYS = set(SpecFile.model_fields)
SOLVER_KEYS = set(SolverEntry.model_fields)
VERIFICATION_KEYS = set(Verification.model_fields)
NAVIGATION_KEYS = set(Navigation.model_fields)
EXECUTOR_KEYS = set(Executor.model_fields)
BUDGET_KEYS = set(Budget.model_fields)

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
    problem: str = "accelerometer"
    gyroscope: dict = field(default_factory=dict)  # the gyroscope study's recording (spec_schema.Gyroscope)

    def canonical(self) -> dict:
        """Everything that determines the trials' results (not the executor or the source path). An
        accelerometer study's has no ``problem`` or ``gyroscope`` key, so its hash is the one it had before
        the gyroscope's problem existed and its study folders still resume."""
        d = asdict(self)
        for k in ("executor", "source", "description", "quick_runs"):
            d.pop(k)
        if self.problem == "accelerometer":
            d.pop("problem")
            d.pop("gyroscope")
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


def _err(where: str, msg: str) -> InputError:
    return InputError(f"spec {where}: {msg}")


def _registry():
    from optcal.solvers import registry  # its listings import every solver module, which registers it

    return registry


def _solver_configs(entries: list[SolverEntry], where: str, budget: dict) -> list[SolverConfig]:
    """The configured solvers of the validated ``[[solvers]]`` entries: names and options checked against the
    registry, ``name = "all"`` expanded, one configuration per grid combination and orientation error."""
    reg = _registry()
    out: list[SolverConfig] = []
    for i, e in enumerate(entries):
        path = f"solvers[{i}]."
        b = (e.budget.model_dump(exclude_none=True) if e.budget is not None else {}) or dict(budget)
        if e.name == "all":
            known = reg.names()
            for x in e.exclude:
                if x not in known:
                    raise _err(where, f"key '{path}exclude': unknown solver {x!r}; registered: {', '.join(known)}")
            picked = [n for n in known if n not in e.exclude and reg.solver_class(n)[0].is_available()]
            if e.staged and "staged" in reg.wrappers():
                picked += [f"staged:{n}" for n in picked]
            out += [SolverConfig(n, n, {}, b) for n in picked]
            continue
        grid = e.grid
        arcsecs = e.reference_error_arcsec
        label = e.name if e.label is None else e.label
        combos = [dict(zip(grid, vals)) for vals in itertools.product(*grid.values())] if grid else [{}]
        for combo in combos:
            opts = {**e.options, **combo}
            try:
                reg.get(e.name, **opts)
            except InputError as exc:
                raise _err(where, f"key '{path}{'options' if opts else 'name'}': {exc}") from None
            except Exception as exc:  # noqa: BLE001 - a wrapper's own check; still a spec error
                raise _err(where, f"key '{path}options': solver {e.name}: {exc}") from None
            for a in arcsecs:
                lab = label
                if combo:
                    lab += "[" + ",".join(f"{k}={v}" for k, v in combo.items()) + "]"
                if len(arcsecs) > 1 or a:
                    lab += f"@{float(a):g}as"
                out.append(SolverConfig(lab, e.name, opts, b, e.reference, float(a)))
    labels = [c.label for c in out]
    dup = sorted({x for x in labels if labels.count(x) > 1})
    if dup:
        raise _err(where, f"key 'solvers': label {dup[0]!r} appears twice; give entries distinct 'label's")
    return out


def parse(obj: dict, where: str = "<spec>", default_name: str = "study") -> Spec:
    """Validate a spec given as a dict (as read from TOML) and return the canonical :class:`Spec`."""
    try:
        f = SpecFile.model_validate(obj)
    except ValidationError as exc:
        raise _err(where, error_line(exc)) from None
    budget = f.budget.model_dump(exclude_none=True) if f.budget is not None else {}
    v, nav, ex = f.verification, f.navigation, f.executor
    gyro = f.problem == "gyroscope"
    # A gyroscope study has no verification set and no navigation (both are the accelerometer's): scheme
    # "none" and navigation off say so in the stored spec.
    verification = {"scheme": "none" if gyro else v.scheme,
                    "noise_ug": f.noise_ug if v.noise_ug is None else v.noise_ug, "tilt_deg": v.tilt_deg}
    navigation = {"enabled": nav.enabled and not gyro, "hours": nav.hours, "latitude_deg": nav.latitude_deg,
                  "attitude_deg": list(nav.attitude_deg)}
    executor = {"kind": ex.kind, "workers": ex.workers, "scheduler": ex.scheduler}
    return Spec(
        name=default_name if f.name is None else f.name, description=f.description, runs=f.runs,
        quick_runs=min(f.runs, 5) if f.quick_runs is None else f.quick_runs, seed=f.seed,
        models=tuple(f.models), schemes=tuple(f.schemes), truth=f.truth, presets=f.presets,
        presets_error_scale=f.presets_error_scale, noise_ug=f.noise_ug, tilt_deg=f.tilt_deg, g_local=f.g_local,
        verification=verification, navigation=navigation, executor=executor,
        solvers=tuple(_solver_configs(f.solvers, where, budget)), source=where, problem=f.problem,
        gyroscope=f.gyroscope.model_dump() if gyro else {},
    )


def resolve_path(spec: str | Path) -> Path:
    """A spec file path, or the name of a spec shipped in ``optcal/studies/specs`` (``compare``, ``bsas2020``...)."""
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
