"""optcal's airspeed velocity (asv) suite: accuracy, success and anytime area of a study's solvers tracked
across commits (``track_*``), and the time of the kernels, of a calibration per backend and of a study run
(``time_*``). asv.conf.json at the repository root runs it; docs/tracking.md says how.

The suite uses only names that every benchmarked commit has (``load``, ``run_study``, ``groups``,
``anytime.collect``, ``simulate``, ``CalibrationProblem``, ``solvers.get``), each looked up where the commit
keeps it (``benchmarks/_paths.py``: the layers' folders since issue #30, the old paths before), so it runs
unchanged over past commits.
"""
