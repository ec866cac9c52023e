"""Calibration solvers: one module per backend, the Solver contract and the registry.

Every module in this package (other than ``base``, ``registry`` and names starting with ``_``) is imported by
the registry before it answers for a name it does not hold (:func:`optcal.solvers.registry.load_builtins`), so a
new solver is added by dropping one file that calls :func:`optcal.solvers.registry.register` (see
CONTRIBUTING.md). This plugin discovery stays inside the package: the names come from the package's own
folder and are imported relative to it, so it cannot reach another layer; third-party solvers come in
through the ``optcal.solvers`` entry points (:func:`optcal.solvers.registry.load_entry_points`).
"""

from optcal.solvers.base import Option, Solver, SolverResult
from optcal.solvers.registry import describe_all, get, names, register, register_variant, register_wrapper

__all__ = ["Option", "Solver", "SolverResult", "describe_all", "get", "names", "register", "register_variant",
           "register_wrapper"]
