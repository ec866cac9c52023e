"""The ``optcal study`` command's work: ``run`` a spec into a folder (then write its report), ``report``,
``export`` (:mod:`optcal.studies.export`).

The study machinery (trials, NumPy, SciPy, the solvers, matplotlib for the report) is imported inside the
functions, so that importing this module costs nothing.
"""

from __future__ import annotations

import sys
from pathlib import Path


def default_folder(spec) -> Path:
    return Path("out") / spec.name


def run(args) -> int:
    from optcal.studies.execute import run_study
    from optcal.studies.report import headline, write_report
    from optcal.studies.spec import load

    spec = load(args.spec)
    if args.quick:
        spec = spec.quick()
    if args.runs is not None:
        spec = spec.with_runs(args.runs)
    folder = Path(args.out) if args.out else default_folder(spec)
    total = spec.runs * len(spec.models) * len(spec.schemes) * len(spec.solvers)
    print(f"study {spec.name}: {len(spec.solvers)} solver configurations × {len(spec.models)} model(s) × "
          f"{len(spec.schemes)} scheme(s) × {spec.runs} runs = {total} trials -> {folder}", file=sys.stderr)
    s = run_study(spec, folder, executor=args.executor, workers=args.workers, scheduler=args.scheduler,
                  progress=None if not args.no_progress else False, limit=args.limit,
                  live_report=not args.no_report)
    print(f"study {spec.name}: ran {s.ran} trials ({s.failed} failed), skipped {s.skipped} already stored, "
          f"in {s.wall_s:.1f} s with {s.executor}" + (f" ×{s.workers}" if s.executor != "serial" else ""))
    if not args.no_report:
        out = write_report(folder)
        print(headline(folder))
        print(f"report: {out}")
    return 0


def report(args) -> int:
    from optcal.studies.report import write_report

    out = write_report(args.dir)
    print(f"report: {out}")
    return 0


def export(args) -> int:
    from optcal.studies.export import export as write

    c = write(args.dir, args.out, args.format, getattr(args, "baseline", None))
    print(f"exported {c['runs']} runs of {c['algorithms']} algorithm(s) on {c['problems']} problem(s) to "
          f"{c['folder']} ({args.format} format)")
    for line in c.get("regressions", []):
        print("REGRESSION:", line)
    return 1 if c.get("regressions") else 0
