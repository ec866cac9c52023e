"""Compile (or load from numba's on-disk cache) every entry point of the evaluation kernel.

The first evaluation after installing optcal compiles the kernel (about 10 s on the 2-core development
machine; docs/performance.md); later processes load the cached machine code in a fraction of a second.
Study runners call :func:`warm` once in the coordinating process before starting workers, so the
workers load instead of compiling side by side; ``python -m optcal.kernels.warm`` does the same after an
install and reports the time.
"""

from __future__ import annotations

import logging
import os
import sys
import time
from pathlib import Path

import numpy as np

COLD_NOTE = ("optcal: compiling the evaluation kernels (the first use after an install: about half a minute; "
             "numba caches them for every later run)")


def is_cold() -> bool:
    """True when numba has no cached machine code of the kernel yet (the next evaluation compiles it).

    Looks where numba's cache locators put the index files, without importing numba: ``__pycache__``
    beside the source, ``$NUMBA_CACHE_DIR``, and the user-wide cache (for a read-only install)."""
    here = Path(__file__).parent
    pattern = "evaluate.cost_one-*.nbi"
    if any((here / "__pycache__").glob(pattern)):
        return False
    for root in (os.environ.get("NUMBA_CACHE_DIR"), Path.home() / ".cache" / "numba"):
        if root and Path(root).is_dir() and any(Path(root).rglob(pattern)):
            return False
    return True


def load():
    """The compiled kernel module; a first use that has to compile it (after an install) says so on the
    ``optcal`` logger, rather than pausing silently."""
    if is_cold():
        logging.getLogger("optcal").warning(COLD_NOTE)
    from . import evaluate

    return evaluate


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
