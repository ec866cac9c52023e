"""Where the compiled kernel comes from: numba's on-disk cache, or a first compilation after an install.

The first evaluation after installing optcal compiles the kernel (docs/performance.md gives the time);
later processes load the cached machine code. :func:`load` is how the problem gets the kernel module, and
says on the ``optcal`` logger when it is about to compile rather than pause silently.
:mod:`optcal.core.warmup` compiles or loads every entry point ahead of use.
"""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path

COLD_NOTE = ("compiling the evaluation kernels (the first use after an install: about half a minute; "
             "numba caches them for every later run)")


def is_cold() -> bool:
    """True when numba has no cached machine code of the kernel yet (the next evaluation compiles it).

    Looks where numba's cache locators put the index files, without importing numba: ``__pycache__``
    beside the source, ``$NUMBA_CACHE_DIR``, and the user-wide cache (for a read-only install). Any entry
    point of the kernel cached for this Python counts: a command that evaluates only batches and Jacobians
    (a plain least-squares fit) caches those and never the single-candidate ``cost_one`` that the warm-up
    also compiles; that entry point compiles alone when first needed (issue #22: after a plain
    ``pip install -e .`` every command warned, whatever it had compiled before)."""
    here = Path(__file__).parent
    pattern = f"evaluate.*.py{sys.version_info.major}{sys.version_info.minor}.nbi"
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
    from optcal.core.kernels import evaluate

    return evaluate
