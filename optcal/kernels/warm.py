"""Compile (or load from numba's on-disk cache) every entry point of the evaluation kernel.

The first evaluation after installing optcal compiles the kernel (about 10 s on the 2-core development
machine; docs/performance.md); later processes load the cached machine code in a fraction of a second.
Study runners call :func:`warm` once in the coordinating process before starting workers, so the
workers load instead of compiling side by side; ``python -m optcal.kernels.warm`` does the same after an
install and reports the time.
"""

from __future__ import annotations

import sys
import time

import numpy as np


def warm() -> float:
    """Evaluate a small problem of each kind (norm and reference residuals, both forward variants,
    one candidate, a batch, the Jacobian); returns the seconds it took."""
    from ..data import PositionsData
    from ..problem import CalibrationProblem
    from ..schemes import scheme

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
