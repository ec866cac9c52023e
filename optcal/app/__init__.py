"""The application layer: what a user runs. The command line (:mod:`optcal.app.cli`, one module per command
in :mod:`optcal.app.commands`), the workflows that run a solver on a core problem
(:mod:`optcal.app.workflows`, :mod:`optcal.app.fit`, :mod:`optcal.app.imu`) and the Python API
(:mod:`optcal.app.api`, :mod:`optcal.app.study`), whose names :mod:`optcal` re-exports. It may import every
layer below it: :mod:`optcal.studies`, :mod:`optcal.solvers` and :mod:`optcal.core`. This file imports nothing.
"""
