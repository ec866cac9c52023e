"""optcal's airspeed velocity (asv) suite: accuracy, success and anytime area of a study's solvers tracked
across commits (``track_*``), and the time of the kernels, of a calibration per backend and of a study run
(``time_*``). asv.conf.json at the repository root runs it; docs/tracking.md says how.

The suite uses only names that every benchmarked commit has (``optcal.studies.spec.load``,
``optcal.studies.execute.run_study``, ``optcal.studies.metrics.groups``, ``optcal.studies.anytime.collect``, ``optcal.simulate``,
``optcal.core.problem.CalibrationProblem``, ``solvers.get``), so it runs unchanged over past commits.
"""
