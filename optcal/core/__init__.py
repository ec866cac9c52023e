"""The core layer: the calibration problem and everything that needs no solver.

Models and their terms, schemes, simulation, reading data and raw recordings (rest detection included), the
calibration problem and its compiled kernels, analysis (the Cramér-Rao bound, observability), discovery's
statistics, noise, navigation, the gyroscope's model and problem, the planner's criteria, figures, and
calibration files with their exchange formats. It imports neither :mod:`optcal.solvers`, :mod:`optcal.studies`
nor :mod:`optcal.app` (the ``layers`` contract in pyproject.toml). This file imports nothing.
"""
