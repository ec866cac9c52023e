"""``optcal study run SPEC`` and ``optcal study report DIR``: Monte-Carlo comparison studies (docs/design.md,
"Studies").

One file in ``optcal/app/commands/``, found by the command line like every other; the work is in
:mod:`optcal.app.study_cli`, imported when the command runs.
"""

from __future__ import annotations

HELP = "run a comparison study from a TOML spec, write a study folder's report, or export its runs"


def add_arguments(parser) -> None:
    sub = parser.add_subparsers(dest="study_command", required=True, metavar="{run,report,export}")
    r = sub.add_parser("run", help="run a study spec (a path, or a shipped spec: compare, bsas2020, nafsa2015, "
                                   "traditional, ci); finished trials in --out are skipped",
                       description="Run a study spec into a folder; a killed study resumes where it stopped.")
    r.add_argument("spec", metavar="SPEC", help="spec file, or the name of a shipped spec")
    r.add_argument("--out", metavar="DIR", help="output folder (default out/<spec name>)")
    r.add_argument("--executor", choices=("serial", "processes", "dask"), help="default: the spec's")
    r.add_argument("--workers", type=int, metavar="N", help="worker processes (processes, dask)")
    r.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler, e.g. tcp://host:8786")
    r.add_argument("--quick", action="store_true", help="the spec's quick variant (quick_runs runs)")
    r.add_argument("--runs", type=int, metavar="N", help="override the number of Monte-Carlo runs")
    r.add_argument("--limit", type=int, metavar="N", help="run at most N pending trials, then stop")
    r.add_argument("--no-report", action="store_true", help="do not write report.md at the end")
    r.add_argument("--no-progress", action="store_true", help="no progress bar")
    p = sub.add_parser("report", help="write report.md, figures and summary.json for a study folder",
                       description="Write report.md, parameters.md, summary.json and figures/ for a study folder.")
    p.add_argument("dir", metavar="DIR", help="a study folder (holding study.sqlite)")
    e = sub.add_parser("export", help="write a study folder's runs in the IOHprofiler format (IOHanalyzer, "
                                      "iohinspector), its metrics for github-action-benchmark, or its baseline "
                                      "check as JUnit XML",
                       description="Write the study's results for other tools (docs/studies.md, docs/tracking.md): "
                                   "ioh: the runs (best cost so far against evaluations) in the IOHprofiler json + "
                                   ".dat format; github-action-benchmark: each solver's metrics with their 95 %% "
                                   "intervals, for hosted CI charts and gates; junit: the check against a baseline "
                                   "(--baseline) as JUnit XML.")
    e.add_argument("dir", metavar="STUDY_DIR", help="a study folder (holding study.sqlite)")
    e.add_argument("--format", default="ioh", choices=("ioh", "github-action-benchmark", "junit"),
                   help="output format (default ioh)")
    e.add_argument("--baseline", metavar="FILE", help="junit: the baseline file (default for the CI spec: "
                                                      "optcal/studies/ci_tolerances.toml)")
    e.add_argument("-o", "--out", required=True, metavar="DIR", help="output folder: new, or an empty one")


def run(args) -> int:
    from optcal.app import study_cli as cli
    from optcal.core.errors import InputError
    if args.study_command == "run":
        if args.runs is not None and args.runs < 1:
            raise InputError(f"--runs must be at least 1, got {args.runs}")
        if args.limit is not None and args.limit < 0:
            raise InputError(f"--limit must be non-negative, got {args.limit}")
        return cli.run(args)
    if args.study_command == "export":
        return cli.export(args)
    return cli.report(args)
