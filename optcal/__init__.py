"""optcal: reference-free calibration of triaxial accelerometers, and a bench for comparing optimisers.

The problem library: models, schemes, simulation, data I/O, the calibration problem, analysis
(observability, Cramér-Rao bounds), discovery, navigation, calibration files and the CLI. It never
imports ``solvers`` or ``studies``; where it needs a fit it asks the registry by name at run time.
"""

from .data import PositionsData, read_positions
from .discovery import DiscoveryReport, discover
from .errors import BudgetExhausted, InputError
from .model import NAMED_MODELS, TERMS, Context, Model, get_model
from .problem import Budget, CalibrationProblem
from .simulate import Simulation, simulate

__version__ = "0.1.0"

__all__ = [
    "NAMED_MODELS", "TERMS", "Budget", "BudgetExhausted", "CalibrationProblem", "Context", "InputError", "Model",
    "DiscoveryReport", "PositionsData", "Simulation", "discover", "get_model", "read_positions", "simulate",
]
