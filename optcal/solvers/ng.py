"""``ng:NAME``: any optimiser registered in nevergrad (``nevergrad.optimizers.registry``), as a solver family.

``ng:NGOpt``, ``ng:TwoPointsDE``, ``ng:OnePlusOne``, ``ng:CMA``, ...: the suffix is the optimiser's name in
nevergrad's registry (Rapin & Teytaud 2018, "Nevergrad - A gradient-free optimization platform",
https://github.com/facebookresearch/nevergrad); docs/algorithms.md, "nevergrad's optimisers (`ng:<NAME>`)". The family
is registered with :func:`optcal.solvers.registry.register_family`; nevergrad is imported only when an ``ng:`` solver
is built.
"""

from __future__ import annotations

import difflib
import importlib.util
import inspect
import math
import warnings

import numpy as np

from optcal.core.errors import BudgetExhausted, InputError
from optcal.solvers._unitbox import normalised_start
from optcal.solvers.base import Option, Solver
from optcal.solvers.registry import register_family

INSTALL = 'pip install "optcal[nevergrad]"'
LIST_HINT = 'python -c "import nevergrad as ng; print(sorted(ng.optimizers.registry))"'


def default_batch(n: int) -> int:
    """4 + ⌊3 ln n⌋, CMA-ES's default population (the batch when ``batch=0``)."""
    return 4 + int(3 * math.log(n))


class Nevergrad(Solver):
    """A nevergrad optimiser (``ng:NAME``) in the problem's unit box, a batch of candidates per evaluation.

    The parametrization is the one nevergrad recommends for a bounded array, ``ng.p.Array(init=z0,
    lower=-1, upper=1)``: the problem's unit box z ∈ [-1, 1]^n (2020 paper §3.4), starting at ``x0`` (the
    presets or the initialiser), with nevergrad's bound handling and its initial mutation scale for a
    bounded array (a sixth of the range, 1/3). Its ``random_state`` is a ``numpy.random.RandomState``
    seeded from ``rng``; nevergrad draws its random numbers there.

    The optimiser is built with ``budget`` = the evaluations the problem has left (None without an
    evaluation limit) and ``num_workers`` = ``batch``, then asked ``batch`` candidates at a time (fewer
    for the last batch of the budget), which are evaluated by ONE ``problem.cost_batch`` call and told
    back one by one; one batch is one iteration. ``batch=0`` is 4 + ⌊3 ln n⌋, or 1 for an optimiser nevergrad
    marks as sequential-only (``no_parallelization``). ``num_workers`` is also what nevergrad's
    meta-optimisers (NGOpt) use, with the budget and the dimension, to choose their algorithm. A
    non-finite cost is told as +inf (nevergrad's own value for a failed evaluation).

    Options: ``batch``, and any keyword of the optimiser's constructor: for a configured family such as
    ``TwoPointsDE`` (``DifferentialEvolution(crossover="twopoints")``) the family's settings
    (``--option F1=0.5 --option popsize=30``), replacing the registered ones; for an optimiser class (``NGOpt``,
    ``CMA``) whatever its ``__init__`` takes beyond ``parametrization, budget, num_workers`` (usually
    nothing). They are checked when the solver is built, by building the optimiser on a small problem.

    Stopping: a solve takes the stagnation rule (:class:`optcal.solvers.base.Stagnation`) only with
    ``stop_on_stagnation=True``: at the compare study's 2,000 evaluations NGOpt and OnePlusOne still improve,
    and TwoPointsDE's best cost stays flat for a tenth of the budget and then improves (the rule would end 92 %
    of its runs and raise its RMSE/CRLB from 11.1 to 16.6; docs/performance.md, "Stopping at convergence").

    Budget: the problem enforces it; the optimiser is asked exactly the evaluations left, so a binding
    budget is used exactly (a time or target budget ends the solve through the problem). The default
    budget, 5000 evaluations, is smaller than the other metaheuristics' because nevergrad's own work per
    candidate is far larger than an evaluation here (docs/performance.md gives the figures).
    """

    name = "ng"
    family = "metaheuristic"
    requires = ("nevergrad",)
    default_budget = 5000
    options = {
        "batch": Option(0, int, "candidates per cost_batch call, nevergrad's num_workers; 0: 4 + floor(3 ln n), "
                        "or 1 if the optimiser is sequential-only", check=lambda v: v >= 0, check_doc=">= 0"),
        "stop_on_stagnation": Option(False, bool, "end the solve by the stagnation rule a study gives (off: "
                                     "TwoPointsDE's best cost stays flat for stretches, then improves)"),
    }

    def __init__(self, optimizer: str, **options):
        self.name = f"ng:{optimizer}"
        self.optimizer = optimizer
        ours = {k: v for k, v in options.items() if k in self.options}
        self.passthrough = {k: v for k, v in options.items() if k not in self.options}
        super().__init__(**ours)
        self.stops_on_stagnation = self.config["stop_on_stagnation"]
        self._factory = None
        if self.is_available():
            self._factory = self._build_factory()

    @classmethod
    def unavailable_message(cls) -> str:
        return f"the ng: solvers need nevergrad; install it with {INSTALL}"

    # -- building the optimiser ------------------------------------------------------------------
    def _build_factory(self):
        """nevergrad's registered optimiser, reconfigured with the pass-through options, and checked."""
        import nevergrad as ng
        from nevergrad.optimization.base import ConfiguredOptimizer

        registry = ng.optimizers.registry
        base = registry[self.optimizer]
        opts = self.passthrough
        if isinstance(base, ConfiguredOptimizer):
            params = inspect.signature(type(base).__init__).parameters
            unknown = sorted(set(opts) - set(params) - {"self"})
            if unknown:
                keys = ", ".join(k for k in params if k != "self")
                raise InputError(f"solver {self.name}: unknown option(s) {', '.join(unknown)}; its options are "
                                 f"batch, stop_on_stagnation and nevergrad's {type(base).__name__} settings: {keys}")
            factory = self._checked(lambda: type(base)(**{**base.config(), **opts})) if opts else base
        else:
            params = inspect.signature(base.__init__).parameters
            fixed = {"self", "parametrization", "budget", "num_workers"}
            takes = [k for k in params if k not in fixed and params[k].kind is not inspect.Parameter.VAR_KEYWORD]
            unknown = sorted(set(opts) - set(takes)) if not any(
                p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()) else []
            if unknown:
                more = f"nevergrad's {base.__name__} also takes {', '.join(takes)}" if takes else (
                    f"nevergrad's {base.__name__} takes no settings of its own")
                raise InputError(f"solver {self.name}: unknown option(s) {', '.join(unknown)}; its options are "
                                 f"batch, stop_on_stagnation ({more})")

            def factory(parametrization, budget, num_workers):
                return base(parametrization=parametrization, budget=budget, num_workers=num_workers, **opts)

        batch = self.config["batch"] or (1 if getattr(base, "no_parallelization", False) else 2)
        self._checked(lambda: factory(parametrization=ng.p.Array(init=np.zeros(2), lower=-1.0, upper=1.0),
                                      budget=100, num_workers=batch))
        return factory

    def _checked(self, build):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return build()
        except InputError:
            raise
        except Exception as exc:  # noqa: BLE001 - nevergrad's own checks raise many kinds; one line to the user
            text = str(exc).strip().splitlines()
            raise InputError(f"solver {self.name}: nevergrad refused the settings {self.passthrough or '{}'} "
                             f"(batch={self.config['batch']}): {type(exc).__name__}: "
                             f"{text[0] if text else ''}") from None

    def _batch(self, n: int) -> int:
        if self.config["batch"]:
            return self.config["batch"]
        import nevergrad as ng

        sequential = getattr(ng.optimizers.registry[self.optimizer], "no_parallelization", False)
        return 1 if sequential else default_batch(n)

    # -- the search -------------------------------------------------------------------------------
    def _solve(self, problem, x0, rng, callback):
        import nevergrad as ng
        from nevergrad.common import errors as ng_errors

        zp, z0 = normalised_start(problem, x0)
        n, counter = zp.n, problem.counter
        max_evals = counter.budget.max_evals
        left = None if max_evals is None else max_evals - counter.nfev
        batch = self._batch(n)
        param = ng.p.Array(init=z0, lower=-1.0, upper=1.0)
        param.random_state = np.random.RandomState(int(rng.integers(2**32)))
        nit, asked = 0, 0
        with warnings.catch_warnings():
            # nevergrad warns when told +inf (a failed candidate) and about its own settings, and the pycma
            # inside some of its optimisers about its internals: expected here, and not the user's to act on
            warnings.simplefilter("ignore", ng_errors.NevergradWarning)
            warnings.filterwarnings("ignore", module=r"(nevergrad|cma)(\.|$)")
            try:
                opt = self._factory(parametrization=param, budget=left, num_workers=batch)
            except Exception as exc:  # noqa: BLE001 - e.g. an optimiser that cannot handle this dimension
                raise InputError(f"solver {self.name}: nevergrad cannot run it on this problem "
                                 f"({n} parameters): {type(exc).__name__}: {exc}") from None
            cost_batch = zp.cost_batch
            try:
                while left is None or asked < left:
                    k = batch if left is None else min(batch, left - asked)
                    cands = [opt.ask() for _ in range(k)]
                    asked += k
                    f = cost_batch(np.array([c.value for c in cands], float))
                    for c, v in zip(cands, f.tolist()):
                        opt.tell(c, v if v < math.inf else math.inf)  # NaN (and +inf) told as +inf
                    nit += 1
                    callback(nit)
            except BudgetExhausted as exc:  # a time or target budget
                return {"nit": nit, "status": 1, "success": True, "message": f"{exc} after {nit} batches of {batch}",
                        "extra": {"batch": batch, "optimizer": opt.name}}
        return {"nit": nit, "status": 1 if left is not None else 0, "success": True,
                "message": f"nevergrad {opt.name}: budget of {left} evaluations asked in {nit} batches of {batch}",
                "extra": {"batch": batch, "optimizer": opt.name}}


def ng_solver(name: str, **options) -> Solver:
    """Any nevergrad optimiser by its registry name: ``ng:NGOpt``, ``ng:TwoPointsDE``, ``ng:CMA``, ..."""
    name = name.strip()
    if not name:
        raise InputError(f"solver ng: needs an optimiser name, e.g. ng:NGOpt; list them with {LIST_HINT}")
    if importlib.util.find_spec("nevergrad") is not None:
        import nevergrad as ng

        known = list(ng.optimizers.registry)
        if name not in known:
            raise InputError(f"unknown nevergrad optimiser {name!r} (ng:{name}); {_close(name, known)}"
                             f"list them with {LIST_HINT}")
    # Without nevergrad the name cannot be checked; the solver is unavailable and says what to install.
    return Nevergrad(name, **options)


def _close(name: str, known: list[str]) -> str:
    lower = {k.lower(): k for k in known}
    hits = difflib.get_close_matches(name.lower(), list(lower), n=5, cutoff=0.6)
    return f"close names: {', '.join(lower[h] for h in hits)}; " if hits else ""


ng_solver.family = Nevergrad.family
ng_solver.options = Nevergrad.options
ng_solver.requires = Nevergrad.requires
ng_solver.list_hint = LIST_HINT
ng_solver.unavailable_message = Nevergrad.unavailable_message
register_family("ng", ng_solver)
