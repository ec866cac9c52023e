"""Calibration solvers: one module per backend, the Solver contract and the registry.

Every module in this package (other than ``base`` and ``registry``) is imported here, so a new solver
is added by dropping one file that calls :func:`solvers.registry.register` (see CONTRIBUTING.md).
"""

import importlib
import pkgutil

from .base import Option, Solver, SolverResult
from .registry import describe_all, get, names, register, register_variant, register_wrapper

for _m in sorted(m.name for m in pkgutil.iter_modules(__path__)):
    if _m not in ("base", "registry") and not _m.startswith("_"):
        importlib.import_module(f"{__name__}.{_m}")

__all__ = ["Option", "Solver", "SolverResult", "describe_all", "get", "names", "register", "register_variant",
           "register_wrapper"]
