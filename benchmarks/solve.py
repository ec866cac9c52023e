"""``time_*``: the evaluation kernel and one calibration per solver backend, on the CI study's problem (the
2020 paper's truth, nonlinear12, 24 positions, 10 µg noise, manufacturer presets)."""

from __future__ import annotations

import numpy as np

from benchmarks._paths import module

BACKENDS = ["scipy-lm", "nlopt-bobyqa", "cmaes", "pso", "staged:bsas", "nafsa"]
BUDGET = 2000  # evaluations per calibration


def _problem():
    presets_mod = module("optcal.core.presets")
    PAPER_TRUTH, manufacturer_presets = presets_mod.PAPER_TRUTH, presets_mod.manufacturer_presets
    CalibrationProblem = module("optcal.core.problem").CalibrationProblem
    simulate = module("optcal.core.simulate").simulate

    rng = np.random.default_rng(4242)
    sim = simulate("nonlinear12", PAPER_TRUTH, rng, scheme="24", noise_g=10e-6, tilt_deg=1.0)
    presets = manufacturer_presets(PAPER_TRUTH, rng, 1.0)
    return CalibrationProblem("nonlinear12", sim.data, presets=presets, noise_g=10e-6)


def _compile():
    """Compile the kernel once per commit (numba caches it on disk beside the installed package), outside
    every timed process: after an install the first evaluation compiles for about half a minute."""
    return module("optcal.core.warmup").warm()


class Kernel:
    """The cost of a population of 100 candidates in one call, and the Jacobian of one."""

    setup_cache = staticmethod(_compile)
    timeout = 300

    def setup(self, _):
        self.p = _problem()
        self.p.start(None)
        self.Z = self.p.x0 + 1e-4 * np.random.default_rng(0).standard_normal((100, self.p.n))

    def time_cost_batch_100(self, _):
        self.p.cost_batch(self.Z)

    def time_jacobian(self, _):
        self.p.jacobian(self.p.x0)


class Calibrate:
    """One calibration of the CI problem, per backend, with a budget of 2,000 evaluations."""

    params = BACKENDS
    param_names = ["solver"]
    timeout = 300
    setup_cache = staticmethod(_compile)

    def setup(self, _, name):
        solvers = module("optcal.solvers")
        if not solvers.get(name).is_available():
            raise NotImplementedError  # asv: skipped
        self.p = _problem()
        self.solver = solvers.get(name)

    def time_calibrate(self, _, name):
        self.solver.solve(self.p, budget=BUDGET, rng=np.random.default_rng(1))
