"""``mealpy:NAME``: any optimiser of mealpy, the largest zoo of nature-inspired metaheuristics, as a solver family.

``mealpy:GWO`` (grey wolf), ``mealpy:WOA`` (whale), ``mealpy:HHO`` (Harris hawks), ``mealpy:OriginalDE``,
``mealpy:DevSMA``, ...: the suffix is the name of an optimiser class of mealpy 3 (Van Thieu & Mirjalili 2023,
"MEALPY: An open-source library for latest meta-heuristic algorithms in Python", Journal of Systems
Architecture 139, 102871), or of its module, which names the algorithm's original version (``GWO`` is
``OriginalGWO``). docs/algorithms.md, "mealpy's optimisers (`mealpy:<NAME>`)". mealpy is GPL-3.0: it is imported when
a ``mealpy:`` solver runs, never copied; ``make`` installs it without its declared dependencies (its pin numpy<=1.26
excludes the NumPy that nlopt and cvxpy need; pyproject.toml, ``[tool.optcal] install-without-deps``).
"""

from __future__ import annotations

import difflib
import functools
import importlib.util
import inspect
import math
import types
import warnings

import numpy as np

from optcal.core.errors import BudgetExhausted, InputError
from optcal.solvers._unitbox import normalised_start, uniform_pm1
from optcal.solvers.base import Option, Solver
from optcal.solvers.registry import register_family

INSTALL = "pip install --no-deps mealpy==3.0.3 opfunu==1.0.4 (make installs them)"
LIST_HINT = "optcal solvers lists them; optcal solvers mealpy:NAME describes one"
# What mealpy is told for a candidate whose cost is NaN (the model's inversion failed): a finite value far
# above any cost in the box (a sum of squared errors of about g per position), because several of its
# optimisers compute with the costs themselves (roulette weights, logarithms, differences), where +inf
# would turn into NaN positions. The problem never keeps such a point as its best.
FAILED = 1e30
MAX_EPOCH = 100_000  # mealpy's own upper bound on ``epoch``
PROBE_EPOCHS = 10


@functools.cache
def optimizers() -> dict[str, tuple[type, str]]:
    """{class name: (class, module name)} of every optimiser mealpy defines, found by walking its modules for
    subclasses of ``mealpy.optimizer.Optimizer`` without constructing any (``mealpy.get_all_optimizers``
    constructs each with its defaults, and one of them, OriginalBCO, refuses its own default)."""
    import mealpy
    from mealpy.optimizer import Optimizer

    out: dict[str, tuple[type, str]] = {}
    for mod_name, mod in inspect.getmembers(mealpy, inspect.ismodule):
        for cls_name, cls in inspect.getmembers(mod, inspect.isclass):
            if issubclass(cls, Optimizer) and cls is not Optimizer and cls.__module__ == mod.__name__:
                out[cls_name] = (cls, mod_name)
    return out


def resolve(name: str) -> type:
    """The optimiser class ``name`` names: a class name (``OriginalGWO``, ``DevSMA``; any letter case), or a
    module name (``GWO``), which stands for its ``Original<module>`` class, or its only class."""
    known = optimizers()
    if name in known:
        return known[name][0]
    lower = {k.lower(): k for k in known}
    if name.lower() in lower:
        return known[lower[name.lower()]][0]
    modules: dict[str, list[str]] = {}
    for cls_name, (_, mod) in known.items():
        modules.setdefault(mod.lower(), []).append(cls_name)
    members = modules.get(name.lower())
    if members:
        original = [c for c in members if c.lower() == "original" + name.lower()]
        if original or len(members) == 1:
            return known[(original or members)[0]][0]
        raise InputError(f"mealpy's module {name} has several optimisers; name one: {', '.join(sorted(members))}")
    hits = difflib.get_close_matches(name.lower(), list(lower) + list(modules), n=5, cutoff=0.6)
    close = [lower.get(h, h.upper()) for h in hits]
    raise InputError(f"unknown mealpy optimiser {name!r} (mealpy:{name}); "
                     + (f"close names: {', '.join(close)}; " if close else "") + LIST_HINT)


def settings_of(cls: type) -> dict[str, inspect.Parameter]:
    """The keywords of an optimiser's constructor (its own settings: ``epoch``, ``pop_size``, ...)."""
    params = inspect.signature(cls.__init__).parameters
    return {k: p for k, p in params.items() if k != "self" and p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)}


class Mealpy(Solver):
    """A mealpy optimiser (``mealpy:NAME``) in the problem's unit box, its population evaluated in one batch.

    The problem given to mealpy is the unit box z ∈ [-1, 1]^n (2020 paper §3.4), ``FloatVar(lb=-1, ub=1)``,
    minimised; mealpy's own bound handling (clipping, ``correct_solution``) keeps its candidates in it. The
    initial population is uniform in the box with ``x0`` (the presets or the initialiser) as its first member
    (``init="start"``) or without it (``"uniform"``), drawn from ``rng``; mealpy's ``seed`` (its NumPy
    Generator, its ``random.Random`` and its variables' generator) is an integer drawn from ``rng``.

    Batches (``mode``): ``"swarm"``, mealpy's mode in which the moves of one step are all made before any is
    evaluated, evaluates each population mealpy hands over (``update_target_for_population``) in ONE
    ``problem.cost_batch`` call; ``"single"``, mealpy's default, evaluates each candidate as it is made
    (``problem.cost``), so later members of a step see earlier ones' costs, as the algorithms' papers write
    them. Optimisers that evaluate candidate by candidate in either mode (those mealpy marks as not
    parallelisable) call ``problem.cost`` for each. A NaN cost is told to mealpy as :data:`FAILED`.

    Epochs: mealpy's schedules run over ``epoch`` iterations (GWO's a falls from 2 to 0 over them). With
    ``epoch=0`` it is sized from the evaluation budget: the evaluations left after the initial population
    over the evaluations one epoch takes, measured once per optimiser, settings and dimension on a sphere
    in the box (mealpy's optimisers take one to three evaluations per member and epoch), rounded up, so the
    schedule ends where the budget does and a binding budget is used exactly. Without an evaluation limit
    (a time budget), mealpy's default ``epoch`` runs. One epoch is one iteration (``callback``).

    Stopping: mealpy has no termination of its own beyond its epochs (its early stop is not used), and its
    optimisers' best costs often stay flat for long stretches and then improve (grey wolf: a tenth of the
    budget without a relative improvement of 1e-5, then 0.16 → 0.48 of the optimum's cost left; docs/
    performance.md), so a solve takes the stagnation rule (:class:`optcal.solvers.base.Stagnation`) only with
    ``stop_on_stagnation=True``.

    Options: ``mode``, ``init``, ``epoch``, ``stop_on_stagnation``, and any keyword of the optimiser's
    constructor (``pop_size``, and its own parameters, e.g. ``--option pop_size=30``), checked when the
    solver is built by constructing the optimiser (mealpy's own range checks give the one-line error).
    """

    name = "mealpy"
    family = "metaheuristic"
    requires = ("mealpy",)
    default_budget = 20000
    options = {
        "mode": Option("swarm", str, "'swarm': each population in one cost_batch call; 'single': each candidate "
                       "evaluated as it is made (mealpy's default)", choices=("swarm", "single")),
        "init": Option("start", str, "initial population: uniform in the box with x0 as one member ('start') or "
                       "without it ('uniform')", choices=("start", "uniform")),
        "epoch": Option(0, int, "mealpy's epochs; 0: sized from the evaluation budget",
                        check=lambda v: 0 <= v <= MAX_EPOCH, check_doc=f"in [0, {MAX_EPOCH}]"),
        "stop_on_stagnation": Option(False, bool, "end the solve by the stagnation rule a study gives (off: "
                                     "mealpy's optimisers often stall for long stretches, then improve)"),
    }

    def __init__(self, optimizer: str, **options):
        self.optimizer = optimizer
        ours = {k: v for k, v in options.items() if k in self.options}
        self.passthrough = {k: v for k, v in options.items() if k not in self.options}
        self.name = f"mealpy:{optimizer}"
        super().__init__(**ours)
        self.stops_on_stagnation = self.config["stop_on_stagnation"]
        self._cls = None
        if self.is_available():
            self._cls = resolve(optimizer)
            self._check_settings()

    @classmethod
    def unavailable_message(cls) -> str:
        return f"the mealpy: solvers need mealpy; install it with {INSTALL}"

    def _check_settings(self) -> None:
        known = settings_of(self._cls)
        unknown = sorted(set(self.passthrough) - set(known))
        if unknown:
            keys = ", ".join(k for k in known if k != "epoch")
            raise InputError(f"solver {self.name}: unknown option(s) {', '.join(unknown)}; its options are "
                             f"{', '.join(self.options)} and mealpy's {self._cls.__name__} settings: {keys or 'none'}")
        self._build(self.config["epoch"] or None)

    def _build(self, epoch: int | None):
        """The optimiser with the pass-through settings (and ``epoch`` if given); mealpy's refusal, one line."""
        kwargs = dict(self.passthrough)
        if epoch is not None:
            kwargs["epoch"] = epoch
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return self._cls(**kwargs)
        except Exception as exc:  # noqa: BLE001 - mealpy's checks raise ValueError, TypeError, ...; one line
            text = str(exc).strip().splitlines()
            raise InputError(f"solver {self.name}: mealpy's {self._cls.__name__} refused the settings "
                             f"{self.passthrough or '{}'}: {type(exc).__name__}: {text[0] if text else ''}; give "
                             "them with --option KEY=VALUE") from None

    # -- the search -------------------------------------------------------------------------------
    def _solve(self, problem, x0, rng, callback):
        zp, z0 = normalised_start(problem, x0)
        n, counter = zp.n, problem.counter
        max_evals = counter.budget.max_evals
        left = None if max_evals is None else max_evals - counter.nfev
        mode, epochs = self.config["mode"], self.config["epoch"] or None
        if epochs is None and left is not None:
            pop = self._build(None).pop_size
            per = evaluations_per_epoch(self._cls, tuple(sorted(self.passthrough.items())), n, mode)
            epochs = min(MAX_EPOCH, max(1, math.ceil((left - pop) / per)))
        opt = self._build(epochs)
        Z = uniform_pm1(rng, (opt.pop_size, n))
        if self.config["init"] == "start":
            Z[0] = z0
        evaluation(opt, zp.cost_batch, Z, mode)
        seed, legacy = (int(v) for v in rng.integers(2**32, size=2))
        nit = [0]
        evolve = opt.evolve

        def counted(epoch):
            evolve(epoch)
            nit[0] = epoch
            callback(epoch)

        opt.evolve = counted
        extra = {"optimizer": type(opt).__name__, "epochs": opt.epoch, "pop_size": opt.pop_size, "mode": mode}
        try:
            run(opt, zp, n, seed, mode, legacy)
        except BudgetExhausted as exc:
            return {"nit": nit[0], "status": 1, "success": True, "extra": extra,
                    "message": f"{exc} in epoch {nit[0] + 1} of {opt.epoch}"}
        return {"nit": nit[0], "status": 0, "success": True, "extra": extra,
                "message": f"mealpy {type(opt).__name__}: {opt.epoch} epochs run"}


def _cost_one(cost):
    def obj(z):
        f = cost(z)
        return f if f == f else FAILED  # NaN: a failed evaluation

    return obj


def evaluation(opt, cost_batch, Z: np.ndarray, mode: str) -> None:
    """Make ``opt`` start from the population ``Z`` and, in "swarm" mode, evaluate every population it hands
    over in one ``cost_batch`` call.

    mealpy builds its initial population in ``generate_population`` (called when it has none); here its
    first call returns the members of ``Z`` (later calls, for restarts, draw from mealpy's generator as
    before). Members are made by the optimiser's own ``generate_agent`` where it defines one (it sets more
    than the cost, e.g. PSO's personal best), one evaluation each, else built empty and evaluated together.
    In "swarm" mode ``update_target_for_population`` (which mealpy runs member by member) is one batch."""
    from mealpy.optimizer import Optimizer
    from mealpy.utils.target import Target

    own_agent = type(opt).generate_agent is not Optimizer.generate_agent
    start = [Z]

    def evaluate(self, pop=None):
        X = np.array([a.solution for a in pop], float)
        f = cost_batch(X)
        f[np.isnan(f)] = FAILED
        w = self.problem.obj_weights
        for a, v in zip(pop, f.tolist()):
            a.target = Target(v, w)
        self.nfe_counter += len(pop)
        return pop

    def generate(self, pop_size=None):
        k = pop_size or self.pop_size
        rows = start.pop() if start and len(start[0]) == k else [None] * k
        if own_agent or mode != "swarm":
            return [self.generate_agent(None if z is None else np.array(z)) for z in rows]
        return evaluate(self, [self.generate_empty_agent(None if z is None else np.array(z)) for z in rows])

    opt.generate_population = types.MethodType(generate, opt)
    if mode == "swarm":
        opt.update_target_for_population = types.MethodType(evaluate, opt)


def run(opt, zp, n: int, seed: int, mode: str, legacy: int) -> None:
    """``opt.solve`` on the n-parameter unit box of ``zp``, quietly (mealpy logs nothing but errors; NumPy's
    warnings from its arithmetic on the box's edges are not the user's to act on).

    Some of mealpy's optimisers draw from NumPy's global random state rather than from their generator
    (SHADE, JADE and L-SHADE-cnEpSin through ``scipy.stats``' ``rvs``; BCO and AO through ``np.random``): it is
    seeded with ``legacy`` for the solve and put back as it was after it, so their runs are reproducible too
    and the caller's global state is untouched."""
    from mealpy import FloatVar

    bounds = FloatVar(lb=[-1.0] * n, ub=[1.0] * n, name="z")
    problem = {"bounds": bounds, "minmax": "min", "obj_func": _cost_one(zp.cost), "obj_weights": [1.0],
               "log_to": None, "name": "optcal"}
    state = np.random.get_state()  # noqa: NPY002 - mealpy draws from the global state: kept and restored
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            np.random.seed(legacy)  # noqa: NPY002 - see the docstring: mealpy's own draws, restored below
            opt.solve(problem, mode=mode, seed=seed)
    finally:
        np.random.set_state(state)  # noqa: NPY002


@functools.cache
def evaluations_per_epoch(cls: type, settings: tuple, n: int, mode: str) -> float:
    """Evaluations one epoch of ``cls`` takes (with ``settings``) on an n-parameter problem: the mean over a
    schedule of :data:`PROBE_EPOCHS` epochs on a sphere in the unit box, from a population drawn with a fixed
    seed (a measurement of the algorithm's bookkeeping, not a part of any solve's random stream), at least 1.
    Optimisers whose evaluations per epoch change along their schedule (HHO's phases) get the mean."""
    count = [0]

    class Sphere:
        @staticmethod
        def cost(z):
            count[0] += 1
            return float(np.dot(z, z))

        @staticmethod
        def cost_batch(Z):
            count[0] += len(Z)
            return np.einsum("ij,ij->i", Z, Z)

    opt = cls(**{**dict(settings), "epoch": PROBE_EPOCHS})
    evaluation(opt, Sphere.cost_batch, np.random.default_rng(0).uniform(-1.0, 1.0, (opt.pop_size, n)), mode)
    evolve, start = opt.evolve, []

    def counted(epoch):
        if not start:
            start.append(count[0])
        evolve(epoch)

    opt.evolve = counted
    run(opt, Sphere, n, 0, mode, 0)
    return max(1.0, (count[0] - start[0]) / PROBE_EPOCHS) if start else float(opt.pop_size)


def mealpy_solver(name: str, **options) -> Solver:
    """Any optimiser of mealpy by its class or module name: ``mealpy:GWO``, ``mealpy:OriginalWOA``, ..."""
    name = name.strip()
    if not name:
        raise InputError(f"solver mealpy: needs an optimiser name, e.g. mealpy:GWO; {LIST_HINT}")
    # Without mealpy the name cannot be checked; the solver is unavailable and says what to install.
    return Mealpy(name, **options)


def members() -> list[str]:
    """Every optimiser class name of mealpy (empty without mealpy)."""
    if importlib.util.find_spec("mealpy") is None:
        return []
    return sorted(optimizers())


def describe_member(name: str) -> dict:
    """One optimiser: its class, module, the first line of its docstring and its constructor's settings (but
    ``epoch``, which the solver's own option sets)."""
    cls = resolve(name)
    doc = (cls.__doc__ or "").strip().splitlines()
    return {"class": cls.__name__, "module": cls.__module__, "doc": doc[0].strip() if doc else "",
            "settings": {k: (None if p.default is inspect.Parameter.empty else p.default)
                         for k, p in settings_of(cls).items() if k != "epoch"}}


mealpy_solver.family = Mealpy.family
mealpy_solver.options = Mealpy.options
mealpy_solver.requires = Mealpy.requires
mealpy_solver.list_hint = LIST_HINT
mealpy_solver.unavailable_message = Mealpy.unavailable_message
mealpy_solver.members = members
mealpy_solver.describe_member = describe_member
register_family("mealpy", mealpy_solver)
