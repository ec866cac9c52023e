"""Compile (or load from numba's on-disk cache) every entry point of the evaluation kernel ahead of use.

Study runners call :func:`warm` once in the coordinating process before starting workers, so the
workers load instead of compiling side by side; ``python -m optcal.core.warmup`` does the same after an
install (the Makefile's install step) and reports the time. It lives beside, not inside,
``optcal.core.kernels``: it builds calibration problems, and the problem loads the kernel
(:func:`optcal.core.kernels.cache.load`), so inside the kernel package it would close an import cycle.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from optcal.core.data import PositionsData
from optcal.core.problem import CalibrationProblem
from optcal.core.schemes import scheme


def warm() -> float:
    """Evaluate a small problem of each kind (norm and reference residuals, both forward variants,
    one candidate, a batch, the Jacobian); returns the seconds it took."""
    t0 = time.perf_counter()
    A = scheme("24", np.random.default_rng(0))
    for model, reference in (("seed15", False), ("linear9+cubic", False), ("seed15", True),
                             ("linear9+cubic", True)):
        data = PositionsData(N=A * 1.001 + 1e-4, ref=A, t=None)
        p = CalibrationProblem(model, data, reference=reference).normalised()
        z = np.zeros(p.n)
        p.start(None)
        p.cost(z)
        p.cost_batch(np.zeros((2, p.n)))
        p.residuals(z)
        p.jacobian(z)
    return time.perf_counter() - t0


def main() -> int:
    seconds = warm()
    print(f"optcal: evaluation kernels ready in {seconds:.1f} s (compiled once after an install, then loaded "
          "from numba's cache)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
